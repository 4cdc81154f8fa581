"""Samples merged in cubes (flux summed at the centroid, the two sides of a thin sheet kept apart): what the direct
sums of the core and middle bands run over (:mod:`convsss.transport.multiscale`)."""

from dataclasses import dataclass

import numpy as np

from ...hashtable import empty, grown, probe
from ...jit import njit


def sheet_side(normal):
    """Per sample, the axis and sign of its normal's largest component, ``2 axis + (component > 0)`` in 0-5 (all 0
    without normals): clusters never merge samples of different sides, so the two sides of a thin sheet stay apart."""
    if normal is None:
        return None
    return _sheet_side(np.ascontiguousarray(normal, dtype=np.float64))


@njit(cache=True)
def _sheet_side(normal):
    side = np.empty(normal.shape[0], dtype=np.int64)
    for k in range(normal.shape[0]):
        axis = 0
        for a in (1, 2):
            if abs(normal[k, a]) > abs(normal[k, axis]):
                axis = a
        side[k] = 2 * axis + (normal[k, axis] > 0)
    return side


@njit(cache=True)
def bounds(points):
    """The lowest and highest coordinates of ``points`` (N, 3), each (3,); zeros for no points."""
    if points.shape[0] == 0:
        return np.zeros(3), np.zeros(3)
    lo, hi = points[0].copy(), points[0].copy()
    for k in range(1, points.shape[0]):
        for c in range(3):
            lo[c] = min(lo[c], points[k, c])
            hi[c] = max(hi[c], points[k, c])
    return lo, hi


@njit(cache=True)
def cube_cells(points, origin, size):
    """The cube of side ``size`` from ``origin`` holding each point: ``floor((x - origin) / size)``, (N, 3) int64."""
    cells = np.empty(points.shape, dtype=np.int64)
    for k in range(points.shape[0]):
        for c in range(3):
            cells[k, c] = np.int64(np.floor((points[k, c] - origin[c]) / size))
    return cells


@dataclass(frozen=True)
class Clusters:
    """Samples merged in cubes: ``centre`` (C, 3) centroids weighted by each member's total flux (by area where a
    cluster has none), ``flux`` (C, 3) and ``area`` (C,) summed, ``side`` (C,) the members' :func:`sheet_side`
    (None without normals)."""

    centre: np.ndarray
    flux: np.ndarray
    area: np.ndarray
    side: np.ndarray | None

    def __len__(self):
        return len(self.centre)


@dataclass(frozen=True)
class Grouping:
    """Which cube each point falls in: ``index`` (N,) its group, ``first`` (G,) a member of each group, ``cells``
    (G, 3) int64 each group's cube, ``side`` (G,) its :func:`sheet_side` (None without normals)."""

    index: np.ndarray
    first: np.ndarray
    cells: np.ndarray
    side: np.ndarray | None

    def __len__(self):
        return len(self.first)


def group(cells, side):
    """Points grouped by their cube ``cells`` (N, 3) int64 (>= 0, :func:`cube_cells`) and, where ``side`` (N,) is
    given, by side (:func:`sheet_side`), groups numbered in the order of their first point: a :class:`Grouping`.
    Grouping its ``cells // k`` again merges whole groups, as grouping the points in cubes ``k`` times as large
    would."""
    index, first = _first_seen(_cube_keys(cells, np.zeros(len(cells), dtype=np.int64) if side is None else side))
    return Grouping(index, first, cells[first], None if side is None else side[first])


@njit(cache=True)
def _cube_keys(cells, side):
    """One int64 per (cube, side): ``((i dims[1] + j) dims[2] + m) 6 + side``, ``dims`` the cubes spanned."""
    dims = np.ones(3, dtype=np.int64)
    for k in range(cells.shape[0]):
        for c in range(3):
            dims[c] = max(dims[c], cells[k, c] + 1)
    key = np.empty(cells.shape[0], dtype=np.int64)
    for k in range(cells.shape[0]):
        key[k] = ((cells[k, 0] * dims[1] + cells[k, 1]) * dims[2] + cells[k, 2]) * 6 + side[k]
    return key


@njit(cache=True)
def _first_seen(key):
    """Per key, the number of distinct keys seen before its first occurrence (a :mod:`~convsss.hashtable` grown to
    stay at most half full), and the first position of each distinct key: ``(index (N,), first (G,))``."""
    n = key.shape[0]
    keys, values = empty(1024)
    index = np.empty(n, dtype=np.int64)
    first = np.empty(n, dtype=np.int64)
    groups = 0
    for k in range(n):
        if k > 0 and key[k] == key[k - 1]:  # neighbouring samples mostly share a cube
            index[k] = index[k - 1]
            continue
        slot = probe(keys, values, key[k])
        if values[slot] < 0:
            keys[slot], values[slot] = key[k], groups
            first[groups] = k
            groups += 1
        index[k] = values[slot]
        if 2 * groups > keys.shape[0]:
            keys, values = grown(keys, values, 2 * keys.shape[0])
    return index, first[:groups].copy()


def merge(grouping, position, area, flux):
    """The :class:`Clusters` of the points (``position`` (N, 3), ``area`` (N,), ``flux`` (N, 3)) of ``grouping``."""
    centre, total, summed = _merge(grouping.index, len(grouping), position, area, flux)
    return Clusters(centre, total, summed, grouping.side)


@njit(cache=True)
def _merge(index, count, position, area, flux):
    """Per group: the centroid weighted by total flux (by area where a group has none), flux and area summed."""
    centre = np.zeros((count, 3))
    total = np.zeros((count, 3))
    summed = np.zeros(count)
    norm = np.zeros(count)
    for k in range(index.shape[0]):
        g = index[k]
        weight = flux[k, 0] + flux[k, 1] + flux[k, 2] + 1e-30 * area[k]
        norm[g] += weight
        summed[g] += area[k]
        for c in range(3):
            centre[g, c] += weight * position[k, c]
            total[g, c] += flux[k, c]
    for g in range(count):
        for c in range(3):
            centre[g, c] /= norm[g]
    return centre, total, summed
