"""The multi-scale transport: the split of the profile (Eq. M1, M2), the clusters, convergence to the exact sum on
spheres and on the bunny at two sizes ten times apart, queries off the surface, memory refused before allocating."""

import numpy as np
import pytest

from convsss import material
from convsss.errors import ConvsssError
from convsss.materials import Material
from convsss.profiles import model_profile
from convsss.samples import IrradianceSamples, ViewFrame
from convsss.transport import MultiscaleTransport, make_transport
from convsss.transport.multiscale import (
    BAND_TABLE,
    core_width,
    cube_cells,
    group,
    merge,
    scales,
    sheet_side,
    split,
)
from convsss.transport.multiscale.far_field import _deposit, _interpolate

FRAME = ViewFrame.look_at(origin=[0, 0, 100], target=[0, 0, 0])


def _mean_rel(test, reference):
    """Mean per-point relative error (floored at 1 % of the channel's mean, as convsss.compare)."""
    floor = 0.01 * reference.mean(axis=0)
    return float(np.mean(np.abs(test - reference) / np.maximum(reference, floor)))


def _lit_sphere(radius, n, seed=0):
    """Stratified-ish samples on a sphere lit from one side (irradiance max(n.l, 0) + a dim ambient term)."""
    k = np.arange(n) + 0.5
    phi, theta = np.arccos(1 - 2 * k / n), np.pi * (1 + 5**0.5) * k
    normal = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
    light = np.array([0.5, 0.3, 0.81]) / np.linalg.norm([0.5, 0.3, 0.81])
    irradiance = np.maximum(normal @ light, 0.0)[:, None] * np.ones(3) + 0.02
    return IrradianceSamples(normal * radius, 4 * np.pi * radius**2 / n, irradiance, normal)


def _table(radius, table, r):
    """A core or band table (uniform in r^2 on [0, radius^2]) at the radii ``r``, 0 beyond."""
    return np.stack([np.interp(r**2, np.linspace(0, radius**2, BAND_TABLE), table[:, c], right=0.0)
                     for c in range(3)], axis=1)


@pytest.mark.parametrize("levels", [1, 3])
@pytest.mark.parametrize("name", ["wholemilk", "skin1", "ketchup"])
def test_the_bands_sum_to_the_profile(name, levels):
    profile = model_profile("dipole", material(name))
    sc = scales(profile, 0.01, levels=levels)
    assert len(sc.radii) == levels + 1 and sc.radii[-1] == pytest.approx(sc.split)
    far, core, bands = split(profile, sc.radii)
    assert len(bands) == levels
    r = np.linspace(0.0, 1.5 * sc.split, 4000)
    far_values = np.where(r[:, None] < sc.split, far[0] + far[1] * r[:, None] ** 2, profile(r))
    parts = [_table(radius, table, r) for radius, table in zip(sc.radii, [core, *bands])]
    total = far_values + sum(parts)
    np.testing.assert_allclose(total, profile(r), rtol=1e-3, atol=1e-6 * profile(0.0).max())
    for radius, part in zip(sc.radii, parts):
        assert np.all(part[r >= radius] == 0)
    assert np.all(parts[0] >= 0) and np.all(far_values > 0)  # the dipole is convex: every cap lies below it
    # The far field is C^1 at r_c: its slope from inside (2 b r_c) is the profile's.
    step = 1e-5 * sc.split
    slope = (profile(sc.split + step) - profile(sc.split - step)) / (2 * step)
    np.testing.assert_allclose(2 * far[1] * sc.split, slope, rtol=1e-4)


def test_the_local_core_keeps_the_energy_and_is_smooth():
    """Eq. M3: with a pixel footprint wider than twice the core width, the core is its energy over a smooth kernel:
    the bands still sum to the profile's energy, and the lengths follow the footprint."""
    profile = model_profile("dipole", material("marble"))
    footprint = 4 * core_width(profile)
    sc = scales(profile, 0.01, cell_size=footprint)
    assert sc.local and sc.core == pytest.approx(footprint)
    far, core, bands = split(profile, sc.radii, local=True)
    exact_core = split(profile, sc.radii)[1]
    u = np.linspace(0, sc.core**2, BAND_TABLE)
    energy = np.pi * np.trapezoid(core, u, axis=0)
    np.testing.assert_allclose(energy, np.pi * np.trapezoid(exact_core, u, axis=0), rtol=1e-3)
    assert np.all(np.diff(core, axis=0) <= 0)  # smooth, falling to 0 at r_0
    assert not scales(profile, 0.01, cell_size=core_width(profile)).local  # resolved: as without a footprint


def test_scales_follow_the_profile_and_the_accuracy():
    milk, skin = model_profile("dipole", material("wholemilk")), model_profile("dipole", material("skin1"))
    assert 0.5 < core_width(milk) / material("wholemilk").mfp_mm.min() < 1.0  # about 0.8 mean free paths
    assert core_width(skin) > 2 * core_width(milk)
    fine, coarse = scales(milk, 0.0025), scales(milk, 0.04)
    assert coarse.cluster == pytest.approx(4 * fine.cluster) and coarse.mesh == pytest.approx(4 * fine.mesh)
    assert fine.band_cluster == pytest.approx(2 * fine.cluster)
    assert fine.split == coarse.split and fine.core < fine.split


def test_clusters_keep_the_flux_and_the_two_sides_of_a_sheet_apart():
    rng = np.random.default_rng(0)
    position = rng.random((5000, 3)) * [4.0, 4.0, 0.01]
    normal = np.tile([0.0, 0.0, 1.0], (5000, 1))
    normal[::2] *= -1  # a sheet much thinner than a cluster, seen from both sides
    flux = rng.random((5000, 3))
    origin = position.min(axis=0)
    side, area = sheet_side(normal), np.full(5000, 1e-3)
    grouping = group(cube_cells(position, origin, 0.5), side)
    fine = merge(grouping, position, area, flux)
    np.testing.assert_allclose(fine.flux.sum(axis=0), flux.sum(axis=0))
    np.testing.assert_allclose(fine.area.sum(), 5.0)
    assert len(fine) == 2 * 8 * 8  # 8 x 8 cubes, two sides each
    assert np.all(fine.centre.min(axis=0) >= origin) and np.all(fine.centre.max(axis=0) <= position.max(axis=0))
    # The groups' cubes halved: whole clusters merge, as if the samples had been clustered in cubes twice as large.
    coarse = merge(group(grouping.cells // 2, grouping.side), fine.centre, fine.area, fine.flux)
    direct = merge(group(cube_cells(position, origin, 1.0), side), position, area, flux)
    assert len(coarse) == len(direct) == 2 * 4 * 4
    np.testing.assert_allclose(coarse.flux, direct.flux)
    np.testing.assert_allclose(coarse.centre, direct.centre)
    np.testing.assert_array_equal(coarse.side, direct.side)


@pytest.mark.slow
@pytest.mark.parametrize("radius", [2.0, 20.0])
def test_converges_to_the_exact_sum_on_spheres_ten_times_apart(radius):
    milk = model_profile("dipole", material("wholemilk"))
    samples = _lit_sphere(radius, 60000 if radius > 5 else 20000)
    points = samples.position[::29] * 1.0
    exact = make_transport("exact", samples, milk).exitance(points)
    errors = [_mean_rel(make_transport("multiscale", samples, milk, FRAME, accuracy=a).exitance(points), exact)
              for a in (0.1, 0.01, 0.003)]
    assert errors[1] < 0.01  # the default accuracy
    assert errors[2] < errors[0] and errors[2] < 0.005


def test_queries_off_the_surface_agree_with_the_exact_sum():
    """Points 1 mm outside a sphere lie in voxels of the middle band that hold no samples, and inside the far-field
    mesh, which reaches r_c past the samples."""
    skin = model_profile("dipole", material("skin1"))
    samples = _lit_sphere(10.0, 40000)
    points = samples.position[::97] * 1.1
    exact = make_transport("exact", samples, skin).exitance(points)
    multi = make_transport("multiscale", samples, skin, FRAME).exitance(points)
    assert _mean_rel(multi, exact) < 0.01


@pytest.mark.slow
def test_the_far_mesh_keeps_the_flux_and_reads_back_a_linear_field_exactly():
    """The quadratic B-spline deposit spreads each point's flux without loss; its read-back reproduces a linear field
    (B-splines reproduce linear functions), so the mesh adds no error of first order."""
    rng = np.random.default_rng(2)
    view, flux = 1.0 + 8.0 * rng.random((500, 3)), rng.random((500, 3))
    grid = np.zeros((3, 12, 12, 12))
    _deposit(view, flux, np.zeros(3), 1.0, grid)
    np.testing.assert_allclose(grid.sum(axis=(1, 2, 3)), flux.sum(axis=0))
    nodes = np.stack(np.meshgrid(*[np.arange(12.0)] * 3, indexing="ij"))
    field = np.stack([2.0 + nodes[0] - 0.5 * nodes[1] + 0.25 * nodes[2]] * 3)
    out = np.zeros((500, 3))
    _interpolate(view, np.zeros(3), 1.0, field, out)
    np.testing.assert_allclose(out[:, 0], 2.0 + view[:, 0] - 0.5 * view[:, 1] + 0.25 * view[:, 2])


@pytest.mark.slow
def test_the_middle_band_is_summed_at_voxel_corners_for_dense_queries_and_at_sparse_ones_directly():
    """Queries denser than the middle band's voxels read it at the voxels' corners, each summed once when first needed
    and kept, so asking in another order gives the same exitance bit for bit; queries sparser than the voxels (fewer
    queries in a batch than the corners they would add) are summed where they are, and agree with the corners to
    the band's interpolation error."""
    skin = model_profile("dipole", material("skin1"))
    samples = _lit_sphere(10.0, 20000)
    jitter = np.random.default_rng(4).normal(scale=0.01, size=(len(samples), 4, 3))
    dense = (samples.position[:, None] + jitter).reshape(-1, 3)  # 4 queries per sample, in the samples' spiral order
    sparse = dense[::32]
    exact = make_transport("exact", samples, skin).exitance(sparse)
    forward = make_transport("multiscale", samples, skin, FRAME)
    at_dense = forward.exitance(dense)
    backward = make_transport("multiscale", samples, skin, FRAME)
    np.testing.assert_array_equal(backward.exitance(dense[::-1])[::-1], at_dense)
    direct = make_transport("multiscale", samples, skin, FRAME)
    at_sparse = direct.exitance(sparse)
    assert forward.stats["band_corners"] > 0 and direct.stats["band_corners"] == 0
    assert _mean_rel(at_sparse, at_dense[::32]) < 0.005  # half the default accuracy (measured 0.23 %)
    assert _mean_rel(at_sparse, exact) < 0.01 and _mean_rel(at_dense[::32], exact) < 0.01


@pytest.mark.slow
def test_more_middle_bands_agree_with_the_exact_sum(monkeypatch):
    """A far mesh kept small (as for an object many profile widths across) adds middle bands, each doubling r_c and
    the mesh spacing: the sum stays within the default accuracy of the exact one."""
    import convsss.transport.multiscale.transport as ms

    milk = model_profile("dipole", material("wholemilk"))
    samples = _lit_sphere(20.0, 60000)
    points = samples.position[::29] * 1.0
    exact = make_transport("exact", samples, milk).exitance(points)
    monkeypatch.setattr(ms, "FAR_CELLS", 1 << 12)
    multi = make_transport("multiscale", samples, milk, FRAME)
    assert multi.scales.levels >= 3
    assert _mean_rel(multi.exitance(points), exact) < 0.01


def _dense():
    """A dense, absorbing medium: its profile is about 0.1 mm wide, far narrower than the samples below are apart."""
    return model_profile("dipole", Material.from_reduced([50.0, 60.0, 70.0], [1.0, 2.0, 3.0]))


def test_the_local_limit_gives_the_total_reflectance_times_the_irradiance():
    """Eq. M3: a profile far narrower than the pixel footprint returns ``R_total E`` where the irradiance is smooth,
    from samples too sparse to resolve it."""
    profile = _dense()
    samples = _lit_sphere(10.0, 40000)  # 0.18 mm apart
    transport = make_transport("multiscale", samples, profile, FRAME, cell_size=1.5)
    assert transport.scales.local
    assert transport.fft_shape is None  # nothing of the profile reaches r_c = 2 r_0: the far field is dropped
    lit = np.flatnonzero(samples.irradiance[:, 0] > 0.3)[::20]
    ratio = transport.exitance(samples.position[lit]) / (samples.irradiance[lit] * profile.total_reflectance)
    # The kernel's O(r_0^2 ∇^2 E): on a sphere of radius R (the area within a chord d is pi d^2), E ~ cos averages
    # to cos (1 - r_0^2 <u> / (2 R^2)), <u> = 1/4 for K = (1 - u)^2 in u = d^2 / r_0^2.
    predicted = 1.0 - transport.scales.core**2 / (8 * 10.0**2)  # 0.9972; measured 0.9966
    np.testing.assert_allclose(ratio.mean(axis=0), predicted, atol=0.001)
    assert np.std(ratio) < 0.003  # an average, not a sum: measured 0.06 % (a sum of E_core K: 0.8 %)


def test_the_local_limit_bounds_memory_and_samples_by_the_footprint():
    """The plan of a dense object seen at a wide pixel: the transport's bytes fall, and the area that sizes the
    samples grows as the footprint squared (so the samples follow the pixels)."""
    profile = model_profile("pbd", material("skin1"))
    bounds = (np.full(3, -20.0), np.full(3, 20.0))
    sharp = MultiscaleTransport.planned_bytes(bounds, profile, 0, {"accuracy": 0.01})
    wide = MultiscaleTransport.planned_bytes(bounds, profile, 0, {"accuracy": 0.01, "cell_size": 0.5})
    assert wide < 0.5 * sharp
    own = MultiscaleTransport.sample_area(profile, {"accuracy": 0.01})
    assert own == pytest.approx(float(np.min(profile.effective_area())))
    assert MultiscaleTransport.sample_area(profile, {"accuracy": 0.01, "cell_size": 0.5}) > 2 * own
    dense = _dense()  # a footprint wider than the whole profile: the area goes as its square
    areas = [MultiscaleTransport.sample_area(dense, {"accuracy": 0.01, "cell_size": f}) for f in (1.0, 2.0)]
    assert areas[0] > 10 * float(np.min(dense.effective_area()))
    assert areas[1] / areas[0] == pytest.approx(4.0, rel=0.1)


def test_no_samples_give_no_exitance():
    empty = IrradianceSamples(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    transport = make_transport("multiscale", empty, model_profile("dipole", material("skin1")), FRAME)
    np.testing.assert_array_equal(transport.exitance(np.ones((2, 3))), 0.0)


def test_memory_is_refused_before_allocating():
    samples = _lit_sphere(20.0, 2000)
    with pytest.raises(ConvsssError, match="multiscale far-field mesh"):
        make_transport("multiscale", samples, model_profile("dipole", material("wholemilk")), FRAME, memory_limit=1e5)


@pytest.fixture(scope="module")
def bunny_cases():
    from convsss.bench.scenes import prepare_case, scene_dict

    return {name: prepare_case(scene_dict(name, 96)) for name in ("bunny4", "bunny40")}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["bunny4", "bunny40"])
def test_bunny_at_two_sizes_within_one_percent_of_the_exact_sum(bunny_cases, name):
    case = bunny_cases[name]
    exact = make_transport("exact", case["samples"], case["profile"]).exitance(case["points"])
    multi = make_transport("multiscale", case["samples"], case["profile"], case["frame"]).exitance(case["points"])
    assert _mean_rel(multi, exact) < 0.01


def test_a_core_of_microns_on_a_large_object_keeps_its_cell_lists_bounded():
    """Beam diffusion's near-singular peak gives a core width of microns: on a 40 mm sphere cubes of that side would
    need a billions-of-cubes offset table; the cubes grow instead (to CELL_LIST_CUBES), and the sum is the same."""
    import convsss.transport.multiscale.cells as ms

    samples = _lit_sphere(20.0, 2000)
    profile = model_profile("pbd", material("wholemilk"))
    transport = make_transport("multiscale", samples, profile, FRAME)
    assert np.prod(transport._core_cells.dims) <= ms.CELL_LIST_CUBES
    assert transport._core_cells.size > transport.scales.core
    points = samples.position[::7] * 1.0
    np.testing.assert_allclose(transport.exitance(points), make_transport("exact", samples, profile).exitance(points),
                               rtol=0.01)
