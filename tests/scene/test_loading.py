import pytest

from convsss.errors import ConvsssError
from convsss.scene.loading import load_scene


def test_resizes_the_film(mi, sphere_scene):
    scene = load_scene(sphere_scene(), width=20, height=10)
    film = scene.sensors()[0].film()
    assert list(film.size()) == [20, 10] and list(film.crop_size()) == [20, 10]


def test_errors_are_one_line(tmp_path):
    with pytest.raises(ConvsssError, match="does not exist"):
        load_scene(tmp_path / "missing.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text('<scene version="3.0.0"><shape type="nonsense"/></scene>')
    with pytest.raises(ConvsssError, match="cannot load scene") as info:
        load_scene(bad)
    assert "\n" not in str(info.value)
    with pytest.raises(ConvsssError, match="width=0"):
        load_scene({"type": "scene", "sensor": {"type": "perspective"}}, width=0)


def test_translucent_meshes_of_one_material_stay_separate_objects(mi, sphere_scene):
    """Mitsuba merges meshes sharing a BSDF and medium by default; two milk cubes must stay two objects."""
    import convsss
    from convsss.scene.materials import translucent
    from convsss.scene.objects import find_translucent_objects

    T = mi.ScalarTransform4f
    cubes = {name: translucent({"type": "cube", "to_world": T().translate([x, 0, 0])}, convsss.material("wholemilk"))
             for name, x in (("left", -3.0), ("right", 3.0))}
    scene = load_scene({**sphere_scene(), **cubes})
    names = [obj.name for obj in find_translucent_objects(mi, scene)]
    assert sorted(names) == ["left", "object", "right"]
