"""Spectral MIS over the colour channels (Miller, Georgiev and Jarosz 2019), the random walk's weights: a path's
weight in channel ``i`` is ``w_i = f_i / mean_j p_j`` (Eq. W1), ``f_i`` its contribution in channel ``i`` and ``p_j``
its density had channel ``j`` drawn it; two techniques' combine by the balance heuristic (Eq. W2). Used by
:mod:`.walk`.

The ratios ``p_j / f_i`` are a rank-one matrix: each event multiplies ``p`` and ``f`` by its own, so they are kept
as the two products, ``(P, F)`` (two Color3f per lane), both divided after each event by the largest ``P_j``, so
that they neither underflow nor overflow over thousands of events (the same range as the ratios themselves). Where
an event's ``f_i`` is 0 (or not finite), channel ``i``'s weight is 0 from then on.
"""

import drjit as dr

from ..backend import import_mitsuba

mi = import_mitsuba()


def ones(n):
    """The ratios of ``n`` paths before any event: ``P = F = 1``."""
    return dr.full(mi.Color3f, 1.0, n), dr.full(mi.Color3f, 1.0, n)


def update(ratios, p, f, active):
    """The ratios times this event's density ``p`` (per channel ``j`` that could have drawn it) and contribution
    ``f`` (per channel ``i``), where ``active`` (Eq. W1)."""
    big, fp = ratios
    big, fp = big * mi.Color3f(p), fp * mi.Color3f(f)
    big = dr.select(dr.isfinite(big), big, 0.0)
    fp = dr.select(dr.isfinite(fp), fp, 0.0)
    scale = dr.max(big)
    scale = dr.select(scale > 0.0, scale, 1.0)
    return dr.select(active, big / scale, ratios[0]), dr.select(active, fp / scale, ratios[1])


def where(mask, ratios, others):
    """``ratios`` where ``mask``, else ``others``."""
    return dr.select(mask, ratios[0], others[0]), dr.select(mask, ratios[1], others[1])


def ended(ratios, ends):
    """The ratios with the channels that ``ends`` (Color3f, 1 or 0) marks at 0: their weight is 0 on."""
    return ratios[0], dr.select(ends > 0.0, 0.0, ratios[1])


def _inverse_weight(ratios):
    """``sum_j p_j / f_i`` per channel ``i`` (infinite where ``f_i`` is 0)."""
    return dr.select(ratios[1] > 0.0, dr.sum(ratios[0]) / ratios[1], dr.inf)


def mis(ratios, others=None):
    """The path's weight per channel from its ratios (Eq. W1: ``3 / sum_j p_j / f_i``); with ``others`` (the same
    path's ratios under another technique), its balance-heuristic weight between the two (Eq. W2:
    ``3 / sum_j (p_j + p'_j) / f_i``); 0 where that sum is 0 or infinite."""
    total = _inverse_weight(ratios) if others is None else _inverse_weight(ratios) + _inverse_weight(others)
    return dr.select((total > 0.0) & dr.isfinite(total), 3.0 / total, 0.0)
