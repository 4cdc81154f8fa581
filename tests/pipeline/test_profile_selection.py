"""The profile chosen per translucent object by the integrator's ``profile`` parameter."""

import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.media.dicts import translucent
from convsss.pipeline.objects import find_translucent_objects
from convsss.profiles import (
    DEFAULT_PROFILE,
    PROFILE_MODELS,
    BeamDiffusionProfile,
    BurleyProfile,
    DipoleProfile,
    TabulatedProfile,
)
from convsss.profiles.models import exact_total, model_profile


@pytest.fixture(scope="module")
def two_spheres(mi):
    T = mi.ScalarTransform4f
    scene = {"type": "scene"}
    for name, x, preset in (("milk", -3.0, "wholemilk"), ("skin", 3.0, "skin1")):
        shape = {"type": "sphere", "radius": 1.0, "to_world": T().translate([x, 0, 0])}
        scene[name] = translucent(shape, convsss.material(preset), boundary="null")
    return mi.load_dict(scene)


def _profiles(mi, scene, spec, total="model"):
    return {o.name: o.profile for o in find_translucent_objects(mi, scene, 1.0, spec, total)}


def test_by_default_every_model_has_the_exact_total(mi, two_spheres, tmp_path):
    """``profile_total`` exact: each model's profile scaled per channel to the half-space's exact total, its shape
    kept; a CSV profile as given."""
    csv = tmp_path / "flat.csv"
    csv.write_text("r_mm,R,G,B\n0,0.1,0.1,0.1\n2,0,0,0\n")
    r = np.array([0.05, 0.5, 2.0])
    for spec in PROFILE_MODELS:
        objects = {o.name: o for o in find_translucent_objects(mi, two_spheres, 1.0, f"{spec},milk={csv}")}
        assert isinstance(objects["milk"].profile, TabulatedProfile)
        skin = objects["skin"]
        own = model_profile(spec, skin.material)
        exact = exact_total(skin.material.albedo_prime, skin.material.eta)
        np.testing.assert_allclose(skin.profile.total_reflectance, exact, rtol=1e-6)
        np.testing.assert_allclose(skin.profile(r) / own(r), np.broadcast_to(exact / own.total_reflectance, (3, 3)),
                                   rtol=1e-9)


def test_one_model_for_every_object_and_per_object_choices(mi, two_spheres, tmp_path):
    assert all(isinstance(p, BeamDiffusionProfile) for p in _profiles(mi, two_spheres, "pbd").values())
    chosen = _profiles(mi, two_spheres, "skin=burley")
    assert isinstance(chosen["skin"], BurleyProfile) and type(chosen["milk"]) is PROFILE_MODELS[DEFAULT_PROFILE]
    chosen = _profiles(mi, two_spheres, "skin=burley,dipole")
    assert isinstance(chosen["skin"], BurleyProfile) and type(chosen["milk"]) is DipoleProfile
    csv = tmp_path / "flat.csv"
    csv.write_text("r_mm,R,G,B\n0,0.1,0.1,0.1\n2,0,0,0\n")
    chosen = _profiles(mi, two_spheres, f"pbd,milk={csv}")
    assert isinstance(chosen["milk"], TabulatedProfile) and isinstance(chosen["skin"], BeamDiffusionProfile)
    # each object's model profile is of its own material
    skin = chosen["skin"]
    assert skin.sigma_s_prime.tolist() == pytest.approx(convsss.material("skin1").sigma_s_prime.tolist())


def test_an_entry_for_no_object_is_refused(mi, two_spheres):
    with pytest.raises(ConvsssError, match="profile entry 'bunny'='pbd' names no translucent object; the translucent "
                                           "objects are: milk, skin"):
        find_translucent_objects(mi, two_spheres, 1.0, "bunny=pbd")
