"""The volume transport: the half-space sum of Eq. 1, corrected by the diffusion equation solved on the object itself.

Paper Eq. 1 reads a half-space's profile at the straight distance between two surface points, so light that crosses
the body, leaves through a thin part or would cross an air gap is counted as if the object were the half-space under
each entry point. The classic dipole is the Green's function of the diffusion equation on a half-space with the
extrapolated boundary; the same equation solved on the object's own volume makes it geometric. Per channel,

    -D ∇²u + sigma_a u = sum_i Phi_i delta(x - x_i + z_r n_i)   in the object grown by z_b,  u = 0 beyond,  (Eq. D1)

with ``D = 1/(3 sigma_t')``, ``z_r = 1/sigma_t'`` (the dipole's real source under the entry point ``x_i``, normal
``n_i``) and ``z_b = 2 A D`` (the extrapolated boundary). It is solved on a voxel grid of spacing ``h`` aligned with
the camera: the domain is where the signed distance to the surface (from the nearest sample's tangent plane) is
below ``z_b``; a link from an inside node to an outside one ends on that boundary at the fraction ``theta`` of the
link where the distance crosses ``z_b``, and adds ``D / (theta h^2)`` to the inside node's diagonal (the symmetric
second-order treatment of Gibou et al. 2002), so the matrix is symmetric positive definite and the boundary sits
where it is, not on the nearest node. Conjugate gradients with smoothed-aggregation multigrid (pyamg) solve it.

The grid cannot resolve the profile's core, so the solve is used as a *difference*: the exitance is

    M(x) = sum_i R_d(|x - x_i|) Phi_i + beta [du/dd(x) - sum_i T(|x - x_i|) Phi_i],                      (Eq. D2)

where ``du/dd`` is the solve's slope along the inward normal at the real surface (read from two depths, Eq. D4),
``beta`` turns it into Fick's flux (Eq. D4), and ``T(r)`` is the same solver's slope on a flat half-space, placed
and read the same way (sources where Eq. D5 puts them, :func:`moment_weights`), averaged over where the boundary
and the source fall within a cell (:func:`half_space_response`, solved exactly in lateral Fourier modes). On a
half-space ``du/dd = sum_i T Phi_i`` and Eq. D2 is Eq. 1: any profile model keeps
its near field. Where the object is not a half-space at the scale of the diffusion length, the bracket adds what
crosses the body and removes what would cross the air. Both sums run on the multiscale transport
(:mod:`.multiscale`), so the cost is theirs plus the solve.

What diffusion cannot do, this cannot either: parts thinner than a few mean free paths, low albedo (single
scattering is traced by shading, as for every transport). A part thinner than a cell keeps Eq. 1 where no node of
the domain is near: sources and queries with no inside node around them add no correction; a channel whose
diffusion length is under :data:`RESOLVED_LENGTH` cells keeps Eq. 1 entirely. Checked against closed forms
(tests/transport/test_volume.py): a single point source on a half-space differs from Eq. 1 near the source (the
grid's response to one source against the average over where it falls in a cell); a slab 2 or 5 mm thick transmits
the 1-D closed form within 2 % and converges to it as the spacing falls; a 5 mm sphere's exitance is the
eigenfunction series' within 2.5 % from 60 degrees off the source on, 5 % nearer. A part only a few cells thick is
not resolved: the 2 mm slab at a 0.5 mm spacing (7 cells across) transmits too little.
"""

import math
from dataclasses import dataclass

import numba
import numpy as np
import pyamg
import scipy.ndimage
import scipy.sparse
from scipy.spatial import cKDTree

from ..errors import ConvsssError
from ..memory import check_memory
from ..parameters import Parameter
from ..profiles.base import ScaledProfile
from ..profiles.dipole import DipoleProfile
from ..profiles.tabulated import TabulatedProfile
from ..samples import IrradianceSamples
from .base import Transport, register_transport
from .kernels import KernelCache
from .multiscale import MultiscaleTransport

#: The half-space response's reach: the radius holding all but this fraction of the profile's energy.
RESPONSE_TAIL = 1e-4
#: The half-space response's largest reach, in cells (its cost grows as the cube).
MAX_REACH = 128
#: Where the boundary falls within a cell, and where the source falls laterally, for the average of
#: :func:`half_space_response` (fractions of a cell).
OFFSETS = (0.125, 0.375, 0.625, 0.875)
#: Read-back pairs per offset in :func:`half_space_response`.
READS = 60_000
#: A channel is corrected where its diffusion length is at least this many cells (where it is shorter, what the
#: grid resolves of the shape is several diffusion lengths wide, and Eq. 1 stands).
RESOLVED_LENGTH = 2.0
#: How many diffusion lengths the medium under an open sheet of samples is grown (:meth:`VolumeTransport._domain`).
OPEN_DEPTH = 3.0
#: A point whose offset from its nearest sample makes an angle with the normal of cosine below this lies beyond a
#: rim (:meth:`Surface.signed_distance`).
RIM_COSINE = 0.7
#: The smallest fraction of a link at which the boundary is put (a node on the boundary itself).
THETA_MIN = 0.01
#: Bytes per grid node: signed distance, three channels' indices, matrices, multigrid hierarchies and fields (an
#: estimate from their sizes: 8 + 3 x (8 + 8 + 7 x 12 x 1.5 + 8) for every node inside; not measured).
BYTES_PER_NODE = 560
#: The half-space responses, keyed by (coefficients, spacing).
RESPONSES = KernelCache()


def medium_of(profile):
    """The classic dipole of the profile's coefficients (``sigma_s'``, ``sigma_a``, ``eta``): it names ``D``, ``z_r``
    and ``A``; a one-line error for a profile without coefficients (a tabulated CSV)."""
    base = profile.base if isinstance(profile, ScaledProfile) else profile
    if not all(hasattr(base, k) for k in ("sigma_s_prime", "sigma_a", "eta")):
        raise ConvsssError("the volume transport needs a profile model with coefficients (sigma_s', sigma_a, eta), "
                           f"not {type(base).__name__}: use a model, or another transport")
    return DipoleProfile(base.sigma_s_prime, base.sigma_a, base.eta)


@dataclass(frozen=True)
class Coefficients:
    """Per channel (3,) each, on a grid of spacing ``h``: ``diffusion`` ``D`` and the grid's ``absorption`` (1/mm,
    Eq. D3) of Eq. D1, ``sigma_tr`` (1/mm), ``z_r`` and ``z_b`` (mm), ``beta`` of Eq. D4; where sources sit (Eq.
    D5): their distance inside the extrapolated boundary ``source_depth`` (mm) and gain ``source_gain``; the reads of
    Eq. D4: their two distances inside the extrapolated boundary ``read_depths`` (2, 3) (mm) and weights
    ``read_weights`` (2, 3) (1/mm)."""

    diffusion: np.ndarray
    absorption: np.ndarray
    sigma_tr: np.ndarray
    z_r: np.ndarray
    z_b: np.ndarray
    beta: np.ndarray
    source_depth: np.ndarray
    source_gain: np.ndarray
    read_depths: np.ndarray
    read_weights: np.ndarray

    def key(self):
        return np.concatenate([self.diffusion, self.absorption, self.source_depth, self.read_depths.ravel()]).tobytes()


def coefficients(profile, h):
    """The :class:`Coefficients` of ``profile`` on a grid of spacing ``h``.

    The grid's absorption makes the discrete equation decay along a grid axis at the continuous rate ``sigma_tr``
    (a lattice decays as ``cosh(kappa h) = 1 + sigma_a h^2 / (2 D)``, slower than ``sigma_tr`` by a relative
    ``(sigma_tr h)^2 / 24``, a 14 % excess ten diffusion lengths out at ``h`` half of one):

        sigma_a,h = (2 D / h^2) (cosh(sigma_tr h) - 1).                                                  (Eq. D3)

    The exitance is Fick's flux through the real surface, ``z_b`` inside the extrapolated boundary, of the field
    of sources of strength ``alpha'`` (the dipole's):

        M = beta du/dd (z_b),   beta = s alpha' D,                                                         (Eq. D4)

    ``d`` the distance inside the extrapolated boundary along the normal, ``s`` the profile's total over the
    classic dipole's (1 for the dipole; the scale of a model, or of the exact total). The slope is that of
    ``u = g(d) (a + b d)`` through the field at two depths, ``d_1 = max(z_b, 0.75 h)`` and ``d_2 = d_1 + h``:
    ``du/dd (z_b) = w_1 u(d_1) + w_2 u(d_2)``, with ``g(d) = sinh(sigma_tr d) / sigma_tr`` the depth profile of a
    field uniform along the surface (``b = 0``; ``b`` takes the field's variation along it: a parabola in ``d``
    instead would miss the uniform field's slope). A fixed ratio of flux to fluence would be right only for a
    uniform field: around a point source, the flux at the surface over ``D sigma_tr coth(sigma_tr z_b)`` times the
    fluence is above 1 near the source and below it farther out, and the half-space's response read that way sat
    above the dipole's.

    The boundary layer (``z_r + z_b``, about one mean free path) is often thinner than a cell; a source in it
    would then depend on where the boundary falls within the cell (by a factor of two on a half-space). Only the
    field away from the source matters to the correction of Eq. D2, and there a source at distance ``d`` inside a
    boundary acts in proportion to ``g(d) = sinh(sigma_tr d) / sigma_tr``. So sources are put at least 1.5 cells
    inside the extrapolated boundary, with the gain that keeps the field they make:

        d_s = max(z_r + z_b, 1.5 h),   gain g(z_r + z_b) / g(d_s).                                       (Eq. D5)
    """
    dipole = medium_of(profile)
    sigma_t_prime = dipole.sigma_s_prime + dipole.sigma_a
    diffusion = 1.0 / (3.0 * sigma_t_prime)
    sigma_tr = np.asarray(dipole.sigma_tr, dtype=np.float64)
    absorption = (2.0 * diffusion / h**2) * (np.cosh(sigma_tr * h) - 1.0)  # Eq. D3
    own = np.asarray(dipole.total_reflectance, dtype=np.float64)
    scale = np.divide(np.asarray(profile.total_reflectance, dtype=np.float64), own, out=np.zeros(3), where=own > 0)
    z_b = 2.0 * dipole.A * diffusion

    def g(d):
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(sigma_tr * d > 1e-8, np.sinh(sigma_tr * d) / np.where(sigma_tr > 0, sigma_tr, 1.0), d)

    source_depth = np.maximum(dipole.z_r + z_b, 1.5 * h)  # Eq. D5
    d_1 = np.maximum(z_b, 0.75 * h)  # Eq. D4: u = g (a + b d) through u(d_1), u(d_2), sloped at z_b
    d_2 = d_1 + h
    lever = np.cosh(sigma_tr * z_b) * (z_b - d_1) + g(z_b)
    w_1 = (np.cosh(sigma_tr * z_b) - lever / h) / g(d_1)
    w_2 = lever / (h * g(d_2))
    return Coefficients(diffusion, absorption, sigma_tr, dipole.z_r, z_b, scale * dipole.alpha_prime * diffusion,
                        source_depth, g(dipole.z_r + z_b) / g(source_depth), np.stack([d_1, d_2]),
                        np.stack([w_1, w_2]))


def auto_spacing(profile, extent):
    """The grid spacing (mm) for an object of largest ``extent`` (mm): half the shortest diffusion length (the far
    field's scale), within [extent / 64, extent / 24]."""
    dipole = medium_of(profile)
    with np.errstate(divide="ignore"):
        length = float(np.min(1.0 / dipole.sigma_tr))
    return float(np.clip(0.5 * length, extent / 64.0, extent / 24.0))


def grid_shape(lo, hi, h, pad):
    """The nodes ``origin + h (i, j, k)`` covering [lo - pad, hi + pad]: (origin, shape)."""
    origin = np.asarray(lo, dtype=np.float64) - pad
    shape = np.floor((np.asarray(hi) + pad - origin) / h).astype(np.int64) + 2
    return origin, tuple(int(n) for n in shape)


def _thomas(lower, diagonal, rhs):
    """Solve tridiagonal systems, one per column: constant ``lower`` (= upper) off-diagonal, ``diagonal`` (n, M)
    and ``rhs`` (n, M, R) for R right-hand sides."""
    n = len(diagonal)
    cp = np.empty_like(diagonal)
    dp = np.empty_like(rhs)
    beta = diagonal[0]
    cp[0] = lower / beta
    dp[0] = rhs[0] / beta[:, None]
    for k in range(1, n):
        beta = diagonal[k] - lower * cp[k - 1]
        cp[k] = lower / beta
        dp[k] = (rhs[k] - lower * dp[k - 1]) / beta[:, None]
    x = np.empty_like(rhs)
    x[-1] = dp[-1]
    for k in range(n - 2, -1, -1):
        x[k] = dp[k] - cp[k][:, None] * x[k + 1]
    return x


def _depth_weights(s, delta, h, moment):
    """Linear weights over the depth nodes ``floor(s)``, ``floor(s) + 1`` (node ``k`` at ``(k + delta) h`` below the
    extrapolated boundary), kept where the node index is >= 0 and scaled to the ``moment`` (:func:`moment_weights`):
    (nodes (2,), weights (2,))."""
    k = math.floor(s)
    nodes = np.array([k, k + 1])
    w = np.where(nodes >= 0, np.array([k + 1 - s, s - k]), 0.0)
    nodes = np.maximum(nodes, 0)
    return nodes, w * moment / np.sum(w * (nodes + delta) * h)


def half_space_response(diffusion, sigma_a, source_depth, read_depths, read_weights, h, reach, seed=0):
    """``T(r)`` of Eq. D2 for one channel: the grid solver's slope of Eq. D4 (``sum_j w_j u(d_j)``, the reads at
    ``read_depths`` with ``read_weights``) under a surface point at distance ``r`` from a unit flux's entry point on
    a flat half-space, averaged over :data:`OFFSETS` of the boundary within a cell and of the source laterally, and
    over directions. Returns (r (n,), T (n,)), non-increasing.

    The grid is periodic laterally (``N`` nodes, twice the reach) and Dirichlet below the reach, so each lateral
    Fourier mode is a tridiagonal system in depth: the same rows as the object's matrix for a boundary parallel to
    a grid plane, solved exactly."""
    n_lat = 2 * int(math.ceil(reach / h)) + 8
    n_z = int(math.ceil((reach + max(read_depths)) / h)) + 4
    m = np.fft.fftfreq(n_lat)
    lam = (4.0 / h**2) * (np.sin(np.pi * m)[:, None] ** 2 + np.sin(np.pi * m)[None, :] ** 2)
    link = diffusion / h**2
    rng = np.random.default_rng(seed)
    edges = np.arange(0.0, reach + 0.25 * h, 0.25 * h)
    total, count = np.zeros(len(edges) - 1), np.zeros(len(edges) - 1)
    for delta in OFFSETS:
        # node k at (k + delta) h inside the extrapolated boundary (the source at Eq. D5's depth, the reads at Eq. D4's)
        diagonal = np.broadcast_to(2.0 * link + sigma_a + diffusion * lam.ravel(), (n_z, lam.size)).copy()
        diagonal[0] += link * (1.0 / delta - 1.0)  # the link to the boundary, a fraction delta of a cell away
        src_nodes, src_w = _depth_weights(source_depth / h - delta, delta, h, source_depth)
        reads = [_depth_weights(d / h - delta, delta, h, d) for d in read_depths]
        rhs = np.zeros((n_z, lam.size, 2))
        rhs[src_nodes[0], :, 0] = 1.0 / h**3
        rhs[src_nodes[1], :, 1] = 1.0 / h**3
        modes = _thomas(-link, diagonal, rhs)  # (n_z, modes, 2)
        fields = np.fft.ifft2(modes.reshape(n_z, n_lat, n_lat, 2), axes=(1, 2)).real  # unit source at (0, 0)
        surface = sum(weight * src_w[a] * read_w[b] * fields[read_nodes[b], :, :, a]
                      for weight, (read_nodes, read_w) in zip(read_weights, reads) for a in (0, 1) for b in (0, 1))
        r = rng.uniform(0.0, reach, READS)
        phi = rng.uniform(0.0, 2.0 * np.pi, READS)
        source = rng.uniform(0.0, 1.0, (READS, 2))  # the entry point within its cell
        read = source + (r / h)[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        value = np.zeros(READS)
        base = np.floor(read).astype(np.int64)
        frac = read - base
        for sx in (0, 1):
            for sy in (0, 1):
                ws = (source[:, 0] if sx else 1 - source[:, 0]) * (source[:, 1] if sy else 1 - source[:, 1])
                for rx in (0, 1):
                    for ry in (0, 1):
                        wr = (frac[:, 0] if rx else 1 - frac[:, 0]) * (frac[:, 1] if ry else 1 - frac[:, 1])
                        ix, iy = (base[:, 0] + rx - sx) % n_lat, (base[:, 1] + ry - sy) % n_lat
                        value += ws * wr * surface[ix, iy]
        which = np.minimum(np.searchsorted(edges, r, side="right") - 1, len(total) - 1)
        total += np.bincount(which, value, len(total))
        count += np.bincount(which, minlength=len(total))
    centre = 0.5 * (edges[1:] + edges[:-1])
    mean = np.minimum.accumulate(np.maximum(total / np.maximum(count, 1), 0.0))
    return np.concatenate([[0.0], centre]), np.concatenate([[mean[0]], mean])


def multigrid(matrix):
    """pyamg's smoothed-aggregation hierarchy of the symmetric positive definite ``matrix``, the same every time:
    its smoother's spectral radius is estimated from numpy's global random numbers, seeded here and restored."""
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


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def _deposit(points, values, origin, h, index, depth, rhs, held):
    """``rhs[n] += w_n values[k]`` over every point's :func:`moment_weights` (one thread: the points share nodes)."""
    nodes, weights = np.zeros(8, dtype=np.int64), np.zeros(8)
    for k in range(len(points)):
        held[k] = moment_weights(points[k], origin, h, index, depth, nodes, weights)
        for corner in range(8):
            rhs[nodes[corner]] += weights[corner] * values[k]


@numba.njit(parallel=True, cache=True)
def _gather(points, field, origin, h, index, depth, out, held):
    """``out[k] = sum_n w_n field[n]`` over each point's :func:`moment_weights`."""
    for k in numba.prange(len(points)):
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


class VolumeTransport(Transport):
    """Eq. 1 summed by the multiscale transport, corrected by the diffusion equation solved on the object's volume
    (Eq. D2); see the module docstring. Needs the samples' normals."""

    name = "volume"
    sums_eq1 = False
    parameters = (
        Parameter("accuracy", float, 0.01, "Relative error aimed at by the sums of Eq. 1 (as the multiscale "
                  "transport's accuracy).", low=0.0, low_open=True, high=0.5),
        Parameter("spacing", float, 0.0, "Grid spacing of the diffusion solve in mm; 0 sets it from the material "
                  "and the object (half the shortest diffusion length, 1/64 to 1/24 of the object's extent).",
                  low=0.0),
        Parameter("memory_limit", float, None, "Bytes the grid and the sums may use (default: what the machine has "
                  "available).", low=0.0, low_open=True, exposed=False),
    )

    memory_advice = "set a coarser spacing for the volume transport, or use the multiscale transport"

    @classmethod
    def spacing_for(cls, bounds, profile, params):
        """The grid spacing (mm) for samples within ``bounds`` (2, 3)."""
        lo, hi = np.asarray(bounds, dtype=np.float64)
        return params.get("spacing") or auto_spacing(profile, float(np.max(hi - lo)))

    @classmethod
    def planned_bytes(cls, bounds, profile, count, params):
        """The grid (:data:`BYTES_PER_NODE` per node) and the two multiscale sums (their far meshes)."""
        lo, hi = np.asarray(bounds, dtype=np.float64)
        h = cls.spacing_for(bounds, profile, params)
        _, shape = grid_shape(lo, hi, h, float(np.max(coefficients(profile, h).z_b)) + 2 * h)
        sums = MultiscaleTransport.planned_bytes(bounds, profile, count, {"accuracy": params.get("accuracy", 0.01)})
        return int(BYTES_PER_NODE * math.prod(shape) + 2 * sums)

    def __init__(self, samples, profile, frame=None, **params):
        super().__init__(samples, profile, frame, **params)
        if len(samples) and samples.normal is None:
            raise ConvsssError("the volume transport needs the samples' normals")
        self.spacing, self.corrected, self._sd = 0.0, np.zeros(3, dtype=bool), np.zeros((0, 0, 0))
        self.coefficients, self._channels = coefficients(profile, 1.0), [(None, None, None)] * 3
        self._half = self._flat = None  # the two sums of Eq. D2, built by the first _build, relit by the others
        if len(samples):  # without samples there is nothing to solve for: Eq. 1 (of nothing)
            self._set_up()
        self._build()

    def _set_up(self):
        """The grid, its matrices and multigrid hierarchies and the half-space responses, for the channels whose
        diffusion length the grid resolves (none: Eq. 1, and no grid is built)."""
        view = self._to_view(self.samples.position)
        normal = self._to_view(self.samples.normal, vectors=True)
        lo, hi = view.min(axis=0), view.max(axis=0)
        self.spacing = h = self.spacing_for((lo, hi), self.profile, self.params)
        self.coefficients = k = coefficients(self.profile, h)
        reach = self._reach(h, float(np.linalg.norm(hi - lo)))
        with np.errstate(divide="ignore"):
            self.corrected = 1.0 / k.sigma_tr >= RESOLVED_LENGTH * h
        self._view, self._normal = view, normal
        if not self.corrected.any():
            return
        with self.timings("domain"):
            self._surface = Surface(view, normal, h)
            self._origin, self._sd = self._domain(lo, hi, h, reach)
        self._channels = []
        for c in range(3):
            if not self.corrected[c]:
                self._channels.append((None, None, None))
                continue
            with self.timings("matrix"):
                matrix, index = assemble(self._sd, k.z_b[c], k.diffusion[c], k.absorption[c], h)
            with self.timings("multigrid"):
                solver = multigrid(matrix) if matrix.shape[0] else None
            self._channels.append((index, k.z_b[c] - self._sd, solver))
        with self.timings("response"):
            self._response = self._half_space(h, reach)

    def _domain(self, lo, hi, h, reach):
        """The grid's origin and the signed distance at its nodes. Where the samples bound nothing (an open sheet,
        the grid's border inside), the medium goes on: the grid grows by the response's reach on those sides."""
        pad = float(np.max(self.coefficients.z_b)) + 2 * h
        low, high = lo - pad, hi + pad
        for grown in (False, True):
            origin, shape = grid_shape(low, high, h, 0.0)
            check_memory(BYTES_PER_NODE * math.prod(shape), "the volume transport's grid", self.memory_advice,
                         self.params["memory_limit"])
            sd = self._surface.signed_distance_on(origin, h, shape, pad + h)
            inside = sd < pad - 2 * h
            open_low = np.array([inside.take(0, axis=d).any() for d in range(3)])
            open_high = np.array([inside.take(-1, axis=d).any() for d in range(3)])
            if grown or not (open_low.any() or open_high.any()):
                return origin, sd
            grow = self._depth_of_medium(reach)
            low, high = low - grow * open_low, high + grow * open_high

    def _reach(self, h, diagonal):
        """How far the half-space response reaches (mm): the profile's reach (:data:`RESPONSE_TAIL`) or the samples'
        diagonal, whichever is shorter (no two samples are farther apart), and at most :data:`MAX_REACH` cells."""
        return min(float(np.max(self.profile.radius_energy(RESPONSE_TAIL))), diagonal + h, MAX_REACH * h)

    def _depth_of_medium(self, reach):
        """How far an open sheet's medium is grown (mm): :data:`OPEN_DEPTH` diffusion lengths (the field falls by
        ``e^-6`` there and back), at most the reach."""
        with np.errstate(divide="ignore"):
            length = float(np.max(1.0 / self.coefficients.sigma_tr))
        return min(reach, OPEN_DEPTH * length)

    def _half_space(self, h, reach):
        """``beta T`` of Eq. D2 as a tabulated profile (``T`` with the source gain of Eq. D5). A channel not corrected
        holds no flux in the second sum, but its response is solved all the same: it sets the sum's scales (with
        the corrected channels' alone, coarser, the slab's far face comes out too dark)."""
        k = self.coefficients
        key = (k.key(), h, reach)
        cached = RESPONSES.get(key)
        if cached is None:
            tables = [half_space_response(k.diffusion[c], k.absorption[c], k.source_depth[c], k.read_depths[:, c],
                                          k.read_weights[:, c], h, reach) for c in range(3)]
            cached = (tables[0][0], np.stack([t[1] for t in tables], axis=1))
            RESPONSES.put(key, cached)
        r, response = cached
        return TabulatedProfile(r, response * (k.beta * k.source_gain), name="half-space response")

    def _build(self):
        """What depends on the flux: the solves of Eq. D1 and the two sums of Eq. D2."""
        flux = self.samples.flux
        held = np.zeros_like(flux)
        self._fields = []
        k = self.coefficients
        for c, (_, _, solver) in enumerate(self._channels):
            if solver is None:
                self._fields.append(np.zeros(0))
                continue
            with self.timings("sources"):  # each sample's source, k.source_depth inside the boundary (Eq. D5)
                rhs, has = self._place(c, self._view, self._normal, k.source_depth[c], flux[:, c])
                held[:, c] = np.where(has, flux[:, c], 0.0)
            with self.timings("solve"):
                field = solver.solve(rhs / self.spacing**3, x0=np.zeros_like(rhs), tol=1e-8, accel="cg", maxiter=200)
                self._fields.append(field)
        with self.timings("sums"):  # relit: the sums keep their clusters (the samples' places are the same)
            if self._half is not None:
                self._half = self._half.relit(self.samples.irradiance)
                self._flat = None if self._flat is None else self._flat.relit(held / self.samples.area[:, None])
                return
            ms = {"accuracy": self.params["accuracy"], "memory_limit": self.params["memory_limit"]}
            self._half = MultiscaleTransport(self.samples, self.profile, self.frame, **ms)
            held_samples = IrradianceSamples(self.samples.position, self.samples.area,
                                             held / self.samples.area[:, None], self.samples.normal)
            self._flat = MultiscaleTransport(held_samples, self._response, self.frame, **ms) \
                if self.corrected.any() else None

    def _place(self, c, points, normal, distance, flux=None, field=None):
        """Channel ``c``'s sources (``flux`` given: returns the right-hand side and which samples are held) or reads
        (``field`` given: returns the values and which points are held) at ``distance`` inside the extrapolated
        boundary under surface ``points`` (sources where Eq. D5 puts them, reads at Eq. D4's depths), with
        :func:`moment_weights`."""
        index, depth, solver = self._channels[c]
        at = points - (distance - self.coefficients.z_b[c]) * normal
        if flux is not None:
            return deposit(at, flux, self._origin, self.spacing, index, depth, solver.levels[0].A.shape[0])
        return gather(at, field, self._origin, self.spacing, index, depth)

    def _relit(self, samples):
        """The same grid, matrices, multigrid hierarchies and responses; the solves and sums again."""
        return self._rebuilt(samples)

    def _exitance(self, points):
        out = self._half.exitance(points)
        view = self._to_view(points)
        if self._flat is None:
            return out
        correction = -self._flat.exitance(points)
        k = self.coefficients
        with self.timings("read_back"):
            normal = self._surface.normal_near(view)
            for c in np.flatnonzero([solver is not None for _, _, solver in self._channels]):
                slope, held = 0.0, np.ones(len(view), dtype=bool)
                for depth, weight in zip(k.read_depths[:, c], k.read_weights[:, c]):  # Eq. D4
                    value, has = self._place(c, view, normal, depth, field=self._fields[c])
                    slope, held = slope + weight * value, held & has
                correction[:, c] += k.beta[c] * k.source_gain[c] * slope
                correction[~held, c] = 0.0
        return np.maximum(out + correction, 0.0)

    @property
    def stats(self):
        """The base stats plus the grid's spacing, shape and unknowns per channel, Eq. D4's ``beta``, the corrected
        channels and the two sums' stats."""
        return {**super().stats, "spacing_mm": self.spacing, "grid": list(self._sd.shape),
                "unknowns": [0 if index is None else int((index >= 0).sum()) for index, _, _ in self._channels],
                "beta": self.coefficients.beta.tolist(), "corrected": self.corrected.tolist(),
                "sums": [t.stats for t in (self._half, self._flat) if t is not None]}


register_transport(VolumeTransport)
