"""Radial diffusion profiles ``R_d(r)``: the material's response to a unit point flux (paper Eq. 1).

Units: ``r`` in mm, ``R_d`` in 1/mm^2 per RGB channel, so ``∫ 2 pi r R_d(r) dr`` (the total diffuse reflectance) is
dimensionless. Every profile answers the same questions, which size the convolution kernels later:

- ``profile(r)`` -> array of shape ``r.shape + (3,)``;
- ``total_reflectance`` -> ``∫_0^inf 2 pi r R_d(r) dr`` per channel;
- ``energy_within(radius)`` -> ``∫_0^radius 2 pi r R_d(r) dr``;
- ``radius_below(t)`` -> smallest r with ``R_d(r) <= t R_d(0)`` (the paper's threshold distance ``d_t``, Eq. 8);
- ``radius_energy(f)`` -> smallest r that holds all but a fraction ``f`` of the total;
- ``effective_area()`` -> ``(∫ R_d dA)^2 / ∫ R_d^2 dA``, the area the profile averages over (sizes the samples).

Models (:data:`PROFILE_MODELS`, chosen per object by the renderer's ``profile`` parameter): the classic dipole of
Jensen et al. 2001 (the paper's choice, here), the better dipole (d'Eon 2012, :mod:`.better_dipole`), photon beam
diffusion with single scattering (Habel et al. 2013, :mod:`.beam_diffusion`), Christensen & Burley 2015
(:mod:`.burley`), and a tabulated profile given by the user (the paper's "arbitrary diffusion profiles").
:mod:`.slab` is their ground truth: a light tracer of the path-traced semi-infinite slab.

Normalization (the one statement for every model). The renderer computes paper Eq. 2,
``E = ∫ F_t(eta, w_i) L_i cos dw_i`` (the flux that enters), Eq. 1, ``M(x_o) = ∫ R_d(|x_o - x_i|) E(x_i) dA``, and
Eq. 7, ``L_o = (1/pi) F_t(eta, w_o) M``. The exitance that Eq. 7 sends out is ``∫ L_o cos dw_o = T_d(eta) M`` with
``T_d = 1 - 2 ∫_0^1 F_r(eta, mu) mu dmu`` (:func:`~convsss.fresnel.diffuse_transmittance`). So a model whose physics
gives the exitance ``M_phys(r)`` that leaves the surface per unit flux that entered (the better dipole's and photon
beam diffusion's ``c_phi phi + c_E E_n``, Christensen–Burley's fit, the Monte Carlo tally) enters Eq. 1 as
``R_d(r) = M_phys(r) / T_d(eta)``: energy is conserved through Eq. 2, 1 and 7, and ``total_reflectance`` is the
slab's albedo over ``T_d``. pbrt writes the same BSSRDF as ``(1 - F_r(cos_o)) S_p(r) S_w(w_i)`` with
``S_w = (1 - F_r(cos_i)) / (pi c)``, ``c = 1 - 2 C_1``: the ``1/c`` there is our ``1/T_d`` moved to the entry side.
The classic dipole keeps the paper's ``R_d`` (the flux ``E_n`` alone, with ``alpha'``), unchanged.
"""

from .base import CHANNELS, PEAK_ENERGY, PROFILE_MODELS, Profile, ScaledProfile, register_profile
from .beam_diffusion import BeamDiffusionProfile
from .better_dipole import BetterDipoleProfile
from .burley import BurleyProfile
from .dipole import DipoleProfile
from .models import DEFAULT_PROFILE, material_from_color, model_profile, parse_profile_spec, resolve_profile
from .tabulated import MAX_PROFILE_ROWS, MAX_RADIUS_MM, TabulatedProfile

__all__ = ["CHANNELS", "DEFAULT_PROFILE", "MAX_PROFILE_ROWS", "MAX_RADIUS_MM", "PEAK_ENERGY", "PROFILE_MODELS",
           "BeamDiffusionProfile", "BetterDipoleProfile", "BurleyProfile", "DipoleProfile", "Profile", "ScaledProfile",
           "TabulatedProfile", "material_from_color", "model_profile", "parse_profile_spec", "register_profile",
           "resolve_profile"]
