"""Christensen & Burley 2015, "Approximate Reflectance Profiles for Efficient Subsurface Scattering": a sum of two
exponentials fitted to Monte Carlo simulations of a searchlight (a beam at normal incidence), single scattering
included,

``R(r) = A s (e^{-s r/l} + e^{-s r/(3 l)}) / (8 pi l r)``,  whose integral ``∫ 2 pi r R dr`` is ``A``,

with ``l`` the mean free path and the shape factor of their searchlight fit ``s = 1.85 - A + 7 |A - 0.8|^3``.
Christensen and Burley parameterize by the surface albedo ``A`` itself; for a material given by its coefficients
``A`` is photon beam diffusion's total reflectance (the package's model with single scattering,
:mod:`convsss.profiles.beam_diffusion`), so the two differ in shape only. In the normalization of Eq. 1
(:mod:`convsss.profiles`) the amplitude is that total; the shape factor takes the albedo actually leaving,
``T_d(eta) A``. Optical units: ``l = 1/sigma_t'``.
"""

import numpy as np

from ..fresnel import diffuse_transmittance
from .beam_diffusion import BeamDiffusionProfile
from .optical import OpticalProfile


def shape_factor(albedo):
    """Christensen & Burley 2015's searchlight fit ``s = 1.85 - A + 7 |A - 0.8|^3``."""
    return 1.85 - albedo + 7.0 * np.abs(albedo - 0.8) ** 3


def burley_values(r, total, leaving):
    """``R(r)`` per mfp^2 with integral ``total`` and shape factor of the albedo ``leaving`` (module docstring)."""
    s = shape_factor(leaving)
    return total * s * (np.exp(-s * r) + np.exp(-s * r / 3.0)) / (8.0 * np.pi * r)


class BurleyProfile(OpticalProfile):
    """Christensen & Burley 2015 (module docstring), with photon beam diffusion's total reflectance.

    Parameters
    ----------
    sigma_s_prime, sigma_a : array_like
        Reduced scattering and absorption, 1/mm.
    eta : float
        Relative index of the boundary.
    """

    model = "burley"

    @classmethod
    def optical_values(cls, r, albedo, eta):
        total = BeamDiffusionProfile.optical_total(albedo, eta)
        return burley_values(r, total, diffuse_transmittance(eta) * total)
