"""The exact transport: the direct sum ``M(x) = sum_i R_d(|x - x_i|) E_i A_i`` over every sample (paper Eq. 1).

Cost ``O(K N)`` for K query points and N samples: the reference for the other transports on small cases. Compiled
with numba, parallel over query points on all cores. ``R_d`` comes from the profile's dense radial table
(:meth:`~convsss.profiles.Profile.radial_table`, about 1e-5 relative), so any profile works.
"""

import numba
import numpy as np

from .base import Transport, register_transport


@numba.njit(inline="always", fastmath=True)
def profile_lookup(r, r_scale, ds, table, c):
    """``R_d(r)`` of channel ``c`` from a radial table (linear in ``s = log(1 + r/r_scale)``); 0 past its end."""
    s = np.log1p(r / r_scale) / ds
    k = int(s)
    if k >= table.shape[0] - 1:
        return 0.0
    w = s - k
    return (1.0 - w) * table[k, c] + w * table[k + 1, c]


@numba.njit(inline="always", fastmath=True)
def sum_samples(px, py, pz, positions, flux, first, last, r_scale, ds, table, r_max2):
    """``sum_{i in [first, last)} R_d(|p - x_i|) Phi_i`` per channel for the point ``(px, py, pz)``."""
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


@numba.njit(parallel=True, fastmath=True, cache=True)
def _direct_sum(points, positions, flux, r_scale, ds, table, r_max):
    out = np.zeros((points.shape[0], 3))
    for k in numba.prange(points.shape[0]):
        m = sum_samples(points[k, 0], points[k, 1], points[k, 2], positions, flux, 0, positions.shape[0],
                        r_scale, ds, table, r_max * r_max)
        out[k, 0], out[k, 1], out[k, 2] = m
    return out


class ExactTransport(Transport):
    """Brute-force sum over all samples; see the module docstring."""

    name = "exact"

    def __init__(self, samples, profile, frame=None, **params):
        super().__init__(samples, profile, frame, **params)
        with self.timings("profile_table"):
            self._r_scale, self._ds, self._table = profile.radial_table()
            self._r_max = self._r_scale * np.expm1(self._ds * (len(self._table) - 1))
        self._flux = np.ascontiguousarray(samples.flux)

    @property
    def query_batch(self):
        """About 2^27 point-sample pairs per call: a fraction of a second whatever the sample count."""
        return max(64, (1 << 27) // max(1, len(self.samples)))

    def _exitance(self, points):
        return _direct_sum(points, self.samples.position, self._flux, self._r_scale, self._ds, self._table,
                           self._r_max)


register_transport(ExactTransport)
