"""An octree over irradiance samples, with the per-node aggregates of Jensen & Buhler 2002.

Jensen, Buhler, "A rapid hierarchical rendering technique for translucent materials", ACM TOG 21(3), 2002, §3.2:
the irradiance samples are stored in an octree whose every node keeps

- ``A_node = sum_i A_i``, the total area of its samples (mm^2);
- ``Phi_node = sum_i E_i A_i`` per channel, its total flux (their "area-weighted irradiance" ``E_node =
  Phi_node / A_node`` times ``A_node``);
- ``p_node = sum_i w_i x_i / sum_i w_i``, a flux-weighted position, with the scalar weight ``w_i = sum_c E_ic A_i``
  (the sum of the channels; the area ``A_i`` where a node carries no flux at all);
- the tight axis-aligned box of its samples (for the "query point outside the node" test of the traversal).

Construction: samples are sorted by their 63-bit Morton code (21 bits per axis over the samples' bounding cube),
so that every octree cell holds a contiguous run of the sorted samples. Nodes are split breadth-first into their
non-empty octants until they hold at most ``leaf_size`` samples (or the 21 levels of the code are used up: samples
closer than 2^-21 of the cloud's extent stay together in one leaf). A cell with a single non-empty octant is not
stored: the split goes on inside it, so every inner node has 2 to 8 children and there are fewer than ``2 N``
nodes. Children of a node are stored contiguously and after their parent, so aggregates are summed bottom-up in
one reverse sweep.
"""

from dataclasses import dataclass

import numpy as np

from ..errors import ConvsssError
from ..jit import njit
from ..morton import MORTON_BITS, interleave


def morton_codes(positions):
    """63-bit Morton codes (x in the lowest bit of each triple) of ``positions`` (N, 3) over their bounding cube.

    Parameters
    ----------
    positions : numpy.ndarray, shape (N, 3), float64
        Sample positions (mm; any length unit), N >= 1.

    Returns
    -------
    numpy.ndarray, shape (N,), uint64
        Each position's cell in a grid of 2^21 cells per axis over the bounding cube (side: the largest extent),
        the bits of x, y, z interleaved.
    """
    lo = positions.min(axis=0)
    extent = float(np.max(positions.max(axis=0) - lo))
    scale = (2**MORTON_BITS - 1) / extent if extent > 0 else 0.0
    cells = np.floor((positions - lo) * scale).astype(np.uint64)
    return interleave(cells)


@njit(cache=True)
def _split(codes, leaf_size):
    """Breadth-first octree topology over sorted Morton ``codes``: per node its sample range, children, depth."""
    n = codes.shape[0]
    capacity = 2 * n + 1
    start = np.empty(capacity, np.int64)
    end = np.empty(capacity, np.int64)
    level = np.empty(capacity, np.int64)
    first_child = np.full(capacity, -1, np.int64)
    child_count = np.zeros(capacity, np.int64)
    depth = np.zeros(capacity, np.int64)
    start[0], end[0], level[0] = 0, n, 0
    count = 1
    head = 0
    bounds = np.empty(9, np.int64)
    while head < count:
        node = head
        head += 1
        lo, hi, lev = start[node], end[node], level[node]
        while hi - lo > leaf_size and lev < MORTON_BITS:
            shift = 3 * (MORTON_BITS - 1 - lev)
            bounds[0] = lo
            for octant in range(8):  # codes are sorted, so the octants are consecutive runs
                k = bounds[octant]
                while k < hi and ((codes[k] >> shift) & 7) == octant:
                    k += 1
                bounds[octant + 1] = k
            nonempty = 0
            for octant in range(8):
                if bounds[octant + 1] > bounds[octant]:
                    nonempty += 1
            lev += 1
            if nonempty == 1:
                continue  # one occupied octant: descend without storing a node
            first_child[node] = count
            child_count[node] = nonempty
            for octant in range(8):
                if bounds[octant + 1] > bounds[octant]:
                    start[count], end[count], level[count] = bounds[octant], bounds[octant + 1], lev
                    depth[count] = depth[node] + 1
                    count += 1
            break
    return start[:count], end[:count], first_child[:count], child_count[:count], depth[:count]


@njit(cache=True)
def _aggregate(start, end, first_child, child_count, position, area, flux):
    """Per node: total area, total flux, flux-weighted position and tight box, summed bottom-up (reverse order)."""
    m = start.shape[0]
    node_area = np.zeros(m)
    node_flux = np.zeros((m, 3))
    node_weight = np.zeros(m)
    node_moment = np.zeros((m, 3))  # sum_i w_i x_i
    area_moment = np.zeros((m, 3))  # sum_i A_i x_i, the fallback for flux-free nodes
    box_lo = np.full((m, 3), np.inf)
    box_hi = np.full((m, 3), -np.inf)
    for node in range(m - 1, -1, -1):
        if child_count[node] == 0:
            members = range(start[node], end[node])
            for i in members:
                w = flux[i, 0] + flux[i, 1] + flux[i, 2]
                node_area[node] += area[i]
                node_weight[node] += w
                for c in range(3):
                    node_flux[node, c] += flux[i, c]
                    node_moment[node, c] += w * position[i, c]
                    area_moment[node, c] += area[i] * position[i, c]
                    box_lo[node, c] = min(box_lo[node, c], position[i, c])
                    box_hi[node, c] = max(box_hi[node, c], position[i, c])
        else:
            for child in range(first_child[node], first_child[node] + child_count[node]):
                node_area[node] += node_area[child]
                node_weight[node] += node_weight[child]
                for c in range(3):
                    node_flux[node, c] += node_flux[child, c]
                    node_moment[node, c] += node_moment[child, c]
                    area_moment[node, c] += area_moment[child, c]
                    box_lo[node, c] = min(box_lo[node, c], box_lo[child, c])
                    box_hi[node, c] = max(box_hi[node, c], box_hi[child, c])
    center = np.empty((m, 3))
    for node in range(m):
        for c in range(3):
            if node_weight[node] > 0:
                center[node, c] = node_moment[node, c] / node_weight[node]
            else:
                center[node, c] = area_moment[node, c] / node_area[node]
            center[node, c] = min(max(center[node, c], box_lo[node, c]), box_hi[node, c])  # rounding only
    return node_area, node_flux, center, box_lo, box_hi


@dataclass(frozen=True, eq=False)
class Octree:
    """An octree over N samples with M nodes; node 0 is the root. See the module docstring.

    Attributes
    ----------
    order : (N,) int64
        Sample indices in Morton order: sample ``order[j]`` is the ``j``-th in every per-node range.
    position, area, flux : (N, 3), (N,), (N, 3) float64
        The samples, reordered by ``order``.
    start, end : (M,) int64
        Node ``k`` holds the reordered samples ``start[k]:end[k]`` (a leaf sums exactly these).
    first_child, child_count : (M,) int64
        Children of node ``k`` are ``first_child[k] : first_child[k] + child_count[k]``; leaves have 0 children.
    depth : (M,) int64
        Edges from the root (root 0).
    node_area, node_flux, center, box_lo, box_hi : (M,), (M, 3), (M, 3), (M, 3), (M, 3) float64
        Total area, total flux ``sum E_i A_i``, flux-weighted position and tight box of the node's samples.
    """

    order: np.ndarray
    position: np.ndarray
    area: np.ndarray
    flux: np.ndarray
    start: np.ndarray
    end: np.ndarray
    first_child: np.ndarray
    child_count: np.ndarray
    depth: np.ndarray
    node_area: np.ndarray
    node_flux: np.ndarray
    center: np.ndarray
    box_lo: np.ndarray
    box_hi: np.ndarray

    @classmethod
    def build(cls, position, area, flux, leaf_size=8):
        """Octree over samples at ``position`` (N, 3) with ``area`` (N,) and ``flux`` (N, 3), ``leaf_size`` >= 1.

        Parameters
        ----------
        position : array_like, shape (N, 3)
            Sample positions (mm), N >= 1.
        area : array_like, shape (N,)
            Sample areas (mm^2).
        flux : array_like, shape (N, 3)
            Sample flux ``E_i A_i`` per RGB channel (the irradiance's unit times mm^2).
        leaf_size : int
            The most samples a leaf holds (unless they share the finest cell).

        Returns
        -------
        Octree
            Its arrays float64 or int64, as listed in the class docstring.
        """
        if isinstance(leaf_size, bool) or not isinstance(leaf_size, (int, np.integer)) or leaf_size < 1:
            raise ConvsssError(f"leaf_size={leaf_size!r} is not allowed: it must be an integer >= 1")
        position = np.ascontiguousarray(position, dtype=np.float64)
        if len(position) == 0:
            raise ConvsssError("an octree needs at least one sample")
        codes = morton_codes(position)
        order = np.argsort(codes, kind="stable")
        position = np.ascontiguousarray(position[order])
        area = np.ascontiguousarray(np.asarray(area, dtype=np.float64)[order])
        flux = np.ascontiguousarray(np.asarray(flux, dtype=np.float64)[order])
        start, end, first_child, child_count, depth = _split(codes[order], int(leaf_size))
        node_area, node_flux, center, box_lo, box_hi = _aggregate(start, end, first_child, child_count, position,
                                                                  area, flux)
        return cls(order, position, area, flux, start, end, first_child, child_count, depth, node_area, node_flux,
                   center, box_lo, box_hi)

    def __len__(self):
        return len(self.start)

    @property
    def leaves(self):
        """Indices of the leaf nodes: an int64 array, ascending."""
        return np.flatnonzero(self.child_count == 0)

    @property
    def stats(self):
        """Node and leaf counts, the deepest level, and the largest leaf."""
        leaves = self.leaves
        return {"nodes": len(self), "leaves": len(leaves), "depth": int(self.depth.max()),
                "max_leaf_samples": int(np.max(self.end[leaves] - self.start[leaves]))}
