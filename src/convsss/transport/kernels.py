"""Convolution kernels of the layered transport: the profile between layers ``m dz`` apart (paper Eq. 5).

``K_m(x, y) = R_d(sqrt(x^2 + y^2 + (m dz)^2))`` on a grid of square cells of side ``h``. Each cell holds the
**cell average** of the profile over its footprint, not a point sample, so that for any cell size

    h^2 sum_{cells} K_m = ∫∫ R_d(sqrt(x^2 + y^2 + e^2)) dx dy = ∫_e^inf 2 pi r R_d(r) dr      (e = m dz)

up to the kernel's truncation at the grid's reach: a coarse grid neither gains nor loses energy. Averages are
midpoint sums over ``s x s`` sub-cells, ``s`` chosen per cell from its distance ``rho`` to the profile's centre so
that sub-cells stay small against the scale on which ``R_d`` varies (``max(rho, r_core)``).

The kernels are returned as spectra (``rfft2`` of the kernel wrapped around the padded grid); a kernel is real and
even, so its spectrum is real and is kept as float32. Spectra are cached per (profile, grid, dz).
"""

from collections import OrderedDict

import numpy as np

from ..jit import njit, prange
from .radial import profile_lookup

#: The bytes a kernel cache may hold (the demo's spectra take tens of MiB).
KERNEL_CACHE_BYTES = 512 * 2**20
_SUBCELL_REACH = 32.0  # sub-cells per cell at distance h, falling as 1/rho
_MAX_SUBCELLS = 256


@njit(parallel=True, fastmath=True, cache=True)
def kernel_quadrant(h, depth, nx, ny, r_scale, ds, table, r_core):
    """Cell averages of ``R_d(sqrt(x^2 + y^2 + depth^2))`` for cells centred on ``(i h, j h)``, i < nx, j < ny.

    Parameters
    ----------
    h : float
        Cell side (mm).
    depth : float
        Depth offset between the two layers, ``m dz`` (mm).
    nx, ny : int
        Cells of the quadrant along x and y (the kernel's reach plus one).
    r_scale, ds, table : float, float, numpy.ndarray of shape (size, 3), float64
        The profile's radial table (:meth:`~convsss.profiles.Profile.radial_table`): ``r_scale`` in mm,
        ``table`` ``R_d`` in 1/mm^2.
    r_core : float
        Radius (mm) on which the profile is flat near its centre; sets the sub-cell count.

    Returns
    -------
    numpy.ndarray, shape (3, ny, nx), float64
        The cell averages per RGB channel (1/mm^2), ``[c, j, i]`` for the cell centred on ``(i h, j h)``.
    """
    out = np.zeros((3, ny, nx))
    for j in prange(ny):
        for i in range(nx):
            gap_x = max(i - 0.5, 0.0) * h
            gap_y = max(j - 0.5, 0.0) * h
            rho = np.sqrt(gap_x * gap_x + gap_y * gap_y + depth * depth)
            s = int(np.ceil(_SUBCELL_REACH * h / max(rho, r_core)))
            s = min(max(s, 1), _MAX_SUBCELLS)
            step = h / s
            acc0 = acc1 = acc2 = 0.0
            for b in range(s):
                y = (j - 0.5) * h + (b + 0.5) * step
                for a in range(s):
                    x = (i - 0.5) * h + (a + 0.5) * step
                    r = np.sqrt(x * x + y * y + depth * depth)
                    acc0 += profile_lookup(r, r_scale, ds, table, 0)
                    acc1 += profile_lookup(r, r_scale, ds, table, 1)
                    acc2 += profile_lookup(r, r_scale, ds, table, 2)
            norm = 1.0 / (s * s)
            out[0, j, i] = acc0 * norm
            out[1, j, i] = acc1 * norm
            out[2, j, i] = acc2 * norm
    return out


def wrap_kernel(quadrant, padded_shape):
    """Mirror a quadrant (3, ny, nx) into a (3, Py, Px) array with negative offsets wrapped to the end.

    Parameters
    ----------
    quadrant : numpy.ndarray, shape (3, ny, nx)
        The kernel at offsets ``(j, i) >= 0`` (:func:`kernel_quadrant`), any unit.
    padded_shape : tuple of int
        ``(Py, Px)``, with ``Py >= 2 ny - 1`` and ``Px >= 2 nx - 1``.

    Returns
    -------
    numpy.ndarray, shape (3, Py, Px), float64
        The whole even kernel, offset ``(dy, dx)`` stored at ``(dy mod Py, dx mod Px)``; zero elsewhere.

    Examples
    --------
    >>> wrap_kernel(np.tile([[[1.0, 2.0]]], (3, 1, 1)), (1, 4))[0]  # offsets 0, 1, (2: empty), -1
    array([[1., 2., 0., 2.]])
    """
    _, ny, nx = quadrant.shape
    py, px = padded_shape
    full_y = np.concatenate([quadrant[:, :0:-1, :], quadrant], axis=1)  # rows -(ny-1)..ny-1
    full = np.concatenate([full_y[:, :, :0:-1], full_y], axis=2)  # columns -(nx-1)..nx-1
    out = np.zeros((3, py, px))
    rows = np.arange(-(ny - 1), ny) % py
    cols = np.arange(-(nx - 1), nx) % px
    out[:, rows[:, None], cols[None, :]] = full
    return out


class KernelCache:
    """Kernel spectra keyed by (profile key, h, dz, distances, reach, padded shape); keeps the newest ``size`` that
    hold at most ``max_bytes`` together (an entry larger than that is not kept: a dense medium's far-field spectra
    can take gigabytes, which a long-lived process would otherwise hold on to)."""

    def __init__(self, size=2, max_bytes=KERNEL_CACHE_BYTES):
        self.size, self.max_bytes = size, max_bytes
        self._entries = OrderedDict()

    def get(self, key):
        if key in self._entries:
            self._entries.move_to_end(key)
            return self._entries[key]
        return None

    def put(self, key, value):
        self._entries.pop(key, None)
        if _nbytes(value) > self.max_bytes:
            return
        self._entries[key] = value
        while len(self._entries) > self.size or self.nbytes > self.max_bytes:
            self._entries.popitem(last=False)

    @property
    def nbytes(self):
        """The bytes of the arrays held."""
        return sum(_nbytes(v) for v in self._entries.values())

    def clear(self):
        self._entries.clear()


def _nbytes(value):
    """Bytes of the numpy arrays in ``value`` (an array, or tuples and lists of them)."""
    if isinstance(value, np.ndarray):
        return value.nbytes
    if isinstance(value, (tuple, list)):
        return sum(_nbytes(v) for v in value)
    return 0


CACHE = KernelCache()


def profile_key(table):
    """A hashable fingerprint of a profile's radial table ``(r_scale, ds, values)``.

    Parameters
    ----------
    table : tuple
        ``(r_scale, ds, values)`` of :meth:`~convsss.profiles.Profile.radial_table`: ``r_scale`` in mm, ``values``
        a float64 array of shape (size, 3) (``R_d`` in 1/mm^2).

    Returns
    -------
    tuple
        ``(r_scale, ds, values.shape, hash of values' bytes)``.
    """
    r_scale, ds, values = table
    return (float(r_scale), float(ds), values.shape, hash(values.tobytes()))


def kernel_spectra(table, r_core, h, dz, distances, reach, padded_shape, workers=-1):
    """Real spectra (float32, shape (distances, 3, Py, Px//2+1)) of the kernels for ``m = 0..distances-1``.

    Parameters
    ----------
    table : tuple
        The profile's ``radial_table()``: ``(r_scale`` in mm, ``ds``, ``values`` (size, 3) float64 ``R_d`` in
        1/mm^2).
    r_core : float
        Radius (mm) on which the profile is flat near its centre; sets the sub-cell count.
    h, dz : float
        Cell side and layer spacing (mm).
    distances : int
        How many layer distances ``m`` (the number of layers).
    reach : tuple of int
        Kernel half-size in cells ``(ry, rx)``.
    padded_shape : tuple of int
        FFT shape ``(Py, Px)``.

    workers : int
        Threads of ``scipy.fft`` (-1: all cores).

    Returns
    -------
    spectra : numpy.ndarray, shape (distances, 3, Py, Px // 2 + 1), float32
        The real part of ``rfft2`` of each kernel ``K_m`` (1/mm^2) wrapped around the padded grid.
    sums : numpy.ndarray, shape (distances, 3), float64
        ``h^2 sum K_m``: the energy each kernel carries, dimensionless (for stats and tests).
    cached : bool
        Whether the spectra came from the cache.
    """
    import scipy.fft

    key = (profile_key(table), float(h), float(dz), int(distances), tuple(reach), tuple(padded_shape))
    hit = CACHE.get(key)
    if hit is not None:
        return hit + (True,)
    r_scale, ds, values = table
    py, px = padded_shape
    spectra = np.empty((distances, 3, py, px // 2 + 1), dtype=np.float32)
    sums = np.empty((distances, 3))
    for m in range(distances):
        quadrant = kernel_quadrant(h, m * dz, reach[1] + 1, reach[0] + 1, r_scale, ds, values, r_core)
        wrapped = wrap_kernel(quadrant, padded_shape)
        sums[m] = wrapped.sum(axis=(1, 2)) * h * h
        spectra[m] = scipy.fft.rfft2(wrapped.astype(np.float32), workers=workers).real
    CACHE.put(key, (spectra, sums))
    return spectra, sums, False
