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
