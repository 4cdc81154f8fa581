"""The integrator's AOVs (``aovs``): film channels through Mitsuba's AOV mechanism, each checked against what it
claims to be, on a 4 mm index-matched skin sphere in front of a floor (box filter, so a pixel averages its samples)."""

import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.pipeline.params import RenderParams

ALL = "exitance,irradiance,object,mask,depth,normal,albedo"
CHANNELS = ["exitance.R", "exitance.G", "exitance.B", "irradiance.R", "irradiance.G", "irradiance.B", "object.I",
            "mask.Y", "depth.T", "normal.X", "normal.Y", "normal.Z", "albedo.R", "albedo.G", "albedo.B"]


def _render(mi, scene_dict, seed=1, **kwargs):
    scene = mi.load_dict(scene_dict)
    return scene, np.array(convsss.render(scene, seed=seed, **kwargs), dtype=np.float64)


def _layers(image, names):
    """The AOV channels (the last ``len(names)`` of the tensor) by name."""
    aovs = image[..., image.shape[2] - len(names):]
    return {name: aovs[..., k] for k, name in enumerate(names)}


@pytest.fixture(scope="module")
def floor_render(mi, sphere_scene):
    """The sphere (index-matched) over a floor with every AOV, 32x32 at 4 spp: (scene, image, channels)."""
    scene, image = _render(mi, sphere_scene(floor=True, res=32, spp=4, integrator={"aovs": ALL}))
    return scene, image, _layers(image, CHANNELS)


def test_channels_are_named_as_mitsubas_aovs_and_follow_rgb(mi, sphere_scene, floor_render):
    scene, image, _ = floor_render
    assert scene.integrator().aov_names() == CHANNELS
    assert image.shape == (32, 32, 3 + len(CHANNELS))
    names = [field.name for field in scene.sensors()[0].film().bitmap().struct_()]
    assert names == ["R", "G", "B", *CHANNELS]
    assert mi.load_dict({"type": "convsss"}).aov_names() == []


def test_aovs_leave_the_radiance_bit_for_bit(mi, sphere_scene, floor_render):
    _, plain = _render(mi, sphere_scene(floor=True, res=32, spp=4))
    np.testing.assert_array_equal(plain, floor_render[1][..., :3])


def test_object_and_mask_mark_the_sphere_not_the_floor(floor_render, object_mask):
    """Pixels whose centre and 8 neighbours' centres hit the sphere are covered: object 1, mask 1; those with no
    such centre around them are not (0), though the floor there is lit."""
    scene, image, aov = floor_render
    centre = object_mask(scene)
    padded = np.pad(centre, 1)
    around = np.stack([padded[1 + dy:33 + dy, 1 + dx:33 + dx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    inside, outside = around.all(axis=0), ~around.any(axis=0)
    assert inside.sum() > 100 and (outside & (image[..., :3].max(axis=2) > 0)).sum() > 300  # a lit floor
    np.testing.assert_array_equal(aov["object.I"][inside], 1.0)
    np.testing.assert_array_equal(aov["mask.Y"][inside], 1.0)
    np.testing.assert_array_equal(aov["object.I"][outside], 0.0)
    np.testing.assert_array_equal(aov["mask.Y"][outside], 0.0)
    edge = ~inside & ~outside
    assert np.all((aov["mask.Y"][edge] >= 0) & (aov["mask.Y"][edge] <= 1))
    assert np.any((aov["mask.Y"][edge] > 0) & (aov["mask.Y"][edge] < 1))  # partly covered pixels


@pytest.mark.slow
@pytest.mark.parametrize("screen", [True, False], ids=["screen-table", "transport"])
def test_exitance_is_what_the_sphere_pixels_are_made_of(mi, sphere_scene, monkeypatch, screen):
    """Index-matched boundary (F_t = 1, no reflection), ``incidence`` normal: every camera sample on the sphere has
    radiance M / pi (paper Eq. 7), so over fully covered pixels pi * RGB equals the exitance AOV, M read from the
    screen table or, with the table disabled, from the transport itself. A 10 mm sphere of whole milk, seen where
    the view cosine is over 0.4: the light crossing it (Eq. S3) is below e^-20 there (chords over 8 mm)."""
    from convsss.pipeline.screen import ScreenExitance

    if not screen:
        monkeypatch.setattr(ScreenExitance, "_projection_agrees", lambda *args: False)
    sphere = {"material": "wholemilk", "radius": 10.0, "floor": True, "res": 32, "spp": 2}
    settings = {"incidence": "normal", "single_scattering": "profile"}
    scene, image = _render(mi, sphere_scene(**sphere, integrator={"aovs": "exitance,mask,normal", **settings}))
    assert scene.integrator().stats["screen_exitance"]["usable"] == screen
    aov = _layers(image, ["exitance.R", "exitance.G", "exitance.B", "mask.Y", "normal.X", "normal.Y", "normal.Z"])
    normal = np.stack([aov[f"normal.{c}"] for c in "XYZ"], axis=-1)
    eye = np.array([0.0, 20.0, 80.0])  # sphere_scene's camera (radius 10 at the origin)
    cos = (normal * (eye - 10.0 * normal)).sum(axis=-1) / np.linalg.norm(eye - 10.0 * normal, axis=-1)
    covered = (aov["mask.Y"] == 1.0) & (cos > 0.4)
    exitance = np.stack([aov[f"exitance.{c}"] for c in "RGB"], axis=-1)
    assert covered.sum() > 100 and np.all(exitance[covered] > 0)
    np.testing.assert_allclose(np.pi * image[covered][:, :3], exitance[covered], rtol=1e-5)
    np.testing.assert_array_equal(exitance[aov["mask.Y"] == 0], 0.0)
    plain, _ = _render(mi, sphere_scene(**sphere, integrator=settings))  # the AOVs asked the transports nothing more
    assert scene.integrator().stats["exitance_lookups"] == plain.integrator().stats["exitance_lookups"]


def test_oblique_exit_weights_the_exitance_by_the_view_cosines_gain(mi, sphere_scene):
    """``incidence`` oblique: a camera sample on the index-matched sphere has radiance ``M g(mu_o) / (pi k)`` (Eq. O4),
    ``mu_o`` its view cosine: over covered pixels away from the rim, pi RGB / M is that of the pixel's normal. The
    sphere is 10 mm in radius, so that light crossing it (Eq. S3) is under 0.2 % of ``M`` where the view cosine is over
    0.4 (chords over 8 mm)."""
    from convsss.profiles.incidence import exit_normalization, gain

    names = ["exitance.R", "exitance.G", "exitance.B", "mask.Y", "normal.X", "normal.Y", "normal.Z"]
    scene, image = _render(mi, sphere_scene(radius=10.0, floor=True, res=32, spp=2, integrator={
        "aovs": "exitance,mask,normal", "single_scattering": "profile"}))  # the radiance is M's alone
    aov = _layers(image, names)
    exitance = np.stack([aov[f"exitance.{c}"] for c in "RGB"], axis=-1)
    normal = np.stack([aov[f"normal.{c}"] for c in "XYZ"], axis=-1)
    eye = np.array([0.0, 20.0, 80.0])  # sphere_scene's camera (radius 10 at the origin)
    cos = (normal * (eye - 10.0 * normal)).sum(axis=-1) / np.linalg.norm(eye - 10.0 * normal, axis=-1)
    covered = (aov["mask.Y"] == 1.0) & (cos > 0.4)
    assert covered.sum() > 100
    albedo = convsss.material("skin1").albedo_prime
    expected = gain(albedo, 1.0, cos[covered]) / exit_normalization(albedo, 1.0)
    np.testing.assert_allclose(np.pi * image[covered][:, :3] / exitance[covered], expected, rtol=0.02)
    assert np.ptp(expected[:, 2]) > 0.1  # the view cosine matters for skin's blue


def test_irradiance_is_the_point_lights_cosine_over_r2(mi, sphere_scene):
    """Direct light only (``indirect_samples`` 0): ``E = I cos / r^2`` at each hit of a pixel-centre ray on the convex
    sphere (``F_t = 1``). The AOV averages the 8 nearest samples over the pixel's random positions: within a few %
    where the light is well above the horizon, 0 on the side facing away."""
    import drjit as dr

    scene, image = _render(mi, sphere_scene(floor=True, res=32, spp=4,
                                            integrator={"aovs": "irradiance,mask", "indirect_samples": 0,
                                                                        "incidence": "normal"}))
    aov = _layers(image, ["irradiance.R", "irradiance.G", "irradiance.B", "mask.Y"])
    y, x = np.mgrid[0:32, 0:32]
    ray, _ = scene.sensors()[0].sample_ray(0.0, 0.5, mi.Point2f(((x.ravel() + 0.5) / 32).astype(np.float32),
                                                                ((y.ravel() + 0.5) / 32).astype(np.float32)),
                                           mi.Point2f(0.5))
    p = dr.ravel(scene.ray_intersect(ray).p).numpy().reshape(32, 32, 3).astype(np.float64)
    to_light = np.array([6.0, 12.0, 8.0]) - p  # sphere_scene's point light, intensity 200; radius 2 at the origin
    r2 = (to_light**2).sum(axis=-1)
    cos = ((p / 2.0) * to_light).sum(axis=-1) / np.sqrt(r2)
    expected = 200.0 * np.maximum(cos, 0.0) / r2
    covered = aov["mask.Y"] == 1.0
    lit, dark = covered & (cos > 0.3), covered & (cos < -0.2)
    assert lit.sum() > 50 and dark.sum() > 10
    for c in "RGB":
        ratio = aov[f"irradiance.{c}"][lit] / expected[lit]
        assert abs(np.median(ratio) - 1.0) < 0.02 and np.mean(np.abs(ratio - 1.0)) < 0.05, ratio
        np.testing.assert_array_equal(aov[f"irradiance.{c}"][dark], 0.0)
    assert np.all(aov["irradiance.G"][~covered & (aov["mask.Y"] == 0)] == 0.0)


def test_depth_and_normal_match_mitsubas_aov_integrator(mi, sphere_scene, floor_render):
    scene_dict = sphere_scene(floor=True, res=32, spp=4)
    scene_dict["integrator"] = {"type": "aov", "aovs": "dd:depth,nn:sh_normal"}
    scene, _ = _render(mi, scene_dict)
    bitmap = scene.sensors()[0].film().bitmap()
    theirs = dict(zip((field.name for field in bitmap.struct_()), np.moveaxis(np.array(bitmap), -1, 0)))
    aov = floor_render[2]
    assert np.count_nonzero(aov["depth.T"]) > 500
    np.testing.assert_allclose(aov["depth.T"], theirs["dd.T"], rtol=1e-5, atol=1e-5)
    for c in "XYZ":
        np.testing.assert_allclose(aov[f"normal.{c}"], theirs[f"nn.{c}"], atol=1e-5)


@pytest.mark.slow
def test_nested_in_mitsubas_aov_integrator(mi, sphere_scene):
    """``<integrator type="aov">`` around convsss: its channels as ``<name>.<aov>``, the same values."""
    scene_dict = sphere_scene(res=24, spp=2)
    scene_dict["integrator"] = {"type": "aov", "aovs": "dd:depth",
                                "sss": {"type": "convsss", "aovs": "mask,depth"}}
    scene, _ = _render(mi, scene_dict)
    bitmap = scene.sensors()[0].film().bitmap()
    names = [field.name for field in bitmap.struct_()]
    assert {"sss.R", "sss.mask.Y", "sss.depth.T", "dd.T"} <= set(names)
    values = np.array(bitmap, dtype=np.float64)
    np.testing.assert_allclose(values[..., names.index("sss.depth.T")], values[..., names.index("dd.T")], atol=1e-5)
    assert values[..., names.index("sss.mask.Y")].sum() > 20


@pytest.mark.parametrize("aovs, message", [
    ("position", "aovs='position' is not allowed: 'position' is not an AOV of convsss; choose from exitance, "
                 "irradiance, object, mask, depth, normal, albedo"),
    ("mask,mask", "'mask' is named twice"),
    ("exitance;object", "'exitance;object' is not an AOV"),
])
def test_bad_aov_names_are_one_line_errors(mi, aovs, message):
    with pytest.raises(ConvsssError, match=message) as error:
        RenderParams(aovs=aovs)
    assert "\n" not in str(error.value)
    with pytest.raises(Exception, match=message):  # Mitsuba's parser wraps it
        mi.load_dict({"type": "convsss", "aovs": aovs})


def test_spaces_and_empty_entries_are_allowed(mi):
    assert mi.load_dict({"type": "convsss", "aovs": " depth , ,object "}).aov_names() == ["depth.T", "object.I"]


def test_exitance_without_shading_paths_is_asked_of_the_transport(mi, sphere_scene, monkeypatch):
    """``max_depth`` 1 (emitters only): the shading asks for no ``M``, so the AOV asks the transport itself (the
    screen table disabled): the same exitance as in the full render."""
    from convsss.pipeline.screen import ScreenExitance

    monkeypatch.setattr(ScreenExitance, "_projection_agrees", lambda *args: False)
    images = [_render(mi, sphere_scene(res=24, spp=2, integrator={"aovs": "exitance", "max_depth": depth}))[1]
              for depth in (1, 6)]
    assert np.count_nonzero(images[1][..., :3]) > 100 and not np.any(images[0][..., :3])
    assert np.count_nonzero(images[0][..., 3:]) > 100
    np.testing.assert_allclose(images[0][..., 3:], images[1][..., 3:], rtol=1e-6)


def test_albedo_is_the_objects_total_reflectance_and_the_floors_reflectance(mi, floor_render, object_mask):
    """The denoiser's guide: on the sphere its profile's total diffuse reflectance (its colour under even light), on
    the floor its diffuse BSDF's reflectance (Mitsuba's default 0.5), 0 where nothing is hit."""
    from scipy.ndimage import binary_erosion

    from convsss.pipeline.objects import find_translucent_objects

    scene, image, aov = floor_render
    albedo = np.stack([aov["albedo.R"], aov["albedo.G"], aov["albedo.B"]], axis=-1)
    p = RenderParams()
    total = find_translucent_objects(mi, scene, p.unit_mm, p.profile, p.profile_total, p.orders)[0].profile
    total = total.total_reflectance
    inside = aov["mask.Y"] == 1.0
    floor = binary_erosion((aov["mask.Y"] == 0.0) & (aov["depth.T"] > 0))  # whole pixels of floor (not its edge)
    assert inside.sum() > 100 and floor.sum() > 100
    np.testing.assert_allclose(albedo[inside], np.broadcast_to(total, albedo[inside].shape), rtol=1e-5)
    np.testing.assert_allclose(albedo[floor], 0.5, rtol=1e-5)
    np.testing.assert_array_equal(albedo[aov["depth.T"] == 0.0], 0.0)
