"""``report.md``: every figure's contact sheet, a table per figure, plots, the error table beyond the paper, and a
closing note with the headline numbers and where they disagree with the paper (computed from this run's numbers).
``figures.json`` holds the same numbers for programs.
"""

import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from ..files import json_ready, write_text
from ..profiles import model_profile
from .render import PROFILE_COLUMNS

#: The paper's numbers quoted against ours (Munoz et al. 2011, §5 and Fig. 2).
PAPER_C = {("small", 0.001): 7, ("large", 0.001): 1, ("small", 0.05): 2}


def _pct(x):
    return "–" if x is None or not math.isfinite(x) else f"{100 * x:.1f} %"


def _num(x, digits=2):
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.{digits}f}"


def caption(record):
    """The lines under a panel: title; parameters and c (or the reference's size); seconds; errors."""
    lines = [record["title"]]
    if record["method"] in ("exact", "volpathmis"):
        state = "cached" if record.get("cached") else "rendered"
        lines.append(f"reference: {record['resolution']}², {record['spp']} spp")
        lines.append(f"{record['seconds']:.1f} s ({state})")
    else:
        second = record["parameters"]
        if record.get("c") is not None:
            second += f" · c = {record['c']:.2g}"
        lines.append(second)
        lines.append(f"{record['seconds']:.2f} s (subsurface {record['sss_seconds']:.2f} s)")
    errors = []
    if record.get("vs_exact"):
        e = record["vs_exact"]
        errors.append(f"vs exact: err {_pct(e['mre'])}, ratio {e['ratio']:.3f}")
    if record.get("vs_pt"):
        e = record["vs_pt"]
        errors.append(f"vs volpathmis: err {_pct(e['mre'])}, ratio {e['ratio']:.3f}")
    lines.extend(errors or ["(the reference of the errors)"])
    return "\n".join(lines)


def error_caption(record):
    """The lines under a panel of the error-map sheet."""
    e = record["vs_exact"]
    return f"{record['title']}\n{record['parameters']}\nerr {_pct(e['mre'])}, ratio {e['ratio']:.3f}"


def _table(records, versus_pt):
    head = ["panel", "method / parameters", "c", "pairs per layer", "seconds", "subsurface s",
            "err vs exact", "ratio vs exact", "rel. L2 vs exact", "FLIP vs exact"]
    if versus_pt:
        head += ["err vs volpathmis", "ratio vs volpathmis"]
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in records:
        e, p = r.get("vs_exact") or {}, r.get("vs_pt") or {}
        pairs = r.get("pairs_per_layer")
        seconds = f"{r['seconds']:.2f}" + (" (cached)" if r.get("cached") else "")
        cells = [r["title"], r["parameters"], _num(r.get("c"), 2), " ".join(map(str, pairs)) if pairs else "–",
                 seconds, _num(r.get("sss_seconds")), _pct(e.get("mre")), _num(e.get("ratio"), 3),
                 _pct(e.get("rel_l2")), _num(e.get("flip"), 3)]
        if versus_pt:
            cells += [_pct(p.get("mre")), _num(p.get("ratio"), 3)]
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows)


def _profile_table(rows):
    """Per scene, each exact-sum column (:data:`~convsss.figures.render.PROFILE_COLUMNS`) against volpathmis: mean
    relative error and ratio of means."""
    columns = list(rows[0]["columns"])
    lines = ["| scene | " + " | ".join(f"{c}: err / ratio" for c in columns) + " |", "|" + "---|" * (1 + len(columns))]
    for row in rows:
        cells = [f"{_pct(row['columns'][c]['mre'])} / {_num(row['columns'][c]['ratio'], 3)}" for c in columns]
        lines.append(f"| {row['scene']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _by(figure, key):
    return {r["panel"]: r for r in figure["panels"]}.get(key)


# --- plots --------------------------------------------------------------------------------------------------------
def _plots(out, figures):
    from ..sheets import plot

    made = {}
    fig = figures.get("fig2")
    if fig:
        def draw(f):
            ax1, ax2 = f.subplots(1, 2)
            for size, marker in (("small", "o"), ("large", "s")):
                rs = [r for r in fig["panels"] if r["panel"].endswith(size)]
                ts = [100 * r["params"]["threshold"] for r in rs]
                ax1.plot(range(len(ts)), [r["c"] for r in rs], marker=marker, label=f"{size} bunny")
                ax2.plot(range(len(ts)), [r["sss_seconds"] for r in rs], marker=marker, label=f"{size} bunny")
            for ax, label in ((ax1, "convolutions per layer c"), (ax2, "subsurface seconds")):
                ax.set_xticks(range(len(ts)), [f"{t:g} %" for t in ts])
                ax.set_xlabel("threshold t")
                ax.set_ylabel(label)
                ax.legend(fontsize=7)
                ax.grid(alpha=0.3)
        made["fig2"] = plot(out / "fig2" / "fig2-plot.png", draw)
    fig = figures.get("fig5")
    if fig:
        conv = [r for r in fig["panels"]
                if r["method"] == "convolution" and r["params"].get("correction", "none") == "none"]
        plane = [r for r in fig["panels"] if r["method"] == "convolution" and r["params"].get("correction") == "plane"]
        hier = _by(fig, "hierarchical")

        def draw(f):
            ax1, ax2 = f.subplots(1, 2)
            n = [r["params"]["layers"] for r in conv]
            ax1.plot(n, [100 * r["vs_exact"]["mre"] for r in conv], "o-", label="convolution: err vs exact")
            ax1.plot(n, [100 * abs(1 - r["vs_exact"]["ratio"]) for r in conv], "s--",
                     label="convolution: |1 - ratio| vs exact")
            if plane:
                ax1.plot([r["params"]["layers"] for r in plane], [100 * r["vs_exact"]["mre"] for r in plane], "^-",
                         label="+ plane correction: err vs exact")
                ax2.plot([r["params"]["layers"] for r in plane], [r["sss_seconds"] for r in plane], "^-",
                         label="+ plane correction (subsurface)")
            if hier:
                ax1.axhline(100 * hier["vs_exact"]["mre"], color="k", lw=1, label="hierarchical: err vs exact")
            ax2.plot(n, [r["sss_seconds"] for r in conv], "o-", label="convolution (subsurface)")
            ax2.plot(n, [r["seconds"] for r in conv], "o:", label="convolution (whole render)")
            if hier:
                ax2.axhline(hier["sss_seconds"], color="k", lw=1, label="hierarchical (subsurface)")
                ax2.axhline(hier["seconds"], color="k", lw=1, ls=":", label="hierarchical (whole render)")
            for ax, unit in ((ax1, "%"), (ax2, "seconds")):
                ax.set_xscale("log", base=2)
                ax.set_xticks(n, [str(x) for x in n])
                ax.set_xlabel("layers")
                ax.set_ylabel(unit)
                ax.legend(fontsize=6)
                ax.grid(alpha=0.3)
        made["fig5"] = plot(out / "fig5" / "fig5-plot.png", draw)
    fig = figures.get("fig3")
    if fig:
        def draw(f):
            ax1, ax2 = f.subplots(1, 2)
            rs = fig["panels"]
            labels = [f"{r['params']['downsample']:g}" for r in rs]
            ax1.bar(labels, [100 * r["vs_exact"]["mre"] for r in rs])
            ax1.set_xlabel("layer resolution r")
            ax1.set_ylabel("err vs exact (%)")
            ax2.bar(labels, [r["sss_seconds"] for r in rs])
            ax2.set_xlabel("layer resolution r")
            ax2.set_ylabel("subsurface seconds")
        made["fig3"] = plot(out / "fig3" / "fig3-plot.png", draw)
    return {k: str(v.relative_to(out)) for k, v in made.items()}


# --- headline numbers and the disagreements -----------------------------------------------------------------------
def headline(run):
    """The closing note's numbers, as a dict (see :func:`closing_note`)."""
    figures = {f["key"]: f for f in run["figures"]}
    panels = [r for f in run["figures"] for r in f["panels"]]
    conv = [r for r in panels if r["method"] == "convolution"]
    out = {"per_figure": {}}
    for f in run["figures"]:
        rs = [r for r in f["panels"] if r["method"] == "convolution"]
        if rs:
            out["per_figure"][f["key"]] = {"median_seconds": float(np.median([r["seconds"] for r in rs])),
                                           "median_sss_seconds": float(np.median([r["sss_seconds"] for r in rs])),
                                           "figure_seconds": f["seconds"]}
    if conv:
        mre = [r["vs_exact"]["mre"] for r in conv]
        ratio = [r["vs_exact"]["ratio"] for r in conv]
        out["conv_vs_exact"] = {"count": len(conv), "mre_median": float(np.median(mre)), "mre_min": float(min(mre)),
                                "mre_max": float(max(mre)), "ratio_min": float(min(ratio)),
                                "ratio_max": float(max(ratio))}
    for method in ("convolution", "hierarchical", "exact"):
        rs = [r for r in panels if r["method"] == method and r.get("vs_pt")]
        if rs:
            out[f"{method}_vs_pt"] = {"mre": [r["vs_pt"]["mre"] for r in rs],
                                      "ratio": [r["vs_pt"]["ratio"] for r in rs],
                                      "panels": [f"{r['figure']} {r['title']}" for r in rs]}
    hier = [r for r in panels if r["method"] == "hierarchical"]
    if hier:
        out["hier_vs_exact"] = {"mre": [r["vs_exact"]["mre"] for r in hier],
                                "ratio": [r["vs_exact"]["ratio"] for r in hier]}
    speed = []
    for f in run["figures"]:
        for h in (r for r in f["panels"] if r["method"] == "hierarchical"):
            same = [r for r in f["panels"] if r["method"] == "convolution" and r["scene"] == h["scene"]]
            for c in same:
                speed.append({"figure": f["key"], "panel": c["title"], "conv_sss": c["sss_seconds"],
                              "hier_sss": h["sss_seconds"], "conv_total": c["seconds"], "hier_total": h["seconds"],
                              "sss_speedup": h["sss_seconds"] / c["sss_seconds"],
                              "total_speedup": h["seconds"] / c["seconds"]})
    out["speed"] = speed
    fig2 = figures.get("fig2")
    if fig2:
        out["fig2_c"] = {r["panel"]: r["c"] for r in fig2["panels"]}
    return out


def _dt_and_dz(record):
    """(d_t in mm, the max over channels of R_d^{-1}(t R_d(0)); dz in mm) of a Fig. 2 convolution panel."""
    from ..materials import material

    t = record["params"]["threshold"]
    dz = record.get("transport_stats", {}).get("dz_mm")
    if t <= 0:
        return math.inf, dz
    profile = model_profile("dipole", material(record["scene"]["material"]))
    return float(np.max(profile.radius_below(t))), dz


def closing_note(run, settings):
    h = headline(run)
    figures = {f["key"]: f for f in run["figures"]}
    lines = ["## Closing note: headline numbers", ""]
    lines.append(f"This {settings['name']} run ({settings['resolution']}² panels, {settings['spp']} spp; errors on "
                 f"{settings['error_resolution']}² renders) took {run['seconds']:.0f} s on {os.cpu_count()} cores "
                 f"(shared with other work: timings are indicative), {run['cache']['hits']} references reused from "
                 f"the cache and {run['cache']['misses']} rendered.")
    lines.append("")
    lines.append("**Time per panel** (convolution panels, median whole render / subsurface part):")
    lines.append("")
    for key, v in h["per_figure"].items():
        lines.append(f"- {key}: {v['median_seconds']:.2f} s / {v['median_sss_seconds']:.2f} s "
                     f"(whole figure with references and errors: {v['figure_seconds']:.0f} s)")
    if "conv_vs_exact" in h:
        v = h["conv_vs_exact"]
        lines += ["", f"- **Convolution against the exact sum** (all {v['count']} convolution panels): "
                  f"mean relative error median {_pct(v['mre_median'])} "
                  f"(range {_pct(v['mre_min'])} – {_pct(v['mre_max'])}), mean ratio {v['ratio_min']:.3f} – "
                  f"{v['ratio_max']:.3f}."]
    if "hier_vs_exact" in h:
        v = h["hier_vs_exact"]
        lines.append(f"- **Hierarchical against the exact sum**: mean relative error "
                     f"{', '.join(_pct(x) for x in v['mre'])}; ratio {', '.join(f'{x:.3f}' for x in v['ratio'])}.")
    for method, label in (("convolution", "Convolution"), ("hierarchical", "Hierarchical"),
                          ("exact", "The exact dipole sum")):
        v = h.get(f"{method}_vs_pt")
        if v:
            items = "; ".join(f"{p}: err {_pct(e)}, ratio {r:.3f}"
                              for p, e, r in zip(v["panels"], v["mre"], v["ratio"]))
            lines.append(f"- **{label} against volpathmis** ({settings['block']}×{settings['block']} blocks): {items}.")
    if h["speed"]:
        lines += ["", "**Speed against the hierarchical method** (same scene, same irradiance samples, same run):", ""]
        lines.append("| figure | convolution panel | subsurface s (conv / hier) | speed-up | whole render s "
                     "(conv / hier) | speed-up |")
        lines.append("|---|---|---|---|---|---|")
        for s in h["speed"]:
            lines.append(f"| {s['figure']} | {s['panel']} | {s['conv_sss']:.2f} / {s['hier_sss']:.2f} | "
                         f"{s['sss_speedup']:.1f}× | {s['conv_total']:.2f} / {s['hier_total']:.2f} | "
                         f"{s['total_speedup']:.1f}× |")
    lines += ["", "## Where this disagrees with the paper, explained", ""]
    lines += _disagreement_lines(_disagreement_numbers(figures, h), settings["resolution"])
    return "\n".join(lines)


def _disagreement_numbers(figures, h):
    """The numbers behind :func:`_disagreement_lines` from the run's ``figures`` (by key) and its :func:`headline`
    ``h``, as a dict with an entry per paragraph that has data:

    - ``fig2``: ``paper_c``, the paper's c against ours with d_t and dz (mm); ``full_c``, c at t = 0;
      ``small_mre``, the small bunny's errors at t = 0, 0.1 %, 5 % (None unless all three are there);
    - ``fig5``: per layer count of the paper's panels (no correction) ``layers``, ``ratio``, ``mre``, ``dz_mm``;
      ``mean_free_paths`` of the object (RGB); whether the error falls ``monotone``ly; the index of the panel whose
      ratio is ``closest`` to 1; the ``plane``-corrected panels' layers, ratio and error;
    - ``exact_vs_pt``: the exact dipole sum against volpathmis (panels, ratios);
    - ``fig5_speed``: the convolution's subsurface speed-ups over the hierarchical method in Fig. 5.
    """
    out = {}
    fig2 = figures.get("fig2")
    if fig2:
        ours = {}
        for r in fig2["panels"]:
            size = "small" if r["panel"].endswith("small") else "large"
            ours[(size, r["params"]["threshold"])] = r
        paper_c = []
        for (size, t), paper in PAPER_C.items():
            r = ours.get((size, t))
            if r is None:
                continue
            dt, dz = _dt_and_dz(r)
            paper_c.append({"size": size, "threshold": t, "paper": paper, "c": r["c"], "dt_mm": dt, "dz_mm": dz})
        small = [ours.get(("small", t)) for t in (0.0, 0.001, 0.05)]
        out["fig2"] = {"paper_c": paper_c, "full_c": [r["c"] for (s, t), r in ours.items() if t == 0],
                       "small_mre": ([r["vs_exact"]["mre"] for r in small]
                                     if all(small) and all(r.get("vs_exact") for r in small) else None)}
    fig5 = figures.get("fig5")
    if fig5:
        conv = [r for r in fig5["panels"]
                if r["method"] == "convolution" and r["params"].get("correction", "none") == "none"]
        plane = [r for r in fig5["panels"] if r["method"] == "convolution" and r["params"].get("correction") == "plane"]
        closest = min(range(len(conv)), key=lambda k: abs(1 - conv[k]["vs_exact"]["ratio"]))
        out["fig5"] = {
            "layers": [r["params"]["layers"] for r in conv],
            "ratio": [r["vs_exact"]["ratio"] for r in conv],
            "mre": [r["vs_exact"]["mre"] for r in conv],
            "dz_mm": [r.get("transport_stats", {}).get("dz_mm") for r in conv],
            "mean_free_paths": conv[0].get("mean_free_paths"),
            "monotone": all(a["vs_exact"]["mre"] >= b["vs_exact"]["mre"] for a, b in zip(conv, conv[1:])),
            "closest": closest,
            "plane": [{"layers": r["params"]["layers"], "ratio": r["vs_exact"]["ratio"], "mre": r["vs_exact"]["mre"]}
                      for r in plane]}
    pt = h.get("exact_vs_pt")
    if pt:
        out["exact_vs_pt"] = {"panels": pt["panels"], "ratio": pt["ratio"]}
    if h["speed"]:
        fig5_speed = [s for s in h["speed"] if s["figure"] == "fig5"]
        if fig5_speed:
            out["fig5_speed"] = [{"panel": s["panel"], "sss_speedup": s["sss_speedup"]} for s in fig5_speed]
    return out


def _fig2_lines(fig2):
    """The bullet points on Fig. 2 (convolutions per layer, the image's change with the threshold)."""
    out = []
    parts = [f"{p['size']} bunny at t = {100 * p['threshold']:g} %: paper c = {p['paper']}, ours c = {p['c']:.2f} "
             f"(d_t = {p['dt_mm']:.2f} mm, dz = {p['dz_mm']:.2f} mm)" for p in fig2["paper_c"]]
    full = fig2["full_c"]
    out.append("- **Fig. 2, convolutions per layer c.** " + "; ".join(parts) + ". c counts, per layer, the "
               "source layers within d_t = R_d⁻¹(t R_d(0)) (Eq. 8, the largest over RGB) of it, averaged over "
               "the layers (end layers have fewer neighbours, so c < 2 d_t/dz + 1). It depends on the profile "
               "and the object's depth, which the paper gives only as \"ten times smaller\": our 4 mm and 40 mm "
               "bunnies are our choice, and wholemilk's blue channel, with the longest reach relative to its "
               "R_d(0), sets d_t. "
               + ("With t = 0 every pair is kept: c = " + ", ".join(f"{c:.2f}" for c in full)
                  + " (the paper's 8 minus the end-layer effect)." if full else ""))
    if fig2["small_mre"] is not None:
        out.append("- **Fig. 2, image change with t** (small bunny, err vs exact at t = 0, 0.1 %, 5 %): "
                   + ", ".join(_pct(e) for e in fig2["small_mre"])
                   + ". The paper sees \"almost identical\" results at 0.1 % and a noticeable difference at 5 %.")
    return out


def _fig5_lines(fig5):
    """The bullet points on Fig. 5 (the layers against the exact sum, and the plane correction)."""
    out = []
    layers, ratio, mre = fig5["layers"], fig5["ratio"], fig5["mre"]
    ratios = ", ".join(f"{k} layers {x:.3f}" for k, x in zip(layers, ratio))
    errs = ", ".join(f"{k}: {_pct(e)}" for k, e in zip(layers, mre))
    mfp = fig5["mean_free_paths"]
    dz_text = ", ".join(f"{k} layers dz = {d:.1f} mm" for k, d in zip(layers, fig5["dz_mm"]) if d)
    closest, last = fig5["closest"], len(layers) - 1
    trend = ("The per-pixel error falls monotonically with the layer count, as the paper's Fig. 5 suggests, "
             if fig5["monotone"] else "The per-pixel error does not fall monotonically with the layer count, "
             "unlike what the paper's Fig. 5 suggests, ")
    trend += (f"but the brightness does not converge from one side: the ratio is closest to 1 at "
              f"{layers[closest]} layers and {layers[last]} layers are "
              f"{100 * (1 - ratio[last]):.0f} % darker than the exact sum. "
              if ratio[last] < 0.95 and closest != last else "and so does the brightness. ")
    if ratio[0] > 1.25:
        trend += (f"With {layers[0]} layers the image is {ratio[0]:.1f}× "
                  "as bright as the exact sum: the paper finds \"good solutions with a very low number of "
                  "layers\", but it tone-mapped every image on its own (the photographic operator keys on each "
                  "image's log-average), which hides a global brightness factor; our sheets show every panel "
                  "at the exposure of the exact sum. ")
    out.append("- **Fig. 5, layers.** Against the exact sum, mean ratio: " + ratios + "; mean relative error "
               + errs + ". " + trend
               + "The layered scheme replaces the depth offset between a surface sample and a shaded point by a "
               "multiple of the layer spacing (" + dz_text + "), an error of first order in dz over the mean "
               "free path"
               + (f" (the bunny spans {', '.join(f'{m:.0f}' for m in mfp)} mean free paths in R, G, B)" if mfp
                  else "")
               + ". Two errors of opposite sign follow: surface at different depths inside one layer slab "
               "couples as if at the same depth (too bright: dominant with few, thick layers), and a sample "
               "split between two layers many mean free paths apart reaches the shaded point partly through "
               "R_d(dz), which is small (too dark: dominant with many layers until dz nears the mean free "
               "path). The paper judged its Fig. 5 by eye against the hierarchical method; the pixel errors "
               "are ours (see the error maps).")
    if fig5["plane"]:
        out.append("- **Fig. 5, beyond the paper.** With the plane correction of the depth discretization "
                   "(convsss.transport.correction), against the exact sum: " + ", ".join(
                       f"{p['layers']} layers: ratio {p['ratio']:.3f}, mean relative error {_pct(p['mre'])}"
                       for p in fig5["plane"]) + ".")
    return out


def _disagreement_lines(n, resolution):
    """The bullet points of "Where this disagrees with the paper" from :func:`_disagreement_numbers` (``n``) and the
    run's panel ``resolution``."""
    out = []
    if n.get("fig2"):
        out += _fig2_lines(n["fig2"])
    if n.get("fig5"):
        out += _fig5_lines(n["fig5"])
    pt = n.get("exact_vs_pt")
    if pt:
        out.append("- **The dipole against path tracing.** The exact dipole sum against volpathmis of the same scene: "
                   + "; ".join(f"{p}: ratio {r:.3f}" for p, r in zip(pt["panels"], pt["ratio"]))
                   + ". The classic dipole (Jensen et al. 2001) is a semi-infinite, flat, diffusion-only model with "
                   "no single scattering: on a curved object with thin parts (ears, edges) lit from behind it is "
                   "not the exact answer, and the paper, which compares only against another dipole method, does "
                   "not measure this. Both methods of the paper share the bias.")
    speed = n.get("fig5_speed")
    if speed:
        text = ", ".join(f"{s['panel']} {s['sss_speedup']:.1f}×" for s in speed)
        out.append("- **Speed against the hierarchical method.** Subsurface time speed-ups of the convolution "
                   f"over the hierarchical method in Fig. 5: {text}. The paper gives no hierarchical timing in "
                   "its text. Our hierarchical lookups run once per camera sample (spp), the convolution's cost "
                   "is per layer pixel; whole-render times also include irradiance sampling and ray tracing, "
                   "shared by both."
                   + (" The ratio grows with the resolution (the hierarchical method's cost grows with pixels × "
                      "log samples, both growing with the image): this run's small images understate it; the "
                      "full run renders the paper's 800×800." if resolution < 800 else ""))
    out.append("- **Absolute times.** The paper quotes about 7 s (4 layers, 800×600, no optimizations) and about 2 s "
               "optimized, plus 14 s of ray tracing, on a 2011 i7. Our per-panel times above are for this run's "
               "resolution; the two cores are shared with other work, so compare ratios measured in one run, not "
               "absolute seconds.")
    out.append("- **Scenes.** The paper's scene files, object sizes, lights and camera are not published: ours are "
               "`quick_scene` (key light and back light, no floor), index-matched wherever path tracing is compared "
               "(so no highlights there), a dielectric with Phong highlights in the gallery. Orange juice, wax and "
               "soap of [MES*11] are not in our tables (substitutes named in the figures' notes).")
    return out


def write_report(out, run):
    """Write ``report.md`` and ``figures.json`` under ``out``; returns the report's path."""
    import mitsuba

    from .. import __version__

    out = Path(out)
    settings = run["settings"]
    figures = {f["key"]: f for f in run["figures"]}
    plots = _plots(out, figures)
    run["plots"] = plots
    lines = ["# The paper's figures, regenerated (`convsss figures`)", "",
             "Munoz, Echevarria, Seron, Gutierrez, *Convolution-Based Simulation of Homogeneous Subsurface "
             "Scattering*, Computer Graphics Forum 30(8), 2011: its Figs. 2–6, re-rendered by convsss, with "
             "errors against the exact dipole sum and against volumetric path tracing.", "",
             f"- run: **{settings['name']}** — panels {settings['resolution']}×{settings['resolution']} at "
             f"{settings['spp']} spp; errors measured on {settings['error_resolution']}² renders of the same panels "
             f"at {settings['error_spp']} spp; volpathmis at {settings['error_resolution']}² with "
             f"{settings['pt_spp']} spp, compared after {settings['block']}×{settings['block']} block averaging; "
             f"seed {settings['seed']}",
             f"- made {time.strftime('%Y-%m-%d %H:%M')} on {platform.machine()} with {os.cpu_count()} cores, "
             f"convsss {__version__}, Mitsuba {mitsuba.__version__}; total {run['seconds']:.0f} s "
             f"(kernel warm-up {run['warm_up_seconds']:.1f} s, not in any panel's time)",
             f"- references: {run['cache']['hits']} reused from `cache/`, {run['cache']['misses']} rendered "
             "(cached by a hash of the scene, renderer settings, spp, seed and resolution)", "",
             "**How to read the numbers.** *seconds*: the whole render of a panel by the convsss integrator "
             "(irradiance samples, transport, shading of the camera rays); *subsurface s*: the transport alone "
             "(the paper's \"simulation of light transport\": splat, kernels and FFTs, or the octree, plus the "
             "exitance lookups). *c*: the paper's convolutions per layer (mean over layers of the source layers "
             "each layer convolves). *err*: mean relative error over the object's pixels, averaged over RGB; "
             "*ratio*: mean(panel) / mean(reference) (below 1: darker); *rel. L2*: root relative mean squared "
             "error; FLIP: mean FLIP of both images through one tone mapping. Against the exact sum the "
             "comparison is pixel by pixel on the same camera rays; against volpathmis on averaged blocks.", ""]
    for key, f in figures.items():
        lines += [f"## {f['title']}", "", f"> Paper: {f['paper']}", ""]
        if f["notes"]:
            lines += [f"Here: {f['notes']}", ""]
        lines += [f"![{key}]({f['sheet']})", "", _table(f["panels"], f["versus_pt"]), ""]
        if f.get("profiles"):
            own = ", ".join(f"{k} {v}" for k, v in PROFILE_COLUMNS["renderer"].items())
            lines += ["The exact sum with each profile model at the paper's setting (its own total, every direction "
                      "a normal beam, single scattering in the profile), and with the renderer's defaults for what "
                      f"that setting pins (\"renderer\": {own}), against volpathmis:", "",
                      _profile_table(f["profiles"]), ""]
        if f.get("errors_sheet"):
            lines += ["Where the panels differ from the exact sum (signed relative luminance error, blue darker, red "
                      "brighter):", "", f"![{key} errors]({f['errors_sheet']})", ""]
        if key in plots:
            lines += [f"![{key} plot]({plots[key]})", ""]
        lines += [f"EXRs (linear) and PNGs of every panel: `{key}/`. Figure time: {f['seconds']:.0f} s.", ""]
        if f["warnings"]:
            lines += ["Warnings:", ""] + [f"- {w}" for w in f["warnings"]] + [""]
    beyond = [r for f in run["figures"] for r in f["panels"] if r.get("vs_pt") or r["method"] == "hierarchical"]
    if beyond:
        lines += ["## Beyond the paper: convolution and hierarchical against the exact sum and path tracing", "",
                  "| figure | panel | method | err vs exact | ratio vs exact | err vs volpathmis "
                  "| ratio vs volpathmis |",
                  "|---|---|---|---|---|---|---|"]
        for r in beyond:
            e, p = r.get("vs_exact") or {}, r.get("vs_pt") or {}
            lines.append(f"| {r['figure']} | {r['title']} | {r['method']} | {_pct(e.get('mre'))} | "
                         f"{_num(e.get('ratio'), 3)} | {_pct(p.get('mre'))} | {_num(p.get('ratio'), 3)} |")
        lines.append("")
    lines.append(closing_note(run, settings))
    lines.append("")
    write_text(out / "figures.json", json.dumps(json_ready(run), indent=1))
    return write_text(out / "report.md", "\n".join(lines))
