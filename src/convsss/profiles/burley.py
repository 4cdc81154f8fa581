"""Christensen & Burley 2015, "Approximate Reflectance Profiles for Efficient Subsurface Scattering": a sum of two
exponentials fitted to Monte Carlo simulations of a searchlight (single scattering included),

``R(r) = A (e^{-r/d} + e^{-r/(3 d)}) / (8 pi d r)``,  with ``∫ 2 pi r R dr = A`` and mean radius
``∫ r 2 pi r R dr / A = 10 d / 4``.

Christensen and Burley give ``d`` from a length and their fits of a shape factor to ``A``; for a material given by
its coefficients the package takes both numbers from photon beam diffusion (:mod:`convsss.profiles.beam_diffusion`,
the model with single scattering): ``A`` its total reflectance (already in the normalization of Eq. 1,
:mod:`convsss.profiles`) and ``d = 0.4 <r>`` from its mean exit radius ``<r>``, so the two agree in energy and in
reach and differ in shape only. Optical units (``sigma_t' = 1``).
"""

import numpy as np

from .base import register_profile
from .beam_diffusion import BeamDiffusionProfile
from .optical import OpticalProfile


def burley_values(r, total, d):
    """``R(r)`` per unit length^2 with integral ``total`` and shape length ``d`` (module docstring)."""
    return total * (np.exp(-r / d) + np.exp(-r / (3.0 * d))) / (8.0 * np.pi * d * r)


def mean_radius(curve):
    """``∫ r 2 pi r R dr / ∫ 2 pi r R dr`` of an :class:`~convsss.profiles.optical.OpticalCurve`."""
    r = np.exp(np.linspace(np.log(curve.r[0]), np.log(curve.end), 8 * len(curve.r)))
    first = np.trapezoid(2.0 * np.pi * r**3 * curve(r), np.log(r))
    return float(first / curve.total)


class BurleyProfile(OpticalProfile):
    """Christensen & Burley 2015 (module docstring), with photon beam diffusion's total and mean radius.

    Parameters
    ----------
    sigma_s_prime, sigma_a : array_like
        Reduced scattering and absorption, 1/mm.
    eta : float
        Relative index of the boundary.
    """

    name = "burley"
    title = "Christensen & Burley 2015"
    rank = 3

    model = "burley"

    @classmethod
    def optical_values(cls, r, albedo, eta):
        pbd = BeamDiffusionProfile.curve(float(albedo), float(eta))
        if pbd.zero:  # alpha' = 0: nothing scatters, nothing comes back
            return np.zeros_like(r)
        return burley_values(r, pbd.total, 0.4 * mean_radius(pbd))


register_profile(BurleyProfile)
