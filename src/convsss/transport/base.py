"""The interface every transport implements, so that transports are interchangeable and comparable.

A transport is built from :class:`~convsss.samples.IrradianceSamples` and a :class:`~convsss.profiles.Profile` and
answers ``exitance(points) -> (K, 3)``: the radiant exitance due to multiple scattering,

    M(x) = ∫_A R_d(|x - x_i|) E(x_i) dA(x_i) ≈ sum_i R_d(|x - x_i|) E_i A_i      (paper Eq. 1, 4),

in the units of ``E``. The outgoing radiance is ``L = (1/pi) F_t(eta, w_o) M`` (paper Eq. 7), applied by shading,
never here. A transport knows nothing of Mitsuba.
"""

import numpy as np

from ..samples import IrradianceSamples, as_points
from ..timing import StageTimer


class Transport:
    """Base class: keeps the samples, the profile, per-stage timings, and answers :meth:`exitance`."""

    name = "transport"

    @property
    def query_batch(self):
        """Query points per :meth:`exitance` call that keep a call short (a caller checks for Ctrl-C between calls)."""
        return 1 << 16

    def __init__(self, samples, profile):
        if not isinstance(samples, IrradianceSamples):
            raise TypeError("samples must be an IrradianceSamples")
        self.samples = samples
        self.profile = profile
        self.timings = StageTimer()

    def exitance(self, points, normals=None):
        """Radiant exitance ``M`` at ``points`` (K, 3) in mm; returns (K, 3) float64.

        ``normals`` (K, 3), the outward surface normals at the points, are optional; transports that can use the
        local surface orientation (the convolution's plane correction) do, the others ignore them.
        """
        points = as_points(points, "query points")
        if normals is not None:
            normals = as_points(normals, "query normals")
            if len(normals) != len(points):
                raise ValueError(f"{len(points)} query points need {len(points)} normals, got {len(normals)}")
        self._prepare(points)
        with self.timings("lookup"):
            out = self._exitance(points)
        if normals is not None:
            self._correct(points, normals, out)
        return out

    def _prepare(self, points):
        """Work a query needs before the lookup itself (timed by the transport under its own stage names)."""

    def _exitance(self, points):
        raise NotImplementedError

    def _correct(self, points, normals, exitance):
        """Adjust ``exitance`` in place using the query normals (timed by the transport); nothing by default."""

    @property
    def stats(self):
        """A JSON-ready dict describing the run: transport name, sample count, per-stage seconds."""
        return {"transport": self.name, "samples": len(self.samples),
                "seconds": {k: float(v) for k, v in self.timings.items()}}


def total_flux(samples):
    """``sum_i E_i A_i`` per channel: with the profile's total reflectance, the energy check of a transport."""
    return np.sum(samples.flux, axis=0)
