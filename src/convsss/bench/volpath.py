"""Equal error against path tracing: how long ``volpathmis`` needs to reach the error of a default ``convsss render``.

Per scene and image size, everything as whole commands in fresh processes on one scene file
(:func:`~convsss.scene.xmlwriter.scene_to_xml` of :func:`~convsss.bench.scenes.scene_dict`):

1. two long references, ``convsss reference --spp REFERENCE_SPP`` with seeds 1 and 2; their own noise is half the
   relative MSE between them (each holds half of the difference's variance);
2. ``convsss render`` with its defaults (and ``--aovs mask``, whose mask selects the object's pixels);
3. ``convsss reference`` at each spp of the ladder (seed 3);
4. with a ``walk_depth``, ``convsss render --walk-depth D`` at each spp of the ladder too (seed 3), and once at
   ``inf`` at the ladder's first spp for the scattering events per path of ``volpathmis``'s estimator.

The error is the relative MSE over the object's pixels (:func:`convsss.compare.metrics`, mean of the channels) less
the first reference's own noise: for an unbiased estimate it falls as 1/spp, and the time a path tracer needs
grows as its inverse. The time ``volpathmis`` needs for convsss's error is read off the ladder by linear
interpolation of log time against log error (beyond its ends, extrapolated with the slope -1 of Monte Carlo
noise); the headline is that time over convsss's own. A convsss error below the references' noise cannot be
measured: the row says so.

With a ``walk_depth`` convsss's error falls with spp too, and each rung of the path tracer is read the other way,
as the issue's goal puts it: the time convsss needs to reach the error ``volpathmis`` has at that spp (log-log
interpolation on convsss's own ladder; at most its first rung's time where that is already better; "not reached"
where its last rung is worse: its bias, or noise beyond the ladder), over ``volpathmis``'s time at that spp.
"""

import math
import os
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from .render import CONVSSS
from .scenes import BenchScene

#: The benchmark's scenes: the demo's object in four materials under the two point lights (null boundary: a point
#: light behind a smooth dielectric is black to a path tracer) and the demo's material behind a smooth dielectric
#: under an area light and a dim environment.
VOLPATH_SCENES = {
    "milk40": BenchScene("bunny", "wholemilk", 40.0),
    "marble40": BenchScene("bunny", "marble", 40.0),
    "skin40": BenchScene("bunny", "skin1", 40.0),
    "ketchup40": BenchScene("bunny", "ketchup", 40.0),
    "milk40-area": BenchScene("bunny", "wholemilk", 40.0, "area"),
}
#: Samples per pixel of the references and of the path tracer's ladder.
REFERENCE_SPP = 1024
LADDER = (4, 16, 64, 256)


def _run(args):
    """Wall seconds of ``convsss ARGS`` in a fresh process (one-line error on failure)."""
    start = time.perf_counter()
    done = subprocess.run([*CONVSSS, *args, "--no-progress"],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode:
        lines = done.stderr.strip().splitlines()
        raise RuntimeError(f"convsss {' '.join(args)} failed: {lines[-1] if lines else done.returncode}")
    return time.perf_counter() - start


def _image(path):
    """The RGB image and, where it has one, the mask layer of the EXR at ``path``."""
    from ..compare import mask_layer
    from ..image import read_image, read_layers

    found = mask_layer(read_layers(path))
    return read_image(path), None if found is None else found[1]


def relative_mse(reference, test, mask):
    """The relative MSE of ``test`` against ``reference`` over ``mask``, mean of the channels."""
    from ..compare import metrics, prepare

    a, b, inside = prepare(reference, test, mask)
    return float(np.mean(metrics(a, b, inside)["relmse"]))


def equal_error_seconds(errors, seconds, target):
    """The seconds at which the ladder (``errors``, ``seconds``, by increasing spp) reaches ``target``: log-log
    interpolation, extrapolated beyond its ends with the slope -1 of Monte Carlo noise."""
    le, lt = np.log(np.asarray(errors, dtype=np.float64)), np.log(np.asarray(seconds, dtype=np.float64))
    x = math.log(target)
    if x >= le[0]:
        return float(math.exp(lt[0] - (x - le[0])))
    if x <= le[-1]:
        return float(math.exp(lt[-1] - (x - le[-1])))
    order = np.argsort(le)
    return float(math.exp(np.interp(x, le[order], lt[order])))


def seconds_to_reach(errors, seconds, target):
    """The seconds a ladder (``errors``, ``seconds``, by increasing spp) needs to reach ``target``, and whether that is
    only an upper bound (its first rung is already better); None where no rung reaches it. Log-log interpolation
    between the rungs either side; never extrapolated (a biased render's error stops falling)."""
    for i, error in enumerate(errors):
        if error <= target:
            if i == 0:
                return float(seconds[0]), True
            le = np.log([errors[i - 1], max(error, 1e-300)])
            lt = np.log([seconds[i - 1], seconds[i]])
            if le[0] == le[1]:
                return float(seconds[i]), False
            return float(math.exp(np.interp(math.log(max(target, 1e-300)), le[::-1], lt[::-1]))), False
    return None


def two_references(scene, folder, reference_spp, step, bar=None):
    """``convsss reference`` of the scene file ``scene`` with seeds 1 and 2 to ``FOLDER/ref1`` and ``ref2`` (half
    the relative MSE between them is the reference's own noise); their seconds. ``step(label)`` names each."""
    seconds = []
    for seed in (1, 2):
        step(f"reference seed {seed}")
        seconds.append(_run(["reference", str(scene), "-o", str(Path(folder) / f"ref{seed}"), "--spp",
                             str(reference_spp), "--seed", str(seed)]))
        if bar is not None:
            bar.update()
    return seconds


def _walks(scene, folder, walk_depth, ladder, reference, mask, noise, step, bar):
    """convsss's ladder at ``walk_depth``: ``[{spp, seconds, error, events_per_path, ended_share}]``, and the events
    per path of a walk to its end (``volpathmis``'s estimator) at the ladder's first spp."""
    import json

    rungs = []
    for spp in (*ladder, None):
        depth = "inf" if spp is None else f"{walk_depth:g}"
        step(f"walk_depth {depth} {spp or ladder[0]} spp")
        out = Path(folder) / "walk"
        seconds = _run(["render", str(scene), "-o", str(out), "--walk-depth", depth, "--spp", str(spp or ladder[0]),
                        "--seed", "3", "--stats", str(out.with_suffix(".json"))])
        walk = json.loads(out.with_suffix(".json").read_text()).get("walk", {})
        if bar is not None:
            bar.update()
        if spp is None:
            return rungs, walk.get("events_per_path")
        rungs.append({"spp": spp, "seconds": seconds, "events_per_path": walk.get("events_per_path"),
                      "ended_share": walk.get("ended_share"),
                      "error": relative_mse(reference, _image(out.with_suffix(".exr"))[0], mask) - noise})


def bench_scene(name, width, folder, reference_spp=REFERENCE_SPP, ladder=LADDER, bar=None, walk_depth=None):
    """One row: ``{scene, width, reference_s, reference_noise, convsss_s, convsss_error, ladder: [{spp, seconds,
    error}], volpath_equal_s, speedup, measurable}`` (errors: relative MSE over the object, the reference's noise
    subtracted); with a ``walk_depth`` also ``walk_depth``, ``walk_ladder`` (:func:`_walks`), ``events_at_inf`` and
    ``at_volpath: [{spp, volpath_s, error, convsss_s, upper_bound, speedup}]`` (None where not reached)."""
    from ..scene.xmlwriter import scene_to_xml
    from .scenes import scene_dict

    folder = Path(folder)
    scene = folder / f"{name}-{width}.xml"
    scene.write_text(scene_to_xml(scene_dict(VOLPATH_SCENES[name], width)))

    def step(label):
        if bar is not None:
            bar.set_postfix_str(f"{name} {width}² {label}")

    references = two_references(scene, folder, reference_spp, step, bar)
    reference = _image(folder / "ref1.exr")[0]
    step("convsss")
    convsss_s = _run(["render", str(scene), "-o", str(folder / "convsss"), "--aovs", "mask"])
    if bar is not None:
        bar.update()
    test, mask = _image(folder / "convsss.exr")
    noise = 0.5 * relative_mse(reference, _image(folder / "ref2.exr")[0], mask)
    convsss_error = relative_mse(reference, test, mask) - noise
    rungs = []
    for spp in ladder:
        step(f"volpathmis {spp} spp")
        seconds = _run(["reference", str(scene), "-o", str(folder / "rung"), "--spp", str(spp), "--seed", "3"])
        error = relative_mse(reference, _image(folder / "rung.exr")[0], mask) - noise
        rungs.append({"spp": spp, "seconds": seconds, "error": error})
        if bar is not None:
            bar.update()
    usable = [r for r in rungs if r["error"] > 0]
    measurable = convsss_error > noise and len(usable) >= 2
    equal = equal_error_seconds([r["error"] for r in usable], [r["seconds"] for r in usable], convsss_error) \
        if measurable else None
    row = {"scene": name, "width": width, "reference_s": statistics.median(references), "reference_noise": noise,
           "convsss_s": convsss_s, "convsss_error": convsss_error, "ladder": rungs, "volpath_equal_s": equal,
           "speedup": None if equal is None else equal / convsss_s, "measurable": measurable}
    if walk_depth is None:
        return row
    walks, events = _walks(scene, folder, walk_depth, ladder, reference, mask, noise, step, bar)
    at = []
    for r in rungs:
        reached = seconds_to_reach([w["error"] for w in walks], [w["seconds"] for w in walks], r["error"]) \
            if r["error"] > 0 else None
        at.append({"spp": r["spp"], "volpath_s": r["seconds"], "error": r["error"],
                   "convsss_s": None if reached is None else reached[0],
                   "upper_bound": None if reached is None else reached[1],
                   "speedup": None if reached is None else r["seconds"] / reached[0]})
    return {**row, "walk_depth": walk_depth, "walk_ladder": walks, "events_at_inf": events, "at_volpath": at}


def bench_volpath(scenes=tuple(VOLPATH_SCENES), widths=(128,), reference_spp=REFERENCE_SPP, ladder=LADDER,
                  progress=True, walk_depth=None):
    """The rows of :func:`bench_scene` for every scene and width, and the machine's facts: ``{meta, rows}``."""
    walks = 0 if walk_depth is None else len(ladder) + 1
    bar = tqdm(total=len(scenes) * len(widths) * (3 + len(ladder) + walks), desc="bench volpath", unit="command",
               disable=not progress)
    meta = {"reference_spp": reference_spp, "ladder": list(ladder), "walk_depth": walk_depth,
            "cpus": os.cpu_count(), "load_average_start": list(os.getloadavg())}
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for width in widths:
            for name in scenes:
                rows.append(bench_scene(name, width, folder, reference_spp, ladder, bar, walk_depth))
    bar.close()
    meta["load_average_end"] = list(os.getloadavg())
    return {"meta": meta, "rows": rows}


def volpath_table(result):
    """The rows as a text table: errors as relative MSE (x 1e-3), seconds, the speed-up at equal error."""
    head = (f"{'scene':>12} {'size':>5} {'ref noise':>9} {'convsss err':>11} {'convsss s':>9} "
            + " ".join(f"{f'{s} spp err/s':>15}" for s in result["meta"]["ladder"])
            + f" {'volpath s at equal':>18} {'speed-up':>8}")
    lines = [head]
    for r in result["rows"]:
        rungs = " ".join(f"{r_['error'] * 1e3:>7.3f}/{r_['seconds']:<7.1f}" for r_ in r["ladder"])
        equal = (f"{r['volpath_equal_s']:>18.1f} {r['speedup']:>8.1f}" if r["measurable"]
                 else f"{'below the reference noise':>27}")
        lines.append(f"{r['scene']:>12} {r['width']:>4}² {r['reference_noise'] * 1e3:>9.3f} "
                     f"{r['convsss_error'] * 1e3:>11.3f} {r['convsss_s']:>9.1f} {rungs} {equal}")
        if "walk_ladder" in r:
            walks = " ".join(f"{w['error'] * 1e3:>7.3f}/{w['seconds']:<7.1f}" for w in r["walk_ladder"])
            lines.append(f"{'walk_depth ' + format(r['walk_depth'], 'g'):>50} {walks}")
            reached = "; ".join(
                f"{a['spp']} spp {a['volpath_s']:.1f} s / "
                + ("not reached" if a["speedup"] is None else
                   f"{'<=' if a['upper_bound'] else ''}{a['convsss_s']:.1f} s = "
                   f"{'>=' if a['upper_bound'] else ''}{a['speedup']:.2f}x")
                for a in r["at_volpath"])
            events = "/".join(f"{w['events_per_path']:.2f}" for w in r["walk_ladder"] if w["events_per_path"])
            lines.append(f"{'':>14} at volpathmis's error (volpathmis s / walk s = speed-up): {reached}")
            lines.append(f"{'':>14} scattering events per camera path: {events} (walk_depth "
                         f"{r['walk_depth']:g}), {r['events_at_inf'] or 0:.2f} (inf: volpathmis's estimator)")
    meta = result["meta"]
    lines.append(f"errors: relative MSE over the object x 1e-3, the reference's own noise subtracted; references "
                 f"{meta['reference_spp']} spp (seeds 1, 2); seconds of fresh-process commands; load average "
                 f"{meta['load_average_start'][0]:.2f} at the start, {meta['load_average_end'][0]:.2f} at the end "
                 f"({meta['cpus']} CPUs)")
    return "\n".join(lines)
