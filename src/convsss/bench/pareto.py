"""Pareto fronts of error against time, and the headline ratio: a method's time at equal error.

Rows are the benchmark's (``seconds``, ``rel_l2``, ``method``); a front keeps, fastest first, each row more accurate
than every faster one; times at equal error are interpolated on the fronts in log-log.
"""

import math

import numpy as np

#: Methods compared: the paper's layers, the layers with the plane correction (beyond the paper), Jensen–Buhler.
METHOD_COLORS = {"multiscale": "tab:red", "convolution": "tab:blue", "convolution+plane": "tab:green",
                 "hierarchical": "tab:orange"}


def pareto_front(rows):
    """Indices of ``rows`` on their Pareto front (time and ``rel_l2``, both lower is better), fastest first."""
    order = sorted(range(len(rows)), key=lambda k: (rows[k]["seconds"], rows[k]["rel_l2"]))
    front, best = [], math.inf
    for k in order:
        if rows[k]["rel_l2"] < best:
            front.append(k)
            best = rows[k]["rel_l2"]
    return front


def mark_pareto(rows):
    """Set ``row["pareto"]`` per method (the exact sum is on no front)."""
    for row in rows:
        row["pareto"] = False
    for name in METHOD_COLORS:
        chosen = [r for r in rows if r.get("method", r["transport"]) == name]
        for k in pareto_front(chosen):
            chosen[k]["pareto"] = True
    return rows


def time_at_error(front, error):
    """Time on a Pareto ``front`` (rows, fastest first, errors falling) at ``error``: log–log interpolation.

    Returns ``(seconds, where)``: ``where`` is ``"inside"``, or ``"below"`` (the front never gets this accurate:
    seconds is None) or ``"above"`` (less accurate than the front's fastest point: seconds is None).
    """
    errors = np.array([r["rel_l2"] for r in front])
    seconds = np.array([r["seconds"] for r in front])
    if len(front) == 0 or error < errors.min():
        return None, "below"
    if error > errors.max():
        return None, "above"
    if len(front) == 1 or error == errors[0]:
        return float(seconds[0]), "inside"
    k = int(np.searchsorted(-errors, -error))  # errors[k-1] > error >= errors[k]
    e0, e1 = np.log(errors[k - 1]), np.log(max(errors[k], 1e-300))
    t0, t1 = np.log(seconds[k - 1]), np.log(seconds[k])
    w = 0.0 if e0 == e1 else (np.log(error) - e0) / (e1 - e0)
    return float(np.exp(t0 + w * (t1 - t0))), "inside"


def headline(rows, convolution="convolution"):
    """The time ratio convolution / hierarchical at equal error, both ways, and a summary.

    ``at_hierarchical``: per hierarchical point, the convolution front's time at its error (the headline).
    ``at_convolution``: per convolution front point, the hierarchical front's time at its error; where that point is
    less accurate than every hierarchical point, the fastest hierarchical point (more accurate) bounds the time, and
    the ratio is a lower bound (``bound: true``). Summary: ``overlap`` (hierarchical points inside the convolution
    front's error range), ``ratio_min / ratio_median / ratio_max`` over them (None without overlap), and the error
    ranges of both methods.
    """
    conv = [r for r in rows if r.get("method", r["transport"]) == convolution]
    hier = [r for r in rows if r["transport"] == "hierarchical"]
    conv_front = [conv[k] for k in pareto_front(conv)]
    hier_front = [hier[k] for k in pareto_front(hier)]
    at_hier = []
    for r in sorted(hier, key=lambda r: r["rel_l2"]):
        seconds, where = time_at_error(conv_front, r["rel_l2"])
        at_hier.append({"epsilon": r["epsilon"], "rel_l2": r["rel_l2"], "hierarchical_s": r["seconds"],
                        "convolution_s": seconds, "ratio": None if seconds is None else seconds / r["seconds"],
                        "where": where})
    at_conv = []
    for r in conv_front:
        seconds, where = time_at_error(hier_front, r["rel_l2"])
        bound = where == "above" and bool(hier_front)
        if bound:
            seconds = hier_front[0]["seconds"]
        at_conv.append({"label": r["label"], "rel_l2": r["rel_l2"], "convolution_s": r["seconds"],
                        "hierarchical_s": seconds, "ratio": None if seconds is None else r["seconds"] / seconds,
                        "where": where, "bound": bound})
    ratios = [p["ratio"] for p in at_hier if p["ratio"] is not None]

    def span(chosen):
        return [min(r["rel_l2"] for r in chosen), max(r["rel_l2"] for r in chosen)] if chosen else None

    return {"method": convolution, "at_hierarchical": at_hier, "at_convolution": at_conv, "overlap": len(ratios),
            "ratio_min": min(ratios) if ratios else None,
            "ratio_median": float(np.median(ratios)) if ratios else None,
            "ratio_max": max(ratios) if ratios else None,
            "convolution_error_range": span(conv), "hierarchical_error_range": span(hier)}


def headline_text(scene, h):
    """A few lines that state the headline of ``scene``."""
    conv, hier = h["convolution_error_range"], h["hierarchical_error_range"]
    name = h.get("method", "convolution")
    if conv is None or hier is None:
        return f"{scene}: nothing to compare"
    lines = [f"{scene}: rel. L2 error: {name} {conv[0]:.2%}–{conv[1]:.2%}, hierarchical {hier[0]:.2%}–"
             f"{hier[1]:.2%}"]
    if h["overlap"]:
        inside = [p for p in h["at_hierarchical"] if p["ratio"] is not None]
        lo, hi = min(p["rel_l2"] for p in inside), max(p["rel_l2"] for p in inside)
        lines.append(f"  time({name}) / time(hierarchical) at equal error = {h['ratio_median']:.2f} (median; "
                     f"{h['ratio_min']:.2f}–{h['ratio_max']:.2f} at the {h['overlap']} hierarchical point"
                     f"{'s' if h['overlap'] != 1 else ''} with errors {lo:.2%}–{hi:.2%} inside the {name} "
                     "front)")
    else:
        lines.append(f"  no hierarchical point lies inside the {name} front's error range: no ratio at equal "
                     "error from the hierarchical side")
    exact = [p for p in h["at_convolution"] if p["ratio"] is not None and not p["bound"]]
    bounds = [p for p in h["at_convolution"] if p["bound"]]
    if exact:
        lines.append(f"  at the {name} front's points: ratio " + ", ".join(
            f"{p['ratio']:.2f} ({p['label']}, {p['rel_l2']:.1%})" for p in exact))
    if bounds:
        lines.append(f"  {name} front points less accurate than the hierarchical front's fastest point (whose "
                     "time bounds the hierarchical time at that error): ratio >= " + ", ".join(
                         f"{p['ratio']:.2f} ({p['label']}, {p['rel_l2']:.1%})" for p in bounds))
    return "\n".join(lines)
