"""Sample noise of the exitance ``M`` (docs/benchmarks.md, issue 11): how much ``M`` at the visible pixel centres
changes from one sample seed to another, as a function of the sampling parameters.

For each configuration the scene is prepared (``ConvsssIntegrator.prepare``: samples, irradiance, indirect light,
transports) with ``SEEDS`` different seeds, and the default transport's ``M`` is evaluated at the object's visible
pixel centres (the same points for every seed; the image at high spp inherits exactly this noise, the shading reading
``M`` at these points). Per pixel and channel, the relative standard deviation over the seeds (ddof 1), divided by
``c4(SEEDS)`` (the mean bias of a sample standard deviation) and relative to the mean over the seeds with the floor
of :mod:`convsss.compare` (1 % of the channel's mean); printed: its mean and 95th percentile over the object's
pixels, the largest over the channels, and the median seconds of the stages.

    PYTHONPATH=src python docs/history/scripts/noise-noise.py SCENE WIDTH SEEDS DENSITY:IRRADIANCE:INDIRECT[:EXTRA=V...][,...]

SCENE: a material key and the bunny's size in mm, e.g. ``milk40`` (the demo: 40 mm wholemilk bunny on the floor,
dielectric boundary, key and back point lights), ``dense10`` (a 10 mm bunny of ``--color 0.8,0.6,0.4 --mfp-mm
0.1``), ``marble40``, ``ketchup40``, ``skin40``, ``espresso40``; with ``-area`` (``milk40-area``) the bunny has no
floor and is lit by the benchmark's square area light and a dim constant environment instead of the point lights.
EXTRA: any integrator parameter, e.g. ``profile_samples=0`` (the pixel rule alone), or ``mesh_order=0`` (meshes
sampled by the plain grid over the square, as before issue 11's stratification along a Morton curve).
Also printed: samples per effective area of the profile (:meth:`convsss.profiles.Profile.effective_area`) per
channel.
With a fifth argument ``--std`` a 95th percentile is also given for an assumed uniform noise: the p95 of the
sample standard deviation of ``SEEDS`` normal draws is that many times its mean (the spread of the estimate alone).
"""

import math
import sys
import time

import numpy as np

import convsss
from convsss.backend import load_mitsuba
from convsss.compare import FLOOR
from convsss.profiles import material_from_color
from convsss.scene.quick import demo_mesh, quick_scene

mi = load_mitsuba()
convsss.register()


MATERIALS = {"milk": "wholemilk", "marble": "marble", "ketchup": "ketchup", "skin": "skin1", "espresso": "espresso"}


def scene_of(name, width):
    """The quick scene of ``NAME[-area]``, NAME a material key and the bunny's size in mm (``milk40``, ``dense10``)."""
    import re


    key, size = re.fullmatch(r"([a-z]+)(\d+(?:\.\d+)?)", name.split("-")[0]).groups()
    material = material_from_color([0.8, 0.6, 0.4], 0.1) if key == "dense" else convsss.material(MATERIALS[key])
    area = name.endswith("-area")
    d = quick_scene(demo_mesh(), material, float(size), width, width, 1, floor=not area)
    if area:
        from convsss.bench.scenes import BenchScene, scene_dict

        lit = scene_dict(BenchScene("bunny", "wholemilk", float(size), "area"), width)
        for light in ("area_light", "environment"):
            d[light] = lit[light]
        d.pop("key_light"), d.pop("back_light")
    return d


def parse(config):
    fields = config.split(":")
    params = {"sample_density": float(fields[0]), "irradiance_samples": int(fields[1]),
              "indirect_samples": float(fields[2])}
    for extra in fields[3:]:
        k, v = extra.split("=")
        try:
            params[k] = float(v)
        except ValueError:  # a string parameter (profile=pbd)
            params[k] = v
    return params


def measure_config(d, config, seeds):
    """:func:`measure` for ``DENSITY:IRRADIANCE:INDIRECT[:EXTRA=V...]``; ``mesh_order=0`` samples meshes by the plain
    grid (:data:`convsss.pipeline.surface.MESH_STRATIFICATION` off)."""
    import convsss.pipeline.surface as surface

    params = parse(config)
    surface.MESH_STRATIFICATION = bool(params.pop("mesh_order", 1))
    try:
        return measure(d, params, seeds)
    finally:
        surface.MESH_STRATIFICATION = True


def measure(d, params, seeds):
    scene = mi.load_dict({**d, "integrator": {"type": "convsss", **params}})
    integ = scene.integrator()
    sensor = scene.sensors()[0]
    values, seconds, samples = [], [], []
    for seed in range(seeds):
        start = time.perf_counter()
        integ.prepare(scene, sensor, seed)
        state = integ.prepared
        visible = state.visible[0]
        values.append(state.transports[0].exitance(visible.position, visible.normal))
        wall = time.perf_counter() - start
        seconds.append({**integ.stats["seconds"], "wall": wall})
        samples.append(integ.stats["objects"][0]["samples"])
    obj = {**integ.stats["objects"][0], "effective_area": integ.prepared.objects[0].profile.effective_area()}
    m = np.stack(values)  # (seeds, K, 3)
    mean = m.mean(axis=0)
    floor = FLOOR * mean.mean(axis=0)
    # The sample standard deviation of n draws underestimates sigma by c4(n) on average: corrected, so that the
    # mean over the pixels estimates the mean noise whatever the number of seeds.
    n = len(values)
    c4 = np.sqrt(2.0 / (n - 1)) * np.exp(math.lgamma(n / 2) - math.lgamma((n - 1) / 2))
    rel = m.std(axis=0, ddof=1) / c4 / np.maximum(mean, floor)
    stages = {k: float(np.median([s.get(k, 0.0) for s in seconds])) for k in seconds[0]}
    return rel, samples[0], obj, stages


def main():
    name, width, seeds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    d = scene_of(name, width)
    if len(sys.argv) > 5 and sys.argv[5] == "--std":
        draws = np.random.default_rng(0).standard_normal((200000, seeds)).std(axis=1, ddof=1)  # sigma = 1
        spread = np.percentile(draws, 95) / draws.mean()
        print(f"p95/mean of a {seeds}-seed std estimate of uniform noise: {spread:.2f}")
    for config in sys.argv[4].split(","):
        rel, count, obj, st = measure_config(d, config, seeds)
        mean, p95 = rel.mean(axis=0), np.percentile(rel, 95, axis=0)
        cell = obj["pixel_footprint_mm"]
        per_area = count * obj["effective_area"] / obj["area_mm2"]
        print(f"{name} {width}px {config}: samples {count} cell {cell:.3f} mm, per profile area "
              f"{np.round(per_area).astype(int)}, rel std mean "
              f"{np.round(100 * mean, 2)} % (max {100 * mean.max():.2f}), p95 {np.round(100 * p95, 2)} % "
              f"(max {100 * p95.max():.2f}); s: samples {st.get('samples', 0):.2f} irradiance "
              f"{st.get('irradiance', 0):.2f} indirect {st.get('indirect', 0):.2f} transport "
              f"{st.get('transport', 0):.2f} wall {st['wall']:.1f}", flush=True)


if __name__ == "__main__":
    main()
