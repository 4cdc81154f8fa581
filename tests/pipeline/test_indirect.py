"""Indirect irradiance (paper Eq. 2 with all incident light): light off the rest of the scene and off other
translucent objects, path traced from the irradiance samples."""

from pathlib import Path

import numpy as np
import pytest

import convsss
from convsss.media.dicts import translucent


@pytest.fixture(scope="module")
def room(mi):
    """``room(integrator, rho)``: a 1 mm skin sphere at the centre of a closed diffuse spherical room of radius 50 mm
    and reflectance ``rho``, a point light of intensity 400 at 20 mm from the centre; the scene after a render."""
    T = mi.ScalarTransform4f

    def make(integrator, rho=0.5, seed=0):
        scene = mi.load_dict({
            "type": "scene",
            "integrator": {"type": "convsss", "sample_density": 1.0, "walk_depth": 0.0, **integrator},
            "sensor": {"type": "perspective", "fov": 20,
                       "to_world": T().look_at(origin=[0, 0, 8], target=[0, 0, 0], up=[0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": 16, "height": 16, "rfilter": {"type": "box"}},
                       "sampler": {"type": "independent", "sample_count": 1}},
            "object": translucent({"type": "sphere", "radius": 1.0}, convsss.material("skin1"), boundary="null"),
            "room": {"type": "sphere", "radius": 50.0, "flip_normals": True,
                     "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [rho] * 3}}},
            "light": {"type": "point", "position": [0, 20, 0], "intensity": {"type": "rgb", "value": [400.0] * 3}},
        })
        scene.integrator().render(scene, scene.sensors()[0], seed=seed)
        return scene

    return make


@pytest.mark.slow
@pytest.mark.parametrize("max_depth, bounces", [(3, 1), (6, 4)])
def test_indirect_light_in_a_spherical_room_is_the_radiosity_series(room, max_depth, bounces):
    """Inside a diffuse sphere of radius R every wall point sees every other under the same form factor
    dA / (4 pi R^2), so after n bounces of a point light's flux 4 pi I the mean irradiance over a small object at the
    centre is rho^n I / R^2 (Eq. 2, null boundary); a path of max_depth segments brings max_depth - 2 bounces.
    Direct light: a point light at distance d irradiates a small sphere by I / (4 d^2) on average."""
    scene = room({"indirect_samples": 16, "max_depth": max_depth, "incidence": "normal",
                  "single_scattering": "profile"})
    obj = scene.integrator().stats["objects"][0]
    area = 4 * np.pi
    expected = 400 / 50**2 * sum(0.5**n for n in range(1, bounces + 1))
    # The sphere hides 1/2500 of the room and its own light off the walls adds as little; the 441 x 16 paths'
    # mean measured 0.2-0.9 % off.
    np.testing.assert_allclose(np.array(obj["flux_indirect"]) / area, expected, rtol=0.02)
    np.testing.assert_allclose(np.array(obj["flux_direct"]) / area, 400 / (4 * 20**2), rtol=0.01)
    np.testing.assert_allclose(obj["flux"], np.add(obj["flux_direct"], obj["flux_indirect"]))


@pytest.mark.slow
def test_indirect_light_brings_its_single_scattering_to_a_profile_without_it(room):
    """Single scattering traced (the default): the shader traces that of direct light, the profile carries the
    multiple scattering alone, and indirect light enters with its single scattering as the profile's own share,
    ``rho(1) / (rho - rho_1)(1)`` per channel at normal incidence (Eq. S1); direct light enters as it is."""
    from convsss.profiles.incidence import escaped

    scene = room({"indirect_samples": 16, "max_depth": 3, "incidence": "normal"})
    obj = scene.integrator().stats["objects"][0]
    albedo = convsss.material("skin1").albedo_prime
    share = np.array([escaped(a, 1.0, 1.0) / escaped(a, 1.0, 1.0, "multiple") for a in albedo])
    assert np.all(share > 1.1)
    area = 4 * np.pi
    np.testing.assert_allclose(np.array(obj["flux_indirect"]) / area, 400 / 50**2 * 0.5 * share, rtol=0.02)
    np.testing.assert_allclose(np.array(obj["flux_direct"]) / area, 400 / (4 * 20**2), rtol=0.01)


@pytest.mark.slow
def test_oblique_incidence_scales_both_by_the_cosine_weighted_gain(room):
    """The room's light is uniform over directions and the point light's cosines on the small sphere are uniform on
    its lit half: with incidence = oblique both fluxes gain 2 ∫ mu g(mu) dmu per channel (Eq. O1, skin1's albedo)."""
    from convsss.profiles.incidence import gain

    scene = room({"indirect_samples": 16, "max_depth": 3, "single_scattering": "profile"})  # g of all the light
    obj = scene.integrator().stats["objects"][0]
    x, w = np.polynomial.legendre.leggauss(64)
    mu, w = 0.5 * (x + 1.0), 0.5 * w
    mean_gain = 2.0 * np.sum((w * mu)[:, None] * gain(convsss.material("skin1").albedo_prime, 1.0, mu), axis=0)
    assert np.all(mean_gain > 1.05)
    area = 4 * np.pi
    np.testing.assert_allclose(np.array(obj["flux_indirect"]) / area, 400 / 50**2 * 0.5 * mean_gain, rtol=0.02)
    np.testing.assert_allclose(np.array(obj["flux_direct"]) / area, 400 / (4 * 20**2) * mean_gain, rtol=0.01)


@pytest.mark.slow
def test_no_indirect_light_when_asked_for_none_or_paths_too_short(room):
    for integrator in ({"indirect_samples": 0}, {"max_depth": 2}):
        scene = room(integrator)
        obj = scene.integrator().stats["objects"][0]
        assert obj["flux_indirect"] == [0.0, 0.0, 0.0] and obj["flux_from_translucent"] == [0.0, 0.0, 0.0]
        assert "indirect" not in scene.integrator().stats["seconds"]


@pytest.mark.slow
def test_a_black_room_gives_no_indirect_light(room):
    scene = room({"indirect_samples": 4}, rho=0.0)
    assert scene.integrator().stats["objects"][0]["flux_indirect"] == [0.0, 0.0, 0.0]


# ---- Against volpathmis: a sphere in a closed diffuse box -----------------------------------------------------------
DATA = Path(__file__).parents[1] / "data"


@pytest.fixture(scope="module")
def against_volpath(mi, object_mask):
    """``against_volpath(name, **integrator)``: mean(convsss) / mean(volpathmis) per channel over the sphere's pixels
    of ``tests/data/indirect_<name>.xml`` (references made as ``tests/data/README.md`` says)."""
    from convsss.image import read_image
    from convsss.scene.loading import load_scene

    def ratio(name, **integrator):
        scene = load_scene(DATA / f"indirect_{name}.xml")
        convsss_integrator = mi.load_dict({"type": "convsss", "max_depth": -1, "walk_depth": 0.0, **integrator})
        image = np.array(convsss_integrator.render(scene, scene.sensors()[0], seed=0), dtype=np.float64)[..., :3]
        reference = read_image(DATA / f"indirect_{name}_ref.exr")
        mask = object_mask(scene)
        return image[mask].mean(axis=0) / reference[mask].mean(axis=0), reference[mask].mean(axis=0)

    return ratio


@pytest.mark.slow
def test_sphere_in_a_closed_box_against_volpathmis(against_volpath):
    """The box's walls bring most of the light. Direct light alone is far too dark; with indirect light the ratio to
    volpathmis comes back to the profile's own bias measured without the box: within 3 % of its bias under the
    same point light alone (the issue's goal), and within 2 % of the bias expected for the box's mix of light: the
    direct share ``s`` (volpathmis without the box over volpathmis in it) at the bias under the point light, the rest
    at the bias under the uniform light of glowing black walls (the walls' light is not quite uniform: measured 0.7-1.1
    % below it here, 0.2-0.9 % at 128 x 128; the light between the sphere and the walls alone is 5 % of the flux)."""
    direct_only, box_reference = against_volpath("box", indirect_samples=0)
    # 16 paths per sample: at 64x64 the sphere has 16k samples, and one path each leaves ~2 % of noise in the mean.
    with_indirect, _ = against_volpath("box", indirect_samples=16)
    point, point_reference = against_volpath("point")
    glow, _ = against_volpath("glow")
    assert np.all(direct_only < 0.3)
    np.testing.assert_allclose(with_indirect, point, atol=0.03)
    share = point_reference / box_reference
    np.testing.assert_allclose(with_indirect, share * point + (1 - share) * glow, atol=0.02)


def test_absurdly_many_indirect_paths_are_refused_before_they_start(mi, sphere_scene):
    scene = mi.load_dict(sphere_scene(integrator={"indirect_samples": 1e7}))
    with pytest.raises(convsss.ConvsssError, match=r"'object' needs .* indirect paths.* indirect_samples"):
        scene.integrator().render(scene, scene.sensors()[0])


@pytest.mark.slow
def test_two_translucent_objects_light_each_other(mi, sphere_scene):
    """A convex sphere alone gets no light from translucent objects; next to another, each gets some, and a second
    pass changes less than the first."""
    second = translucent({"type": "sphere", "radius": 2.0, "center": [4.5, 0.0, 0.0]}, convsss.material("skin1"),
                         boundary="null")
    alone = mi.load_dict(sphere_scene(res=32))
    alone.integrator().render(alone, alone.sensors()[0])
    stats = alone.integrator().stats
    assert stats["objects"][0]["flux_from_translucent"] == [0.0, 0.0, 0.0] and stats["translucent_passes"] == []
    for passes in (1, 2):
        pair = mi.load_dict(sphere_scene(res=32, extra={"second": second}, integrator={"indirect_passes": passes}))
        pair.integrator().render(pair, pair.sensors()[0])
        stats = pair.integrator().stats
        for obj in stats["objects"]:
            assert np.all(np.array(obj["flux_from_translucent"]) > 0)
            np.testing.assert_allclose(obj["flux"], np.add(obj["flux_direct"], obj["flux_indirect"]))
        changes = [p["flux_change"] for p in stats["translucent_passes"]]
        assert len(changes) == passes and changes == sorted(changes, reverse=True) and changes[-1] > 0
