"""The random walk (convsss.pipeline.walk): at walk_depth inf the render is a volumetric path tracer, so it equals
Mitsuba's volpathmis of the same scene within both renders' noise (two seeds each), over boundaries, lights, media
and phase functions."""

import numpy as np
import pytest

import convsss
from convsss.pipeline.reference import reference_integrator
from convsss.scene.materials import albedo_volume_dict, medium_dict, translucent

RES, SPP = 32, 256


def _lights(mi, kind, radius):
    T = mi.ScalarTransform4f
    if kind == "point":
        return {"light": {"type": "point", "position": [3 * radius, 6 * radius, 4 * radius],
                          "intensity": {"type": "rgb", "value": [50 * radius**2] * 3}}}
    if kind == "spot":
        return {"light": {"type": "spot", "cutoff_angle": 25.0,
                          "intensity": {"type": "rgb", "value": [80 * radius**2] * 3},
                          "to_world": T().look_at(origin=[-4 * radius, 5 * radius, -3 * radius], target=[0, 0, 0],
                                                  up=[0, 1, 0])}}
    if kind == "area":  # behind and above: back light through the object
        return {"light": {"type": "rectangle",
                          "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [4.0] * 3}},
                          "to_world": T().look_at(origin=[0, 3 * radius, -4 * radius], target=[0, 0, 0],
                                                  up=[0, 1, 0]).scale(1.5 * radius)}}
    return {"light": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 0.9, 0.8]}}}


def _means_and_noise(images):
    """Per channel: the two seeds' mean over the pixels, and its standard error from the seeds' per-pixel spread."""
    a, b = images
    mean = (a + b).mean(axis=(0, 1)) / 2
    error = np.sqrt(np.mean((a - b) ** 2, axis=(0, 1)) / 4 / (a.shape[0] * a.shape[1]))
    return mean, error


def _compare(mi, scene):
    walk = mi.load_dict({"type": "convsss", "walk_depth": float("inf"), "max_depth": -1})
    reference = reference_integrator()
    ours = [np.array(mi.render(scene, integrator=walk, spp=SPP, seed=s), dtype=np.float64)[..., :3] for s in (1, 2)]
    truth = [np.array(mi.render(scene, integrator=reference, spp=SPP, seed=s), dtype=np.float64)[..., :3]
             for s in (3, 4)]
    (m_ours, e_ours), (m_truth, e_truth) = _means_and_noise(ours), _means_and_noise(truth)
    assert np.all(m_truth > 0)
    # Means within 1 % beyond both noises (four standard errors).
    assert np.all(np.abs(m_ours - m_truth) <= 0.01 * m_truth + 4 * np.hypot(e_ours, e_truth)), (m_ours / m_truth)
    # Per pixel within noise: the squared difference of the two means is what the seeds' spread predicts.
    spread = np.mean((ours[0] - ours[1]) ** 2 + (truth[0] - truth[1]) ** 2) / 4
    assert np.mean(((ours[0] + ours[1]) / 2 - (truth[0] + truth[1]) / 2) ** 2) <= 1.3 * spread


@pytest.mark.parametrize("material, boundary, light", [
    ("skin1", "null", "point"),
    ("wholemilk", "roughdielectric", "point"),  # the light through the boundary's BSDF once, not also straight
    pytest.param("ketchup", "dielectric", "environment", marks=pytest.mark.slow),
    pytest.param("wholemilk", "roughdielectric", "area", marks=pytest.mark.slow),
    pytest.param("skin1", "null", "spot", marks=pytest.mark.slow),
])
def test_walking_to_the_end_is_volpathmis(mi, sphere_scene, material, boundary, light):
    scene = sphere_scene(material=material, radius=1.0, boundary=boundary, res=RES, floor=True,
                         emitters=_lights(mi, light, 1.0))
    _compare(mi, mi.load_dict(scene))


@pytest.mark.slow
def test_an_anisotropic_medium_behind_a_dielectric_is_volpathmis(mi, sphere_scene):
    scene = sphere_scene(material="marble", radius=1.0, boundary="dielectric", res=RES,
                         emitters=_lights(mi, "environment", 1.0))
    scene["object"]["interior"]["phase"] = {"type": "hg", "g": 0.8}
    _compare(mi, mi.load_dict(scene))


@pytest.mark.slow
def test_a_heterogeneous_interior_is_volpathmis(mi, sphere_scene, tmp_path):
    n = 8
    x = (np.arange(n) + 0.5) / n
    albedo = np.broadcast_to((0.5 + 0.49 * np.cos(6 * x))[None, None, :, None], (n, n, n, 3)).astype(np.float32)
    grid = tmp_path / "albedo.vol"
    mi.VolumeGrid(np.ascontiguousarray(albedo)).write(str(grid))
    to_world = mi.ScalarTransform4f().translate([-1.1] * 3).scale(2.2)
    scene = sphere_scene(material="skin1", radius=1.0, boundary="null", res=RES, emitters=_lights(mi, "area", 1.0))
    scene["object"]["interior"] = albedo_volume_dict(convsss.material("skin1"), grid, to_world)
    _compare(mi, mi.load_dict(scene))


@pytest.mark.slow
def test_two_objects_close_together_are_volpathmis(mi, sphere_scene):
    T = mi.ScalarTransform4f
    scene = sphere_scene(material="skin1", radius=0.7, boundary="null", res=RES, emitters=_lights(mi, "area", 1.0))
    scene["object"]["to_world"] = T().translate([-0.72, 0, 0])
    other = translucent({"type": "sphere", "radius": 0.7, "to_world": T().translate([0.72, 0, 0])},
                        convsss.material("marble"), boundary="null")
    scene["other"] = {**other, "interior": medium_dict(convsss.material("marble"))}
    _compare(mi, mi.load_dict(scene))
