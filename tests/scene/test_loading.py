import numpy as np
import pytest

from convsss.backend import ordered_kernels
from convsss.errors import ConvsssError
from convsss.scene.loading import load_scene
from convsss.scene.quick import demo_mesh, mesh_dict


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


def test_computed_vertex_normals_are_reordered_and_given_ones_kept(mi, tmp_path):
    """The bunny has no normals: they become Mitsuba's recomputation on one thread. A PLY copy whose normals are
    Mitsuba's in even rows and others (pointing away from the centre) in odd rows keeps the odd rows as loaded."""

    def scene(shape):
        return load_scene({"type": "scene", "sensor": {"type": "perspective"}, "shape": shape}).shapes()[0]

    def normals(shape):
        return np.array(shape.vertex_normals_buffer()).reshape(-1, 3)

    bunny = scene(mesh_dict(demo_mesh()))
    computed = normals(bunny)
    with ordered_kernels():
        bunny.recompute_vertex_normals()
    assert np.array_equal(normals(bunny), computed)

    params = mi.traverse(bunny)
    position = np.array(params["vertex_positions"]).reshape(-1, 3)
    given = position - position.mean(axis=0)
    given /= np.linalg.norm(given, axis=1, keepdims=True)
    given[::2] = computed[::2]
    mesh = mi.Mesh("copy", len(position), len(params["faces"]) // 3, has_vertex_normals=True)
    copy = mi.traverse(mesh)
    copy["vertex_positions"], copy["faces"] = params["vertex_positions"], params["faces"]
    copy["vertex_normals"] = mi.Float(given.astype(np.float32).ravel())
    copy.update()
    mesh.write_ply(str(tmp_path / "copy.ply"))
    ply = {"type": "ply", "filename": str(tmp_path / "copy.ply")}
    loaded = normals(scene(ply))
    assert np.array_equal(loaded[1::2], normals(mi.load_dict(ply))[1::2])
    assert np.array_equal(loaded[::2], computed[::2])
