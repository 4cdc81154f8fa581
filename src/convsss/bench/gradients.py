"""Gradients through a walked render against finite differences of ``volpathmis`` (issue 63), and the backward pass's
cost beside the render's.

Issue 63's cases and its boundaries: a unit sphere (mm) of a homogeneous medium, isotropic, under a constant
environment, 16x16, ``walk_depth`` inf, the loss the image's mean; per channel ``c``, d(mean of channel c) / d(the
parameter's channel c). ``convsss``: ``dr.backward`` through ``mi.render``, ``SEEDS`` seeds of ``spp``; the
reference: central differences (h = 0.01 on the rgb value) of ``volpathmis`` renders on common seeds, ``SEEDS`` seeds
of ``reference_spp``. Each with its standard error from its seeds' spread. Then the dense case (sigma_t 20/mm,
albedo 0.95) at 128x128: the primal render and ``dr.backward`` (seconds, medians of 3 after a first of each; and
each one's peak memory, in a fresh process of its own: the backward's process renders the primal image first).

    python -m convsss.bench.gradients [SPP] [REFERENCE_SPP]
"""

import json
import resource
import subprocess
import sys
import time

import numpy as np

SEEDS = 4
H = 0.01
#: (name, parameter, albedo, sigma_t per mm, boundary)
CASES = [
    ("albedo, grey sigma_t 2/mm", "albedo", (0.8,) * 3, (2.0,) * 3, "null"),
    ("albedo, sigma_t 2/6/9", "albedo", (0.8,) * 3, (2.0, 6.0, 9.0), "null"),
    ("sigma_t, grey 2/mm", "sigma_t", (0.8,) * 3, (2.0,) * 3, "null"),
    ("sigma_t, 2/6/9", "sigma_t", (0.8,) * 3, (2.0, 6.0, 9.0), "null"),
    ("albedo, 2/6/9, dielectric", "albedo", (0.8,) * 3, (2.0, 6.0, 9.0), "dielectric"),
    ("sigma_t, 2/6/9, rough dielectric", "sigma_t", (0.8, 0.7, 0.9), (2.0, 6.0, 9.0), "roughdielectric"),
    ("albedo, sigma_t 20/mm, albedo 0.95", "albedo", (0.95,) * 3, (20.0,) * 3, "null"),
]
DENSE = CASES[-1]
#: The dense case's film for its cost (seconds, memory): large enough that its paths, not the process, weigh.
COST_RES = 128


def scene_dict(albedo, sigma_t, boundary, integrator, res=16, light="constant"):
    """Issue 63's sphere: radius 1 (mm), ``sigma_t`` as its rgb value times a scale (the largest channel), under a
    constant environment (``light`` "constant") or a point light ("point"); a rough boundary's alpha 0.2."""
    import mitsuba as mi

    T = mi.ScalarTransform4f
    bsdf = {"type": "null"} if boundary == "null" else {"type": boundary, "int_ior": 1.4}
    if boundary == "roughdielectric":
        bsdf["alpha"] = 0.2
    scale = max(sigma_t)
    return {"type": "scene", "integrator": integrator,
            "sensor": {"type": "perspective", "fov": 30.0,
                       "to_world": T().look_at(origin=[0, 0, 5], target=[0, 0, 0], up=[0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": res, "height": res, "rfilter": {"type": "box"}},
                       "sampler": {"type": "independent", "sample_count": 4}},
            "sphere": {"type": "sphere", "radius": 1.0, "bsdf": bsdf,
                       "interior": {"type": "homogeneous", "albedo": {"type": "rgb", "value": list(albedo)},
                                    "sigma_t": {"type": "rgb", "value": [s / scale for s in sigma_t]},
                                    "scale": scale}},
            "light": {"type": "constant"} if light == "constant" else {
                "type": "point", "position": [2.0, 3.0, 2.0], "intensity": {"type": "rgb", "value": [10.0] * 3}}}


CONVSSS = {"type": "convsss", "walk_depth": "inf"}


def gradient(mi, case, seed, spp, res=16):
    """``dr.backward`` of the image's mean: d(mean of channel c) / d(parameter c), and its seconds."""
    import drjit as dr

    _, parameter, albedo, sigma_t, boundary = case
    scene = mi.load_dict(scene_dict(albedo, sigma_t, boundary, CONVSSS, res))
    params = mi.traverse(scene)
    key = f"sphere.interior_medium.{parameter}.value.value"
    dr.enable_grad(params[key])
    params.update()
    image = mi.render(scene, params, seed=seed, seed_grad=seed + 1000, spp=spp)
    dr.eval(image)
    start = time.perf_counter()
    dr.backward(dr.mean(dr.ravel(image[..., :3])))
    grad = 3 * np.array(dr.grad(params[key]), dtype=np.float64).ravel()
    return grad, time.perf_counter() - start


def difference(mi, case, seed, spp):
    """Central differences of ``volpathmis`` (common seed) for the same derivative."""
    from convsss.pipeline.reference import reference_integrator

    _, parameter, albedo, sigma_t, boundary = case
    sides = []
    for sign in (1, -1):
        a = tuple(x + sign * H for x in albedo) if parameter == "albedo" else albedo
        s = tuple(x + sign * H * max(sigma_t) for x in sigma_t) if parameter == "sigma_t" else sigma_t
        scene = mi.load_dict(scene_dict(a, s, boundary, {"type": "volpathmis"}))
        image = mi.render(scene, integrator=reference_integrator(), seed=seed, spp=spp)
        sides.append(np.array(image, dtype=np.float64)[..., :3].mean(axis=(0, 1)))
    return (sides[0] - sides[1]) / (2 * H)


def _peak_memory(mode, spp):
    """Run the dense case's ``mode`` (primal or backward) in a fresh process: its peak resident memory (MB)."""
    out = subprocess.run([sys.executable, "-m", "convsss.bench.gradients", "--memory", mode, str(spp)],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])["peak_mb"]


def _memory_child(mode, spp):
    import drjit as dr

    import convsss

    mi = convsss.register()
    if mode == "primal":
        scene = mi.load_dict(scene_dict(*DENSE[2:], CONVSSS, COST_RES))
        dr.eval(mi.render(scene, seed=1, spp=spp))
    else:
        gradient(mi, DENSE, 1, spp, COST_RES)
    print(json.dumps({"peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))


def bench_gradients(spp=64, reference_spp=512):
    """One row per case: convsss's gradient and the differences', each mean and standard error per channel; then the
    dense case's seconds and memory."""
    import drjit as dr

    import convsss

    mi = convsss.register()
    rows = []
    for case in CASES:
        ours = np.array([gradient(mi, case, seed, spp)[0] for seed in range(SEEDS)])
        ref = np.array([difference(mi, case, seed, reference_spp) for seed in range(SEEDS)])
        rows.append({"case": case[0], "convsss": ours.mean(0), "convsss_se": ours.std(0) / np.sqrt(SEEDS),
                     "volpathmis": ref.mean(0), "volpathmis_se": ref.std(0) / np.sqrt(SEEDS)})
    scene = mi.load_dict(scene_dict(*DENSE[2:], CONVSSS, COST_RES))
    primal = []
    for k in range(4):
        start = time.perf_counter()
        dr.eval(mi.render(scene, seed=k, spp=spp))
        primal.append(time.perf_counter() - start)
    backward = [gradient(mi, DENSE, k, spp, COST_RES)[1] for k in range(4)]
    cost = {"primal_s": float(np.median(primal[1:])), "backward_s": float(np.median(backward[1:])),
            "primal_mb": _peak_memory("primal", spp), "backward_mb": _peak_memory("backward", spp)}
    return rows, cost


def _fmt(values, errors):
    return " / ".join(f"{v:.4f}±{e:.4f}" for v, e in zip(values, errors))


def main(argv):
    if argv[:1] == ["--memory"]:
        _memory_child(argv[1], int(argv[2]))
        return
    spp = int(argv[0]) if argv else 64
    reference_spp = int(argv[1]) if len(argv) > 1 else 512
    rows, cost = bench_gradients(spp, reference_spp)
    print(f"{SEEDS} seeds each: convsss dr.backward at {spp} spp, volpathmis central differences (h {H}) at "
          f"{reference_spp} spp; R / G / B, mean ± standard error")
    print("| gradient | convsss | volpathmis differences | ratio |")
    print("|---|---|---|---|")
    for r in rows:
        ratio = " / ".join(f"{a / b:.3f}" for a, b in zip(r["convsss"], r["volpathmis"]))
        print(f"| {r['case']} | {_fmt(r['convsss'], r['convsss_se'])} | "
              f"{_fmt(r['volpathmis'], r['volpathmis_se'])} | {ratio} |")
    print(f"dense case ({DENSE[0]}), {COST_RES}x{COST_RES}, {spp} spp: primal {cost['primal_s']:.3f} s, "
          f"backward {cost['backward_s']:.3f} s ({cost['backward_s'] / cost['primal_s']:.2f}x); "
          f"peak memory of a fresh process: primal {cost['primal_mb']:.0f} MB, backward {cost['backward_mb']:.0f} MB "
          f"({cost['backward_mb'] / cost['primal_mb']:.2f}x)")


if __name__ == "__main__":
    main(sys.argv[1:])
