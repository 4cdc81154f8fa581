"""Accuracy against time: the convolution and hierarchical transports against the exact sum on one set of samples.

What is measured, per scene:

1. **Inputs, once.** The scene's translucent object is prepared by the integrator's own path
   (:meth:`~convsss.pipeline.integrator.ConvsssIntegrator.prepare` with ``downsample = 1``): stratified irradiance
   samples over its whole surface (``sample_density`` per full-resolution pixel footprint, as a render) with their
   irradiance (paper Eq. 2). The **visible points** are the first hits on that object of one camera ray through each
   pixel centre. Every transport gets exactly these samples and these points.
2. **Reference.** :class:`~convsss.transport.exact.ExactTransport` (the direct sum, paper Eq. 1 discretized) at the
   visible points; timed once.
3. **Configurations.** The convolution transport (paper §4–5) for every ``layers x downsample x threshold`` (cell
   size: the pixel footprint at the object, as a render), as published (method ``convolution``) and with the plane
   correction of its depth discretization (``convolution+plane``, beyond the paper, given the visible points'
   normals), and the hierarchical transport (Jensen & Buhler 2002) for every ``epsilon`` (leaf size 4).
4. **Time** (``seconds``): wall time of *constructing the transport and calling* ``exitance(points)`` once, the whole
   transport stage of a render. Convolution kernels and plane-correction tables are computed cold in every run
   (their caches are cleared first, as in a single render); the octree is built in every run. Median of ``runs``
   runs, the runs of all configurations interleaved (so a change of machine load spreads over all of them).
   Sampling, irradiance and shading are not timed: they are the same for every transport.
5. **Error** of the radiant exitance ``M`` (K points x 3 channels, without the common ``(1/pi) F_t`` factor)
   against the exact ``M_ref``:

   - ``rel_l2 = ||M - M_ref||_F / ||M_ref||_F`` (all points and channels), the Pareto plot's error;
   - ``mean_rel = mean(|M - M_ref| / max(M_ref, f_c))`` and ``max_rel`` (the same ratio's maximum), with the floor
     ``f_c = 0.01 mean_k(M_ref[:, c])`` of :mod:`convsss.compare`.

6. **Pareto fronts** per method (no other point of the method is both faster and more accurate), and the headline
   **time ratio at equal error** (for each convolution method): for each hierarchical point, the convolution
   front's time at that point's
   ``rel_l2`` (piecewise linear in log time against log error between front points; none where the error is outside
   the front's range), divided by the hierarchical time. Ratio > 1: the convolution transport is slower.

Scenes (:func:`bunny_scene`): the bundled Stanford bunny (``size_mm``, whole milk by default), framed by
:func:`~convsss.scene.quick.quick_scene`; ``null``: index-matched boundary (eta = 1) and its two point lights (key and
back light); ``dielectric``: a smooth dielectric (the material's eta) lit by a square area light at the key light's
place and a dim constant environment.
"""

import hashlib
import os
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..compare import FLOOR
from ..transport import TRANSPORTS, clear_caches, make_transport
from ..transport.convolution import CORRECTIONS, DOWNSAMPLES
from .pareto import METHOD_COLORS, headline, headline_text, mark_pareto, pareto_front
from .scenes import REFERENCE_POINTS, SCENES, prepare_case, scene_dict

LAYERS = (4, 8, 16)
THRESHOLDS = (0.001,)
EPSILONS = (0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0)
ACCURACIES = (0.003, 0.01, 0.03, 0.1)
#: Where exact sums are kept between runs (keyed by a hash of the samples and the points).
EXACT_CACHE = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "convsss" / "exact"


# --- metrics -------------------------------------------------------------------------------------------------------
def error_metrics(test, reference):
    """``{rel_l2, mean_rel, max_rel}`` of ``test`` against ``reference`` (K, 3); see the module doc."""
    test, reference = np.asarray(test, dtype=np.float64), np.asarray(reference, dtype=np.float64)
    norm = float(np.linalg.norm(reference))
    rel_l2 = float(np.linalg.norm(test - reference) / norm) if norm > 0 else 0.0
    floor = np.maximum(FLOOR * reference.mean(axis=0), 1e-300)
    relative = np.abs(test - reference) / np.maximum(reference, floor)
    return {"rel_l2": rel_l2, "mean_rel": float(relative.mean()), "max_rel": float(relative.max())}


def convolution_configs(layer_counts=LAYERS, downsamples=DOWNSAMPLES, thresholds=THRESHOLDS, corrections=CORRECTIONS):
    """Configuration dicts of the convolution transport (every combination)."""
    return [{"transport": "convolution", "layers": int(n), "downsample": float(d), "threshold": float(t),
             "correction": c} for c in corrections for n in layer_counts for d in downsamples for t in thresholds]


def method(config):
    """``convolution``, ``convolution+plane``, ``hierarchical`` or ``exact``."""
    if config["transport"] == "convolution" and config.get("correction", "none") == "plane":
        return "convolution+plane"
    return config["transport"]


def hierarchical_configs(epsilons=EPSILONS):
    return [{"transport": "hierarchical", "epsilon": float(e)} for e in epsilons]


def multiscale_configs(accuracies=ACCURACIES):
    return [{"transport": "multiscale", "accuracy": float(a)} for a in accuracies]


def label(config):
    """Short name of a configuration for tables and plots, e.g. ``L8 d0.5 t0.1%``, ``eps0.05`` or ``acc0.01``."""
    if config["transport"] == "convolution":
        plane = " +plane" if config.get("correction", "none") == "plane" else ""
        return f"L{config['layers']} d{config['downsample']:g} t{config['threshold']:.3g}{plane}"
    if config["transport"] == "hierarchical":
        return f"eps{config['epsilon']:g}"
    if config["transport"] == "multiscale":
        return f"acc{config['accuracy']:g}"
    return config["transport"]


def build_transport(config, samples, profile, frame, cell_size):
    """The transport of ``config`` (its name under ``transport``, then its parameters) on ``samples``, given the
    pixel footprint ``cell_size`` if it takes one (constructed, not yet queried)."""
    kind = config["transport"]
    params = {k: v for k, v in config.items() if k != "transport"}
    if TRANSPORTS[kind].accepts("cell_size"):
        params["cell_size"] = cell_size
    return make_transport(kind, samples, profile, frame, **params)


def timed_run(config, samples, points, profile, frame, cell_size, normals=None):
    """One run: ``(seconds, exitance (K, 3), transport)``; kernels and plane-correction tables cold."""
    clear_caches()
    start = time.perf_counter()
    transport = build_transport(config, samples, profile, frame, cell_size)
    exitance = transport.exitance(points, normals)
    return time.perf_counter() - start, exitance, transport


def _warm_up(samples, points, profile, frame, cell_size):
    """Compile (or load from numba's cache) every kernel once, untimed, on a few points."""
    few = points[: max(1, min(len(points), 64))]
    for config in ({"transport": "exact"}, {"transport": "hierarchical", "epsilon": 0.1},
                   {"transport": "convolution", "layers": 2, "downsample": 0.25, "threshold": 0.001},
                   {"transport": "multiscale", "accuracy": 0.1}):
        timed_run(config, samples, few, profile, frame, cell_size)


def _stages(transport):
    return {k: float(v) for k, v in transport.timings.items()}


def exact_reference(samples, points, profile, cache=EXACT_CACHE):
    """The exact sum at ``points``: ``(exitance (K, 3), seconds)``, read from ``cache`` (a folder, or None) when these
    samples and points were summed before (``seconds`` is then the time it took that first run)."""
    key = hashlib.sha1(b"".join(np.ascontiguousarray(a).tobytes() for a in (
        samples.position, samples.flux, points, profile.radial_table()[2]))).hexdigest()
    path = None if cache is None else Path(cache) / f"{key}.npz"
    if path is not None and path.is_file():
        with np.load(path) as stored:
            return stored["exitance"], float(stored["seconds"])
    start = time.perf_counter()
    exitance = make_transport("exact", samples, profile).exitance(points)
    seconds = time.perf_counter() - start
    if path is not None:
        from ..files import atomic_write

        def write(tmp):
            with open(tmp, "wb") as stream:
                np.savez(stream, exitance=exitance, seconds=seconds)

        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, write)
    return exitance, seconds


def reference_subset(n_points, size=REFERENCE_POINTS, seed=1):
    """Sorted indices of a fixed random subset of ``size`` of ``n_points`` (all of them where there are fewer)."""
    if n_points <= size:
        return np.arange(n_points)
    return np.sort(np.random.default_rng(seed).choice(n_points, size, replace=False))


def bench_points(samples, points, profile, frame, cell_size, configs, runs=3, bar=None, scene="scene",
                 normals=None, subset=None, cache=None):
    """Rows for one set of samples and visible points (numpy in, rows out); the exact sum first (error 0).

    Every configuration is timed on all ``points`` (construct + one ``exitance`` call: the transport of a render
    with one query per visible pixel); its error is measured against the exact sum at ``points[subset]`` (all of
    them by default; :func:`exact_reference`, kept in ``cache``).

    Each row: ``scene, transport, label, layers, downsample, threshold, epsilon, accuracy, seconds`` (median of
    ``runs``), ``seconds_runs``, ``stage_median_s`` (the transport's own stage timings), ``rel_l2, mean_rel,
    max_rel``, ``points, samples`` and, for the convolution transport, ``fft_shape`` and ``pairs_per_layer``. The
    exact row's ``seconds`` and ``points`` are those of the reference subset.
    """
    subset = np.arange(len(points)) if subset is None else np.asarray(subset)
    _warm_up(samples, points, profile, frame, cell_size)
    reference, seconds = exact_reference(samples, points[subset], profile, cache)
    if bar is not None:
        bar.update()
    rows = [_row(scene, {"transport": "exact"}, [seconds], [{}], error_metrics(reference, reference), None,
                 len(subset), len(samples))]
    times = [[] for _ in configs]
    stages = [[] for _ in configs]
    errors, last = [None] * len(configs), [None] * len(configs)
    for run in range(runs):
        for k, config in enumerate(configs):
            seconds, exitance, transport = timed_run(config, samples, points, profile, frame, cell_size, normals)
            times[k].append(seconds)
            stages[k].append(_stages(transport))
            if run == 0:  # every run computes the same numbers
                errors[k] = error_metrics(exitance[subset], reference)
            last[k] = _facts(config, transport)  # not the transport: one per configuration at 800² fills the memory
            del transport
            if bar is not None:
                bar.update()
    for k, config in enumerate(configs):
        rows.append(_row(scene, config, times[k], stages[k], errors[k], last[k], len(points), len(samples)))
    mark_pareto(rows)
    return rows


def _facts(config, transport):
    """What a row reports of a configuration's transport beyond its times and errors (:func:`_row`)."""
    if config["transport"] == "convolution":
        return {"fft_shape": list(transport.padded_shape),
                "pairs_per_layer": float(transport.pairs_per_layer.mean())}
    if config["transport"] == "hierarchical":
        return {"nodes_visited_per_query": float(transport.stats["nodes_visited_per_query"])}
    if config["transport"] == "multiscale":
        return {"scales_mm": transport.stats["scales_mm"], "clusters": transport.stats["clusters"]}
    return {}


def _row(scene, config, times, stages, errors, facts, n_points, n_samples):
    names = sorted({name for s in stages for name in s})
    row = {"scene": scene, "transport": config["transport"], "method": method(config), "label": label(config),
           "layers": config.get("layers"), "downsample": config.get("downsample"),
           "threshold": config.get("threshold"), "correction": config.get("correction"),
           "epsilon": config.get("epsilon"), "accuracy": config.get("accuracy"),
           "seconds": float(np.median(times)), "seconds_runs": [float(t) for t in times],
           "stage_median_s": {name: float(np.median([s.get(name, 0.0) for s in stages])) for name in names},
           **errors, "points": int(n_points), "samples": int(n_samples), **(facts or {})}
    return row


# --- the whole benchmark -------------------------------------------------------------------------------------------
def bench_accuracy(scenes=tuple(SCENES), resolution=800, layer_counts=LAYERS, downsamples=(1.0,),
                   thresholds=THRESHOLDS, epsilons=EPSILONS, accuracies=ACCURACIES, runs=3, sample_density=4.0,
                   seed=0, reference_points=REFERENCE_POINTS, cache=EXACT_CACHE, progress=True, profile=""):
    """Run the benchmark on each scene (names in :data:`SCENES`): ``{"meta", "rows", "headline": {scene: ...}}``;
    the headline of each method against the hierarchical one (module doc). ``profile``: the objects' profile (the
    integrator's ``profile`` parameter; empty: the default model)."""
    configs = (multiscale_configs(accuracies) + convolution_configs(layer_counts, downsamples, thresholds)
               + hierarchical_configs(epsilons))
    meta = {"resolution": int(resolution), "runs": int(runs), "sample_density": float(sample_density),
            "seed": int(seed), "reference_points": int(reference_points), "profile": profile,
            "cpus": os.cpu_count(),
            "load_average_start": list(os.getloadavg()), "scenes": {}}
    rows, headlines = [], {}
    bar = tqdm(total=len(scenes) * (1 + runs * len(configs)), desc="bench accuracy", unit="run",
               disable=not progress)
    for scene in scenes:
        bar.set_postfix_str(f"{scene}: samples")
        case = prepare_case(scene_dict(scene, resolution), sample_density, seed, profile)
        subset = reference_subset(len(case["points"]), reference_points)
        bar.set_postfix_str(f"{scene}: exact sum at {len(subset)} points")
        spec = SCENES[scene]
        meta["scenes"][scene] = {"mesh": spec.mesh, "material": spec.material, "size_mm": spec.size_mm,
                                 "lighting": spec.lighting, "points": len(case["points"]),
                                 "reference_points": len(subset), "samples": len(case["samples"]),
                                 "cell_size_mm": case["cell_size"], "image": case["image"],
                                 "boundary": case["object"]["boundary"], "eta": case["object"]["eta"],
                                 "mean_free_paths": case["object"]["mean_free_paths"],
                                 "profile": case["object"]["profile"],
                                 "prepare_s": case["prepare_s"]}
        scene_rows = bench_points(case["samples"], case["points"], case["profile"], case["frame"], case["cell_size"],
                                  configs, runs, bar, scene, case["normals"], subset, cache)
        rows += scene_rows
        for name in ("multiscale", "convolution", "convolution+plane"):
            headlines[scene if name == "convolution" else f"{scene} {name}"] = headline(scene_rows, name)
    bar.close()
    meta["load_average_end"] = list(os.getloadavg())
    return {"meta": meta, "rows": rows, "headline": headlines}


# --- reports -------------------------------------------------------------------------------------------------------
def accuracy_table(rows):
    """The rows as a fixed-width text table; ``*`` marks a method's Pareto front."""
    head = (f"{'scene':<16} {'transport':<12} {'acc':>6} {'lay':>3} {'down':>5} {'t':>6} {'eps':>5} {'seconds':>8} "
            f"{'kernels':>8} {'rel_l2':>8} {'mean_rel':>8} {'max_rel':>8}  front")
    lines = [head]
    for r in rows:
        def opt(value, fmt):
            return format(value, fmt) if value is not None else "-"

        kernels = r["stage_median_s"].get("kernels")
        lines.append(f"{r['scene']:<16} {r['transport']:<12} {opt(r.get('accuracy'), 'g'):>6} "
                     f"{opt(r['layers'], '>3d'):>3} "
                     f"{opt(r['downsample'], 'g'):>5} {opt(r['threshold'], '.1%'):>6} {opt(r['epsilon'], 'g'):>5} "
                     f"{r['seconds']:>8.3f} {opt(kernels, '.3f'):>8} {r['rel_l2']:>8.2%} {r['mean_rel']:>8.2%} "
                     f"{r['max_rel']:>8.1%}  {'*' if r.get('pareto') else ''}")
    return "\n".join(lines)


def report_text(result):
    """Table, scene facts and headlines as the text the command prints."""
    meta = result["meta"]
    lines = [accuracy_table(result["rows"]), ""]
    for scene, facts in meta["scenes"].items():
        lines.append(f"{scene}: {facts['image'][0]}x{facts['image'][1]} image, {facts['points']} visible points "
                     f"({facts.get('reference_points', facts['points'])} with the exact sum), "
                     f"{facts['samples']} samples, "
                     f"boundary {facts['boundary']} (eta {facts['eta']:.3g}), "
                     f"pixel {facts['cell_size_mm']:.3f} mm"
                     + (f", profile {facts['profile'].partition('(')[0]}" if facts.get("profile") else ""))
    lines.append(f"median of {meta['runs']} runs; load average {meta['load_average_start'][0]:.2f} at the start, "
                 f"{meta['load_average_end'][0]:.2f} at the end ({meta['cpus']} CPUs)")
    lines += [headline_text(scene, h) for scene, h in result["headline"].items()]
    return "\n".join(lines)


def accuracy_plot(result, path):
    """A PNG: per scene, rel_l2 (log) against seconds (log), both methods, their Pareto fronts, labelled points."""
    from matplotlib.figure import Figure

    from ..files import atomic_write

    scenes = list(result["meta"]["scenes"])
    fig = Figure(figsize=(7.0 * len(scenes), 5.5), layout="constrained")
    axes = fig.subplots(1, len(scenes), squeeze=False)[0]
    for ax, scene in zip(axes, scenes):
        rows = [r for r in result["rows"] if r["scene"] == scene]
        for name, color in METHOD_COLORS.items():
            chosen = [r for r in rows if r.get("method", r["transport"]) == name]
            if not chosen:
                continue
            ax.scatter([r["seconds"] for r in chosen], [r["rel_l2"] for r in chosen], s=18, color=color, alpha=0.6,
                       label=name)
            front = [chosen[k] for k in pareto_front(chosen)]
            ax.step([r["seconds"] for r in front], [r["rel_l2"] for r in front], where="post", color=color, lw=1.5)
            for k, r in enumerate(front if name.startswith("convolution") else chosen):
                ax.annotate(r["label"], (r["seconds"], r["rel_l2"]), fontsize=6.5, color=color,
                            xytext=(4, 3 if k % 2 == 0 else -9), textcoords="offset points")
        exact = [r["seconds"] for r in rows if r["transport"] == "exact"]
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("transport seconds (construct + exitance at the visible points)")
        ax.set_ylabel("relative L2 error of M vs the exact sum")
        facts = result["meta"]["scenes"][scene]
        timing = f"; exact sum {exact[0]:.1f} s" if exact else ""
        ax.set_title(f"{scene} boundary: {facts['points']} points, {facts['samples']} samples{timing}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    return atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=130))
