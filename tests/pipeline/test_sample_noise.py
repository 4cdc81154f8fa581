"""How many surface samples an object gets, and the noise they leave in the exitance (issue 11): the pixel rule
(``sample_density``), the profile rule (``profile_samples``), the cap, and a two-seed noise measurement."""

import math

import numpy as np
import pytest

import convsss
from convsss.pipeline.irradiance import sample_count

#: Bound on the two-seed noise of the small bunny (measured 0.87-1.31 %: see the test).
NOISE_BOUND = 0.02


def test_sample_count_takes_the_larger_of_the_two_rules():
    # 4 per cell of 0.5 mm over 100 mm^2: 1600; 1500 per 2 mm^2 of profile: 75 000.
    assert sample_count(100.0, 0.5, 4.0) == 1600
    assert sample_count(100.0, 0.5, 4.0, 2.0, 1500.0) == 75_000
    assert sample_count(100.0, 0.5, 4.0, 200.0, 1500.0) == 1600  # a wide profile: the pixels decide
    assert sample_count(100.0, 0.5, 4.0, 2.0, 0.0) == 1600  # rule off
    assert sample_count(100.0, 0.5, 4.0, math.inf, 1500.0) == 1600  # a profile that is zero everywhere
    assert sample_count(0.01, 0.5, 4.0) == 64


def _dense_sphere(mi, sphere_scene, **integrator):
    """A 1 mm cream sphere (core width 0.11 mm) at 24 x 24: the pixel footprint, 0.18 mm, is wider than the core."""
    return mi.load_dict(sphere_scene(material="cream", radius=1.0, res=24, integrator=integrator))


@pytest.mark.slow
def test_a_dense_medium_gets_the_profile_rule_count(mi, sphere_scene):
    from convsss.pipeline.params import PROFILE_SAMPLES
    from convsss.transport.multiscale import core_width

    scene = _dense_sphere(mi, sphere_scene)
    integrator = scene.integrator()
    integrator.prepare(scene, scene.sensors()[0], 0)
    obj = integrator.stats["objects"][0]
    profile = integrator.prepared.objects[0].profile
    assert obj["pixel_footprint_mm"] > core_width(profile)
    area_eff = float(np.min(profile.effective_area()))
    wanted = math.ceil(PROFILE_SAMPLES * obj["area_mm2"] / area_eff)
    assert obj["samples_profile_rule"] == wanted
    assert obj["samples_pixel_rule"] == math.ceil(4.0 * obj["area_mm2"] / obj["cell_size_mm"] ** 2)
    assert wanted > 3 * obj["samples_pixel_rule"]  # the rule this test is about decides
    assert obj["samples"] == math.ceil(math.sqrt(wanted)) ** 2  # a stratified k x k square at least that large
    assert obj["samples_per_profile_area"] >= PROFILE_SAMPLES

    scene = _dense_sphere(mi, sphere_scene, profile_samples=0.0)
    integrator = scene.integrator()
    integrator.prepare(scene, scene.sensors()[0], 0)
    obj = integrator.stats["objects"][0]
    assert obj["samples"] == math.ceil(math.sqrt(obj["samples_pixel_rule"])) ** 2


@pytest.mark.slow
def test_the_profile_rule_is_capped_with_a_warning(mi, sphere_scene, monkeypatch):
    """A count above the rule's share of the memory guard is cut to it (never below the pixel rule), with a
    warning; the render goes on."""
    from convsss.pipeline import plan as module

    scene = _dense_sphere(mi, sphere_scene)
    integrator = scene.integrator()
    monkeypatch.setattr(module, "available_memory", lambda: 5_000 * module.BYTES_PER_SAMPLE / module.USABLE_FRACTION
                        / module.PROFILE_RULE_MEMORY)
    with pytest.warns(module.SampleNoiseWarning, match=r"surface samples would keep its sample noise"):
        integrator.prepare(scene, scene.sensors()[0], 0)
    obj = integrator.stats["objects"][0]
    assert obj["samples_profile_rule"] > 5_000
    assert obj["samples"] == math.ceil(math.sqrt(max(5_000, obj["samples_pixel_rule"]))) ** 2


def _exitance_noise(mi, profile_samples, stratified, seeds=(0, 1)):
    """Mean over the visible pixels of the relative standard deviation of ``M`` between two sample seeds (the
    larger over the channels): ``|M_0 - M_1| / sqrt(2)``, divided by ``c4(2) = sqrt(2/pi)`` (the mean bias of a
    two-draw standard deviation), relative to the mean of the two."""
    import convsss.pipeline.surface as surface
    from convsss.scene.quick import demo_mesh, quick_scene

    options = {} if profile_samples is None else {"profile_samples": profile_samples}
    d = quick_scene(demo_mesh(), convsss.material("wholemilk"), 4.0, 32, 32, 1, boundary="null",
                    integrator={"type": "convsss", "walk_depth": 0.0, **options})
    scene = mi.load_dict(d)
    integrator = scene.integrator()
    values = []
    saved = surface.MESH_STRATIFICATION
    surface.MESH_STRATIFICATION = stratified
    try:
        for seed in seeds:
            integrator.prepare(scene, scene.sensors()[0], seed)
            visible = integrator.prepared.visible[0]
            values.append(integrator.prepared.transports[0].exitance(visible.position, visible.normal))
    finally:
        surface.MESH_STRATIFICATION = saved
    mean = 0.5 * (values[0] + values[1])
    relative = np.abs(values[0] - values[1]) / math.sqrt(2) / math.sqrt(2 / math.pi) / np.maximum(
        mean, 0.01 * mean.mean(axis=0))
    return float(relative.mean(axis=0).max()), integrator.stats["objects"][0]["samples"]


@pytest.mark.slow
def test_sample_noise_of_a_small_bunny_stays_below_the_measured_bound(mi):
    """The 4 mm whole-milk bunny at 32 x 32 (pixel footprint 0.33 mm, core width 0.21 mm, no floor, point lights):
    with the defaults (21 316 samples) the exitance's sample noise measured 0.87-1.31 % over six pairs of seeds
    (mean over the pixels, the noisiest channel); the pixel rule alone on the plain grid over the square (2 304
    samples, as before issue 11) left 5.2-8.1 %."""
    noise, samples = _exitance_noise(mi, None, True)
    assert noise < NOISE_BOUND, (noise, samples)
    before, fewer = _exitance_noise(mi, 0.0, False)
    assert fewer < samples / 5
    assert before > 2 * NOISE_BOUND, before
