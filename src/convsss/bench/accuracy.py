"""Accuracy against time: the convolution and hierarchical transports against the exact sum on one set of samples.

What is measured, per scene:

1. **Inputs, once.** The scene's translucent object is prepared by the integrator's own path
   (:meth:`~convsss.scene.integrator.ConvsssIntegrator.prepare` with ``downsample = 1``): stratified irradiance
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

import os
import time

import numpy as np
from tqdm import tqdm

from ..compare import FLOOR
from ..transport import TRANSPORTS, clear_caches, make_transport
from ..transport.convolution import CORRECTIONS, DOWNSAMPLES
from .pareto import METHOD_COLORS, headline, headline_text, mark_pareto, pareto_front

LAYERS = (2, 4, 8, 16)
THRESHOLDS = (0.0, 0.001, 0.05)
#: The sweep asked for (0.01–1), plus 2 and 5: coarse enough to reach the convolution transport's errors.
EPSILONS = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)
SCENES = ("null", "dielectric")


# --- inputs --------------------------------------------------------------------------------------------------------
def bunny_scene(kind, resolution=256, size_mm=40.0, material="wholemilk"):
    """The Mitsuba scene dictionary of one benchmark scene: ``kind`` is ``null`` or ``dielectric`` (module doc)."""
    from ..materials import material as lookup_material
    from ..scene.quick import demo_mesh, quick_scene

    if kind not in SCENES:
        raise ValueError(f"scene {kind!r}: choose one of {', '.join(SCENES)}")
    scene = quick_scene(demo_mesh(), lookup_material(material), size_mm, resolution, resolution, boundary=kind)
    if kind == "dielectric":
        from ..backend import load_mitsuba
        from ..scene.quick import mesh_bounds

        transform = load_mitsuba().ScalarTransform4f
        lo, hi = mesh_bounds(demo_mesh())
        centre = [0.0, 0.5 * size_mm * float((hi - lo)[1] / np.max(hi - lo)), 0.0]  # quick_scene's layout
        key = np.asarray(scene.pop("key_light")["position"])
        scene.pop("back_light")
        side = 0.5 * size_mm
        # A square light facing the object (a rectangle emits along its +z), irradiance about 1 at the object,
        # and a dim environment that lights the back.
        radiance = float(np.sum((key - centre) ** 2)) / side**2
        to_world = transform().look_at(origin=key.tolist(), target=centre, up=[0.0, 1.0, 0.0])
        scene["area_light"] = {"type": "rectangle", "to_world": to_world @ transform().scale([side / 2, side / 2, 1]),
                               "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [radiance] * 3}}}
        scene["environment"] = {"type": "constant", "radiance": {"type": "rgb", "value": [0.05] * 3}}
    return scene


def prepare_case(scene_dict, sample_density=4.0, seed=0):
    """Samples and visible points of the scene's (first) translucent object, as a render prepares them.

    Returns a dict: ``samples`` (IrradianceSamples), ``points`` (K, 3) mm, their outward ``normals``, ``profile``,
    ``frame`` (ViewFrame),
    ``cell_size`` (mm, the pixel footprint at the object), ``object`` (its summary) and ``prepare_s`` (seconds).
    """
    import drjit as dr

    from ..backend import load_mitsuba
    from ..scene.camera import pixel_footprint, sensor_frame
    from ..scene.irradiance import object_samples, sample_count
    from ..scene.loading import load_scene
    from ..scene.objects import find_translucent_objects, hit_indices
    from ..scene.params import RenderParams

    mi = load_mitsuba()
    start = time.perf_counter()
    scene = load_scene(scene_dict)
    params = RenderParams(transport="exact", sample_density=sample_density)
    sensor = scene.sensors()[0]
    frame = sensor_frame(sensor, params.unit_mm)
    obj = find_translucent_objects(mi, scene, params.unit_mm)[0]
    depth = float(frame.to_view((0.5 * (obj.bbox_mm[0] + obj.bbox_mm[1]))[None])[0, 2])
    cell = pixel_footprint(sensor, frame, depth, params.unit_mm)
    samples = object_samples(scene, obj, sample_count(obj.area_mm2, cell, sample_density), params.irradiance_samples,
                             params.unit_mm, seed)
    summary = {**obj.summary(), "samples": len(samples), "pixel_footprint_mm": cell, "view_depth_mm": depth}

    width, height = (int(x) for x in sensor.film().crop_size())
    y, x = np.mgrid[0:height, 0:width]
    film = mi.Point2f(((x.ravel() + 0.5) / width).astype(np.float32), ((y.ravel() + 0.5) / height).astype(np.float32))
    ray, _ = sensor.sample_ray(0.0, 0.5, film, mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    on_object = si.is_valid().numpy() & obj.hit(*hit_indices(mi, si))
    points = dr.ravel(si.p).numpy().reshape(-1, 3)[on_object].astype(np.float64) * params.unit_mm
    normals = dr.ravel(mi.Vector3f(si.n)).numpy().reshape(-1, 3)[on_object].astype(np.float64) * obj.orientation
    return {"samples": samples, "points": np.ascontiguousarray(points), "normals": np.ascontiguousarray(normals),
            "profile": obj.profile,
            "frame": frame, "cell_size": cell,
            "object": summary, "image": [width, height], "prepare_s": time.perf_counter() - start}


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


def label(config):
    """Short name of a configuration for tables and plots, e.g. ``L8 d0.5 t0.1%`` or ``eps0.05``."""
    if config["transport"] == "convolution":
        plane = " +plane" if config.get("correction", "none") == "plane" else ""
        return f"L{config['layers']} d{config['downsample']:g} t{config['threshold']:.3g}{plane}"
    if config["transport"] == "hierarchical":
        return f"eps{config['epsilon']:g}"
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
                   {"transport": "convolution", "layers": 2, "downsample": 0.25, "threshold": 0.001}):
        timed_run(config, samples, few, profile, frame, cell_size)


def _stages(transport):
    return {k: float(v) for k, v in transport.timings.items()}


def bench_points(samples, points, profile, frame, cell_size, configs, runs=3, bar=None, scene="scene",
                 normals=None):
    """Rows for one set of samples and visible points (numpy in, rows out); the exact sum first (error 0).

    Each row: ``scene, transport, label, layers, downsample, threshold, epsilon, seconds`` (median of ``runs``),
    ``seconds_runs``, ``stage_median_s`` (the transport's own stage timings), ``rel_l2, mean_rel, max_rel``,
    ``points, samples`` and, for the convolution transport, ``fft_shape`` and ``pairs_per_layer``.
    """
    _warm_up(samples, points, profile, frame, cell_size)
    seconds, reference, exact = timed_run({"transport": "exact"}, samples, points, profile, frame, cell_size)
    if bar is not None:
        bar.update()
    rows = [_row(scene, {"transport": "exact"}, [seconds], [_stages(exact)], error_metrics(reference, reference),
                 exact, len(points), len(samples))]
    times = [[] for _ in configs]
    stages = [[] for _ in configs]
    errors, last = [None] * len(configs), [None] * len(configs)
    for run in range(runs):
        for k, config in enumerate(configs):
            seconds, exitance, transport = timed_run(config, samples, points, profile, frame, cell_size, normals)
            times[k].append(seconds)
            stages[k].append(_stages(transport))
            if run == 0:  # every run computes the same numbers
                errors[k] = error_metrics(exitance, reference)
            last[k] = transport
            if bar is not None:
                bar.update()
    for k, config in enumerate(configs):
        rows.append(_row(scene, config, times[k], stages[k], errors[k], last[k], len(points), len(samples)))
    mark_pareto(rows)
    return rows


def _row(scene, config, times, stages, errors, transport, n_points, n_samples):
    names = sorted({name for s in stages for name in s})
    row = {"scene": scene, "transport": config["transport"], "method": method(config), "label": label(config),
           "layers": config.get("layers"), "downsample": config.get("downsample"),
           "threshold": config.get("threshold"), "correction": config.get("correction"),
           "epsilon": config.get("epsilon"),
           "seconds": float(np.median(times)), "seconds_runs": [float(t) for t in times],
           "stage_median_s": {name: float(np.median([s.get(name, 0.0) for s in stages])) for name in names},
           **errors, "points": int(n_points), "samples": int(n_samples)}
    if config["transport"] == "convolution":
        row["fft_shape"] = list(transport.padded_shape)
        row["pairs_per_layer"] = float(transport.pairs_per_layer.mean())
    if config["transport"] == "hierarchical":
        row["nodes_visited_per_query"] = float(transport.stats["nodes_visited_per_query"])
    return row


# --- the whole benchmark -------------------------------------------------------------------------------------------
def bench_accuracy(scenes=SCENES, resolution=256, size_mm=40.0, material="wholemilk", layer_counts=LAYERS,
                   downsamples=DOWNSAMPLES, thresholds=THRESHOLDS, epsilons=EPSILONS, runs=3, sample_density=4.0,
                   seed=0, progress=True):
    """Run the benchmark on each scene: ``{"meta", "rows", "headline": {scene: ...}}`` (module doc)."""
    configs = convolution_configs(layer_counts, downsamples, thresholds) + hierarchical_configs(epsilons)
    meta = {"resolution": int(resolution), "size_mm": float(size_mm), "material": material, "runs": int(runs),
            "sample_density": float(sample_density), "seed": int(seed), "cpus": os.cpu_count(),
            "load_average_start": list(os.getloadavg()), "scenes": {}}
    rows, headlines = [], {}
    bar = tqdm(total=len(scenes) * (1 + runs * len(configs)), desc="bench accuracy", unit="run",
               disable=not progress)
    for scene in scenes:
        bar.set_postfix_str(f"{scene}: samples")
        case = prepare_case(bunny_scene(scene, resolution, size_mm, material), sample_density, seed)
        bar.set_postfix_str(scene)
        meta["scenes"][scene] = {"points": len(case["points"]), "samples": len(case["samples"]),
                                 "cell_size_mm": case["cell_size"], "image": case["image"],
                                 "boundary": case["object"]["boundary"], "eta": case["object"]["eta"],
                                 "mean_free_paths": case["object"]["mean_free_paths"],
                                 "prepare_s": case["prepare_s"]}
        scene_rows = bench_points(case["samples"], case["points"], case["profile"], case["frame"], case["cell_size"],
                                  configs, runs, bar, scene, case["normals"])
        rows += scene_rows
        headlines[scene] = headline(scene_rows)
        headlines[f"{scene} +plane"] = headline(scene_rows, "convolution+plane")
    bar.close()
    meta["load_average_end"] = list(os.getloadavg())
    return {"meta": meta, "rows": rows, "headline": headlines}


# --- reports -------------------------------------------------------------------------------------------------------
def accuracy_table(rows):
    """The rows as a fixed-width text table; ``*`` marks a method's Pareto front."""
    head = (f"{'scene':<10} {'transport':<12} {'lay':>3} {'down':>5} {'t':>6} {'eps':>5} {'seconds':>8} "
            f"{'kernels':>8} {'rel_l2':>8} {'mean_rel':>8} {'max_rel':>8}  front")
    lines = [head]
    for r in rows:
        def opt(value, fmt):
            return format(value, fmt) if value is not None else "-"

        kernels = r["stage_median_s"].get("kernels")
        lines.append(f"{r['scene']:<10} {r['transport']:<12} {opt(r['layers'], '>3d'):>3} "
                     f"{opt(r['downsample'], 'g'):>5} {opt(r['threshold'], '.1%'):>6} {opt(r['epsilon'], 'g'):>5} "
                     f"{r['seconds']:>8.3f} {opt(kernels, '.3f'):>8} {r['rel_l2']:>8.2%} {r['mean_rel']:>8.2%} "
                     f"{r['max_rel']:>8.1%}  {'*' if r.get('pareto') else ''}")
    return "\n".join(lines)


def report_text(result):
    """Table, scene facts and headlines as the text the command prints."""
    meta = result["meta"]
    lines = [accuracy_table(result["rows"]), ""]
    for scene, facts in meta["scenes"].items():
        lines.append(f"{scene}: {facts['image'][0]}x{facts['image'][1]} image, {facts['points']} visible points, "
                     f"{facts['samples']} samples, boundary {facts['boundary']} (eta {facts['eta']:.3g}), "
                     f"pixel {facts['cell_size_mm']:.3f} mm")
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
