"""What a sample and a command cost where the render walks: ``walk_depth inf`` (``volpathmis``'s estimator) against
``volpathmis`` itself, on ``bench walk``'s scenes (issue 60, item 1).

Per scene, at the same size and samples per pixel:

1. **per sample**, warm, in this process: ``mi.render`` of the scene by ``convsss`` at ``walk_depth`` inf and by
   ``volpathmis``, each with its defaults (Russian roulette from depth 5: ``volpathmis``'s odds its throughput, at
   most 0.95; the walk's its weight over :data:`~convsss.pipeline.walk.ROULETTE_WEIGHT`, at most 1) and both
   without roulette (``rr_depth`` 2^30), one untimed render each first (Dr.Jit compiles), then ``runs`` renders of
   distinct seeds; medians. The last default convsss render's Dr.Jit kernel history splits its time into its
   kernels' (the walk's, one per chunk of paths, the film's gather, the camera rays) and the rest
   (Python between kernels, launches);
2. **per command**, fresh processes on the scene written to a file: ``convsss render --walk-depth inf``, ``convsss
   render`` (the default, ``auto``) and Mitsuba's own ``mitsuba`` on the same file, one untimed run of each first,
   then ``runs`` each, interleaved; medians.
"""

import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tqdm import tqdm

from .render import CONVSSS

#: The commands of the second part, by label: ``convsss`` arguments, or the ``mitsuba`` executable's.
COMMANDS = {"inf": ["render", "--walk-depth", "inf"], "auto": ["render"], "mitsuba": None}


def mitsuba_executable():
    """Mitsuba's ``mitsuba`` command beside this Python, or on the PATH."""
    beside = Path(sys.executable).with_name("mitsuba")
    found = str(beside) if beside.is_file() else shutil.which("mitsuba")
    if found is None:
        raise RuntimeError("Mitsuba's `mitsuba` command is neither beside this Python nor on the PATH")
    return found


def _render_seconds(mi, dr, scene, integrator, spp, seed, history=False):
    """Wall seconds of one ``mi.render`` until its image is evaluated; with ``history``, also its JIT kernels'
    execution seconds (Dr.Jit's kernel history)."""
    if history:
        dr.set_flag(dr.JitFlag.KernelHistory, True)
    start = time.perf_counter()
    dr.eval(mi.render(scene, integrator=integrator, spp=spp, seed=seed))
    dr.sync_thread()
    seconds = time.perf_counter() - start
    if not history:
        return seconds, None
    kernels = [k.get("execution_time", 0.0) / 1000.0 for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
    dr.set_flag(dr.JitFlag.KernelHistory, False)
    return seconds, kernels


#: Part 1's integrators, by label: the walk at inf and ``volpathmis``, with their defaults and without roulette.
INTEGRATORS = {"convsss": {"type": "convsss", "walk_depth": float("inf")}, "volpathmis": {"type": "volpathmis"},
               "convsss_no_rr": {"type": "convsss", "walk_depth": float("inf"), "rr_depth": 2**30},
               "volpathmis_no_rr": {"type": "volpathmis", "rr_depth": 2**30}}


def per_sample(bench_scene, width, spp, runs):
    """Part 1 (module doc): the median seconds by label of :data:`INTEGRATORS` (``{label}_s``), the ratios
    ``ratio`` (defaults) and ``ratio_no_rr``, and the last default convsss render's ``kernels_s``, ``kernel_count``,
    ``outside_kernels_s`` and ``longest_kernels_s``."""
    from ..pipeline.integrator import register
    from .scenes import scene_dict

    mi = register()
    import drjit as dr

    description = scene_dict(bench_scene, width)
    description.pop("integrator", None)
    scene = mi.load_dict(description)
    seconds, kernels = {}, None
    for label, spec in INTEGRATORS.items():
        integrator = mi.load_dict(spec)
        _render_seconds(mi, dr, scene, integrator, spp, 0)
        runs_s = []
        for seed in range(1, runs + 1):
            took, history = _render_seconds(mi, dr, scene, integrator, spp, seed,
                                            history=label == "convsss" and seed == runs)
            runs_s.append(took)
            kernels = history if history is not None else kernels
        seconds[label] = statistics.median(runs_s)
    return {**{f"{label}_s": value for label, value in seconds.items()},
            "ratio": seconds["convsss"] / seconds["volpathmis"],
            "ratio_no_rr": seconds["convsss_no_rr"] / seconds["volpathmis_no_rr"], "kernels_s": sum(kernels),
            "kernel_count": len(kernels), "outside_kernels_s": max(seconds["convsss"] - sum(kernels), 0.0),
            "longest_kernels_s": sorted(kernels, reverse=True)[:6]}


def per_command(path, folder, runs, bar=None):
    """Part 2 (module doc): median wall seconds by label of :data:`COMMANDS` on the scene file ``path``."""
    lines = {label: [*CONVSSS, *args, str(path), "-o", str(Path(folder) / label), "--no-progress"] if args else
             [mitsuba_executable(), str(path), "-o", str(Path(folder) / f"{label}.exr")]
             for label, args in COMMANDS.items()}
    seconds = {label: [] for label in lines}
    for run in range(runs + 1):  # the first round fills the caches (numba's, Dr.Jit's kernels, the file system's)
        for label, line in lines.items():
            start = time.perf_counter()
            done = subprocess.run(line, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            took = time.perf_counter() - start
            if done.returncode:
                error = done.stderr.strip().splitlines()
                raise RuntimeError(f"{' '.join(line)} failed: {error[-1] if error else done.returncode}")
            if run:
                seconds[label].append(took)
            if bar is not None:
                bar.update()
    return {label: statistics.median(values) for label, values in seconds.items()}


def bench_cost(scenes, width=192, spp=64, runs=3, commands=True, progress=True):
    """Both parts for each of ``scenes`` (names of ``bench walk``'s scenes): ``{meta, rows}``."""
    from ..scene.xmlwriter import scene_to_xml
    from .scenes import scene_dict
    from .walk import WALK_SCENES

    load = list(os.getloadavg())
    bar = tqdm(total=len(scenes) * (1 + (len(COMMANDS) * (runs + 1) if commands else 0)), desc="bench cost",
               unit="step", disable=not progress)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name in scenes:
            bar.set_postfix_str(f"{name} per sample")
            row = {"scene": name, **per_sample(WALK_SCENES[name], width, spp, runs)}
            bar.update()
            if commands:
                bar.set_postfix_str(f"{name} commands")
                description = scene_dict(WALK_SCENES[name], width)
                description["sensor"]["sampler"]["sample_count"] = spp
                path = Path(folder) / f"{name}.xml"
                path.write_text(scene_to_xml(description))
                row["command_s"] = per_command(path, folder, runs, bar)
            rows.append(row)
    bar.close()
    meta = {"width": width, "spp": spp, "runs": runs, "cpus": os.cpu_count(), "load_average_start": load,
            # set, Python compiles convsss's modules in every fresh process (about 0.08 s of each command)
            "PYTHONDONTWRITEBYTECODE": os.environ.get("PYTHONDONTWRITEBYTECODE", "")}
    return {"meta": meta, "rows": rows}


def cost_table(result):
    """The rows as a text table."""
    meta = result["meta"]
    cached = "without" if meta["PYTHONDONTWRITEBYTECODE"] else "with"
    lines = [f"{meta['width']}², {meta['spp']} spp, medians of {meta['runs']} runs; per sample warm in one process "
             f"(convsss at walk_depth inf, volpathmis; defaults, and no roulette: no rr); commands in fresh "
             f"processes, {cached} bytecode caches",
             f"{'scene':18s} {'convsss s':>9s} {'volpath s':>9s} {'ratio':>6s} {'no rr: cv':>9s} {'vp':>6s} "
             f"{'ratio':>6s} {'kernels s':>9s} {'(n)':>4s} {'outside s':>9s} | {'cmd inf s':>9s} {'cmd auto s':>10s} "
             f"{'mitsuba s':>9s}  longest kernels s"]
    for row in result["rows"]:
        command = row.get("command_s")
        tail = (f"{command['inf']:9.3f} {command['auto']:10.3f} {command['mitsuba']:9.3f}" if command else
                f"{'-':>9s} {'-':>10s} {'-':>9s}")
        lines.append(f"{row['scene']:18s} {row['convsss_s']:9.3f} {row['volpathmis_s']:9.3f} {row['ratio']:6.2f} "
                     f"{row['convsss_no_rr_s']:9.3f} {row['volpathmis_no_rr_s']:6.3f} {row['ratio_no_rr']:6.2f} "
                     f"{row['kernels_s']:9.3f} {row['kernel_count']:4d} {row['outside_kernels_s']:9.3f} | {tail}  "
                     + " ".join(f"{k:.3f}" for k in row["longest_kernels_s"]))
    return "\n".join(lines)
