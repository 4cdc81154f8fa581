"""Cell lists over clusters and the direct sums of the core (Eq. M3's local limit too) and of the middle bands, read
at voxel corners (:mod:`convsss.transport.multiscale`)."""

import math

import numpy as np

from ...hashtable import capacity, empty, grown, probe
from ...jit import njit, prange
from ...memory import check_memory
from .far_field import _corner

#: Cubes of a cell list at most (their offsets: 128 MiB), beyond which the cubes grow.
CELL_LIST_CUBES = 1 << 24


def cube_side(extent, size):
    """The side of a :class:`CellList`'s cubes over ``extent`` (3,) mm: ``size``, or as much larger as keeps them at
    most :data:`CELL_LIST_CUBES` (a surface far larger than its profile's core: the cubes' offsets are held for the
    whole box, the clusters only on the surface)."""
    extent = np.maximum(np.asarray(extent, dtype=np.float64), 0.0)
    while float(np.prod(np.maximum(np.ceil(extent / size), 1))) > CELL_LIST_CUBES:
        size *= 1.25
    return size


def cell_list_bytes(lo, hi, size):
    """The start offsets of a :class:`CellList` of cubes of side ``size`` over ``lo``, ``hi``: one int64 a cube."""
    extent = np.asarray(hi) - np.asarray(lo)
    dims = np.maximum(np.ceil(extent / cube_side(extent, size)), 1)
    return 8 * (float(np.prod(dims)) + 1)


@njit(cache=True)
def _cell_list(view, origin, size, dims):
    """Counting sort of points into cubes of ``size``: ``order`` and ``starts`` (cells + 1), cells in x-major order."""
    n_cells = dims[0] * dims[1] * dims[2]
    cell = np.empty(view.shape[0], dtype=np.int64)
    starts = np.zeros(n_cells + 1, dtype=np.int64)
    for k in range(view.shape[0]):
        i = min(max(int((view[k, 0] - origin[0]) / size), 0), dims[0] - 1)
        j = min(max(int((view[k, 1] - origin[1]) / size), 0), dims[1] - 1)
        m = min(max(int((view[k, 2] - origin[2]) / size), 0), dims[2] - 1)
        cell[k] = (i * dims[1] + j) * dims[2] + m
        starts[cell[k] + 1] += 1
    for c in range(n_cells):
        starts[c + 1] += starts[c]
    fill = starts[:-1].copy()
    order = np.empty(view.shape[0], dtype=np.int64)
    for k in range(view.shape[0]):
        order[fill[cell[k]]] = k
        fill[cell[k]] += 1
    return order, starts


@njit(inline="always")
def _home_cube(point, origin, size):
    """The cube of side ``size`` from ``origin`` that ``point`` (3,) falls in: ``(i, j, m)``."""
    return (int(np.floor((point[0] - origin[0]) / size)), int(np.floor((point[1] - origin[1]) / size)),
            int(np.floor((point[2] - origin[2]) / size)))


@njit(inline="always")
def _column(i, j, cm, reach, dims, starts):
    """The range of sorted clusters in the cubes ``(i, j, cm - reach .. cm + reach)`` of a :class:`CellList` (one
    run: its cubes are in x-major order)."""
    base = (i * dims[1] + j) * dims[2]
    return starts[base + min(max(cm - reach, 0), dims[2])], starts[base + max(min(cm + reach + 1, dims[2]), 0)]


@njit(parallel=True, fastmath=True, cache=True)
def _band_sum(view, position, flux, starts, origin, size, dims, reach, table, r_c2, out):
    """``out[k] += sum_{|x_k - x_j| < r} R(|x_k - x_j|) Phi_j`` over the clusters (sorted into cubes of side
    ``size >= r / reach``), for a band ``R`` tabulated uniformly in ``r^2`` on ``[0, r^2 = r_c2]``."""
    scale = (table.shape[0] - 1) / r_c2
    for k in prange(view.shape[0]):
        px, py, pz = view[k, 0], view[k, 1], view[k, 2]
        ci, cj, cm = _home_cube(view[k], origin, size)
        m0 = m1 = m2 = 0.0
        for i in range(max(ci - reach, 0), min(ci + reach + 1, dims[0])):
            for j in range(max(cj - reach, 0), min(cj + reach + 1, dims[1])):
                for q in range(*_column(i, j, cm, reach, dims, starts)):
                    dx = position[q, 0] - px
                    dy = position[q, 1] - py
                    dz = position[q, 2] - pz
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 >= r_c2:
                        continue
                    t = d2 * scale
                    e = int(t)
                    f = t - e
                    m0 += ((1.0 - f) * table[e, 0] + f * table[e + 1, 0]) * flux[q, 0]
                    m1 += ((1.0 - f) * table[e, 1] + f * table[e + 1, 1]) * flux[q, 1]
                    m2 += ((1.0 - f) * table[e, 2] + f * table[e + 1, 2]) * flux[q, 2]
        out[k, 0] += m0
        out[k, 1] += m1
        out[k, 2] += m2


@njit(parallel=True, fastmath=True, cache=True)
def _local_sum(view, position, flux, area, starts, origin, size, dims, reach, r_02, energy, out):
    """Eq. M3: ``out[k] += E_core`` times the irradiance around ``view[k]`` averaged over the clusters with the
    weights ``(1 - d^2 / r_0^2)^2``, ``sum w_j Phi_j / sum w_j A_j`` (sorted into cubes as for :func:`_band_sum`)."""
    for k in prange(view.shape[0]):
        px, py, pz = view[k, 0], view[k, 1], view[k, 2]
        ci, cj, cm = _home_cube(view[k], origin, size)
        m0 = m1 = m2 = held = 0.0
        for i in range(max(ci - reach, 0), min(ci + reach + 1, dims[0])):
            for j in range(max(cj - reach, 0), min(cj + reach + 1, dims[1])):
                for q in range(*_column(i, j, cm, reach, dims, starts)):
                    dx = position[q, 0] - px
                    dy = position[q, 1] - py
                    dz = position[q, 2] - pz
                    d2 = dx * dx + dy * dy + dz * dz
                    if d2 >= r_02:
                        continue
                    t = 1.0 - d2 / r_02
                    wt = t * t
                    held += wt * area[q]
                    m0 += wt * flux[q, 0]
                    m1 += wt * flux[q, 1]
                    m2 += wt * flux[q, 2]
        if held > 0.0:
            out[k, 0] += energy[0] * m0 / held
            out[k, 1] += energy[1] * m1 / held
            out[k, 2] += energy[2] * m2 / held


@njit(cache=True)
def _voxel_set(view, origin, size, dims):
    """The voxels of side ``size`` (keys ``(i dims[1] + j) dims[2] + m``) holding the points ``view`` (N, 3), all
    inside the ``dims`` voxels from ``origin``: a :mod:`~convsss.hashtable` ``(keys, values)``, values 0 where held."""
    keys, values = empty(capacity(view.shape[0]))
    for k in range(view.shape[0]):
        i = int(np.floor((view[k, 0] - origin[0]) / size))
        j = int(np.floor((view[k, 1] - origin[1]) / size))
        m = int(np.floor((view[k, 2] - origin[2]) / size))
        key = (i * dims[1] + j) * dims[2] + m
        slot = probe(keys, values, key)
        keys[slot], values[slot] = key, 0
    return keys, values


@njit(inline="always")
def _held_voxel(point, origin, size, dims, voxels):
    """The voxel ``(i, j, m)`` of side ``size`` that ``point`` falls in, if it is one of the ``voxels``
    (:func:`_voxel_set`); ``i`` is -1 otherwise."""
    i = int(np.floor((point[0] - origin[0]) / size))
    j = int(np.floor((point[1] - origin[1]) / size))
    m = int(np.floor((point[2] - origin[2]) / size))
    if i < 0 or j < 0 or m < 0 or i >= dims[0] or j >= dims[1] or m >= dims[2]:
        return -1, j, m
    if voxels[1][probe(voxels[0], voxels[1], (i * dims[1] + j) * dims[2] + m)] < 0:
        return -1, j, m
    return i, j, m


@njit(inline="always")
def _corner_key(i, j, m, c, dims):
    """The key of corner ``c`` (0-7, bits x y z) of voxel ``(i, j, m)``, on the lattice of ``dims + 1`` corners per
    axis."""
    return ((i + (c >> 2)) * (dims[1] + 1) + (j + ((c >> 1) & 1))) * (dims[2] + 1) + (m + (c & 1))


@njit(cache=True)
def _missing_corners(view, origin, size, dims, voxels, table):
    """How many distinct corners of the held voxels that the points ``view`` (K, 3) fall in are not yet in the corner
    ``table``: the sums :func:`_corner_slots` would add."""
    seen = empty(capacity(8 * view.shape[0]))
    missing = 0
    for k in range(view.shape[0]):
        i, j, m = _held_voxel(view[k], origin, size, dims, voxels)
        if i < 0:
            continue
        for c in range(8):
            key = _corner_key(i, j, m, c, dims)
            if table[1][probe(table[0], table[1], key)] >= 0:
                continue
            slot = probe(seen[0], seen[1], key)
            if seen[1][slot] < 0:
                seen[0][slot], seen[1][slot] = key, 0
                missing += 1
    return missing


@njit(cache=True)
def _corner_slots(view, origin, size, dims, voxels, table, count, new_keys):
    """Per point of ``view`` (K, 3) in one of the ``voxels`` (:func:`_voxel_set`) of side ``size``, the slots of its
    voxel's 8 corners, on the lattice of ``dims + 1`` corners per axis from ``origin``: found in the corner ``table``
    (a :mod:`~convsss.hashtable`, room left for 8 K more) or added to it as slots ``count, count + 1, ...``, their
    keys written to ``new_keys``; -1 for the other points. Returns (slots (K, 8), the new count)."""
    slots = np.full((view.shape[0], 8), -1, dtype=np.int64)
    first = count
    for k in range(view.shape[0]):
        i, j, m = _held_voxel(view[k], origin, size, dims, voxels)
        if i < 0:
            continue
        for c in range(8):
            key = _corner_key(i, j, m, c, dims)
            slot = probe(table[0], table[1], key)
            if table[1][slot] < 0:
                table[0][slot], table[1][slot] = key, count
                new_keys[count - first] = key
                count += 1
            slots[k, c] = table[1][slot]
    return slots, count


@njit(parallel=True, cache=True)
def _corner_interpolate(view, origin, size, slots, values, out):
    """``out[k] +=`` the trilinear interpolation at ``view[k]`` of the ``values`` at its voxel's corner ``slots``."""
    for k in prange(view.shape[0]):
        if slots[k, 0] < 0:
            continue
        u = (view[k, 0] - origin[0]) / size
        v = (view[k, 1] - origin[1]) / size
        w = (view[k, 2] - origin[2]) / size
        fu, fv, fw = u - np.floor(u), v - np.floor(v), w - np.floor(w)
        for c in range(8):
            wt = _corner(c, fu, fv, fw)[3]
            for ch in range(3):
                out[k, ch] += wt * values[slots[k, c], ch]


class CellList:
    """Clusters sorted into cubes of side ``size``, for a band of ``radius``: a query visits the cubes within
    ``reach = ceil(radius / size)`` of its own. (The middle band's list has cubes of ``r_c / 2``, as the core's of
    ``r_1``, and visits 5^3 of them: 0.7 times the clusters that 3^3 cubes of ``r_c`` hold on a surface.)"""

    def __init__(self, position, flux, origin, radius, size, area=None):
        extent = position.max(axis=0) - origin if len(position) else np.zeros(3)
        size = cube_side(extent, size)
        self.origin, self.radius, self.size = origin, radius, size
        self.reach = math.ceil(radius / size - 1e-9)
        self.dims = np.maximum(np.ceil(extent / size).astype(np.int64), 1)
        # Its start offsets, one int64 a cube (at most CELL_LIST_CUBES of them, :func:`cube_side`): refused before
        # allocating where even those do not fit.
        cubes = " x ".join(map(str, self.dims))
        check_memory(8 * (float(np.prod(self.dims.astype(np.float64))) + 1),
                     f"the offsets of the multiscale transport's cell list ({cubes} cubes of {size:.3g} mm)",
                     "use the hierarchical or exact transport for this profile, or raise the accuracy")
        order, self.starts = _cell_list(position, origin, size, self.dims)
        self.position = np.ascontiguousarray(position[order])
        self.flux = np.ascontiguousarray(flux[order])
        self.area = None if area is None else np.ascontiguousarray(area[order])  # for the local limit's average

    def add_sum(self, view, table, out):
        """``out += sum_j R(|x - x_j|) Phi_j`` at ``view`` (K, 3) for the band ``table`` (on ``[0, radius^2]``)."""
        _band_sum(view, self.position, self.flux, self.starts, self.origin, self.size, self.dims, self.reach, table,
                  self.radius * self.radius, out)

    def add_average(self, view, energy, out):
        """``out += energy`` (3,) times the irradiance averaged within ``radius`` of ``view`` (K, 3) (Eq. M3; the
        list must hold the clusters' ``area``)."""
        _local_sum(view, self.position, self.flux, self.area, self.starts, self.origin, self.size, self.dims,
                   self.reach, self.radius * self.radius, energy, out)


class BandCorners:
    """The middle band where it is asked for: at a query in a voxel of side ``size`` that holds clusters, the
    trilinear interpolation of the band at the voxel's corners (it is smooth at ``r_1``, larger than the voxels),
    each corner summed through the band's ``cells`` the first time a query needs it and kept (queries lie on the
    visible surface, a fraction of where the samples are, and neighbouring voxels share corners); at any other
    query, the band summed where it is. A chunk of queries that would add more corners than it holds queries (queries
    sparser than the voxels: a pixel wider than a voxel, scattered path vertices) is summed where its queries are. So
    a point's value may depend on the batch it is asked in, by the band's interpolation error: the same queries in the
    same order give the same bits (the shader sorts its hits)."""

    #: Query points per call of the corner table (it keeps room for 8 new corners each).
    CHUNK = 1 << 14

    def __init__(self, cells, table, clusters, lo, hi, size):
        self.cells, self.table, self.size = cells, table, size
        self.origin = lo - 0.5 * size
        self.dims = np.ceil((hi + size - self.origin) / size).astype(np.int64) + 1
        self._voxels = _voxel_set(clusters, self.origin, size, self.dims)
        self.count = 0
        self._table = empty(1)
        self._values = np.zeros((0, 3))

    def add(self, view, out):
        """``out +=`` the band at ``view`` (K, 3)."""
        for start in range(0, len(view), self.CHUNK):
            chunk = view[start:start + self.CHUNK]
            if _missing_corners(chunk, self.origin, self.size, self.dims, self._voxels, self._table) > len(chunk):
                # Queries sparser than the voxels: fewer sums where they are than at the corners they would add.
                self.cells.add_sum(chunk, self.table, out[start:start + self.CHUNK])
                continue
            self._reserve(self.count + 8 * len(chunk))
            fresh = np.empty(8 * len(chunk), dtype=np.int64)
            first = self.count
            slots, self.count = _corner_slots(chunk, self.origin, self.size, self.dims, self._voxels, self._table,
                                              first, fresh)
            i, rest = np.divmod(fresh[:self.count - first], (self.dims[1] + 1) * (self.dims[2] + 1))
            j, m = np.divmod(rest, self.dims[2] + 1)
            corners = self.origin + self.size * np.stack([i, j, m], axis=1).astype(np.float64)
            self.cells.add_sum(corners, self.table, self._values[first:self.count])
            _corner_interpolate(chunk, self.origin, self.size, slots, self._values, out[start:start + self.CHUNK])
            direct = np.flatnonzero(slots[:, 0] < 0)
            if len(direct):
                band = np.zeros((len(direct), 3))
                self.cells.add_sum(np.ascontiguousarray(chunk[direct]), self.table, band)
                out[start + direct] += band

    def _reserve(self, corners):
        """Room for ``corners`` in the table (at most half full) and the values."""
        if 2 * corners <= len(self._table[0]):
            return
        size = 1 << (2 * corners - 1).bit_length()
        self._table = grown(*self._table, size)
        values = np.zeros((size // 2, 3))
        values[:self.count] = self._values[:self.count]
        self._values = values
