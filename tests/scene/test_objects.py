import warnings

import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.scene.materials import translucent
from convsss.scene.objects import MeshWarning, UnitsWarning, find_translucent_objects


def _objects(mi, shapes, unit_mm=1.0):
    return find_translucent_objects(mi, mi.load_dict({"type": "scene", **shapes}), unit_mm)


def test_material_eta_and_units_from_the_scene(mi):
    skin = convsss.material("skin1")
    shapes = {"a": translucent({"type": "sphere", "radius": 2.0}, skin, unit_mm=0.5, boundary="dielectric"),
              "b": translucent({"type": "cube"}, skin, unit_mm=0.5, boundary="null"),
              "floor": {"type": "rectangle"}}
    objects = _objects(mi, shapes, unit_mm=0.5)
    assert [o.name for o in objects] == ["a", "b"]
    a, b = objects
    np.testing.assert_allclose(a.material.sigma_s_prime, skin.sigma_s_prime, rtol=1e-6)
    np.testing.assert_allclose(a.material.sigma_a, skin.sigma_a, rtol=1e-4)
    assert a.eta == pytest.approx(skin.eta, rel=1e-4) and b.eta == 1.0
    assert a.extent_mm == pytest.approx(2.0) and a.area_mm2 == pytest.approx(4 * np.pi * 1.0, rel=1e-4)
    assert b.shape_index != a.shape_index


def test_hg_phase_reduces_scattering(mi):
    medium = {"type": "homogeneous", "sigma_t": 1.0, "albedo": 0.9, "scale": 2.0, "phase": {"type": "hg", "g": 0.5}}
    (obj,) = _objects(mi, {"s": {"type": "sphere", "bsdf": {"type": "null"}, "interior": medium}})
    np.testing.assert_allclose(obj.material.sigma_s_prime, 2.0 * 0.9 * 0.5, rtol=1e-5)
    np.testing.assert_allclose(obj.material.sigma_a, 2.0 * 0.1, rtol=1e-5)


@pytest.mark.parametrize("shape, message", [
    ({"type": "sphere"}, "no translucent shape"),
    ({"type": "sphere", "bsdf": {"type": "dielectric", "int_ior": 1.0, "ext_ior": 1.5},
      "interior": {"type": "homogeneous"}}, "eta = int_ior/ext_ior = 0.6667"),
    ({"type": "sphere", "bsdf": {"type": "diffuse"}, "interior": {"type": "homogeneous"}}, "'SmoothDiffuse' BSDF"),
    ({"type": "sphere", "bsdf": {"type": "null"}, "interior": {"type": "heterogeneous"}},
     "'HeterogeneousMedium' interior medium"),
])
def test_bad_objects(mi, shape, message):
    with pytest.raises(ConvsssError, match=message):
        _objects(mi, {"s": shape})


CUBE_VERTICES = "".join(f"v {x} {y} {z}\n" for x in (0, 1) for y in (0, 1) for z in (0, 1))
CUBE_FACES = ["1 2 4 3", "5 7 8 6", "1 5 6 2", "3 4 8 7", "1 3 7 5", "2 6 8 4"]  # outward, counter-clockwise


def _obj(path, faces):
    path.write_text(CUBE_VERTICES + "".join(f"f {f}\n" for f in faces))
    return {"type": "obj", "filename": str(path)}


def test_open_and_inverted_meshes_warn(mi, tmp_path):
    skin = convsss.material("skin1")
    with pytest.warns(MeshWarning, match="not watertight"):
        _objects(mi, {"s": translucent(_obj(tmp_path / "open.obj", CUBE_FACES[:-1]), skin)})
    inverted = [" ".join(reversed(f.split())) for f in CUBE_FACES]
    with pytest.warns(MeshWarning, match="inward-facing"):
        (obj,) = _objects(mi, {"s": translucent(_obj(tmp_path / "inverted.obj", inverted), skin)})
    assert obj.orientation == -1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (obj,) = _objects(mi, {"s": translucent(_obj(tmp_path / "closed.obj", CUBE_FACES), skin)})
    assert obj.orientation == 1.0


def test_wrong_units_warn(mi):
    skin = convsss.material("skin1")
    with pytest.warns(UnitsWarning, match="mean free paths"):
        _objects(mi, {"s": translucent({"type": "sphere", "radius": 1e6}, skin)})
    with pytest.warns(UnitsWarning, match="unit_mm"):
        _objects(mi, {"s": translucent({"type": "sphere", "radius": 1e-4}, skin)})
