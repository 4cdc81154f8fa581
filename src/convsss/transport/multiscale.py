"""The multi-scale transport: the exact sum's accuracy at any object size, by splitting the profile by distance.

As particle–particle/particle–mesh N-body codes and multilevel summation split a force, the profile is split at
radii ``r_0 < r_1 < ... < r_L = r_c``, each twice the last, into a core, ``L`` middle bands and a far field,
``R_d = R_core + R_1 + ... + R_L + R_far``, each piece smooth at the scale of its inner split radius. A split at
``r`` replaces ``f`` inside ``r`` by a cap,

    cap_r[f](x) = a + b x^2,   a, b per channel matching the value and slope of f at r,                 (Eq. M1)

so that ``f - cap_r[f]`` is zero from ``r`` on and ``cap_r[f]`` is C^1:

    R_far  = R_d beyond r_c, cap_{r_c}[R_d] inside;                                                      (Eq. M2)
    R_k    = f_k beyond r_{k-1}, cap_{r_{k-1}}[f_k] inside (zero from r_k on), f_k = R_d - R_far - R_L - ... - R_{k+1};
    R_core = f_0 (zero from r_0 on; >= 0 for a profile convex inside r_0, such as the dipole).

One middle band (``L = 1``) unless the far mesh would hold more than :data:`FAR_CELLS` cells (an object many
profile widths across): each further band doubles ``r_c`` and the mesh spacing.

- **Far field** ``sum_i R_far(|x - x_i|) Phi_i``: smooth at the scale ``r_c``, so it needs neither image resolution
  nor thin layers. The flux is deposited on a voxel mesh of spacing ``h`` aligned with the camera (the
  paper's layers with spacing ``h`` in x, y *and* depth: its §7 "layers with variable resolution"), convolved with
  ``R_far`` on the mesh by 3-D FFTs (the layer mixing of Eq. 6 is itself a convolution along depth; zero-padded, so
  nothing wraps around) and read back, with the weights of a quadratic B-spline (each point spread over the 3^3
  nodes around it, the triangular-shaped cloud of particle-mesh codes). The kernel's spectrum is divided by the
  transfer function of the deposit and the read-back (``sinc^6`` per axis), which removes their blur to second order.
- **Middle bands**: band ``k`` summed directly (through a cell list) at the corners of the voxels of side
  ``2^(k-1) g`` that hold clusters and that queries fall in, each corner once, when first needed, and read back
  trilinearly: it is smooth at the scale ``r_{k-1} > 2^(k-1) g``. (At a query in any other voxel, or among queries
  sparser than the voxels, it is summed where the query is.)
- **Core**: summed directly at each query point over the samples within ``r_0``.

Both direct sums run over *clusters*: the samples merged in cubes of side ``s`` for the core, those clusters merged
again in cubes of side ``2^k s`` for the smoother band ``k`` (flux summed, placed at its centroid; the two sides of a
thin sheet are kept apart by the normals' directions). The render's samples are many
times denser than the profile's core is wide, so the sums lose almost nothing (the error is second order in ``s``
and cancels where the irradiance is smooth) for a small fraction of the cost.

One knob, ``accuracy`` (the relative error aimed at), sets every length from the profile's core width ``w`` (the
radius where ``R_d`` falls to half its peak, smallest over the channels: about 0.8 mean free paths for the dipole);
see :func:`scales`. The lengths are common to the channels, sized by the narrowest.

**The local limit.** What the image cannot show need not be resolved. Given the pixel footprint ``f`` where the
object is seen (``cell_size``), the lengths are set by ``w' = max(w, f / 3)``; where ``w' > w`` (a dense medium, a
small image, a sharp-peaked model such as photon beam diffusion's) the core is narrower than the samples are apart,
and its sum is replaced by its local limit, its energy times the irradiance averaged over the samples around
the query with a smooth kernel of radius ``r_0``:

    M_core(x) = E_core sum_i K_i Phi_i / sum_i K_i A_i,   K_i = (1 - |x - x_i|^2 / r_0^2)^2,
    E_core = ∫ R_core dA,                                                                                (Eq. M3)

``M = E_core E(x) + O(r_0^2 ∇^2 E)`` at the scale of the pixel (``K``'s rms radius is ``r_0 / 2 = f / 2``). As a
ratio it keeps the energy wherever the samples lie (a concave or thin part gathers more surface within ``r_0``
than a plane: a sum of ``E_core K`` would be too bright there) and it has little noise. The far
mesh and the samples follow the image (:meth:`MultiscaleTransport.sample_area`), not the mean free path. A far
field holding less than ``accuracy / 10`` of every channel's energy is dropped (:func:`far_energy`).
"""

import math
from dataclasses import dataclass

import numba
import numpy as np
import scipy.fft

from ..errors import ConvsssError
from ..hashtable import capacity, empty, grown, probe
from ..memory import check_memory
from ..parameters import Parameter
from .base import Transport, register_transport
from .kernels import KernelCache, profile_key
from .radial import RadialTable, profile_lookup

#: Entries of the core and middle-band tables, uniform in ``r^2``.
BAND_TABLE = 4096
#: The far kernel is cut where all but this fraction of the profile's energy is held.
FAR_TAIL = 1e-5
#: Far-field kernel spectra, keyed by (profile, r_c, h, FFT shape).
SPECTRA = KernelCache()
#: The local limit's scale: the lengths follow ``max(w, LOCAL_SCALE f)`` for a pixel footprint ``f`` (Eq. M3), so
#: ``r_0 = f``. (Chosen against the resolved sum, whose means per channel it keeps slightly low; at ``f / 2`` they
#: spread further.)
LOCAL_SCALE = 1.0 / 3.0
#: A far field holding less than this share of ``accuracy`` of every channel's energy is dropped.
FAR_SKIP = 0.1
#: The far mesh's FFT cells at most (600 MB of spectra), where more middle bands can keep it so. Each band adds its
#: interpolation error (two bands where one fits raise the error against the exact sum, ``convsss bench accuracy``),
#: so a band is added only where the mesh would not fit otherwise.
FAR_CELLS = 1 << 24
#: Middle bands at most (each doubles the far mesh's spacing).
MAX_LEVELS = 24
#: Cubes of a cell list at most (their offsets: 128 MiB), beyond which the cubes grow.
CELL_LIST_CUBES = 1 << 24


def core_width(profile):
    """The profile's core width ``w`` in mm: the smallest radius, over the channels where it is not zero, where
    ``R_d`` falls to half its peak (a profile with an infinite peak uses a quarter of its half-energy radius; one
    that is zero in every channel, 1 mm: it has nothing to resolve)."""
    peak = np.asarray(profile(0.0), dtype=np.float64)
    live = peak > 0
    if not live.any():
        return 1.0
    if np.all(np.isfinite(peak)):
        w = float(np.min(np.asarray(profile.radius_below(0.5))[live]))
    else:
        w = 0.25 * float(np.min(np.asarray(profile.radius_energy(0.5))[live]))
    if not math.isfinite(w) or w <= 0:
        raise ConvsssError("multiscale transport: the profile has no finite core width")
    return w


def far_reach(profile):
    """Per channel, the radius holding all but :data:`FAR_TAIL` of the profile's energy (0 where it is zero)."""
    live = np.asarray(profile(0.0), dtype=np.float64) > 0
    return np.where(live, np.asarray(profile.radius_energy(FAR_TAIL), dtype=np.float64), 0.0)


@dataclass(frozen=True)
class Scales:
    """The lengths of the multi-scale transport in mm: cluster side ``s`` of the core sums, that of the first middle
    band, core radius ``r_0``, voxel side ``g`` of the first band, split radius ``r_c`` and far mesh spacing ``h``;
    ``levels`` the middle bands ``L`` between ``r_0`` and ``r_c = 2^L r_0`` (:meth:`band`); ``local`` where the
    lengths follow the pixel footprint rather than the profile (Eq. M3)."""

    cluster: float
    band_cluster: float
    core: float
    voxel: float
    split: float
    mesh: float
    levels: int = 1
    local: bool = False

    @property
    def radii(self):
        """``r_0 < r_1 < ... < r_L = r_c``, each twice the last."""
        return tuple(self.core * 2**k for k in range(self.levels + 1))

    def band(self, k):
        """Middle band ``k`` (1 to ``levels``): its outer radius ``r_k``, cluster side and voxel side, each ``2^(k-1)``
        times the first band's."""
        return self.core * 2**k, self.band_cluster * 2 ** (k - 1), self.voxel * 2 ** (k - 1)


def scales(profile, accuracy, cell_size=None, levels=1):
    """The :class:`Scales` for ``accuracy`` from the profile's core width ``w`` (:func:`core_width`), or from
    ``LOCAL_SCALE`` times the pixel footprint ``cell_size`` (mm) where that is larger (the local limit, Eq. M3), with
    ``levels`` middle bands.

    The errors are second order in the cluster sides, the voxel side and the mesh spacing relative to the profile's
    features, so these grow as ``sqrt(accuracy)``: ``s = w k``, ``2 s`` for the middle band (smooth at ``r_0``, it
    needs no finer sources: on the benchmark scenes the default's mean error grows a little and the band's corner
    sums get much cheaper), ``g = 0.75 w k``, ``h = 2.5 w k`` with ``k = sqrt(accuracy / 0.01)``; the split radii
    stay at ``r_0 = 3 w`` and ``r_c = 6 w``. (The far field's quadratic B-splines, against trilinear tents at
    ``h = 2 w k``: a lower mean error on all five benchmark scenes, with half the mesh cells.) The factors were
    chosen by measurement against the exact sum (``convsss bench accuracy``) to stay below ``accuracy`` on renders.
    Each further band doubles ``r_c`` and ``h`` (the far field is smooth at ``r_c``): band ``k`` is smooth at
    ``r_{k-1}`` and is summed as the first is at twice the lengths of the band before it.
    """
    w = core_width(profile)
    local = cell_size is not None and LOCAL_SCALE * cell_size > w
    w = LOCAL_SCALE * cell_size if local else w
    grow = math.sqrt(accuracy / 0.01)
    wide = 2 ** (levels - 1)
    return Scales(cluster=w * grow, band_cluster=2.0 * w * grow, core=3.0 * w, voxel=0.75 * w * grow,
                  split=6.0 * w * wide, mesh=2.5 * w * grow * wide, levels=levels, local=local)


def cap(fn, r):
    """Eq. M1: ``(a, b)`` per channel, shape (3,) each, with ``a + b r^2`` matching ``fn`` (radii -> (..., 3)) in
    value and slope at ``r``."""
    step = 1e-4 * r
    value = np.asarray(fn(np.float64(r)), dtype=np.float64)
    slope = (np.asarray(fn(np.float64(r + step))) - np.asarray(fn(np.float64(r - step)))) / (2 * step)
    b = slope / (2 * r)
    return value - b * r * r, b


def split(profile, radii, local=False):
    """Eq. M2 over the radii ``r_0 < ... < r_L = r_c`` (:attr:`Scales.radii`): the far cap ``(a, b)``, the core table
    (BAND_TABLE, 3) uniform in ``r^2`` on ``[0, r_0^2]``, and the ``L`` middle bands' tables, band ``k`` on
    ``[0, r_k^2]`` (the residual less the caps beyond ``r_{k-1}``, its cap inside), each table's last entry 0;
    ``local``: the core as its energy over the smooth kernel of Eq. M3."""
    caps = [cap(profile, radii[-1])]  # the far cap, then each band's, outermost first

    def residual(r, caps):  # R_d less the caps, inside the innermost of their radii
        r = np.asarray(r, dtype=np.float64)
        out = np.asarray(profile(r), dtype=np.float64)
        for a, b in caps:
            out = out - (a + b * r[..., None] ** 2)
        return out

    bands = []
    for outer, inner in zip(radii[:0:-1], radii[-2::-1]):
        held = list(caps)
        caps.append(cap(lambda r, held=held: residual(r, held), inner))
        r2 = np.linspace(0.0, outer * outer, BAND_TABLE)[:, None]
        band = np.where(r2 < inner * inner, caps[-1][0] + caps[-1][1] * r2, residual(np.sqrt(r2[:, 0]), held))
        band[-1] = 0.0
        bands.insert(0, np.ascontiguousarray(band))
    r_0 = radii[0]
    r2 = np.linspace(0.0, r_0 * r_0, BAND_TABLE)[:, None]
    if local:
        # Eq. M3: E_core = the energy within r_0 less the caps' there (∫ 2 pi r (a + b r^2) dr = pi (a r^2 + b r^4/2)).
        held = sum(a * r_0**2 + 0.5 * b * r_0**4 for a, b in caps)
        energy = np.asarray(profile.energy_within(r_0), dtype=np.float64) - np.pi * held
        core = energy * 3.0 / (np.pi * r_0**2) * (1.0 - r2 / r_0**2) ** 2
    else:
        core = residual(np.sqrt(r2[:, 0]), caps)
    core[-1] = 0.0
    return caps[0], np.ascontiguousarray(core), bands


def far_energy(profile, r_c, far):
    """Per channel, the share of the profile's energy that its far field ``R_far`` (Eq. M2, cap ``far``) holds."""
    inner = np.pi * (far[0] * r_c**2 + 0.5 * far[1] * r_c**4)
    total = np.asarray(profile.total_reflectance, dtype=np.float64)
    outer = total - np.asarray(profile.energy_within(r_c), dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total > 0, (inner + outer) / np.where(total > 0, total, 1.0), 0.0)


def summed_area(profile, radii, far, core, bands):
    """The effective area (:meth:`~convsss.profiles.Profile.effective_area`, uncut: the tables have no singular
    peak) of the profile as the bands sum it, ``(∫ R dA)^2 / ∫ R^2 dA`` per channel (mm^2, shape (3,)), for the
    ``far`` cap and the ``core`` and ``bands`` tables of :func:`split` over ``radii``: with the core of Eq. M3, it
    grows as the pixel footprint squared."""
    u = np.linspace(0.0, radii[-1] ** 2, BAND_TABLE)
    inner = far[0] + far[1] * u[:, None]
    for radius, table in zip(radii, [core, *bands]):
        inner = inner + np.stack([np.interp(u, np.linspace(0.0, radius**2, BAND_TABLE), table[:, c], right=0.0)
                                  for c in range(3)], axis=1)
    second = np.pi * np.trapezoid(inner**2, u, axis=0)  # dA = pi d(r^2)
    r_scale, ds, values = profile.radial_table()
    r = r_scale * np.expm1(ds * np.arange(len(values)))
    out = r >= radii[-1]
    second += np.trapezoid(2.0 * np.pi * r[out, None] * values[out] ** 2, r[out], axis=0)
    total = np.asarray(profile.total_reflectance, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(second > 0, total * total / np.where(second > 0, second, 1.0), np.inf)


@numba.njit(parallel=True, fastmath=True, cache=True)
def _far_octant(h, shape, r_c, a, b, reach, r_scale, ds, table):
    """``R_far`` (Eq. M2) at the mesh offsets ``h (i, j, m)``, ``0 <= i, j, m < shape``; 0 from ``reach`` on."""
    out = np.zeros((3, shape[0], shape[1], shape[2]))
    r_c2 = r_c * r_c
    for i in numba.prange(shape[0]):
        for j in range(shape[1]):
            for m in range(shape[2]):
                r2 = h * h * (i * i + j * j + m * m)
                for c in range(3):
                    if r2 < r_c2:
                        out[c, i, j, m] = a[c] + b[c] * r2
                    elif r2 < reach[c] * reach[c]:
                        out[c, i, j, m] = profile_lookup(np.sqrt(r2), r_scale, ds, table, c)
    return out


def even_fast_len(n):
    """The smallest length >= ``n`` that is even and fast for ``scipy.fft`` (:func:`far_spectrum` needs it even)."""
    n = scipy.fft.next_fast_len(int(n), real=True)
    while n % 2:
        n = scipy.fft.next_fast_len(n + 1, real=True)
    return n


def far_spectrum(radial, r_c, a, b, h, fft_shape, reach):
    """The spectrum (``rfftn``) of ``R_far`` (Eq. M2) on a zero-padded mesh of ``fft_shape`` (every length even;
    negative offsets wrapped to the end) divided by the transfer function of the deposit and read-back,
    ``prod_axes sinc^6(f)`` (``f`` in cycles per cell, each quadratic B-spline being ``sinc^3``), so that on average
    over where the samples and the queries fall in their cells the mesh reproduces ``R_far`` rather than its blur.
    Per channel: (3, nx, ny, nz // 2 + 1) float32 (real: the kernel is even along every axis).

    An even sequence's DFT of even length ``N`` is the type-I DCT of its first ``N/2 + 1`` entries, so the transform
    runs on the kernel's first octant alone (1/8 of the mesh) and the spectrum is unfolded by ``X[N - k] = X[k]``.
    """
    half = [n // 2 + 1 for n in fft_shape]
    octant = _far_octant(h, np.array(half), r_c, a, b, reach, radial.r_scale, radial.ds, radial.values)
    folded = scipy.fft.dctn(octant, type=1, axes=(1, 2, 3), workers=-1)
    window = [np.sinc(np.arange(m) / n) ** 6 for m, n in zip(half, fft_shape)]  # even too: folded the same way
    folded /= window[0][:, None, None] * window[1][None, :, None] * window[2][None, None, :]
    index = [np.minimum(np.arange(n), n - np.arange(n)) for n in fft_shape[:2]]
    return folded.astype(np.float32)[:, index[0][:, None], index[1][None, :], :]


def far_mesh(sc, reach, lo, hi):
    """The far field's mesh for samples within ``lo``, ``hi`` (3,) of the view frame, :class:`Scales` ``sc`` and the
    kernel's ``reach`` per channel: ``(origin, shape, fft_shape)``. The mesh reaches ``r_c`` past the samples; its
    FFT is zero-padded by the reach (nothing wraps around)."""
    h = sc.mesh
    origin = np.asarray(lo, dtype=np.float64) - sc.split
    shape = np.ceil((np.asarray(hi, dtype=np.float64) + sc.split - origin) / h).astype(np.int64) + 2
    pad = np.minimum(shape - 1, math.ceil(float(np.max(reach)) / h))
    return origin, shape, tuple(even_fast_len(int(n + q)) for n, q in zip(shape, pad))


def far_bytes(fft_shape):
    """The spectra of the grid (complex) and of the kernel (real), 3 channels, 4 bytes a number: at most 36 bytes per
    cell of the padded mesh (the grid and the field hold only the unpadded cells)."""
    return 36 * int(np.prod(np.asarray(fft_shape, dtype=np.float64)))


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


def padded_convolution(grid, kernel_hat, fft_shape):
    """The cyclic convolution on ``fft_shape`` of ``grid`` (C, nx, ny, nz), zero-padded to it, with a kernel of
    spectrum ``kernel_hat`` (``rfftn`` over the last three axes), read back on the grid's own cells.

    The same as ``irfftn(rfftn(grid padded) * kernel_hat)[:, :nx, :ny, :nz]``, with the transforms along each axis
    run only over the lines that hold data or are read back (about 0.6 times the work for a grid padded to twice
    its size per axis).
    """
    _, nx, ny, nz = grid.shape
    spectrum = scipy.fft.rfft(grid, n=fft_shape[2], axis=3, workers=-1)
    spectrum = scipy.fft.fft(spectrum, n=fft_shape[1], axis=2, workers=-1, overwrite_x=True)
    spectrum = scipy.fft.fft(spectrum, n=fft_shape[0], axis=1, workers=-1, overwrite_x=True)
    spectrum *= kernel_hat
    spectrum = scipy.fft.ifft(spectrum, axis=1, workers=-1, overwrite_x=True)[:, :nx]
    spectrum = scipy.fft.ifft(spectrum, axis=2, workers=-1, overwrite_x=True)[:, :, :ny]
    return np.ascontiguousarray(scipy.fft.irfft(spectrum, n=fft_shape[2], axis=3, workers=-1)[..., :nz])


def sheet_side(normal):
    """Per sample, the axis and sign of its normal's largest component, ``2 axis + (component > 0)`` in 0-5 (all 0
    without normals): clusters never merge samples of different sides, so the two sides of a thin sheet stay apart."""
    if normal is None:
        return None
    return _sheet_side(np.ascontiguousarray(normal, dtype=np.float64))


@numba.njit(cache=True)
def _sheet_side(normal):
    side = np.empty(normal.shape[0], dtype=np.int64)
    for k in range(normal.shape[0]):
        axis = 0
        for a in (1, 2):
            if abs(normal[k, a]) > abs(normal[k, axis]):
                axis = a
        side[k] = 2 * axis + (normal[k, axis] > 0)
    return side


@numba.njit(cache=True)
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


@numba.njit(cache=True)
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


@numba.njit(cache=True)
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


@numba.njit(cache=True)
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


@numba.njit(cache=True)
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


@numba.njit(inline="always")
def _corner(c, fu, fv, fw):
    """Corner ``c`` (0-7, bits ``di dj dm``) of a cell and its trilinear weight at the fractions ``fu, fv, fw``."""
    di, dj, dm = c >> 2, (c >> 1) & 1, c & 1
    return di, dj, dm, (fu if di else 1.0 - fu) * (fv if dj else 1.0 - fv) * (fw if dm else 1.0 - fw)


@numba.njit(inline="always")
def _spline_node(u, n):
    """The mesh node nearest to ``u`` (in cells; kept one node inside a mesh of ``n``) and the offset from it."""
    i = min(max(int(np.floor(u + 0.5)), 1), n - 2)
    return i, u - i


@numba.njit(inline="always")
def _spline(d, t):
    """The quadratic B-spline's weight of node ``t - 1`` (``t`` in 0-2) around the nearest node, at offset ``d``."""
    if t == 0:
        return 0.5 * (0.5 - d) ** 2
    if t == 1:
        return 0.75 - d * d
    return 0.5 * (0.5 + d) ** 2


@numba.njit(cache=True)
def _deposit(view, flux, origin, h, grid):
    """Quadratic B-spline (triangular-shaped cloud) deposit of ``flux`` (C, 3) at ``view`` (C, 3) on ``grid``
    (3, nx, ny, nz): each point's flux spread over the 3^3 nodes around its nearest."""
    for k in range(view.shape[0]):
        i, du = _spline_node((view[k, 0] - origin[0]) / h, grid.shape[1])
        j, dv = _spline_node((view[k, 1] - origin[1]) / h, grid.shape[2])
        m, dw = _spline_node((view[k, 2] - origin[2]) / h, grid.shape[3])
        for a in range(3):
            for b in range(3):
                wab = _spline(du, a) * _spline(dv, b)
                for e in range(3):
                    wt = wab * _spline(dw, e)
                    for c in range(3):
                        grid[c, i + a - 1, j + b - 1, m + e - 1] += wt * flux[k, c]


@numba.njit(parallel=True, cache=True)
def _interpolate(view, origin, h, field, out):
    """``out[k] +=`` ``field`` (3, nx, ny, nz) read back at ``view[k]`` with the deposit's quadratic B-spline
    weights (a point farther than a node from the mesh's border reads it there)."""
    nx, ny, nz = field.shape[1], field.shape[2], field.shape[3]
    for k in numba.prange(view.shape[0]):
        i, du = _spline_node(min(max((view[k, 0] - origin[0]) / h, 1.0), nx - 2.0), nx)
        j, dv = _spline_node(min(max((view[k, 1] - origin[1]) / h, 1.0), ny - 2.0), ny)
        m, dw = _spline_node(min(max((view[k, 2] - origin[2]) / h, 1.0), nz - 2.0), nz)
        for a in range(3):
            for b in range(3):
                wab = _spline(du, a) * _spline(dv, b)
                for e in range(3):
                    wt = wab * _spline(dw, e)
                    for c in range(3):
                        out[k, c] += wt * field[c, i + a - 1, j + b - 1, m + e - 1]


@numba.njit(cache=True)
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


@numba.njit(inline="always")
def _home_cube(point, origin, size):
    """The cube of side ``size`` from ``origin`` that ``point`` (3,) falls in: ``(i, j, m)``."""
    return (int(np.floor((point[0] - origin[0]) / size)), int(np.floor((point[1] - origin[1]) / size)),
            int(np.floor((point[2] - origin[2]) / size)))


@numba.njit(inline="always")
def _column(i, j, cm, reach, dims, starts):
    """The range of sorted clusters in the cubes ``(i, j, cm - reach .. cm + reach)`` of a :class:`CellList` (one
    run: its cubes are in x-major order)."""
    base = (i * dims[1] + j) * dims[2]
    return starts[base + min(max(cm - reach, 0), dims[2])], starts[base + max(min(cm + reach + 1, dims[2]), 0)]


@numba.njit(parallel=True, fastmath=True, cache=True)
def _band_sum(view, position, flux, starts, origin, size, dims, reach, table, r_c2, out):
    """``out[k] += sum_{|x_k - x_j| < r} R(|x_k - x_j|) Phi_j`` over the clusters (sorted into cubes of side
    ``size >= r / reach``), for a band ``R`` tabulated uniformly in ``r^2`` on ``[0, r^2 = r_c2]``."""
    scale = (table.shape[0] - 1) / r_c2
    for k in numba.prange(view.shape[0]):
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


@numba.njit(parallel=True, fastmath=True, cache=True)
def _local_sum(view, position, flux, area, starts, origin, size, dims, reach, r_02, energy, out):
    """Eq. M3: ``out[k] += E_core`` times the irradiance around ``view[k]`` averaged over the clusters with the
    weights ``(1 - d^2 / r_0^2)^2``, ``sum w_j Phi_j / sum w_j A_j`` (sorted into cubes as for :func:`_band_sum`)."""
    for k in numba.prange(view.shape[0]):
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


@numba.njit(cache=True)
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


@numba.njit(inline="always")
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


@numba.njit(inline="always")
def _corner_key(i, j, m, c, dims):
    """The key of corner ``c`` (0-7, bits x y z) of voxel ``(i, j, m)``, on the lattice of ``dims + 1`` corners per
    axis."""
    return ((i + (c >> 2)) * (dims[1] + 1) + (j + ((c >> 1) & 1))) * (dims[2] + 1) + (m + (c & 1))


@numba.njit(cache=True)
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


@numba.njit(cache=True)
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


@numba.njit(parallel=True, cache=True)
def _corner_interpolate(view, origin, size, slots, values, out):
    """``out[k] +=`` the trilinear interpolation at ``view[k]`` of the ``values`` at its voxel's corner ``slots``."""
    for k in numba.prange(view.shape[0]):
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


class MultiscaleTransport(Transport):
    """Core and middle band summed directly over clustered samples, far field on a 3-D mesh by FFT; see the module
    docstring."""

    name = "multiscale"
    parameters = (
        Parameter("accuracy", float, 0.01, "Relative error aimed at by the multiscale transport: sets its cluster "
                  "and voxel sizes, split radii and far-field mesh from the profile's core width.", low=0.0,
                  low_open=True, high=0.5),
        Parameter("cell_size", float, None, "The pixel footprint in mm where the object is seen (the renderer "
                  "sets it): the profile's features narrower than a third of it are summed as their energy over a "
                  "smooth kernel (the local limit), so that the work follows the image.", low=0.0, low_open=True,
                  exposed=False),
        Parameter("memory_limit", float, None, "Bytes the far-field mesh may use (default: what the machine has "
                  "available).", low=0.0, low_open=True, exposed=False),
    )

    memory_advice = "raise the transport's accuracy (a coarser far-field mesh), or use the hierarchical transport"

    @classmethod
    def _split(cls, profile, params, lo, hi):
        """The :class:`Scales` under ``params`` for samples within ``lo``, ``hi`` (3,) of the view frame, the
        profile's split (:func:`split`) and whether the far field is kept (it holds at least :data:`FAR_SKIP` of the
        accuracy in some channel): as few middle bands as keep the far mesh within :data:`FAR_CELLS` FFT cells (or
        drop its field), one where it fits."""
        accuracy, reach = params.get("accuracy", 0.01), far_reach(profile)
        for levels in range(1, MAX_LEVELS + 1):
            sc = scales(profile, accuracy, params.get("cell_size"), levels)
            parts = split(profile, sc.radii, sc.local)
            kept = bool(np.max(far_energy(profile, sc.split, parts[0])) >= FAR_SKIP * accuracy)
            if not kept or np.prod(np.asarray(far_mesh(sc, reach, lo, hi)[2], dtype=np.float64)) <= FAR_CELLS:
                break
        return sc, parts, kept

    @classmethod
    def planned_bytes(cls, bounds, profile, count, params):
        """The far-field mesh's spectra and the cell lists' offsets (:func:`far_mesh`, :class:`CellList`)."""
        lo, hi = bounds
        sc, _, kept = cls._split(profile, params, lo, hi)
        held = cell_list_bytes(lo, hi, sc.core)
        held += sum(cell_list_bytes(lo, hi, 0.5 * sc.band(k)[0]) for k in range(1, sc.levels + 1))
        if kept:
            held += far_bytes(far_mesh(sc, far_reach(profile), lo, hi)[2])
        return int(held)

    @classmethod
    def sample_area(cls, profile, params):
        """The smallest effective area of the profile as the bands sum it (:func:`summed_area`, with one middle
        band): the profile's own where it is resolved, growing as the pixel footprint squared in the local limit
        (Eq. M3)."""
        sc = scales(profile, params.get("accuracy", 0.01), params.get("cell_size"))
        if not sc.local:
            return super().sample_area(profile, params)
        return float(np.min(summed_area(profile, sc.radii, *split(profile, sc.radii, sc.local))))

    def __init__(self, samples, profile, frame=None, **params):
        super().__init__(samples, profile, frame, **params)
        with self.timings("clusters"):  # the samples' places: which cluster each falls in, whatever its flux
            self._view = self._to_view(samples.position)
            self._lo, self._hi = bounds(self._view)
        with self.timings("kernels"):
            sc, (self._far_cap, self._core, self._band_tables), self._far_kept = self._split(profile, self.params,
                                                                                             self._lo, self._hi)
            self.scales = sc
        with self.timings("clusters"):
            side = sheet_side(None if samples.normal is None else self._to_view(samples.normal, vectors=True))
            self._fine = group(cube_cells(self._view, self._lo, sc.cluster), side)
            self._groups = [group(self._fine.cells // round(sc.band(k)[1] / sc.cluster), self._fine.side)
                            for k in range(1, sc.levels + 1)]
        self._build()

    def _build(self):
        """Everything that depends on the samples' flux: the clusters' flux and centroids, the cell lists, the far
        field and the middle bands."""
        sc, lo, hi = self.scales, self._lo, self._hi
        with self.timings("clusters"):
            fine = merge(self._fine, self._view, self.samples.area, self.samples.flux)
            coarse = [merge(g, fine.centre, fine.area, fine.flux) for g in self._groups]
            self.clusters = len(fine)
        with self.timings("cell_lists"):
            self._core_cells = CellList(fine.centre, fine.flux, lo, sc.core, sc.core, fine.area if sc.local else None)
            band_cells = [CellList(c.centre, c.flux, lo, sc.band(k)[0], 0.5 * sc.band(k)[0])
                          for k, c in enumerate(coarse, start=1)]
        self._far_field(fine.centre, fine.flux, lo, hi)
        with self.timings("band"):
            self._bands = [BandCorners(cells, table, fine.centre, lo, hi, sc.band(k)[2])
                           for k, (cells, table) in enumerate(zip(band_cells, self._band_tables), start=1)]

    def _relit(self, samples):
        """The same places and clusters with the new samples' flux: only :meth:`_build` runs again."""
        return self._rebuilt(samples)

    def _far_field(self, position, flux, lo, hi):
        """Deposit the clusters' flux on the mesh, convolve with ``R_far`` by 3-D FFTs (Eq. M2), keep the field.

        The mesh reaches ``r_c`` past the samples (queries off the surface within that distance read it; farther
        ones read its border); float32 throughout (the error aimed at is far above its round-off).
        """
        self._field = None
        if not self._far_kept:
            self._mesh_origin, self.fft_shape = lo, None
            return
        h = self.scales.mesh
        reach = far_reach(self.profile)
        lo, shape, fft_shape = far_mesh(self.scales, reach, lo, hi)
        check_memory(far_bytes(fft_shape), "the multiscale far-field mesh and its spectra",
                     "raise the transport's accuracy (a coarser mesh)", self.params["memory_limit"])
        self._mesh_origin, self.fft_shape = lo, fft_shape
        with self.timings("far_kernel"):
            radial = RadialTable.of(self.profile)
            key = (profile_key((radial.r_scale, radial.ds, radial.values)), self.scales.split, h, fft_shape)
            kernel_hat = SPECTRA.get(key)
            if kernel_hat is None:
                kernel_hat = far_spectrum(radial, self.scales.split, *self._far_cap, h, fft_shape, reach)
                SPECTRA.put(key, kernel_hat)
        with self.timings("deposit"):
            grid = np.zeros((3,) + tuple(int(n) for n in shape), dtype=np.float32)
            _deposit(position, flux, lo, h, grid)
        with self.timings("far_fft"):
            self._field = padded_convolution(grid, kernel_hat, fft_shape)

    @property
    def query_batch(self):
        """Query points per call (each sums the clusters within ``r_1``)."""
        return 1 << 17

    def _exitance(self, points):
        view = self._to_view(points)
        out = np.zeros((len(points), 3))
        if self._field is not None:
            with self.timings("far_lookup"):
                _interpolate(view, self._mesh_origin, self.scales.mesh, self._field, out)
        with self.timings("band"):
            for band in self._bands:
                band.add(view, out)
        with self.timings("core_sum"):
            if self.scales.local:  # Eq. M3, E_core from the kernel's peak: K(0) = 3 / (pi r_0^2)
                self._core_cells.add_average(view, self._core[0] * np.pi * self.scales.core**2 / 3.0, out)
            else:
                self._core_cells.add_sum(view, self._core, out)
        return np.maximum(out, 0.0)

    @property
    def stats(self):
        """The base stats plus the lengths chosen, the cluster count and the far-field FFT shape (None where the far
        field is dropped)."""
        return {**super().stats, "scales_mm": dict(vars(self.scales)), "clusters": self.clusters,
                "band_corners": sum(b.count for b in self._bands),
                "fft_shape": None if self.fft_shape is None else list(self.fft_shape)}


register_transport(MultiscaleTransport)
