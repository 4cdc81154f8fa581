"""The classic dipole of Jensen, Marschner, Levoy, Hanrahan 2001: the paper's profile."""

import numpy as np

from ..errors import ConvsssError
from ..fresnel import diffuse_fresnel_reflectance
from .base import Profile, register_profile


class DipoleProfile(Profile):
    """Classic dipole of Jensen, Marschner, Levoy, Hanrahan 2001 (their Eq. 4), with the reduced-albedo factor.

    ``R_d(r) = alpha'/(4 pi) [ z_r (1 + sigma_tr d_r) e^{-sigma_tr d_r} / d_r^3
    + z_v (1 + sigma_tr d_v) e^{-sigma_tr d_v} / d_v^3 ]``
    with ``sigma_t' = sigma_a + sigma_s'``, ``alpha' = sigma_s'/sigma_t'``, ``sigma_tr = sqrt(3 sigma_a sigma_t')``,
    ``z_r = 1/sigma_t'``, ``z_v = z_r (1 + 4A/3)``, ``A = (1 + F_dr)/(1 - F_dr)``, ``d = sqrt(r^2 + z^2)``.
    ``sigma_a = 0`` (no absorption) is allowed: then ``sigma_tr = 0`` and the profile decays as ``r^-3``.
    """

    name = "dipole"
    title = "classic dipole (Jensen et al. 2001)"
    rank = 0

    @classmethod
    def optical_total(cls, albedo, eta):
        """The closed-form total reflectance for one channel of reduced albedo ``albedo``: it does not depend on
        the mean free path."""
        return float(cls(albedo, 1.0 - albedo, eta).total_reflectance[0])

    def __init__(self, sigma_s_prime, sigma_a, eta):
        self.sigma_s_prime = np.broadcast_to(np.asarray(sigma_s_prime, dtype=np.float64), (3,)).copy()
        self.sigma_a = np.broadcast_to(np.asarray(sigma_a, dtype=np.float64), (3,)).copy()
        self.eta = float(eta)
        sigma_t_prime = self.sigma_a + self.sigma_s_prime
        if np.any(sigma_t_prime <= 0):
            raise ConvsssError("a dipole needs sigma_a + sigma_s' > 0 in every channel")
        self.alpha_prime = self.sigma_s_prime / sigma_t_prime
        self.sigma_tr = np.sqrt(3.0 * self.sigma_a * sigma_t_prime)
        f_dr = diffuse_fresnel_reflectance(self.eta)
        self.A = (1.0 + f_dr) / (1.0 - f_dr)
        self.z_r = 1.0 / sigma_t_prime
        self.z_v = self.z_r * (1.0 + 4.0 * self.A / 3.0)

    def __repr__(self):
        return (f"DipoleProfile(sigma_s_prime={self.sigma_s_prime.tolist()}, sigma_a={self.sigma_a.tolist()}, "
                f"eta={self.eta})")

    def __call__(self, r):
        r2 = np.square(np.asarray(r, dtype=np.float64))[..., None]
        d_r = np.sqrt(r2 + self.z_r**2)
        d_v = np.sqrt(r2 + self.z_v**2)
        real = self.z_r * (1.0 + self.sigma_tr * d_r) * np.exp(-self.sigma_tr * d_r) / d_r**3
        virtual = self.z_v * (1.0 + self.sigma_tr * d_v) * np.exp(-self.sigma_tr * d_v) / d_v**3
        return self.alpha_prime / (4.0 * np.pi) * (real + virtual)

    def energy_within(self, radius):
        """Closed form: ``alpha'/2 sum_{z in z_r, z_v} (e^{-sigma_tr z} - z e^{-sigma_tr d}/d)``, ``d = sqrt(R^2+z^2)``.

        It follows from ``d/dd [-e^{-s d}/d] = (1 + s d) e^{-s d}/d^2`` and ``r dr = d dd``.
        """
        r2 = np.square(np.asarray(radius, dtype=np.float64))[..., None]
        total = 0.0
        for z in (self.z_r, self.z_v):
            d = np.sqrt(r2 + z**2)
            with np.errstate(invalid="ignore"):
                inner = np.where(np.isinf(d), 0.0, z * np.exp(-self.sigma_tr * d) / d)
            total = total + np.exp(-self.sigma_tr * z) - inner
        return 0.5 * self.alpha_prime * total

    @property
    def total_reflectance(self):
        """Closed form ``alpha'/2 (1 + e^{-4/3 A sqrt(3(1-alpha'))}) e^{-sqrt(3(1-alpha'))}`` (Jensen et al. 2001)."""
        s = np.sqrt(3.0 * (1.0 - self.alpha_prime))
        return 0.5 * self.alpha_prime * (1.0 + np.exp(-4.0 / 3.0 * self.A * s)) * np.exp(-s)


register_profile(DipoleProfile)
