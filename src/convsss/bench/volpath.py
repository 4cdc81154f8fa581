"""Equal error against path tracing: how long ``volpathmis`` needs to reach the error of a default ``convsss render``.

Per scene and image size, everything as whole commands in fresh processes on one scene file
(:func:`~convsss.scene.xmlwriter.scene_to_xml` of :func:`~convsss.bench.scenes.scene_dict`):

1. two long references, ``convsss reference --spp REFERENCE_SPP`` with seeds 1 and 2; their own noise is half the
   relative MSE between them (each holds half of the difference's variance);
2. ``convsss render`` with its defaults (and ``--aovs mask``, whose mask selects the object's pixels);
3. ``convsss reference`` at each spp of the ladder (seed 3).

The error is the relative MSE over the object's pixels (:func:`convsss.compare.metrics`, mean of the channels) less
the first reference's own noise: for an unbiased estimate it falls as 1/spp, and the time a path tracer needs
grows as its inverse. The time ``volpathmis`` needs for convsss's error is read off the ladder by linear
interpolation of log time against log error (beyond its ends, extrapolated with the slope -1 of Monte Carlo
noise); the headline is that time over convsss's own. A convsss error below the references' noise cannot be
measured: the row says so.
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


def bench_scene(name, width, folder, reference_spp=REFERENCE_SPP, ladder=LADDER, bar=None):
    """One row: ``{scene, width, reference_s, reference_noise, convsss_s, convsss_error, ladder: [{spp, seconds,
    error}], volpath_equal_s, speedup, measurable}`` (errors: relative MSE over the object, the reference's noise
    subtracted)."""
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
    return {"scene": name, "width": width, "reference_s": statistics.median(references), "reference_noise": noise,
            "convsss_s": convsss_s, "convsss_error": convsss_error, "ladder": rungs, "volpath_equal_s": equal,
            "speedup": None if equal is None else equal / convsss_s, "measurable": measurable}


def bench_volpath(scenes=tuple(VOLPATH_SCENES), widths=(128,), reference_spp=REFERENCE_SPP, ladder=LADDER,
                  progress=True):
    """The rows of :func:`bench_scene` for every scene and width, and the machine's facts: ``{meta, rows}``."""
    bar = tqdm(total=len(scenes) * len(widths) * (3 + len(ladder)), desc="bench volpath", unit="command",
               disable=not progress)
    meta = {"reference_spp": reference_spp, "ladder": list(ladder), "cpus": os.cpu_count(),
            "load_average_start": list(os.getloadavg())}
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for width in widths:
            for name in scenes:
                rows.append(bench_scene(name, width, folder, reference_spp, ladder, bar))
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
    meta = result["meta"]
    lines.append(f"errors: relative MSE over the object x 1e-3, the reference's own noise subtracted; references "
                 f"{meta['reference_spp']} spp (seeds 1, 2); seconds of fresh-process commands; load average "
                 f"{meta['load_average_start'][0]:.2f} at the start, {meta['load_average_end'][0]:.2f} at the end "
                 f"({meta['cpus']} CPUs)")
    return "\n".join(lines)
