"""The object's interior on a grid: the surface's signed distance, the diffusion equation's sparse system with the
boundary cut into the links (Eq. D2-D4), its multigrid solver, and the moments that deposit sources on the nodes and
gather the field from them (:mod:`convsss.transport.volume`)."""


import numpy as np

from ...jit import njit, prange

#: A point whose offset from its nearest sample makes an angle with the normal of cosine below this lies beyond a
#: rim (:meth:`Surface.signed_distance`).
RIM_COSINE = 0.7


#: The smallest fraction of a link at which the boundary is put (a node on the boundary itself).
THETA_MIN = 0.01


#: Bytes per grid node: signed distance, three channels' indices, matrices, multigrid hierarchies and fields (an
#: estimate from their sizes: 8 + 3 x (8 + 8 + 7 x 12 x 1.5 + 8) for every node inside; not measured).
BYTES_PER_NODE = 560


def grid_shape(lo, hi, h, pad):
    """The nodes ``origin + h (i, j, k)`` covering [lo - pad, hi + pad]: (origin, shape)."""
    origin = np.asarray(lo, dtype=np.float64) - pad
    shape = np.floor((np.asarray(hi) + pad - origin) / h).astype(np.int64) + 2
    return origin, tuple(int(n) for n in shape)


def multigrid(matrix):
    """pyamg's smoothed-aggregation hierarchy of the symmetric positive definite ``matrix``, the same every time:
    its smoother's spectral radius is estimated from numpy's global random numbers, seeded here and restored."""
    import pyamg

    state = np.random.get_state()
    try:
        np.random.seed(0)
        return pyamg.smoothed_aggregation_solver(matrix, symmetry="hermitian")
    finally:
        np.random.set_state(state)


class Surface:
    """The object's surface as its samples tell it, thinned to one per cube of side ``h / 4``: the signed distance
    to it (> 0 outside) along the nearest sample's normal, and the normal near any point."""

    def __init__(self, position, normal, h):
        from scipy.spatial import cKDTree

        cell = np.floor((position - position.min(axis=0)) / (0.25 * h)).astype(np.int64)
        dims = cell.max(axis=0) + 1
        _, first = np.unique((cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2], return_index=True)
        self.position, self.normal = position[first], normal[first]
        self._tree = cKDTree(self.position)

    def _nearest(self, points):
        return self._tree.query(points, k=1, workers=-1)[1]

    def normal_near(self, points):
        """The nearest sample's normal (K, 3)."""
        return self.normal[self._nearest(points)]

    def signed_distance(self, points, band=np.inf):
        """At ``points`` (K, 3): the distance to the nearest sample's tangent plane (> 0 outside), or, where the
        point lies off that sample along the surface rather than along its normal (beyond a rim or an edge, where
        the plane would reach out past the object), the distance to the sample itself, outside; NaN farther than
        ``band`` from every sample."""
        distance, nearest = self._tree.query(points, k=1, workers=-1, distance_upper_bound=band)
        far = ~np.isfinite(distance)
        nearest[far] = 0
        offset = points - self.position[nearest]
        along = np.einsum("ij,ij->i", offset, self.normal[nearest])
        distance = np.linalg.norm(offset, axis=1)
        return np.where(far, np.nan, np.where(np.abs(along) >= RIM_COSINE * distance, along, distance))

    def signed_distance_on(self, origin, h, shape, band):
        """:meth:`signed_distance` at the nodes ``origin + h (i, j, k)`` of ``shape`` within ``band`` (mm) of the
        samples; a node farther away gets ``-band`` (inside) or ``band`` (outside): the side of the nodes within the
        band that its connected region of far nodes touches, where they agree (a closed surface: a k-d tree query
        that stops at the band is much cheaper than one that finds every node's nearest sample), else
        (an open sheet of samples, whose inside and outside meet around its rim) the side of its nearest sample's
        tangent plane."""
        import scipy.ndimage

        axes = [origin[d] + h * np.arange(shape[d]) for d in range(3)]
        nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        sd = self.signed_distance(nodes, band).reshape(shape)
        far = np.isnan(sd)
        regions, count = scipy.ndimage.label(far)
        touching = scipy.ndimage.grey_dilation(regions, size=(3, 3, 3))  # each near node: a far region beside it
        near = ~far & (touching > 0)
        inside = np.bincount(touching[near], sd[near] < 0, count + 1)
        outside = np.bincount(touching[near], sd[near] >= 0, count + 1)
        side = np.where(inside > 0, -band, band)[regions]
        mixed = far & (inside > 0)[regions] & (outside > 0)[regions]
        if mixed.any():
            nearest = self._nearest(nodes[mixed.ravel()])
            plane = np.einsum("ij,ij->i", nodes[mixed.ravel()] - self.position[nearest], self.normal[nearest])
            side[mixed] = np.where(plane < 0, -band, band)
        sd[far] = side[far]
        return sd


def assemble(sd, z_b, diffusion, sigma_a, h):
    """The matrix of Eq. D1 on the nodes with ``sd < z_b`` (``sd`` of the grid's shape): (CSR matrix, index grid
    with -1 outside). Each inside link couples its nodes by ``-D/h^2``; a link leaving the domain adds
    ``D / (theta h^2)`` to its inside node (``theta`` where ``sd`` crosses ``z_b`` along it, Gibou et al. 2002)."""
    import scipy.sparse

    inside = sd < z_b
    index = np.full(sd.shape, -1, dtype=np.int64)
    n = int(inside.sum())
    index[inside] = np.arange(n)
    link = diffusion / h**2
    diagonal = np.full(n, sigma_a)
    rows, cols = [], []
    for axis in range(3):
        a = [slice(None)] * 3
        b = [slice(None)] * 3
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        ia, ib = index[tuple(a)], index[tuple(b)]
        sa, sb = sd[tuple(a)], sd[tuple(b)]
        both = (ia >= 0) & (ib >= 0)
        rows.append(ia[both])
        cols.append(ib[both])
        np.add.at(diagonal, ia[both], link)
        np.add.at(diagonal, ib[both], link)
        for own, other, s_own, s_other in ((ia, ib, sa, sb), (ib, ia, sb, sa)):
            leaving = (own >= 0) & (other < 0)
            theta = (z_b - s_own[leaving]) / (s_other[leaving] - s_own[leaving])
            np.add.at(diagonal, own[leaving], link / np.maximum(theta, THETA_MIN))
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    off = np.full(len(rows), -link)
    matrix = scipy.sparse.coo_matrix((np.concatenate([off, off, diagonal]),
                                      (np.concatenate([rows, cols, np.arange(n)]),
                                       np.concatenate([cols, rows, np.arange(n)]))), shape=(n, n)).tocsr()
    return matrix, index


@njit(cache=True)
def moment_weights(point, origin, h, index, depth, nodes, weights):
    """The 8 nodes around ``point`` and their trilinear weights, written to ``nodes`` and ``weights`` (8,), kept on
    inside nodes (``index >= 0``) and scaled so that ``sum_k w_k d_k`` is the point's own distance inside the
    extrapolated boundary (``depth`` at the nodes, ``d_k``, interpolated over all eight: the nearest boundary's,
    which in a part thinner than two extrapolation lengths is the other face's).

    Near the boundary the field of Eq. D1 is proportional to that distance (it is zero on the boundary), so what
    a point source puts in the far field is its strength times its distance (its *moment*), and the value at a
    point is the distance times the local slope. A source at ``z_r`` under the surface has the moment
    ``z_r + z_b``, a surface point reads ``z_b`` times the slope: with these weights neither depends on where the
    boundary falls within a cell, where plain trilinear weights renormalized over the inside nodes change the
    half-space's exitance by a factor of two when the boundary layer is thinner than a cell.

    Returns whether the point is held: whether the inside nodes near it carry at least a tenth of the moment (if
    not, its weights are zero)."""
    nx, ny, nz = index.shape
    u = (point[0] - origin[0]) / h, (point[1] - origin[1]) / h, (point[2] - origin[2]) / h
    i0, j0, l0 = int(np.floor(u[0])), int(np.floor(u[1])), int(np.floor(u[2]))
    fx, fy, fz = u[0] - i0, u[1] - j0, u[2] - l0
    moment = inside = total = 0.0
    corner = 0
    for dx in range(2):
        for dy in range(2):
            for dz in range(2):
                i, j, m = i0 + dx, j0 + dy, l0 + dz
                w = (fx if dx else 1 - fx) * (fy if dy else 1 - fy) * (fz if dz else 1 - fz)
                nodes[corner], weights[corner] = 0, 0.0
                if 0 <= i < nx and 0 <= j < ny and 0 <= m < nz:
                    d = depth[i, j, m]
                    moment += w * d
                    node = index[i, j, m]
                    if node >= 0:
                        nodes[corner], weights[corner] = node, w
                        inside += w * d
                        total += w
                corner += 1
    held = moment > 0 and inside > 0.1 * moment * total
    for corner in range(8):
        weights[corner] = weights[corner] * moment / inside if held else 0.0
    return held


@njit(cache=True)
def _deposit(points, values, origin, h, index, depth, rhs, held):
    """``rhs[n] += w_n values[k]`` over every point's :func:`moment_weights` (one thread: the points share nodes)."""
    nodes, weights = np.zeros(8, dtype=np.int64), np.zeros(8)
    for k in range(len(points)):
        held[k] = moment_weights(points[k], origin, h, index, depth, nodes, weights)
        for corner in range(8):
            rhs[nodes[corner]] += weights[corner] * values[k]


@njit(parallel=True, cache=True)
def _gather(points, field, origin, h, index, depth, out, held):
    """``out[k] = sum_n w_n field[n]`` over each point's :func:`moment_weights`."""
    for k in prange(len(points)):
        nodes, weights = np.zeros(8, dtype=np.int64), np.zeros(8)
        held[k] = moment_weights(points[k], origin, h, index, depth, nodes, weights)
        value = 0.0
        for corner in range(8):
            value += weights[corner] * field[nodes[corner]]
        out[k] = value


def deposit(points, values, origin, h, index, depth, size):
    """Point sources of strength ``values`` (K,) at ``points`` (K, 3) on the grid's inside nodes, by
    :func:`moment_weights`: (right-hand side (size,), held (K,))."""
    rhs, held = np.zeros(size), np.zeros(len(points), dtype=np.bool_)
    _deposit(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(values, dtype=np.float64),
             np.asarray(origin, dtype=np.float64), float(h), index, depth, rhs, held)
    return rhs, held


def gather(points, field, origin, h, index, depth):
    """The field read at ``points`` (K, 3) from the inside nodes, by :func:`moment_weights`: (values (K,), held
    (K,))."""
    out, held = np.zeros(len(points)), np.zeros(len(points), dtype=np.bool_)
    _gather(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(field, dtype=np.float64),
            np.asarray(origin, dtype=np.float64), float(h), index, depth, out, held)
    return out, held
