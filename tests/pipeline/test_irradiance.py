import drjit as dr
import numpy as np
import pytest

from convsss.fresnel import fresnel_transmittance


@pytest.fixture(scope="module")
def irr(mi):
    from convsss.pipeline import irradiance

    return irradiance


def _points(irr, scene, count=2000, seed=1):
    """Stratified surface points of the scene's first shape (:func:`convsss.pipeline.surface.sample_surface`)."""
    from convsss.pipeline.surface import sample_surface

    p, n, area = sample_surface(scene.shapes()[0], count, seed)
    return p, n, dr.width(area), dr.ravel(p).numpy().reshape(-1, 3).astype(np.float64)


@pytest.mark.parametrize("eta", [1.0, 1.4])
def test_point_and_spot_lights_are_exact(mi, irr, eta):
    light = {"type": "point", "position": [0, 0, 5], "intensity": {"type": "rgb", "value": [25, 25, 25]}}
    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}, "l": light})
    p, n, _, pts = _points(irr, scene)
    e = irr.surface_irradiance(scene, p, n, eta, 4, seed=0)
    d = np.array([0, 0, 5.0]) - pts
    r = np.linalg.norm(d, axis=1)
    cos = np.clip(np.einsum("ij,ij->i", pts, d) / r, 0, None)
    expected = 25 * cos / r**2 * fresnel_transmittance(eta, cos)
    np.testing.assert_allclose(e, np.repeat(expected[:, None], 3, axis=1), atol=2e-5)


def test_shadows_count(mi, irr):
    light = {"type": "directional", "direction": [0, 0, -1], "irradiance": {"type": "rgb", "value": [1, 1, 1]}}
    blocker = {"type": "sphere", "center": [0, 0, 3], "radius": 2.0}
    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}, "b": blocker, "l": light})
    p, n, _, pts = _points(irr, scene)
    e = irr.surface_irradiance(scene, p, n, 1.0, 4, seed=0)
    assert np.all(e == 0)


def test_environment_gives_pi_times_radiance(mi, irr):
    env = {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 0.5, 0.25]}}
    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}, "e": env})
    p, n, _, _ = _points(irr, scene)
    e = irr.surface_irradiance(scene, p, n, 1.0, 16, seed=3)
    np.testing.assert_allclose(e.mean(axis=0), np.pi * np.array([1.0, 0.5, 0.25]), rtol=0.02)
    again = irr.surface_irradiance(scene, p, n, 1.0, 16, seed=3)
    np.testing.assert_array_equal(e, again)


def test_area_light_matches_point_light_far_away(mi, irr):
    """A small square lamp far away irradiates like a point light of intensity L * area."""
    T = mi.ScalarTransform4f
    lamp = {"type": "rectangle", "to_world": T().translate([0, 0, 20]).rotate([1, 0, 0], 180).scale(0.5),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [400, 400, 400]}}}
    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}, "l": lamp})
    p, n, _, pts = _points(irr, scene)
    e = irr.surface_irradiance(scene, p, n, 1.0, 16, seed=0)[:, 0]
    d = np.array([0, 0, 20.0]) - pts
    r = np.linalg.norm(d, axis=1)
    cos_surface = np.clip(np.einsum("ij,ij->i", pts, d) / r, 0, None)
    expected = 400 * 1.0 * cos_surface * (d[:, 2] / r) / r**2
    assert e.sum() == pytest.approx(expected.sum(), rel=0.02)


@pytest.mark.parametrize("eta", [1.0, 1.3, 1.5])
def test_dr_jit_and_numpy_fresnel_transmittance_agree(mi, eta):
    """Irradiance (Dr.Jit) and shading (numpy) each need F_t; they are one function in two array libraries."""
    from convsss.fresnel import fresnel_transmittance as numpy_ft
    from convsss.pipeline.irradiance import fresnel_transmittance as drjit_ft

    cos = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(drjit_ft(eta, mi.Float(cos.astype(np.float32))).numpy(), numpy_ft(eta, cos), atol=1e-6)


def _uniform_incident(radiance):
    """An ``incident`` callable for :func:`indirect_irradiance`: the same radiance from every direction."""
    calls = []

    def incident(sampler, rays, weight, tags):
        calls.append(np.array(tags))
        assert dr.width(rays.o) == len(tags) == len(weight)
        return weight * np.asarray(radiance)[None, :], []

    return incident, calls


@pytest.mark.parametrize("paths", [1, 4])
def test_indirect_irradiance_of_uniform_radiance_is_pi_times_it(mi, irr, paths):
    """Eq. 2 with L_i = L from every direction and eta = 1 is pi L, at every point and for any number of paths."""
    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}})
    p, n, size, _ = _points(irr, scene, 400)
    incident, calls = _uniform_incident([1.0, 0.5, 0.25])
    e, _ = irr.indirect_irradiance(incident, p, n, np.full(size, 4 * np.pi / size), 1.0, paths, seed=2)
    np.testing.assert_allclose(e, np.pi * np.array([[1.0, 0.5, 0.25]] * size), rtol=1e-5)
    np.testing.assert_array_equal(np.sort(np.concatenate(calls)), np.repeat(np.arange(size), paths))


def test_indirect_irradiance_through_a_fresnel_boundary(mi, irr):
    """With eta != 1 the mean is pi L (1 - F_dr): the cosine-weighted mean of F_t, here by quadrature."""
    from convsss.fresnel import fresnel_reflectance

    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}})
    p, n, size, _ = _points(irr, scene, 4000)
    incident, _ = _uniform_incident([1.0, 1.0, 1.0])
    e = irr.indirect_irradiance(incident, p, n, np.full(size, 4 * np.pi / size), 1.4, 4, seed=0)[0][:, 0]
    mu = (np.arange(100000) + 0.5) / 100000
    expected = np.pi * (1 - 2 * np.mean(fresnel_reflectance(1.4, mu) * mu))
    # Per point: the mean of 4 values F_t pi with F_t in [F_t(0), 1]; the mean of 4096 points is within 0.5 %.
    assert e.mean() == pytest.approx(expected, rel=0.005)
    assert np.all(e <= np.pi) and np.all(e >= np.pi * (1 - fresnel_reflectance(1.4, 0.0)))


def test_fewer_paths_than_points_trace_a_fraction_with_inverse_weights(mi, irr):
    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}})
    p, n, size, _ = _points(irr, scene, 4000)
    incident, calls = _uniform_incident([1.0, 1.0, 1.0])
    e = irr.indirect_irradiance(incident, p, n, np.full(size, 4 * np.pi / size), 1.0, 0.25, seed=5)[0][:, 0]
    traced = np.concatenate(calls)
    assert len(np.unique(traced)) == len(traced)
    assert abs(len(traced) - size / 4) < 4 * np.sqrt(size * 0.25 * 0.75)
    np.testing.assert_allclose(e[traced], 4 * np.pi, rtol=1e-5)
    assert np.all(np.delete(e, traced) == 0)


def test_directions_are_stratified_across_neighbouring_points(irr):
    """Points in one voxel share a 4 x 4 grid of [0,1]^2: 16 of them cover each cell once, 32 twice."""
    rng = np.random.default_rng(0)
    points = np.concatenate([rng.random((16, 3)) * 0.9, 5 + rng.random((32, 3)) * 0.9])
    owners = np.arange(len(points))
    u = irr.stratified_directions(points, owners, spacing=1.0, seed=3, strata=4)
    assert u.shape == (48, 2) and np.all((u >= 0) & (u < 1))
    cell = (np.floor(u[:, 0] * 4) + 4 * np.floor(u[:, 1] * 4)).astype(int)
    np.testing.assert_array_equal(np.bincount(cell[:16], minlength=16), np.ones(16))
    np.testing.assert_array_equal(np.bincount(cell[16:], minlength=16), np.full(16, 2))
    # Many voxels: uniform over the square (each path's point is uniform).
    many = irr.stratified_directions(rng.random((20000, 3)) * 50, np.arange(20000), 1.0, seed=1)
    counts = np.histogram2d(many[:, 0], many[:, 1], bins=4, range=[[0, 1], [0, 1]])[0]
    assert np.all(np.abs(counts - 20000 / 16) < 5 * np.sqrt(20000 / 16))


@pytest.mark.parametrize("eta", [1.0, 1.4])
def test_oblique_incidence_weights_each_direction_by_its_gain(mi, irr, eta):
    """With the medium's albedo, a point light's irradiance is F_t cos I / r^2 times the gain of Eq. O1 per channel."""
    from convsss.profiles.incidence import gain

    light = {"type": "point", "position": [0, 0, 5], "intensity": {"type": "rgb", "value": [25, 25, 25]}}
    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}, "l": light})
    p, n, _, pts = _points(irr, scene)
    albedo = np.array([0.99, 0.8, 0.3])
    e = irr.surface_irradiance(scene, p, n, eta, 4, seed=0, albedo=albedo)
    d = np.array([0, 0, 5.0]) - pts
    r = np.linalg.norm(d, axis=1)
    cos = np.clip(np.einsum("ij,ij->i", pts, d) / r, 0, None)
    expected = (25 * cos / r**2 * fresnel_transmittance(eta, cos))[:, None] * gain(albedo, eta, cos)
    np.testing.assert_allclose(e, expected, rtol=1e-4, atol=2e-5)
    lit = (cos > 0) & (cos < 0.9)
    assert np.all(e[lit, 2] > e[lit, 0])


def test_oblique_incidence_weights_indirect_paths(mi, irr):
    """Uniform radiance through an index-matched boundary: E = pi L times the cosine-weighted mean of the gain."""
    from convsss.profiles.incidence import gain

    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}})
    p, n, size, _ = _points(irr, scene, 4096)
    albedo = np.array([0.9, 0.5, 0.1])
    incident, _ = _uniform_incident([1.0, 1.0, 1.0])
    e, _ = irr.indirect_irradiance(incident, p, n, np.full(size, 4 * np.pi / size), 1.0, 4, seed=0, albedo=albedo)
    x, w = np.polynomial.legendre.leggauss(64)
    mu, w = 0.5 * (x + 1.0), 0.5 * w
    mean_gain = 2.0 * np.sum((w * mu)[:, None] * gain(albedo, 1.0, mu), axis=0)
    np.testing.assert_allclose(e.mean(axis=0), np.pi * mean_gain, rtol=0.01)


