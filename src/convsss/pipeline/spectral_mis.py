"""Spectral MIS over the colour channels (Miller, Georgiev and Jarosz 2019), the random walk's weights: a path's
weight in channel ``i`` is ``w_i = f_i / mean_j p_j`` (Eq. W1), ``f_i`` its contribution in channel ``i`` and ``p_j``
its density had channel ``j`` drawn it, kept per lane as the ratios ``p_j / f_i`` (three Color3f: row ``i``, column
``j``), updated at each event; two techniques' ratios combine by the balance heuristic (Eq. W2). Used by
:mod:`.walk`.
"""

import drjit as dr

from ..backend import import_mitsuba

mi = import_mitsuba()


def ones(n):
    """The ratios of ``n`` paths before any event: all 1."""
    return tuple(dr.full(mi.Color3f, 1.0, n) for _ in range(3))


def update(ratios, p, f, active):
    """The path-density ratios ``p_j / f_i`` (three Color3f: row ``i``, column ``j``) times this event's ``p / f``
    (Eq. W1), where ``active``; a ratio that is not finite counts as 0."""
    out = []
    for i in range(3):
        ratio = mi.Color3f(p) / mi.Color3f(f)[i]
        ratio = dr.select(dr.isfinite(ratio), ratio, 0.0) * ratios[i]
        out.append(dr.select(active, dr.select(dr.isnan(ratio), 0.0, ratio), ratios[i]))
    return tuple(out)


def where(mask, ratios, others):
    """``ratios`` where ``mask``, else ``others``."""
    return tuple(dr.select(mask, ratios[i], others[i]) for i in range(3))


def ended(ratios, ends):
    """The ratios with the rows of the channels that ``ends`` (Color3f, 1 or 0) set to 0: their weight is 0 on."""
    return tuple(dr.select(ends[i] > 0.0, 0.0, ratios[i]) for i in range(3))


def mis(ratios, others=None):
    """The path's weight per channel from its ratios (Eq. W1: ``3 / sum_j p_j / f_i``); with ``others`` (the same
    path's ratios under another technique), its balance-heuristic weight between the two (Eq. W2:
    ``3 / sum_j (p_j + p'_j) / f_i``)."""
    weight = []
    for i in range(3):
        row = ratios[i] if others is None else ratios[i] + others[i]
        total = dr.sum(row)
        weight.append(dr.select(total == 0.0, 0.0, 3.0 / total))
    return mi.Color3f(*weight)
