"""Profiles computed in optical units (lengths in reduced mean free paths) per channel, scaled to a material in mm.

A model that has no closed form everywhere (photon beam diffusion integrates along the beam) or diverges at ``r = 0``
(single scattering and Christensen–Burley fall as ``1/r``) is sampled once per ``(albedo, eta)`` on a geometric grid
of optical radii, :data:`PER_DECADE` points a decade from :data:`CORE` to where the energy left beyond is about
:data:`TAIL`, and read back by a monotone cubic in ``(log r, log R)``. With ``sigma_t' = sigma_a + sigma_s'``,
``R(r) = sigma_t'^2 R_opt(sigma_t' r)`` in 1/mm^2.

Inside :data:`CORE` mean free paths the profile is a constant (a ``1/r`` peak is finite in every pixel and kernel
cell anyway): the one that holds the energy of the local power law continued to 0, so nothing is lost to first
order; ``total_reflectance`` is the integral of the profile as defined, so the two always agree.
"""

from functools import lru_cache

import numpy as np

from ..errors import ConvsssError
from .base import Profile

#: Radius (mfp) inside which a profile is held constant; grid points per decade of optical radius.
CORE = 0.01
PER_DECADE = 64
#: The grid ends where ``2 pi r^2 R_opt`` (the energy per unit log radius) stays below TAIL, or at R_LIMIT mfp.
TAIL = 1e-9
R_LIMIT = 1e5


def optical_grid(sigma_tr):
    """Optical radii from :data:`CORE` to ``min(R_LIMIT, 40/sigma_tr + 1e3)`` mfp (``sigma_tr`` in 1/mfp)."""
    end = R_LIMIT if sigma_tr <= 0 else min(R_LIMIT, 40.0 / sigma_tr + 1e3)
    n = int(np.ceil(np.log10(end / CORE) * PER_DECADE)) + 1
    return CORE * np.power(end / CORE, np.linspace(0.0, 1.0, n))


class OpticalCurve:
    """One channel of a profile in optical units: ``R_opt`` on a radial grid, its cubic and cumulative energy."""

    def __init__(self, r, values):
        from scipy.interpolate import PchipInterpolator

        self.zero = not np.any(values > 0)  # a channel that does not scatter (alpha' = 0) returns nothing
        if self.zero:
            self.r, self.values, self.end, self.total, self.core_value = r[:2], np.zeros(2), float(r[1]), 0.0, 0.0
            return
        # End where the energy per unit log r, 2 pi r^2 R, has fallen below TAIL for good (both an exponential and
        # an r^-3 tail then hold less than about TAIL past the end) or the profile has underflowed.
        alive = np.flatnonzero((2.0 * np.pi * r * r * values > TAIL) & (values > 0))
        last = max(int(alive[-1]) + 2, 2) if len(alive) else 2
        r, values = r[:last], values[:last]
        if np.any(~np.isfinite(values)) or np.any(values <= 0):
            raise ConvsssError("a profile model produced a non-positive or non-finite value")
        self.r, self.values = r, values
        self.end = float(r[-1])
        self._log = PchipInterpolator(np.log(r), np.log(values))
        # Inside the core: the constant that holds the energy of the local power law R ~ r^-p continued to r = 0,
        # ∫_0^c 2 pi r R(c) (c/r)^p dr = pi c^2 R(c) 2/(2 - p) (p from the first grid step, in [0, 1.5]).
        p = float(np.clip(-np.log(values[1] / values[0]) / np.log(r[1] / r[0]), 0.0, 1.5))
        self.core_value = 2.0 * values[0] / (2.0 - p)
        # energy: pi CORE^2 R_core inside, then ∫ 2 pi r^2 R d(log r) by Simpson on a 4x finer grid
        fine = np.exp(np.linspace(np.log(r[0]), np.log(r[-1]), 4 * (len(r) - 1) + 1))
        integrand = 2.0 * np.pi * fine**2 * np.exp(self._log(np.log(fine)))
        h = np.diff(np.log(fine))[0]
        pairs = h / 3.0 * (integrand[:-2:2] + 4.0 * integrand[1:-1:2] + integrand[2::2])
        self._energy_r = fine[::2]
        self._energy = np.pi * r[0] ** 2 * self.core_value + np.concatenate([[0.0], np.cumsum(pairs)])
        self.total = float(self._energy[-1])

    def __call__(self, r):
        r = np.asarray(r, dtype=np.float64)
        if self.zero:
            return np.zeros(r.shape)
        inside = r <= self.end
        held = np.clip(r, self.r[0], self.end)
        return np.where(r < self.r[0], self.core_value, np.where(inside, np.exp(self._log(np.log(held))), 0.0))

    def energy_within(self, radius):
        radius = np.asarray(radius, dtype=np.float64)
        if self.zero:
            return np.zeros(radius.shape)
        core = np.pi * np.minimum(radius, self.r[0]) ** 2 * self.core_value
        outer = np.interp(np.log(np.clip(radius, self.r[0], self.end)), np.log(self._energy_r),
                          self._energy - self._energy[0])
        return core + np.where(radius > self.r[0], outer, 0.0)


class OpticalProfile(Profile):
    """Base of models defined per channel in optical units by ``optical_values(r, albedo, eta) -> R_opt(r)``
    (already in the normalization of Eq. 1, :mod:`convsss.profiles`).

    Parameters
    ----------
    sigma_s_prime, sigma_a : array_like
        Reduced scattering and absorption, 1/mm (one number or three).
    eta : float
        Relative index of the boundary.
    """

    #: Name in the registry (``convsss.profiles.PROFILE_MODELS``).
    model = ""

    def __init__(self, sigma_s_prime, sigma_a, eta):
        self.sigma_s_prime = np.broadcast_to(np.asarray(sigma_s_prime, dtype=np.float64), (3,)).copy()
        self.sigma_a = np.broadcast_to(np.asarray(sigma_a, dtype=np.float64), (3,)).copy()
        self.eta = float(eta)
        self.sigma_t_prime = self.sigma_a + self.sigma_s_prime
        if np.any(self.sigma_t_prime <= 0):
            raise ConvsssError(f"a {self.model} profile needs sigma_a + sigma_s' > 0 in every channel")
        self.albedo_prime = self.sigma_s_prime / self.sigma_t_prime
        self._curves = [type(self).curve(float(a), self.eta) for a in self.albedo_prime]
        self.support = float(max(c.end / s for c, s in zip(self._curves, self.sigma_t_prime)))

    @classmethod
    def optical_values(cls, r, albedo, eta):
        raise NotImplementedError

    @classmethod
    @lru_cache(maxsize=512)
    def curve(cls, albedo, eta):
        """The :class:`OpticalCurve` of one channel (cached per model, albedo and eta)."""
        sigma_tr = float(np.sqrt(3.0 * (1.0 - albedo)))
        r = optical_grid(sigma_tr)
        return OpticalCurve(r, cls.optical_values(r, albedo, eta))

    @classmethod
    def optical_total(cls, albedo, eta):
        """``∫ 2 pi r R_opt dr`` for one channel: the total reflectance, which does not depend on the mfp."""
        return cls.curve(float(albedo), float(eta)).total

    def __repr__(self):
        return (f"{type(self).__name__}(sigma_s_prime={self.sigma_s_prime.tolist()}, "
                f"sigma_a={self.sigma_a.tolist()}, eta={self.eta})")

    def __call__(self, r):
        r = np.asarray(r, dtype=np.float64)
        return np.stack([s * s * c(r * s) for c, s in zip(self._curves, self.sigma_t_prime)], axis=-1)

    def energy_within(self, radius):
        radius = np.asarray(radius, dtype=np.float64)
        return np.stack([c.energy_within(radius * s) for c, s in zip(self._curves, self.sigma_t_prime)], axis=-1)

    @property
    def total_reflectance(self):
        return np.array([c.total for c in self._curves])
