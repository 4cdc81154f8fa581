"""The noise benchmark (convsss.bench.noise): its estimate of one render's per-pixel noise from two seeds."""

import numpy as np
import pytest

from convsss.bench.noise import bench_noise, noise_table, pixel_noise


def test_pixel_noise_of_two_draws_is_the_relative_standard_deviation():
    rng = np.random.default_rng(0)
    mean = rng.uniform(0.5, 2.0, size=(64, 64, 3))
    sigma = 0.02
    a, b = (mean * (1 + sigma * rng.standard_normal(mean.shape)) for _ in range(2))
    inside = np.ones((64, 64), bool)
    inside[:8] = False
    noise = pixel_noise(a, b, inside)
    assert noise.shape == (inside.sum(), 3)
    # |a - b| / sqrt(2) / mean is sigma |z|: its median is 0.6745 sigma, its root mean square sigma
    np.testing.assert_allclose(np.median(noise, axis=0), 0.6745 * sigma, rtol=0.05)
    np.testing.assert_allclose(np.sqrt(np.mean(noise**2, axis=0)), sigma, rtol=0.05)


def test_pixel_noise_floors_dark_pixels_at_a_share_of_the_mean():
    a = np.ones((4, 4, 3))
    b = a.copy()
    a[0, 0], b[0, 0] = 1e-6, 0.0  # black in both but for a speck: relative to 1 % of the mean, not to 5e-7
    noise = pixel_noise(a, b, np.ones((4, 4), bool))
    assert noise.max() < 1e-3


@pytest.mark.slow
def test_bench_noise_rows_and_table():
    rows = bench_noise(width=24, spp=1, passes=(1, 2), progress=False)
    assert [r["passes"] for r in rows] == [1, 2] and [r["spp"] for r in rows] == [1, 2]
    assert rows[1]["samples"] == 2 * rows[0]["samples"] and rows[0]["pixels"] > 20
    for r in rows:
        assert all(0 < m <= p for m, p in zip(r["median"], r["p95"]))
        np.testing.assert_allclose(r["median_sqrt_passes"], np.array(r["median"]) * np.sqrt(r["passes"]))
    table = noise_table(rows, 24)
    assert "| 2 | 2 |" in table and "median x sqrt(passes)" in table


@pytest.mark.slow
def test_bench_noise_of_the_walk():
    rows = bench_noise(width=24, spp=1, passes=(1, 2), progress=False, walk_depth=4.0)
    assert all(0 < m <= p for r in rows for m, p in zip(r["median"], r["p95"]))
    assert "walk_depth 4" in noise_table(rows, 24, 4.0)
