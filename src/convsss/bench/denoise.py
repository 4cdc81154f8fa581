"""The denoiser against path tracing: per-pixel error of the raw and the denoised default render on the ``bench walk``
scenes (issue 61: the denoised error at most half the raw, its mean within 1 %, 512² denoised within 0.5 s).

Per scene (:data:`~.walk.WALK_SCENES`, the film's filter a box: the denoiser's input), in one process: the default
render (``walk_depth`` auto) at ``spp``, denoised (:func:`convsss.denoise.denoise`, guided by its albedo and normal
AOVs), and a reference of the same scene, ``walk_depth`` inf (``volpathmis``'s estimator) at ``reference_spp``, two
seeds (its own noise). The error is the relative RMSE over 2x2 blocks of the object's pixels (the reference's mask
AOV), and the same less the reference's own noise (in quadrature).

    python -m convsss.bench.denoise [WIDTH] [SPP] [REFERENCE_SPP]
"""

import sys
import time

import numpy as np


def _blocks(image):
    h, w = image.shape[0] // 2 * 2, image.shape[1] // 2 * 2
    return image[:h, :w].reshape(h // 2, 2, w // 2, 2, -1).mean(axis=(1, 3))


def _error(test, reference, inside):
    return float(np.sqrt(np.mean((_blocks(test) - reference)[inside] ** 2)) / np.mean(reference[inside]))


def bench_denoise(width=128, spp=16, reference_spp=512):
    """One row per scene: raw and denoised error, their ratio, the means' ratio, the reference's own error."""
    import convsss
    from convsss.denoise import denoise, guides_of
    from convsss.pipeline.aovs import film_channels

    from .scenes import scene_dict
    from .walk import WALK_SCENES

    mi = convsss.register()
    rows = []
    for name, scene in WALK_SCENES.items():
        def render(walk_depth, count, seed, aovs, scene=scene):
            d = scene_dict(scene, width)
            d["sensor"]["film"]["rfilter"] = {"type": "box"}
            d["integrator"] = {"type": "convsss", "walk_depth": walk_depth, "aovs": aovs}
            loaded = mi.load_dict(d)
            return film_channels(mi.render(loaded, seed=seed, spp=count), loaded.integrator().aov_names())

        film, channels = render(float("inf"), reference_spp, 101, "mask")
        ref, mask = film[..., :3], film[..., channels.index("mask.Y"), None]
        ref2 = render(float("inf"), reference_spp, 202, "")[0]
        reference, inside = _blocks(ref), _blocks(mask)[..., 0] > 0.999
        film, channels = render("auto", spp, 1, "albedo,normal")
        raw = film[..., :3]
        start = time.perf_counter()
        clean = denoise(raw, *guides_of(film, channels))
        seconds = time.perf_counter() - start
        e_raw, e_den = _error(raw, reference, inside), _error(clean, reference, inside)
        object_pixels = inside.repeat(2, 0).repeat(2, 1)
        rows.append({"scene": name, "raw": e_raw, "denoised": e_den, "ratio": e_den / e_raw,
                     "mean_ratio": float(_blocks(clean)[inside].mean() / _blocks(raw)[inside].mean()),
                     "reference_noise": _error(ref2, reference, inside) / np.sqrt(2), "denoise_s": seconds,
                     "pixels": int(object_pixels.sum())})
        r = rows[-1]
        noise = r["reference_noise"]
        r["raw_excess"], r["denoised_excess"] = (float(np.sqrt(max(e * e - noise * noise, 0.0)))
                                                 for e in (e_raw, e_den))
        print(f"{name:18s} raw {r['raw']:.4f}  denoised {r['denoised']:.4f}  ratio {r['ratio']:.3f}  "
              f"less the reference's noise {r['raw_excess']:.4f} / {r['denoised_excess']:.4f}  "
              f"mean {r['mean_ratio']:.4f}  reference noise {noise:.4f}  denoise {seconds:.2f} s", flush=True)
    return rows


def denoise_seconds(width=512, repeats=5):
    """Median seconds to denoise a ``width``² image with both guides (after one call that loads the filter)."""
    from convsss.denoise import denoise

    rng = np.random.default_rng(0)
    color, albedo = rng.random((width, width, 3)), rng.random((width, width, 3))
    normal = np.broadcast_to([0.0, 0.0, 1.0], color.shape)
    denoise(color, albedo, normal)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        denoise(color, albedo, normal)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:]]
    bench_denoise(*args)
    print(f"denoise 512²: {denoise_seconds():.3f} s (median of 5)")
