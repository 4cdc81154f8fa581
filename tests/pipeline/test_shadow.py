"""The shadow rays of the surface estimators (:mod:`convsss.pipeline.shadow`): one stepper, one physics."""

import drjit as dr
import numpy as np

import convsss


def _transmittance(mi, scene, ray):
    """What the scene's shadow rays let through along ``ray`` (numpy (3,) per lane)."""
    from convsss.pipeline.objects import find_translucent_objects
    from convsss.pipeline.shadow import Shadows

    objects = find_translucent_objects(mi, scene) if scene.shapes() else []
    return dr.ravel(Shadows(scene, objects, 1.0).transmittance(ray, mi.Bool(True))).numpy()


def _slab(mi, material, boundary="null", thickness=0.5):
    from convsss.media.dicts import translucent

    T = mi.ScalarTransform4f
    return translucent({"type": "cube", "to_world": T().translate([0, 0, 5]).scale([3, 3, thickness / 2])}, material,
                       boundary=boundary)


def _ray(mi):
    ray = mi.Ray3f(mi.Point3f(0, 0, 0), mi.Vector3f(0, 0, 1))
    ray.maxt = 10.0
    return ray


def test_a_delta_lights_shadow_ray_crosses_an_index_matched_medium_unscattered(mi):
    """Issue 51: light through an ear onto the head was missing (the shadow ray stopped at the translucent occluder).
    Through a 0.5 mm skin1 slab (null boundary) it arrives as e^{-sigma_t' 0.5 mm}; behind a dielectric one, none."""
    skin = convsss.material("skin1")
    for boundary, expected in (("null", np.exp(-skin.sigma_t_prime * 0.5)), ("dielectric", 0.0)):
        scene = mi.load_dict({"type": "scene", "slab": _slab(mi, skin, boundary)})
        # float32 hit distances and spawn offsets 5 mm out: the chord to about 1e-4 mm, e^{-sigma_t l} to 1e-3
        np.testing.assert_allclose(_transmittance(mi, scene, _ray(mi)), expected, rtol=1e-3, atol=1e-7)
    assert np.all(_transmittance(mi, mi.load_dict({"type": "scene"}), _ray(mi)) == 1)


def test_one_physics_the_reduced_extinction_of_an_anisotropic_medium(mi):
    """Issue 59: the irradiance samples dimmed by the medium's sigma_t, the camera's vertices by sigma_t'. One stepper
    now: e^{-sigma_t' l} for a medium of g = 0.8 (sigma_t = 5 sigma_t' here, so the other physics is far off)."""
    skin = convsss.material("skin1")
    sigma_s = skin.sigma_s_prime / (1.0 - 0.8)
    sigma_t = sigma_s + skin.sigma_a
    slab = _slab(mi, skin)
    slab["interior"] = {"type": "homogeneous", "sigma_t": {"type": "rgb", "value": (sigma_t / sigma_t.max()).tolist()},
                        "albedo": {"type": "rgb", "value": (sigma_s / sigma_t).tolist()}, "scale": sigma_t.max(),
                        "phase": {"type": "hg", "g": 0.8}}
    scene = mi.load_dict({"type": "scene", "slab": slab})
    through = _transmittance(mi, scene, _ray(mi))
    np.testing.assert_allclose(through, np.exp(-skin.sigma_t_prime * 0.5), rtol=1e-3)


def test_light_dimmed_past_the_floor_is_done(mi):
    """A shadow ray through 8 mm of whole milk (e^-20 and darker) counts as blocked, and stops stepping."""
    from convsss.pipeline.shadow import SHADOW_FLOOR

    milk = convsss.material("wholemilk")
    assert np.all(np.exp(-milk.sigma_t_prime * 8.0) < SHADOW_FLOOR)
    scene = mi.load_dict({"type": "scene", "slab": _slab(mi, milk, thickness=8.0)})
    assert np.all(_transmittance(mi, scene, _ray(mi)) == 0)
    thin = mi.load_dict({"type": "scene", "slab": _slab(mi, milk, thickness=0.1)})
    chord = -np.log(_transmittance(mi, thin, _ray(mi))) / milk.sigma_t_prime  # float32 spawn offsets: 1e-3 mm
    np.testing.assert_allclose(chord, 0.1, atol=1e-3)


def test_a_shadow_ray_crosses_a_constant_volume_as_its_homogeneous_medium(mi, tmp_path):
    """A heterogeneous medium of constant coefficients (an albedo gridvolume, a constant extinction) lets a delta
    light's beam through as its homogeneous medium does, bit for bit: it had blocked it, so the constant marble block
    of `bench media` rendered 0.5 % of the peak away from its homogeneous twin."""
    from convsss.media.dicts import medium_parameters

    skin = convsss.material("skin1")
    p = medium_parameters(skin)
    T = mi.ScalarTransform4f
    volume = tmp_path / "albedo.vol"
    mi.VolumeGrid(np.ascontiguousarray(np.broadcast_to(p["albedo"].astype(np.float32), (2, 2, 2, 3)))).write(
        str(volume))
    slab = _slab(mi, skin)
    homogeneous = _transmittance(mi, mi.load_dict({"type": "scene", "slab": slab}), _ray(mi))
    slab["interior"] = {"type": "heterogeneous", "scale": p["scale"],
                        "albedo": {"type": "gridvolume", "filename": str(volume),
                                   "to_world": T().translate([-3, -3, 4.75]).scale([6, 6, 0.5])},
                        "sigma_t": {"type": "constvolume", "value": {"type": "rgb", "value": p["sigma_t"].tolist()},
                                    "to_world": T().translate([-3, -3, 4.75]).scale([6, 6, 0.5])}}
    constant = _transmittance(mi, mi.load_dict({"type": "scene", "slab": slab}), _ray(mi))
    assert np.all(homogeneous > 0.1)
    np.testing.assert_array_equal(constant, homogeneous)
