"""The multi-scale transport: the split of the profile (Eq. M1, M2), the clusters, convergence to the exact sum on
spheres and on the bunny at two sizes ten times apart, queries off the surface, memory refused before allocating."""

import numpy as np
import pytest

from convsss import material
from convsss.errors import ConvsssError
from convsss.profiles import model_profile
from convsss.samples import IrradianceSamples, ViewFrame
from convsss.transport import make_transport
from convsss.transport.multiscale import (
    BAND_TABLE,
    _deposit,
    _interpolate,
    core_width,
    cube_cells,
    group,
    merge,
    scales,
    sheet_side,
    split,
)

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


@pytest.mark.parametrize("name", ["wholemilk", "skin1", "ketchup"])
def test_the_three_bands_sum_to_the_profile(name):
    profile = model_profile("dipole", material(name))
    sc = scales(profile, 0.01)
    far, core, band = split(profile, sc.core, sc.split)
    r = np.linspace(0.0, 1.5 * sc.split, 2000)
    far_values = np.where(r[:, None] < sc.split, far[0] + far[1] * r[:, None] ** 2, profile(r))
    core_values = np.stack([np.interp(r**2, np.linspace(0, sc.core**2, BAND_TABLE), core[:, c], right=0.0)
                            for c in range(3)], axis=1)
    band_values = np.stack([np.interp(r**2, np.linspace(0, sc.split**2, BAND_TABLE), band[:, c], right=0.0)
                            for c in range(3)], axis=1)
    total = core_values + band_values + far_values
    np.testing.assert_allclose(total, profile(r), rtol=1e-3, atol=1e-6 * profile(0.0).max())
    assert np.all(core_values[r >= sc.core] == 0) and np.all(band_values[r >= sc.split] == 0)
    assert np.all(core_values >= 0) and np.all(far_values > 0)  # the dipole is convex: every cap lies below it
    # The far field is C^1 at r_c: its slope from inside (2 b r_c) is the profile's.
    step = 1e-5 * sc.split
    slope = (profile(sc.split + step) - profile(sc.split - step)) / (2 * step)
    np.testing.assert_allclose(2 * far[1] * sc.split, slope, rtol=1e-4)


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


def test_a_cell_list_too_large_is_refused_before_allocating():
    """Beam diffusion's near-singular peak gives a core width of microns: on a 40 mm sphere the cell list would need
    a billions-of-cubes offset table; a one-line error, not a MemoryError."""
    samples = _lit_sphere(20.0, 2000)
    with pytest.raises(ConvsssError, match="cell list .* use the hierarchical or exact transport"):
        make_transport("multiscale", samples, model_profile("pbd", material("wholemilk")), FRAME)
