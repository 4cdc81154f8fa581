"""The better dipole (d'Eon 2012, "A better dipole"): the classic dipole's single real source at one mean free path,
with what the classic one leaves out (:mod:`convsss.profiles.diffusion`): Grosjean's diffusion coefficient, the
extrapolated boundary ``z_b = 2 A D`` from the Fresnel moments, and the exitance ``c_phi phi + c_E E_n`` instead of
the flux ``E_n`` alone.

In optical units (``sigma_t' = 1``), a source of power ``alpha'`` (the first collision scatters with that
probability) at depth ``z_r = 1``: ``M(r) = alpha' M_point(r, 1)``, per unit transmitted flux. The profile of Eq. 1
is ``M / T_d(eta)`` (:mod:`convsss.profiles`). Its total has a closed form (``∫ 2 pi r e^{-s d}/d dr = e^{-s z}/s``
and ``∫ 2 pi r z (1 + s d) e^{-s d}/d^3 dr = 2 pi e^{-s z}``):
``alpha' [c_phi (e^{-s z_r} - e^{-s z_v}) / (2 D s) + c_E (e^{-s z_r} + e^{-s z_v}) / 2] / T_d``,
``z_v = z_r + 4 A D``, ``s = sigma_tr`` (the first bracket tends to ``c_phi (z_v - z_r)/(2 D)`` without absorption).
"""

import numpy as np

from ..fresnel import diffuse_transmittance
from .base import register_profile
from .diffusion import boundary, grosjean, point_source_exitance
from .optical import OpticalProfile


class BetterDipoleProfile(OpticalProfile):
    """The better dipole of d'Eon 2012 in the normalization of Eq. 1 (module docstring).

    Parameters
    ----------
    sigma_s_prime, sigma_a : array_like
        Reduced scattering and absorption, 1/mm.
    eta : float
        Relative index of the boundary.
    """

    name = "better-dipole"
    title = "better dipole (d'Eon 2012)"
    rank = 1

    model = "better-dipole"

    @classmethod
    def optical_values(cls, r, albedo, eta):
        return albedo * point_source_exitance(r, 1.0, albedo, eta) / diffuse_transmittance(eta)

    @staticmethod
    def closed_form_total(albedo, eta):
        """The total reflectance in closed form (module docstring), for checking the sampled one."""
        c_phi, c_e, a = boundary(float(eta))
        d, s = grosjean(albedo)
        z_r, z_v = 1.0, 1.0 + 4.0 * a * d
        fluence = (z_v - z_r) if s == 0 else (np.exp(-s * z_r) - np.exp(-s * z_v)) / s
        flux = 0.5 * (np.exp(-s * z_r) + np.exp(-s * z_v))
        return float(albedo * (c_phi * fluence / (2.0 * d) + c_e * flux) / diffuse_transmittance(eta))


register_profile(BetterDipoleProfile)
