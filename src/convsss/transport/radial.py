"""A radial profile as compiled code reads it: a dense table, its lookup, and the direct sum over samples.

:meth:`~convsss.profiles.Profile.radial_table` samples ``R_d`` on ``r_k = r_scale (e^{k ds} - 1)``: uniform steps
near 0, geometric in the tail, to the radius holding all but 1e-7 of the energy. Every transport that evaluates
``R_d`` in numba (the exact sum, the hierarchical leaves and nodes, the convolution's cell-averaged kernels) reads it
through :func:`profile_lookup`, linear in ``s = log(1 + r/r_scale)`` (about 1e-5 relative).
"""

from dataclasses import dataclass

import numpy as np

from ..jit import njit


@dataclass(frozen=True)
class RadialTable:
    """``values[k]`` (size, 3) ``= R_d(r_scale (e^{k ds} - 1))``; ``R_d = 0`` from ``r_max`` on.

    ``r_scale`` and ``r_max`` in mm, ``ds`` dimensionless, ``values`` float64 in 1/mm^2.
    """

    r_scale: float
    ds: float
    values: np.ndarray
    r_max: float

    @classmethod
    def of(cls, profile):
        """The table of ``profile`` (any :class:`~convsss.profiles.Profile`).

        Parameters
        ----------
        profile : Profile

        Returns
        -------
        RadialTable
            Its ``radial_table()`` (``values`` of shape (size, 3), float64, 1/mm^2) and the radius ``r_max`` (mm)
            of the last entry.
        """
        r_scale, ds, values = profile.radial_table()
        return cls(r_scale, ds, values, r_scale * float(np.expm1(ds * (len(values) - 1))))


@njit(inline="always", fastmath=True)
def profile_lookup(r, r_scale, ds, table, c):
    """``R_d(r)`` of channel ``c`` from a radial table (linear in ``s = log(1 + r/r_scale)``); 0 past its end.

    Parameters
    ----------
    r : float
        Distance (mm), >= 0.
    r_scale, ds : float
        The table's radial scale (mm) and step in ``s``.
    table : numpy.ndarray, shape (size, 3), float64
        ``R_d`` (1/mm^2) at ``r_k = r_scale (e^{k ds} - 1)``.
    c : int
        The channel, 0 to 2.

    Returns
    -------
    float
        ``R_d(r)`` in 1/mm^2.
    """
    s = np.log1p(r / r_scale) / ds
    k = int(s)
    if k >= table.shape[0] - 1:
        return 0.0
    w = s - k
    return (1.0 - w) * table[k, c] + w * table[k + 1, c]


@njit(inline="always", fastmath=True)
def sum_samples(px, py, pz, positions, flux, first, last, r_scale, ds, table, r_max2):
    """``sum_{i in [first, last)} R_d(|p - x_i|) Phi_i`` per channel for the point ``(px, py, pz)``.

    Parameters
    ----------
    px, py, pz : float
        The query point (mm).
    positions : numpy.ndarray, shape (N, 3), float64
        Sample positions (mm).
    flux : numpy.ndarray, shape (N, 3), float64
        Sample flux ``Phi_i = E_i A_i`` (the irradiance's unit times mm^2).
    first, last : int
        The samples summed, ``first <= i < last``.
    r_scale, ds, table
        The radial table, as in :func:`profile_lookup`.
    r_max2 : float
        Squared radius (mm^2) from which ``R_d`` counts as 0.

    Returns
    -------
    tuple of 3 floats
        The exitance per RGB channel, in the irradiance's unit.
    """
    m0 = m1 = m2 = 0.0
    for i in range(first, last):
        dx = positions[i, 0] - px
        dy = positions[i, 1] - py
        dz = positions[i, 2] - pz
        d2 = dx * dx + dy * dy + dz * dz
        if d2 >= r_max2:
            continue
        r = np.sqrt(d2)
        m0 += profile_lookup(r, r_scale, ds, table, 0) * flux[i, 0]
        m1 += profile_lookup(r, r_scale, ds, table, 1) * flux[i, 1]
        m2 += profile_lookup(r, r_scale, ds, table, 2) * flux[i, 2]
    return m0, m1, m2
