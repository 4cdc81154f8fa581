import numpy as np
import pytest

from convsss.pipeline.reference import reference_integrator


@pytest.mark.slow
def test_opaque_shapes_get_mitsubas_direct_light(mi, sphere_scene, object_mask):
    """Off the object, max_depth 2 is direct lighting: the floor matches Mitsuba's `direct` integrator (behind a
    dielectric boundary, which both take for an occluder: through an index-matched one convsss lets the light
    through that crosses unscattered, test below)."""
    scene_dict = sphere_scene(floor=True, res=32, spp=16, integrator={"max_depth": 2}, boundary="dielectric")
    scene = mi.load_dict(scene_dict)
    ours = np.array(mi.render(scene, seed=1))[..., :3]
    theirs = np.array(mi.render(scene, integrator=mi.load_dict({"type": "direct"}), seed=1))[..., :3]
    floor = ~object_mask(scene) & (theirs.sum(axis=-1) > 0)
    assert floor.sum() > 200
    np.testing.assert_allclose(ours[floor].mean(axis=0), theirs[floor].mean(axis=0), rtol=0.01)


@pytest.mark.slow
def test_bounces_pick_up_the_objects_glow(mi, sphere_scene, object_mask):
    images = {}
    for depth in (2, 4):
        scene = mi.load_dict(sphere_scene(floor=True, res=32, spp=8, integrator={"max_depth": depth}))
        images[depth] = np.array(mi.render(scene, seed=1))[..., :3]
    floor = ~object_mask(scene)
    assert images[4][floor].sum() > images[2][floor].sum()


@pytest.mark.slow
def test_paths_ending_at_max_depth_return_evaluated_radiance(tmp_path):
    """A dielectric sphere under a constant environment, box filter, paths cut by max_depth: rendered in a child
    process, since the defect was Dr.Jit aborting the whole process ('dirty variable' in jit_assemble)."""
    import subprocess
    import sys

    code = (
        "import convsss, numpy as np\n"
        "from convsss.media.dicts import translucent\n"
        "mi = convsss.register()\n"
        "T = mi.ScalarTransform4f\n"
        "scene = mi.load_dict({'type': 'scene', 'integrator': {'type': 'convsss', 'max_depth': 2},\n"
        "    'sensor': {'type': 'perspective', 'fov': 30,\n"
        "               'to_world': T().look_at(origin=[0, 4, 16], target=[0, 0, 0], up=[0, 1, 0]),\n"
        "               'film': {'type': 'hdrfilm', 'width': 24, 'height': 24, 'rfilter': {'type': 'box'}},\n"
        "               'sampler': {'type': 'independent', 'sample_count': 2}},\n"
        "    'object': translucent({'type': 'sphere', 'radius': 2.0}, convsss.material('wholemilk'),\n"
        "                          boundary='dielectric'),\n"
        "    'env': {'type': 'constant'}})\n"
        "image = np.array(mi.render(scene))\n"
        "print(np.isfinite(image).all(), image.min() >= 0, image.mean())\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    finite, non_negative, mean = proc.stdout.split()
    assert finite == "True" and non_negative == "True" and float(mean) > 0


@pytest.mark.slow
def test_more_recorded_hits_than_room_trace_the_same_paths_again(mi, sphere_scene, monkeypatch):
    """Hits the screen table does not know are recorded in the path loop; with room for almost none, the paths are
    traced again from a copy of the sampler and the image is the same."""
    import convsss.pipeline.lookups as lookups_module

    scene = mi.load_dict(sphere_scene(material="wholemilk", res=32, spp=2, floor=True, boundary="dielectric",
                                      integrator={"indirect_samples": 0}))
    image = np.asarray(mi.render(scene, seed=3))
    lookups = scene.integrator().stats["exitance_lookups"]
    assert lookups > 10
    monkeypatch.setattr(lookups_module, "RECORD_ROOM", 1e-6)
    again = np.asarray(mi.render(scene, seed=3))
    assert scene.integrator().stats["exitance_lookups"] == lookups
    np.testing.assert_allclose(again, image, rtol=1e-5, atol=1e-7)


@pytest.mark.slow
def test_traced_single_scattering_matches_volpathmis_on_a_low_albedo_sphere(mi, sphere_scene, object_mask):
    """Ketchup's green and blue (reduced albedo 0.07, 0.02) send back almost only once-scattered light. A 4 mm sphere
    is 4-6 mean free paths across there: its curvature lets more of that light out than a half-space does, which the
    profile (a half-space's) misses, measured 10-13 % too dark; Eq. S2 traces it through the sphere and agrees with
    volumetric path tracing of the same scene (measured within 1 %)."""
    means = {}
    for mode in ("profile", "traced"):
        scene = mi.load_dict(sphere_scene(material="ketchup", radius=4.0, res=32, spp=64,
                                          integrator={"single_scattering": mode}))
        means[mode] = np.array(mi.render(scene, seed=1), dtype=np.float64)[..., :3]
    reference = np.array(mi.render(scene, integrator=mi.load_dict({"type": "volpathmis"}), seed=2, spp=1024),
                         dtype=np.float64)[..., :3]
    mask = object_mask(scene)
    ratio = {mode: image[mask].mean(axis=0) / reference[mask].mean(axis=0) for mode, image in means.items()}
    assert np.all(ratio["profile"][1:] < 0.92), ratio
    np.testing.assert_allclose(ratio["traced"][1:], 1.0, atol=0.03)


def _absorbing_sphere(mi, boundary, spp, radius=2.0):
    """A sphere of radius 2 mm that absorbs (sigma_a 0.3, 0.5, 1 /mm) and hardly scatters (sigma_s' 1e-4 /mm), under a
    constant environment of radiance 1, seen by a 32x32 camera with a box filter."""
    from convsss.materials import Material
    from convsss.media.dicts import translucent

    T = mi.ScalarTransform4f
    absorber = Material(sigma_s_prime=[1e-4] * 3, sigma_a=[0.3, 0.5, 1.0], eta=1.3)
    return mi.load_dict({
        "type": "scene", "integrator": {"type": "convsss", "walk_depth": 0.0},  # the transport's path tracer
        "sensor": {"type": "perspective", "fov": 30,
                   "to_world": T().look_at(origin=[0, 2 * radius, 8 * radius], target=[0, 0, 0], up=[0, 1, 0]),
                   "film": {"type": "hdrfilm", "width": 32, "height": 32, "rfilter": {"type": "box"}},
                   "sampler": {"type": "independent", "sample_count": spp}},
        "object": translucent({"type": "sphere", "radius": radius}, absorber, boundary=boundary),
        "environment": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0] * 3}}})


@pytest.mark.filterwarnings("ignore::convsss.materials.OpticallyThinWarning")
def test_a_ray_crosses_an_index_matched_absorber_unscattered(mi):
    """Eq. S3: through an index-matched sphere that only absorbs, each camera ray sees the environment behind it
    dimmed by ``e^{-sigma_t l}`` over its chord ``l``; the pixels (box filter) are that averaged over their area,
    computed on a 4x4 grid of rays per pixel. Measured: means within 0.12 %, pixels within 0.023 (the spp's noise
    over the pixel area); without the crossing the sphere would be black."""
    scene = _absorbing_sphere(mi, "null", spp=64)
    image = np.array(mi.render(scene, seed=1), dtype=np.float64)[..., :3]
    sub, res = 4, 32
    grid = (np.arange(res * sub) + 0.5) / (res * sub)
    u, v = np.meshgrid(grid, grid)
    rays, _ = scene.sensors()[0].sample_ray(0.0, 0.5, mi.Point2f(u.ravel(), v.ravel()), mi.Point2f(0.5, 0.5))
    origin, direction = np.array(rays.o).reshape(3, -1).T, np.array(rays.d).reshape(3, -1).T
    nearest = origin - (origin * direction).sum(axis=1, keepdims=True) * direction  # to the sphere's centre
    squared = (nearest ** 2).sum(axis=1)
    chord = 2.0 * np.sqrt(np.maximum(4.0 - squared, 0.0))
    sigma_t = np.array([0.3, 0.5, 1.0]) + 1e-4
    expected = np.exp(-chord[:, None] * sigma_t).reshape(res, sub, res, sub, 3).mean(axis=(1, 3))
    covered = (squared < 4.0).reshape(res, sub, res, sub).all(axis=(1, 3))
    assert covered.sum() > 100
    np.testing.assert_allclose(image[covered].mean(axis=0) / expected[covered].mean(axis=0), 1.0, atol=0.005)
    assert np.abs(image[covered] - expected[covered]).max() < 0.04


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::convsss.materials.OpticallyThinWarning")
def test_light_through_a_dielectric_absorber_matches_volpathmis(mi, object_mask):
    """Eq. S3 behind a smooth dielectric (eta 1.3): the crossing refracts in and out and reflects inside as the
    boundary's BSDF says. Against volumetric path tracing of the same scene (two seeds of 1024 spp, which agree
    within 0.5 %), convsss at 256 spp was measured within 0.65 % per channel over three seeds."""
    scene = _absorbing_sphere(mi, "dielectric", spp=256)
    mask = object_mask(scene)
    volpath = reference_integrator()
    references = [np.array(mi.render(scene, integrator=volpath, seed=seed, spp=1024), dtype=np.float64)[..., :3][mask]
                  .mean(axis=0) for seed in (2, 3)]
    noise = np.abs(references[0] / references[1] - 1.0)
    ours = np.array(mi.render(scene, seed=1), dtype=np.float64)[..., :3][mask].mean(axis=0)
    ratio = ours / np.mean(references, axis=0)
    assert np.all(np.abs(ratio - 1.0) < 0.01 + noise), (ratio, noise)


@pytest.mark.slow
def test_environment_light_into_a_low_albedo_medium_matches_volpathmis(mi, sphere_scene, object_mask):
    """Issue 37: ketchup's green and blue (reduced albedo 0.07, 0.02) under a constant environment, null and
    dielectric boundaries. Most of what they send back crossed the sphere unscattered (Eq. S3) or scattered once
    (Eq. S2). Measured on this 4 mm sphere against volpathmis at 1024 spp (two seeds, which differ by up to 1.3 %):
    0.999 / 0.999 (null) and 1.000 / 1.028 (dielectric); without Eq. S3, 0.33 / 0.39 and 0.72 / 0.90. Red (reduced
    albedo 0.75 on a sphere two mean free paths in radius) is outside the diffusion model and not asserted."""
    for boundary in ("null", "dielectric"):
        scene = mi.load_dict(sphere_scene(material="ketchup", radius=2.0, res=32, spp=64, boundary=boundary,
                                          emitters={"environment": {"type": "constant", "radiance": 1.0}}))
        mask = object_mask(scene)
        ours = np.array(mi.render(scene, seed=1), dtype=np.float64)[..., 1:3][mask].mean(axis=0)
        volpath = reference_integrator()
        references = [np.array(mi.render(scene, integrator=volpath, seed=seed, spp=1024), dtype=np.float64)[..., 1:3]
                      [mask].mean(axis=0) for seed in (2, 3)]
        noise = np.abs(references[0] / references[1] - 1.0)
        ratio = ours / np.mean(references, axis=0)
        assert np.all(np.abs(ratio - 1.0) < 0.03 + noise), (boundary, ratio, noise)


@pytest.mark.slow
def test_paths_drawn_with_another_sampling_material_estimate_the_same_image(mi, sphere_scene, object_mask):
    """A sphere whose paths draw Eq. S2's distances and Eq. S3's crossings with sigma_t' x 2.5
    (``TranslucentObject.sampling``, what a fit keeps fixed) renders the same image within noise: the weights divide
    by the density the choice was drawn from. Measured at 64 spp: 0.2-0.7 % apart, seed to seed 0.1-0.3 %; at 256
    spp, two seeds each, with sigma_t' x 2.5 and x 0.4: within 0.7 % of the own, either sign."""
    import dataclasses

    from convsss.materials import Material

    scene = mi.load_dict(sphere_scene(material="skin1", res=32, spp=64, integrator={"single_scattering": "traced"}))
    integrator, sensor, mask = scene.integrator(), scene.sensors()[0], object_mask(scene)
    integrator.prepare(scene, sensor, 0)
    own = integrator.prepared.objects[0]
    means = {}
    for name, sampling in (("own", None), ("denser", Material(own.material.sigma_s_prime * 2.5,
                                                             own.material.sigma_a * 2.5, eta=own.material.eta))):
        integrator.reprepare([dataclasses.replace(own, sampling=sampling)])
        image = np.array(integrator.render_prepared(spp=64, seed=1), dtype=np.float64)[..., :3]
        means[name] = image[mask].mean(axis=0)
    np.testing.assert_allclose(means["denser"], means["own"], rtol=0.02)


@pytest.mark.filterwarnings("ignore::convsss.materials.OpticallyThinWarning")
def test_a_point_lights_shadow_ray_crosses_an_index_matched_occluder(mi):
    """A floor under a 0.5 mm index-matched absorbing slab, a point light 6 mm above it, direct light only: the
    floor in the slab's shadow gets the light the slab lets through unscattered, ``e^{-sigma_t 0.5 / cos}``, of the
    floor without the slab (Mitsuba's ``direct``) (issue 51: the camera paths' shadow rays had stopped at the slab,
    leaving it black)."""
    from convsss.materials import Material
    from convsss.media.dicts import translucent

    T = mi.ScalarTransform4f
    absorber = Material(sigma_s_prime=[1e-4] * 3, sigma_a=[0.3, 0.5, 1.0], eta=1.0)
    base = {"type": "scene", "integrator": {"type": "convsss", "max_depth": 2, "walk_depth": 0.0},
            "sensor": {"type": "perspective", "fov": 20,
                       "to_world": T().look_at(origin=[0, -12, 1.5], target=[0, 0, 0], up=[0, 0, 1]),
                       "film": {"type": "hdrfilm", "width": 32, "height": 32, "rfilter": {"type": "box"}},
                       "sampler": {"type": "independent", "sample_count": 16}},
            "floor": {"type": "rectangle", "to_world": T().scale(10.0), "bsdf": {"type": "diffuse"}},
            "light": {"type": "point", "position": [0, 0, 8], "intensity": {"type": "rgb", "value": [100.0] * 3}}}
    slab = translucent({"type": "cube", "to_world": T().translate([0, 0, 2]).scale([6, 6, 0.25])}, absorber,
                       boundary="null")
    direct = mi.load_dict({"type": "direct"})  # the floor without the slab, as convsss lights it (test above)
    open_floor = np.array(mi.render(mi.load_dict(base), integrator=direct, seed=1, spp=16), dtype=np.float64)[..., :3]
    shaded = np.array(mi.render(mi.load_dict({**base, "slab": slab}), seed=1), dtype=np.float64)[..., :3]
    # The floor points within 2 mm of the light's foot (cos > 0.96) seen below the slab: rows of the lower half.
    sensor = mi.load_dict(base).sensors()[0]
    u, v = np.meshgrid((np.arange(32) + 0.5) / 32, (np.arange(32) + 0.5) / 32)
    rays, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(u.ravel(), v.ravel()), mi.Point2f(0.5, 0.5))
    o, d = np.array(rays.o).reshape(3, -1).T, np.array(rays.d).reshape(3, -1).T
    foot = o - (o[:, 2:] / d[:, 2:]) * d  # where each pixel's centre ray meets the floor
    near = (np.linalg.norm(foot[:, :2], axis=1) < 2.0) & (d[:, 2] < 0)
    near = near.reshape(32, 32)
    assert near.sum() > 20
    sigma_t = np.array([0.3, 0.5, 1.0]) + 1e-4
    cos = 8.0 / np.sqrt(64.0 + (foot[:, :2] ** 2).sum(axis=1)).reshape(32, 32)
    expected = np.exp(-sigma_t[None, :] * 0.5 / cos[near][:, None])
    ratio = shaded[near] / open_floor[near]  # pixels: their samples spread over a long strip of floor at this angle
    np.testing.assert_allclose(ratio.mean(axis=0), expected.mean(axis=0), rtol=0.002)  # measured: 0.02 %
    np.testing.assert_allclose(ratio, expected, rtol=0.01)  # measured: 0.26 %
