"""The exact transport: the direct sum ``M(x) = sum_i R_d(|x - x_i|) E_i A_i`` over every sample (paper Eq. 1).

Cost ``O(K N)`` for K query points and N samples: the reference for the other transports on small cases. Compiled
with numba, parallel over query points on all cores. ``R_d`` comes from the profile's dense radial table
(:class:`.radial.RadialTable`, about 1e-5 relative), so any profile works.
"""

import numpy as np

from ..jit import njit, prange
from .base import Transport, register_transport
from .radial import RadialTable, sum_samples


@njit(parallel=True, fastmath=True, cache=True)
def _direct_sum(points, positions, flux, r_scale, ds, table, r_max):
    out = np.zeros((points.shape[0], 3))
    for k in prange(points.shape[0]):
        m = sum_samples(points[k, 0], points[k, 1], points[k, 2], positions, flux, 0, positions.shape[0],
                        r_scale, ds, table, r_max * r_max)
        out[k, 0], out[k, 1], out[k, 2] = m
    return out


class ExactTransport(Transport):
    """Brute-force sum over all samples; see the module docstring."""

    name = "exact"

    def __init__(self, samples, profile, frame=None, material=None, **params):
        super().__init__(samples, profile, frame, material, **params)
        with self.timings("profile_table"):
            self._radial = RadialTable.of(profile)
        self._flux = np.ascontiguousarray(samples.flux)

    @property
    def query_batch(self):
        """About 2^27 point-sample pairs per call, so that a call stays short whatever the sample count (a caller checks
        for Ctrl-C between calls)."""
        return max(64, (1 << 27) // max(1, len(self.samples)))

    def _exitance(self, points):
        t = self._radial
        return _direct_sum(points, self.samples.position, self._flux, t.r_scale, t.ds, t.values, t.r_max)


register_transport(ExactTransport)
