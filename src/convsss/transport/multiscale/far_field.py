"""The far field: flux deposited on a voxel mesh with quadratic B-spline weights, convolved with ``R_far`` by 3-D FFTs,
read back with the same weights (:mod:`convsss.transport.multiscale`)."""

import math

import numpy as np

from ...jit import njit, prange
from ..kernels import KernelCache
from ..radial import profile_lookup

#: Far-field kernel spectra, keyed by (profile, r_c, h, FFT shape).
SPECTRA = KernelCache()


#: The far mesh's FFT cells at most (600 MB of spectra), where more middle bands can keep it so. Each band adds its
#: interpolation error (two bands where one fits raise the error against the exact sum, ``convsss bench accuracy``),
#: so a band is added only where the mesh would not fit otherwise.
FAR_CELLS = 1 << 24


@njit(parallel=True, fastmath=True, cache=True)
def _far_octant(h, shape, r_c, a, b, reach, r_scale, ds, table):
    """``R_far`` (Eq. M2) at the mesh offsets ``h (i, j, m)``, ``0 <= i, j, m < shape``; 0 from ``reach`` on."""
    out = np.zeros((3, shape[0], shape[1], shape[2]))
    r_c2 = r_c * r_c
    for i in prange(shape[0]):
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
    import scipy.fft

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
    import scipy.fft

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


def padded_convolution(grid, kernel_hat, fft_shape):
    """The cyclic convolution on ``fft_shape`` of ``grid`` (C, nx, ny, nz), zero-padded to it, with a kernel of
    spectrum ``kernel_hat`` (``rfftn`` over the last three axes), read back on the grid's own cells.

    The same as ``irfftn(rfftn(grid padded) * kernel_hat)[:, :nx, :ny, :nz]``, with the transforms along each axis
    run only over the lines that hold data or are read back (about 0.6 times the work for a grid padded to twice
    its size per axis).
    """
    import scipy.fft

    _, nx, ny, nz = grid.shape
    spectrum = scipy.fft.rfft(grid, n=fft_shape[2], axis=3, workers=-1)
    spectrum = scipy.fft.fft(spectrum, n=fft_shape[1], axis=2, workers=-1, overwrite_x=True)
    spectrum = scipy.fft.fft(spectrum, n=fft_shape[0], axis=1, workers=-1, overwrite_x=True)
    spectrum *= kernel_hat
    spectrum = scipy.fft.ifft(spectrum, axis=1, workers=-1, overwrite_x=True)[:, :nx]
    spectrum = scipy.fft.ifft(spectrum, axis=2, workers=-1, overwrite_x=True)[:, :, :ny]
    return np.ascontiguousarray(scipy.fft.irfft(spectrum, n=fft_shape[2], axis=3, workers=-1)[..., :nz])


@njit(inline="always")
def _corner(c, fu, fv, fw):
    """Corner ``c`` (0-7, bits ``di dj dm``) of a cell and its trilinear weight at the fractions ``fu, fv, fw``."""
    di, dj, dm = c >> 2, (c >> 1) & 1, c & 1
    return di, dj, dm, (fu if di else 1.0 - fu) * (fv if dj else 1.0 - fv) * (fw if dm else 1.0 - fw)


@njit(inline="always")
def _spline_node(u, n):
    """The mesh node nearest to ``u`` (in cells; kept one node inside a mesh of ``n``) and the offset from it."""
    i = min(max(int(np.floor(u + 0.5)), 1), n - 2)
    return i, u - i


@njit(inline="always")
def _spline(d, t):
    """The quadratic B-spline's weight of node ``t - 1`` (``t`` in 0-2) around the nearest node, at offset ``d``."""
    if t == 0:
        return 0.5 * (0.5 - d) ** 2
    if t == 1:
        return 0.75 - d * d
    return 0.5 * (0.5 + d) ** 2


@njit(cache=True)
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


@njit(parallel=True, cache=True)
def _interpolate(view, origin, h, field, out):
    """``out[k] +=`` ``field`` (3, nx, ny, nz) read back at ``view[k]`` with the deposit's quadratic B-spline
    weights (a point farther than a node from the mesh's border reads it there)."""
    nx, ny, nz = field.shape[1], field.shape[2], field.shape[3]
    for k in prange(view.shape[0]):
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
