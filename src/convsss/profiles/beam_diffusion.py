"""Photon beam diffusion (Habel, Christensen, Jarosz 2013, "Photon Beam Diffusion: A Hybrid Monte Carlo Method for
Subsurface Scattering"): the multiple scattering of a refracted beam as a continuum of point sources along it, plus
its exact single scattering. pbrt-v3/v4 tabulate the same model over albedo and optical radius.

A beam entering at normal incidence (optical units, ``sigma_t' = 1``, reduced albedo ``alpha'``) has its first
collision at depth ``t`` with density ``e^{-t}``; it scatters there with probability ``alpha'``.

- Multiple scattering (Habel et al. 2013, Eq. 11–12): each collision is a diffusion point source
  (:func:`~convsss.profiles.diffusion.point_source_exitance`) weighted by a second ``alpha'`` — light that scatters
  at least once more, the first scattering being the single-scattering term — and by Habel's near-surface factor
  ``kappa = 1 - e^{-2 (d_r + t)}`` that removes the diffusion solution's light from sources too close to the exit:
  ``M_ms(r) = alpha'^2 ∫_0^inf e^{-t} kappa(r, t) M_point(r, t) dt``.
- Single scattering (Habel et al. 2013, Eq. 7; isotropic phase ``1/(4 pi)`` as the reduced medium has): from the
  collision at depth ``t`` straight to the surface point at distance ``d = sqrt(r^2 + t^2)``, arriving at
  ``cos = t/d``, transmitted with ``1 - F_r(1/eta, cos)`` (zero inside the critical angle):
  ``M_ss(r) = alpha' ∫_0^inf e^{-t} e^{-d} (1 - F_r(1/eta, t/d)) t / (4 pi d^3) dt``.

Both are exitances per unit transmitted flux; the profile of Eq. 1 is ``(M_ms + M_ss) / T_d(eta)``
(:mod:`convsss.profiles`). The ``t`` integrals use a geometric grid from 1e-7 to 80 mfp (Simpson in ``log t``); single
scattering's start past the critical depth ``r sqrt(eta^2 - 1)``.
"""

import numpy as np

from ..fresnel import diffuse_transmittance, fresnel_reflectance
from .base import register_profile
from .diffusion import point_source_exitance
from .optical import OpticalProfile

#: Depth nodes of the beam integral (geometric, Simpson in log t).
DEPTHS = np.exp(np.linspace(np.log(1e-7), np.log(80.0), 1025))


def _depth_integral(integrand):
    """``∫ f(t) dt`` for ``integrand`` (n_r, n_t) = f(t_0 + DEPTHS) (Simpson in log of the depth past ``t_0``)."""
    g = integrand * DEPTHS
    h = np.log(DEPTHS[1] / DEPTHS[0])
    return h / 3.0 * (g[:, 0] + g[:, -1] + 4.0 * g[:, 1:-1:2].sum(axis=1) + 2.0 * g[:, 2:-1:2].sum(axis=1))


def multiple_scattering(r, albedo, eta):
    """``M_ms(r)`` (optical units, per unit transmitted flux; module docstring). ``r`` 1-D, returns ``r.shape``."""
    out = np.empty(len(r))
    t = DEPTHS[None, :]
    for k in range(0, len(r), 64):
        rr = np.asarray(r[k:k + 64], dtype=np.float64)[:, None]
        d_r = np.sqrt(rr * rr + t * t)
        kappa = -np.expm1(-2.0 * (d_r + t))  # Habel et al. 2013, Eq. 12
        out[k:k + 64] = albedo**2 * _depth_integral(np.exp(-t) * kappa * point_source_exitance(rr, t, albedo, eta))
    return out


def single_scattering(r, albedo, eta):
    """``M_ss(r)`` (optical units, per unit transmitted flux; module docstring). ``r`` 1-D, returns ``r.shape``."""
    out = np.empty(len(r))
    for k in range(0, len(r), 64):
        rr = np.asarray(r[k:k + 64], dtype=np.float64)[:, None]
        # nothing leaves from depths above t_c = r sqrt(eta^2 - 1) (total internal reflection): start there
        t = rr * np.sqrt(max(eta * eta - 1.0, 0.0)) + DEPTHS[None, :]
        d = np.sqrt(rr * rr + t * t)
        cos = t / d
        leave = 1.0 - fresnel_reflectance(1.0 / eta, cos)  # Habel et al. 2013, Eq. 7
        out[k:k + 64] = albedo * _depth_integral(np.exp(-t - d) * leave * cos / (4.0 * np.pi * d * d))
    return out


class BeamDiffusionProfile(OpticalProfile):
    """Photon beam diffusion with single scattering (Habel et al. 2013), in the normalization of Eq. 1.

    Parameters
    ----------
    sigma_s_prime, sigma_a : array_like
        Reduced scattering and absorption, 1/mm.
    eta : float
        Relative index of the boundary.
    """

    name = "pbd"
    title = "photon beam diffusion + single scattering (Habel et al. 2013)"
    rank = 2

    model = "pbd"

    @classmethod
    def optical_values(cls, r, albedo, eta):
        return (multiple_scattering(r, albedo, eta) + single_scattering(r, albedo, eta)) / diffuse_transmittance(eta)


register_profile(BeamDiffusionProfile)
