"""The default render's efficiency against ``volpathmis`` as estimators: warm, in one process, many seeds (issue 60).

Per scene (a ``bench walk`` or ``bench volpath`` scene), at one size and spp:

1. two ``volpathmis`` references of ``reference_spp`` (no roulette; seeds apart): the first is the truth, half the
   relative MSE between them its own noise;
2. ``convsss`` (its defaults: ``auto``; or at another ``walk_depth``) and ``volpathmis`` (no roulette, unbounded
   paths), one untimed render each first (Dr.Jit compiles), then ``seeds`` renders of distinct seeds: the median
   seconds of a render (its image evaluated), the mean relative MSE over the object's pixels less the reference's
   noise, and the efficiency ``1 / (relative MSE x seconds)``.

A render's relative MSE is dominated by its rarest heavy paths: one seed says little, twelve say it within about 10 %.
The command's time (start, scene loading) is ``bench walk``'s and ``bench cost``'s; this is the estimator's. To
compare two versions of convsss, run this module under each (``PYTHONPATH=that/src``) on the same machine, back to
back.

    python -m convsss.bench.efficiency [--width W] [--spp S] [--seeds N] [--reference-spp R] [--walk-depth D]
                                       [-o FILE] SCENE...
"""

import argparse
import json
import statistics
import time

#: The references' passes (samples per pixel each; the last one the rest).
PASS_SPP = 256


def _timed(mi, dr, scene, integrator, spp, seed):
    """``(seconds, image (H, W, 3))`` of one render, its image evaluated."""
    import numpy as np

    start = time.perf_counter()
    image = mi.render(scene, integrator=integrator, spp=spp, seed=seed)
    dr.eval(image)
    dr.sync_thread()
    return time.perf_counter() - start, np.array(image, dtype=np.float64)[..., :3]


def bench_efficiency(names, width=96, spp=32, seeds=12, reference_spp=1024, walk_depth="auto"):
    """One row per scene: ``{scene, walk_depth, reference_noise, convsss: {...}, volpathmis: {...}, ratio}``, each
    estimator's ``{seconds, error, efficiency, mean_ratio}`` (module doc); ``ratio`` convsss's efficiency over
    volpathmis's; convsss renders at ``walk_depth`` (``"auto"``, a number, ``inf``)."""
    import drjit as dr
    import numpy as np

    import convsss
    from convsss.pipeline.reference import reference_integrator, translucent_pixels

    from .scenes import scene_dict
    from .volpath import VOLPATH_SCENES, relative_mse
    from .walk import WALK_SCENES

    mi = convsss.register()
    rows = []
    for name in names:
        spec = scene_dict({**VOLPATH_SCENES, **WALK_SCENES}[name], width)
        spec.pop("integrator", None)
        scene = mi.load_dict(spec)
        mask = translucent_pixels(scene).astype(np.float64)
        inside = mask > 0.5
        volpath = reference_integrator()
        references = []
        shares = [PASS_SPP] * (reference_spp // PASS_SPP) + [reference_spp % PASS_SPP] * bool(reference_spp % PASS_SPP)
        for start in (1 << 20, 2 << 20):  # seeds apart from the renders'
            references.append(sum(share * _timed(mi, dr, scene, volpath, share, start + k)[1]
                                  for k, share in enumerate(shares)) / reference_spp)
        truth = references[0]
        noise = 0.5 * relative_mse(truth, references[1], mask)
        row = {"scene": name, "walk_depth": str(walk_depth), "reference_noise": noise}
        ours = mi.load_dict({"type": "convsss", "walk_depth": walk_depth})
        for label, integrator in (("convsss", ours), ("volpathmis", volpath)):
            _timed(mi, dr, scene, integrator, spp, 1 << 30)
            seconds, errors, means = [], [], []
            for seed in range(seeds):
                took, image = _timed(mi, dr, scene, integrator, spp, seed)
                seconds.append(took)
                errors.append(relative_mse(truth, image, mask))
                means.append(image[inside].mean(axis=0) / np.maximum(truth[inside].mean(axis=0), 1e-30))
            took, error = statistics.median(seconds), statistics.fmean(errors) - noise
            row[label] = {"seconds": took, "error": error, "efficiency": 1.0 / (took * error) if error > 0 else None,
                          "mean_ratio": np.mean(means, axis=0).tolist()}
        ours, theirs = row["convsss"]["efficiency"], row["volpathmis"]["efficiency"]
        row["ratio"] = ours / theirs if ours and theirs else None
        rows.append(row)
    return rows


def efficiency_table(rows):
    """The rows as text: per scene and estimator, seconds, relative MSE, efficiency, mean over the truth."""
    lines = [f"{'scene':>18} {'estimator':>10} {'seconds':>8} {'relMSE':>9} {'efficiency':>10} {'mean R/G/B':>18}"]
    for row in rows:
        for label in ("convsss", "volpathmis"):
            r = row[label]
            eff = "" if r["efficiency"] is None else f"{r['efficiency']:.3g}"
            lines.append(f"{row['scene']:>18} {label:>10} {r['seconds']:>8.3f} {r['error']:>9.3g} {eff:>10} "
                         f"{'/'.join(f'{x:.3f}' for x in r['mean_ratio']):>18}")
        ratio = "" if row["ratio"] is None else f"{row['ratio']:.2f}x"
        lines.append(f"{'':>18} {'ratio':>10} {ratio:>8}   (reference noise {row['reference_noise']:.3g})")
    return "\n".join(lines)


def _walk_depth(text):
    """``--walk-depth`` as the integrator checks its ``walk_depth`` (:func:`~convsss.pipeline.params.render_parameters`:
    auto, a number of at least 0, inf)."""
    from ..errors import ConvsssError
    from ..pipeline.params import render_parameters

    declared = next(p for p in render_parameters() if p.name == "walk_depth")
    try:
        return declared.check(text)
    except ConvsssError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m convsss.bench.efficiency",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="+", metavar="SCENE", help="a bench walk or bench volpath scene")
    parser.add_argument("--width", type=int, default=96, help="image width and height in pixels (default 96)")
    parser.add_argument("--spp", type=int, default=32, help="samples per pixel of each render (default 32)")
    parser.add_argument("--seeds", type=int, default=12, help="renders of distinct seeds per estimator (default 12)")
    parser.add_argument("--reference-spp", type=int, default=1024,
                        help="samples per pixel of each of the two volpathmis references (default 1024)")
    parser.add_argument("--walk-depth", default="auto", type=_walk_depth,
                        help="convsss's walk_depth: auto (the default), a number of scattering events, or inf")
    parser.add_argument("-o", "--output", help="write the rows as JSON to this file")
    args = parser.parse_args(argv)
    from .volpath import VOLPATH_SCENES
    from .walk import WALK_SCENES

    unknown = [name for name in args.scenes if name not in {**VOLPATH_SCENES, **WALK_SCENES}]
    if unknown:
        parser.error(f"unknown scene {unknown[0]!r}: one of {', '.join(sorted({**VOLPATH_SCENES, **WALK_SCENES}))}")
    if min(args.width, args.spp, args.seeds, args.reference_spp) < 1:
        parser.error("--width, --spp, --seeds and --reference-spp are at least 1")
    rows = bench_efficiency(args.scenes, args.width, args.spp, args.seeds, args.reference_spp, args.walk_depth)
    print(efficiency_table(rows))
    if args.output:
        from ..files import atomic_write, text_writer

        atomic_write(args.output, text_writer(json.dumps(rows, indent=1)))


if __name__ == "__main__":
    main()
