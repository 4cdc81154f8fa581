"""Benchmarks that print tables: medians of several runs, per stage, and ratios measured in the same run.

``transport``: the layered convolution transport on a synthetic lit sphere (wholemilk, 10 mm radius, about two
samples per cell), per stage (splat, kernels cold and cached, forward FFT, mixing, inverse FFT, lookup), against the
**bare FFT floor**: the same number and size of ``rfft2`` / ``irfft2`` calls (float32, all cores) with nothing
else. ``ratio = (stages with cached kernels) / floor``.
"""

import time

import numpy as np
import scipy.fft
from tqdm import tqdm

from ..materials import material
from ..profiles import model_profile
from ..samples import IrradianceSamples, ViewFrame
from ..transport import clear_caches
from ..transport.convolution import ConvolutionTransport

STAGES = ("splat", "kernels_cold", "kernels_cached", "forward_fft", "mixing", "inverse_fft", "lookup")


def lit_sphere(n, radius=10.0):
    """``n`` Fibonacci points on a sphere lit by a directional light; the front half is the query set.

    Parameters
    ----------
    n : int
        Samples on the sphere.
    radius : float
        Sphere radius (mm), centred on the origin.

    Returns
    -------
    samples : IrradianceSamples
        Positions (mm), equal areas ``4 pi radius^2 / n`` (mm^2), outward normals and the irradiance
        ``max(n . l, 0)`` in every channel (a light of irradiance 1).
    query : numpy.ndarray, shape (K, 3), float64
        The sample positions with ``z > 0`` (mm).
    """
    k = np.arange(n) + 0.5
    phi, theta = np.arccos(1 - 2 * k / n), np.pi * (1 + 5**0.5) * k
    normal = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
    light = np.array([0.6, 0.3, 0.74]) / np.linalg.norm([0.6, 0.3, 0.74])
    irradiance = np.maximum(normal @ light, 0.0)[:, None] * np.ones(3)
    samples = IrradianceSamples(normal * radius, 4 * np.pi * radius**2 / n, irradiance, normal)
    return samples, samples.position[normal[:, 2] > 0]


def fft_floor(padded_shape, forward, inverse, workers=-1):
    """Seconds for ``forward`` rfft2 and ``inverse`` irfft2 batches of 3 channels of ``padded_shape`` (float32)."""
    spatial = np.random.default_rng(0).random((forward, 3) + tuple(padded_shape), dtype=np.float32)
    start = time.perf_counter()
    spectra = scipy.fft.rfft2(spatial, workers=workers)
    scipy.fft.irfft2(spectra[:inverse], s=padded_shape, workers=workers)
    return time.perf_counter() - start


def transport_run(samples, query, frame, profile, resolution, layers, threshold):
    """One timed run: stage seconds (cold kernels, then a second build with cached ones) and the FFT floor.

    Parameters
    ----------
    samples : IrradianceSamples
    query : numpy.ndarray, shape (K, 3), float64
        Points (mm) whose exitance is looked up.
    frame : ViewFrame
    profile : Profile
    resolution, layers : int
        Grid cells across and layers of the convolution transport.
    threshold : float
        The paper's threshold t (Eq. 8).

    Returns
    -------
    seconds : dict
        Seconds per stage of :data:`STAGES`.
    floor : float
        Seconds of the bare FFTs (:func:`fft_floor`).
    transport : ConvolutionTransport
        The build with cached kernels, every layer computed.
    """
    clear_caches()
    common = dict(layers=layers, resolution=resolution, threshold=threshold, correction="none")  # the paper's layers
    cold = ConvolutionTransport(samples, profile, frame, **common)
    warm = ConvolutionTransport(samples, profile, frame, **common)
    warm.compute_layers(range(warm.n_layers))
    warm.exitance(query)
    seconds = {stage: warm.timings.get(stage, 0.0) for stage in STAGES if stage != "kernels_cold"}
    seconds["kernels_cached"] = warm.timings["kernels"]
    seconds["kernels_cold"] = cold.timings["kernels"]
    floor = fft_floor(warm.padded_shape, len(warm.source_layers), int(warm.computed.sum()))
    return seconds, floor, warm


def bench_transport(grids=(256, 512, 1024), layer_counts=(4, 8, 16), thresholds=(0.0, 0.001), runs=5,
                    progress=True):
    """Rows ``{grid, layers, threshold, stage_median_s, fft_floor_s, ratio, fft_shape, pairs_per_layer}``."""
    frame = ViewFrame.look_at([0, 0, 100], [0, 0, 0])
    profile = model_profile("dipole", material("wholemilk"))
    configs = [(g, n, t) for g in grids for n in layer_counts for t in thresholds]
    rows = []
    bar = tqdm(total=len(configs) * runs, desc="bench transport", unit="run", disable=not progress)
    for grid in grids:
        samples, query = lit_sphere(2 * grid * grid)
        for layers, threshold in [(n, t) for n in layer_counts for t in thresholds]:
            per_run, floors = [], []
            for _ in range(runs):
                seconds, floor, transport = transport_run(samples, query, frame, profile, grid, layers, threshold)
                per_run.append(seconds)
                floors.append(floor)
                bar.update()
            median = {stage: float(np.median([r[stage] for r in per_run])) for stage in STAGES}
            floor = float(np.median(floors))
            cached_total = sum(v for k, v in median.items() if k != "kernels_cold")
            rows.append({
                "grid": grid, "layers": layers, "threshold": threshold, "stage_median_s": median,
                "fft_floor_s": floor, "ratio": cached_total / floor, "fft_shape": list(transport.padded_shape),
                "pairs_per_layer": float(transport.pairs_per_layer.mean()), "samples": len(samples),
            })
    bar.close()
    return rows


def transport_table(rows):
    """The rows as a fixed-width text table (seconds)."""
    head = (f"{'grid':>5} {'lay':>3} {'t':>6} {'fft':>11} {'c':>5} "
            + " ".join(f"{s[:11]:>11}" for s in STAGES) + f" {'floor':>8} {'ratio':>6}")
    lines = [head]
    for r in rows:
        stages = " ".join(f"{r['stage_median_s'][s]:>11.4f}" for s in STAGES)
        fft = "x".join(map(str, r["fft_shape"]))
        lines.append(f"{r['grid']:>5} {r['layers']:>3} {r['threshold']:>6.3%} {fft:>11} {r['pairs_per_layer']:>5.2f} "
                     f"{stages} {r['fft_floor_s']:>8.4f} {r['ratio']:>6.2f}")
    return "\n".join(lines)
