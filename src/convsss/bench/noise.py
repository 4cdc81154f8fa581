"""The image's sample noise against passes (issue 33): does it fall as 1/sqrt(passes)?

The scene is the demo's (:func:`~convsss.bench.render.demo_scene`: the 40 mm whole-milk bunny behind a dielectric,
on a floor, key and back light). A render of ``k`` passes gives each pass the budget of a default one-pass render
(``sample_density``, ``profile_samples`` and ``spp`` times ``k``, which the passes share out again), so its noise
should be ``1/sqrt(k)`` of one pass. Per ``k``, two renders with different seeds; per object pixel (the ``mask``
AOV) and channel, the noise is ``|a - b| / sqrt(2)`` relative to the pair's mean (floored at
:data:`convsss.compare.FLOOR` of the channel's mean, as the comparisons are). Reported per channel: its median, 95th
percentile and root mean square over the object (the last weighs the few dark or edge pixels most), and the median
times ``sqrt(k)``, which stays constant where the noise falls as it should. The noise is everything random in a
render: the surface samples' (the exitance) and the camera paths' (the shading).
"""

import math

import numpy as np
from tqdm import tqdm

from ..compare import FLOOR

#: The pass counts of the table.
PASSES = (1, 2, 4, 8)
#: The two seeds of each pair.
SEEDS = (1, 2)


def pixel_noise(a, b, inside):
    """Per object pixel and channel, the relative noise of one render estimated from two seeds, (n, 3).

    ``a``, ``b``: (H, W, 3) linear RGB of the same render at two seeds; ``inside``: (H, W) bool."""
    a, b = (np.asarray(x, dtype=np.float64)[inside] for x in (a, b))
    mean = 0.5 * (a + b)
    floor = FLOOR * mean.mean(axis=0)
    return np.abs(a - b) / math.sqrt(2.0) / np.maximum(mean, floor)


def _scene(mi, width, spp, passes, aovs="mask", walk_depth=0.0):
    from ..materials import material
    from ..pipeline.params import RenderParams
    from ..scene.quick import demo_mesh, quick_scene
    from .render import DEMO

    defaults = RenderParams()
    integrator = {"type": "convsss", "specular": "phong", "aovs": aovs, "passes": passes, "walk_depth": walk_depth,
                  "sample_density": defaults.sample_density * passes,
                  "profile_samples": defaults.profile_samples * passes}
    return mi.load_dict(quick_scene(demo_mesh(), material(DEMO["material"]), DEMO["size_mm"], width=width,
                                    height=width, spp=spp * passes, floor=True, integrator=integrator))


def bench_noise(width=128, spp=4, passes=PASSES, progress=True, walk_depth=0.0):
    """Rows ``{passes, spp, samples, pixels, seconds, median, p95, rms, median_sqrt_passes}`` (the noises per channel,
    relative), one per pass count: each pass at a default render's budget of ``spp`` samples per pixel, the camera
    paths walking to ``walk_depth`` (0: the transport alone)."""
    import time

    import convsss

    mi = convsss.register()
    rows = []
    bar = tqdm(total=len(passes) * len(SEEDS), desc="bench noise", unit="render", disable=not progress)
    for k in passes:
        scene = _scene(mi, width, spp, k, walk_depth=walk_depth)
        images, seconds, samples = [], [], 0
        for seed in SEEDS:
            start = time.perf_counter()
            image = np.array(convsss.render(scene, seed=seed), dtype=np.float64)
            seconds.append(time.perf_counter() - start)
            samples = scene.integrator().stats["samples"]
            images.append(image)
            bar.update()
        inside = images[0][..., -1] > 0.5
        noise = pixel_noise(images[0][..., :3], images[1][..., :3], inside)
        median = np.median(noise, axis=0)
        rows.append({"passes": k, "spp": spp * k, "samples": int(samples), "pixels": int(inside.sum()),
                     "seconds": float(np.median(seconds)), "median": median.tolist(),
                     "p95": np.percentile(noise, 95, axis=0).tolist(),
                     "rms": np.sqrt(np.mean(noise**2, axis=0)).tolist(),
                     "median_sqrt_passes": (median * math.sqrt(k)).tolist()})
    bar.close()
    return rows


def noise_table(rows, width, walk_depth=0.0):
    """A Markdown table of :func:`bench_noise`'s rows."""

    def rgb(values):
        return "/".join(f"{100 * v:.2f}" for v in values)

    walk = f", walk_depth {walk_depth:g}" if walk_depth else ""
    lines = [f"The demo at {width}²{walk}, each pass at a default render's budget; noise per object pixel (%, R/G/B), "
             "from two seeds", "",
             "| passes | spp | samples (all passes) | seconds | median | p95 | rms | median x sqrt(passes) |",
             "|---:|---:|---:|---:|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['passes']} | {r['spp']} | {r['samples']} | {r['seconds']:.1f} | {rgb(r['median'])} | "
                     f"{rgb(r['p95'])} | {rgb(r['rms'])} | {rgb(r['median_sqrt_passes'])} |")
    return "\n".join(lines)
