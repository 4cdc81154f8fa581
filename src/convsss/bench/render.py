"""Whole renders of the demo scene per stage, beside Mitsuba's own ``path`` integrator on the same scene.

The scene is ``make demo``'s: the bundled bunny, 40 mm of whole milk behind a dielectric boundary, on a grey floor,
lit by a key light and a back light (:func:`~convsss.scene.quick.quick_scene`). Per resolution and spp, in one
process: one warm-up render of each integrator (Dr.Jit compiles its kernels, numba loads its cache), then ``runs``
timed renders of each, alternating; reported are the medians of the ``convsss`` stages (the integrator's
``stats["seconds"]``), of its whole ``mi.render`` call and of Mitsuba's ``path`` (``max_depth`` as the integrator's)
rendering the same scene. The headline ratio is shading / ``path`` at equal spp: both trace the same camera paths,
and ``convsss`` only replaces what happens where they meet the translucent object.

``commands``: the wall time of whole command lines in fresh processes (interpreter start, imports, Mitsuba variant,
numba cache, scene, render, files): ``convsss --version`` and ``convsss render`` of the demo at 64² and at 800²,
1 spp. ``scaling``: whole render commands in fresh processes against the image size (the demo, 64² to 1600²) and
against the object's size in mean free paths (10 to 10 000, at 256²), per stage, with their peak memory.
"""

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tqdm import tqdm

from ..pipeline import STAGES

#: Resolutions (square) and samples per pixel of the full benchmark.
RESOLUTIONS = (256, 512, 800)
SPPS = (1, 4, 16)
#: The demo's object.
DEMO = {"material": "wholemilk", "size_mm": 40.0}
#: ``convsss`` as a command line in a fresh process, in this interpreter.
CONVSSS = [sys.executable, "-c", "from convsss.cli import main; main()"]
#: The scaling benchmark's image widths (the demo) and object spans in mean free paths (the bunny at 256²).
SCALING_WIDTHS = (64, 128, 256, 512, 800, 1600)
SCALING_SPANS = (10, 100, 1000, 10000)


def demo_scene(mi, width, spp):
    """The loaded demo scene at ``width``² and ``spp``, its integrator ``convsss`` as ``convsss render --mesh`` sets
    it (the defaults, with the paper's Phong highlight)."""
    from ..materials import material
    from ..scene.quick import demo_mesh, quick_scene

    return mi.load_dict(quick_scene(demo_mesh(), material(DEMO["material"]), DEMO["size_mm"], width=width,
                                    height=width, spp=spp, floor=True,
                                    integrator={"type": "convsss", "specular": "phong"}))


def _timed(scene, **options):
    """Wall seconds of ``mi.render(scene, **options)``, its image evaluated (:func:`convsss.render`: the
    integrator's own errors)."""
    import drjit as dr

    import convsss

    start = time.perf_counter()
    image = convsss.render(scene, **options)
    dr.eval(image)
    dr.sync_thread()
    return time.perf_counter() - start


def bench_render(resolutions=RESOLUTIONS, spps=SPPS, runs=5, progress=True):
    """Rows ``{width, spp, stages_s: {stage: median}, convsss_s, path_s, shading_ratio, total_ratio}`` (seconds,
    medians of ``runs``), one per resolution and spp."""
    import convsss

    mi = convsss.register()
    configs = [(w, s) for w in resolutions for s in spps]
    bar = tqdm(total=len(configs) * (runs + 1) * 2, desc="bench render", unit="render", disable=not progress)
    rows = []
    for width, spp in configs:
        scene = demo_scene(mi, width, spp)
        integrator = scene.integrator()
        path = mi.load_dict({"type": "path", "max_depth": integrator.params.max_depth,
                             "rr_depth": integrator.params.rr_depth})
        stages, ours, theirs = {name: [] for name in STAGES}, [], []
        for run in range(runs + 1):
            bar.set_postfix_str(f"{width}² {spp} spp" + (" (warm-up)" if run == 0 else ""))
            seconds = _timed(scene, seed=run, spp=spp)
            bar.update()
            path_seconds = _timed(scene, integrator=path, seed=run, spp=spp)
            bar.update()
            if run == 0:
                continue
            ours.append(seconds)
            theirs.append(path_seconds)
            for name in STAGES:
                stages[name].append(integrator.stats["seconds"].get(name, 0.0))
        medians = {name: statistics.median(values) for name, values in stages.items()}
        path_s, convsss_s = statistics.median(theirs), statistics.median(ours)
        rows.append({"width": width, "spp": spp, "stages_s": medians, "convsss_s": convsss_s, "path_s": path_s,
                     "shading_ratio": medians["shading"] / path_s, "total_ratio": convsss_s / path_s,
                     "screen_queries": integrator.stats["screen_exitance"]["queries"],
                     "exitance_lookups": integrator.stats["exitance_lookups"]})
    bar.close()
    return rows


def bench_commands(runs=5, progress=True):
    """Wall seconds (median of ``runs``, each in a fresh process) of whole command lines: ``{name: seconds}``."""
    command = CONVSSS
    demo = ["render", "--mesh", "bunny", "--material", DEMO["material"], "--size-mm", f"{DEMO['size_mm']:g}",
            "--floor", "--spp", "1", "--no-progress"]
    with tempfile.TemporaryDirectory() as folder:
        lines = {"convsss --version": ["--version"],
                 "render 64² 1 spp": demo + ["--width", "64", "--height", "64", "-o", str(Path(folder) / "a")],
                 "render 800² 1 spp": demo + ["--width", "800", "--height", "800", "-o", str(Path(folder) / "b")]}
        bar = tqdm(total=len(lines) * (runs + 1), desc="bench commands", unit="run", disable=not progress)
        result = {}
        for name, args in lines.items():
            seconds = []
            for _ in range(runs + 1):  # the first run fills the numba and Dr.Jit caches if they are cold
                start = time.perf_counter()
                subprocess.run(command + args, check=True, capture_output=True)
                seconds.append(time.perf_counter() - start)
                bar.update()
            result[name] = statistics.median(seconds[1:])
        bar.close()
    return result


def _command(args, folder):
    """One ``convsss`` command line in a fresh process: ``(wall seconds, peak RSS in bytes, its --stats JSON)``."""
    import json
    import os

    stats, log = Path(folder) / "stats.json", Path(folder) / "stderr.txt"
    line = [*CONVSSS, *args, "--no-progress", "--stats", str(stats), "-o", str(Path(folder) / "image")]
    start = time.perf_counter()
    with open(log, "wb") as stderr:  # a file, not a pipe: a full pipe would block the child before wait4 returns
        child = subprocess.Popen(line, stdout=subprocess.DEVNULL, stderr=stderr)
        _, status, usage = os.wait4(child.pid, 0)
    seconds = time.perf_counter() - start
    code = os.waitstatus_to_exitcode(status)
    if code:
        error = log.read_text(errors="replace").strip().splitlines()
        raise RuntimeError(f"convsss {' '.join(args)} failed: {error[-1] if error else code}")
    return seconds, usage.ru_maxrss * 1024, json.loads(stats.read_text())


def scaling_configs(widths=SCALING_WIDTHS, spans=SCALING_SPANS, spp=4):
    """The command lines of :func:`bench_scaling`: ``(axis, value, args)``, the demo at each width, then the demo's
    bunny (no floor) at 256² sized to each span in mean free paths of its material (the smallest channel's), each
    rendered with the transport (walk_depth 0: what scales with the object's span is the transport's work)."""
    from ..materials import material

    demo = ["render", "--mesh", "bunny", "--material", DEMO["material"], "--spp", str(spp), "--walk-depth", "0"]
    mfp = float(min(material(DEMO["material"]).mfp_mm))
    out = [("width", w, demo + ["--size-mm", f"{DEMO['size_mm']:g}", "--floor", "--width", str(w), "--height",
                                str(w)]) for w in widths]
    out += [("mean free paths", n, demo + ["--size-mm", f"{n * mfp:.6g}", "--width", "256", "--height", "256"])
            for n in spans]
    return out


def bench_scaling(widths=SCALING_WIDTHS, spans=SCALING_SPANS, runs=3, spp=4, progress=True):
    """Whole ``convsss render`` commands in fresh processes (warm caches: one untimed run first) against the image
    size and against the object's size in mean free paths: rows ``{axis, value, seconds, stages_s, peak_bytes,
    samples, pixels}``, medians of ``runs``."""
    configs = scaling_configs(widths, spans, spp)
    bar = tqdm(total=len(configs) * runs + 1, desc="bench scaling", unit="run", disable=not progress)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        _command(configs[0][2], folder)  # fills the numba and Dr.Jit caches
        bar.update()
        for axis, value, args in configs:
            bar.set_postfix_str(f"{axis} {value:g}")
            runs_out = []
            for _ in range(runs):
                runs_out.append(_command(args, folder))
                bar.update()
            stats = runs_out[-1][2]
            rows.append({"axis": axis, "value": value, "seconds": statistics.median(r[0] for r in runs_out),
                         "stages_s": {name: statistics.median(r[2]["seconds"].get(name, 0.0) for r in runs_out)
                                      for name in STAGES},
                         "peak_bytes": max(r[1] for r in runs_out), "samples": stats["samples"],
                         "pixels": stats["film"]["size"][0] * stats["film"]["size"][1]})
    bar.close()
    return rows


def scaling_table(rows):
    """The rows of :func:`bench_scaling` as a text table, with each row's time over the first row's of its axis."""
    head = (f"{'axis':>16} {'value':>7} " + " ".join(f"{name:>10}" for name in STAGES)
            + f" {'command':>8} {'x first':>7} {'samples':>9} {'peak GiB':>8}")
    lines, first = [head], {}
    for r in rows:
        base = first.setdefault(r["axis"], r["seconds"])
        lines.append(f"{r['axis']:>16} {r['value']:>7g} " + " ".join(f"{r['stages_s'][n]:>10.3f}" for n in STAGES)
                     + f" {r['seconds']:>8.2f} {r['seconds'] / base:>7.2f} {r['samples']:>9d}"
                     + f" {r['peak_bytes'] / 2**30:>8.2f}")
    lines.append("seconds, medians of fresh-process commands (warm caches); stages from --stats; x first = the "
                 "command's time over the first row's of its axis; peak = the largest resident set of the runs")
    return "\n".join(lines)


def render_table(rows, commands=None):
    """The rows as a text table (seconds), then the command lines' wall times."""
    head = f"{'size':>6} {'spp':>4} " + " ".join(f"{name:>10}" for name in STAGES)
    head += f" {'convsss':>8} {'path':>7} {'shade/path':>10} {'all/path':>8} {'lookups':>8}"
    lines = [head]
    for r in rows:
        lines.append(f"{r['width']:>5}² {r['spp']:>4} " + " ".join(f"{r['stages_s'][n]:>10.3f}" for n in STAGES)
                     + f" {r['convsss_s']:>8.3f} {r['path_s']:>7.3f} {r['shading_ratio']:>10.2f}"
                     + f" {r['total_ratio']:>8.2f} {r['exitance_lookups']:>8d}")
    lines.append("seconds, medians; shade/path = shading stage / Mitsuba's path on the same scene and spp; "
                 "lookups = transport queries made while shading (besides the screen table's)")
    for name, seconds in (commands or {}).items():
        lines.append(f"{name}: {seconds:.2f} s wall (fresh process, median)")
    return "\n".join(lines)
