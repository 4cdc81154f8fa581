"""The hierarchical transport of Jensen & Buhler 2002: the paper's comparison method (Munoz et al. 2011, §6).

Jensen, Buhler, "A rapid hierarchical rendering technique for translucent materials", ACM TOG 21(3), 2002, §3.
The irradiance samples go into an :class:`~convsss.transport.octree.Octree` whose nodes keep their total area
``A_node``, total flux ``Phi_node = sum_i E_i A_i`` and flux-weighted position ``p_node``. The exitance at a query
point ``x``,

    M(x) = sum_i R_d(|x - x_i|) E_i A_i                                   (Munoz et al. Eq. 1, discretized),

is summed by a depth-first walk from the root. At a node:

1. if the distance from ``x`` to the node's (tight) box is at least ``r_max``, the node is skipped: the profile is
   zero there for every sample, exactly as in :class:`~convsss.transport.exact.ExactTransport` (``r_max`` is the
   end of the profile's radial table);
2. if the node is a leaf, its samples are summed exactly;
3. if ``x`` lies strictly outside the node's box and ``A_node / |x - p_node|^2 < epsilon`` (Jensen & Buhler's
   solid-angle-like criterion ``ΔA/|x - p|^2 < ε``), the node is used whole: it adds
   ``R_d(|x - p_node|) Phi_node``;
4. otherwise its children are visited.

``epsilon = 0`` never uses an inner node whole and gives the exact sum; larger values trade accuracy for speed
(pbrt-v2 defaults to 0.05, Mitsuba 0.6 to 0.2). ``R_d`` is evaluated from the profile's radial table with the same
compiled lookup as the exact transport. The walk is compiled with numba, parallel over query points on all cores,
with an explicit stack per thread.
"""

import numpy as np

from ..jit import njit, prange
from ..parameters import Parameter
from .base import Transport, register_transport
from .octree import Octree
from .radial import RadialTable, profile_lookup, sum_samples

#: Query points per parallel work item (one traversal stack each).
_BLOCK = 64


@njit(parallel=True, fastmath=True, cache=True)
def _traverse(points, epsilon, r_scale, ds, table, r_max, position, flux, start, end, first_child, child_count,
              node_area, node_flux, center, box_lo, box_hi, max_depth):
    """Exitance (K, 3) at ``points``, and per query the nodes visited, nodes used whole, samples summed exactly."""
    n_query = points.shape[0]
    out = np.zeros((n_query, 3))
    visited = np.zeros(n_query, np.int64)
    approximated = np.zeros(n_query, np.int64)
    summed = np.zeros(n_query, np.int64)
    r_max2 = r_max * r_max
    stack_size = 8 * (max_depth + 1)  # a popped node leaves at most 7 siblings per level on the stack
    n_blocks = (n_query + _BLOCK - 1) // _BLOCK
    for b in prange(n_blocks):
        stack = np.empty(stack_size, np.int64)
        for k in range(b * _BLOCK, min((b + 1) * _BLOCK, n_query)):
            px, py, pz = points[k, 0], points[k, 1], points[k, 2]
            m0 = m1 = m2 = 0.0
            n_visited = n_approximated = n_summed = 0
            stack[0] = 0  # the root
            top = 1
            while top > 0:
                top -= 1
                node = stack[top]
                n_visited += 1
                gx = max(box_lo[node, 0] - px, 0.0, px - box_hi[node, 0])
                gy = max(box_lo[node, 1] - py, 0.0, py - box_hi[node, 1])
                gz = max(box_lo[node, 2] - pz, 0.0, pz - box_hi[node, 2])
                gap2 = gx * gx + gy * gy + gz * gz
                if gap2 >= r_max2:
                    continue  # step 1: out of the profile's reach
                if child_count[node] == 0:  # step 2: a leaf, summed exactly
                    l0, l1, l2 = sum_samples(px, py, pz, position, flux, start[node], end[node], r_scale, ds, table,
                                             r_max2)
                    m0 += l0
                    m1 += l1
                    m2 += l2
                    n_summed += end[node] - start[node]
                    continue
                dx = center[node, 0] - px
                dy = center[node, 1] - py
                dz = center[node, 2] - pz
                d2 = dx * dx + dy * dy + dz * dz
                if gap2 > 0.0 and node_area[node] < epsilon * d2:  # step 3: the node as one sample
                    n_approximated += 1
                    if d2 < r_max2:
                        r = np.sqrt(d2)
                        m0 += profile_lookup(r, r_scale, ds, table, 0) * node_flux[node, 0]
                        m1 += profile_lookup(r, r_scale, ds, table, 1) * node_flux[node, 1]
                        m2 += profile_lookup(r, r_scale, ds, table, 2) * node_flux[node, 2]
                    continue
                for child in range(first_child[node], first_child[node] + child_count[node]):  # step 4
                    stack[top] = child
                    top += 1
            out[k, 0] = m0
            out[k, 1] = m1
            out[k, 2] = m2
            visited[k] = n_visited
            approximated[k] = n_approximated
            summed[k] = n_summed
    return out, visited, approximated, summed


class HierarchicalTransport(Transport):
    """Jensen & Buhler 2002's octree transport; see the module docstring.

    Parameters
    ----------
    samples : IrradianceSamples
    profile : Profile
    frame : ViewFrame or None
        Not used: the octree needs no view.
    epsilon : float, >= 0
        The error threshold of the criterion ``A_node / |x - p_node|^2 < epsilon``; 0 gives the exact sum.
    leaf_size : int, >= 1
        The most samples a leaf holds (unless they share the finest octree cell).
    """

    name = "hierarchical"
    parameters = (
        Parameter("epsilon", float, 0.05, "Jensen & Buhler's error threshold: a node is used whole when A_node / d^2 "
                  "< epsilon (0: the exact sum; 0.05 as pbrt-v2, 0.2 as Mitsuba 0.6).", low=0.0),
        Parameter("leaf_size", int, 4, "Most samples per octree leaf (a leaf's samples are summed one by one, so "
                  "large leaves give up what the nodes' aggregates save, and tiny ones add nodes to visit).",
                  low=1, high=4096),
    )

    def __init__(self, samples, profile, frame=None, material=None, **params):
        super().__init__(samples, profile, frame, material, **params)
        self.epsilon, self.leaf_size = self.params["epsilon"], self.params["leaf_size"]
        with self.timings("profile_table"):
            self._radial = RadialTable.of(profile)
        with self.timings("octree"):
            self.octree = Octree.build(samples.position, samples.area, samples.flux, self.leaf_size)
        self._max_depth = int(self.octree.depth.max())
        self._queries = 0
        self._visited = 0
        self._approximated = 0
        self._summed = 0

    def _exitance(self, points):
        t, r = self.octree, self._radial
        out, visited, approximated, summed = _traverse(
            points, self.epsilon, r.r_scale, r.ds, r.values, r.r_max, t.position, t.flux, t.start,
            t.end, t.first_child, t.child_count, t.node_area, t.node_flux, t.center, t.box_lo, t.box_hi,
            self._max_depth)
        self._queries += len(points)
        self._visited += int(visited.sum())
        self._approximated += int(approximated.sum())
        self._summed += int(summed.sum())
        return out

    @property
    def stats(self):
        """The base stats plus the octree (nodes, leaves, depth) and, per query so far, the mean number of nodes
        visited, of nodes used whole and of samples summed exactly."""
        stats = super().stats
        per_query = max(self._queries, 1)
        stats.update(epsilon=self.epsilon, leaf_size=self.leaf_size, octree=self.octree.stats, queries=self._queries,
                     nodes_visited_per_query=self._visited / per_query,
                     nodes_used_whole_per_query=self._approximated / per_query,
                     samples_summed_per_query=self._summed / per_query)
        return stats


register_transport(HierarchicalTransport)
