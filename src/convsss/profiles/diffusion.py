"""What the better dipole and photon beam diffusion share: the boundary of a diffusive half-space, and one point source.

Derivation (d'Eon 2012, "A better dipole", §2–3; Habel et al. 2013, §3). Inside, the diffusion radiance is
``L(w) = phi/(4 pi) + 3/(4 pi) E . w``. Through a smooth boundary of relative index ``eta``, light inside meets the
index ``1/eta``; with the Fresnel moments ``C_n = ∫_0^1 F_r(1/eta, mu) mu^n dmu``:

- leaving (the exitance outside, over the upper hemisphere): ``M = c_phi phi + c_E E_n``, with
  ``c_phi = (1 - 2 C_1)/4`` and ``c_E = (1 - 3 C_2)/2`` (d'Eon 2012, Eq. 11);
- coming back (partial-current boundary condition: the inward current is the reflected part of the outward one):
  ``phi = 2 A D d phi/dn``, ``A = (1 + 3 C_2)/(1 - 2 C_1)`` (d'Eon 2012, Eq. 12), so ``phi`` vanishes on a plane
  ``z_b = 2 A D`` above the surface and a negative image source at ``-(z + 2 z_b)`` stands for the boundary.
- Grosjean's diffusion coefficient ``D = (2 sigma_a + sigma_s')/(3 sigma_t'^2)`` and ``sigma_tr = sqrt(sigma_a/D)``
  (d'Eon 2012, Eq. 5; Habel et al. 2013, Eq. 9).

A unit isotropic point source at depth ``z`` then gives at radius ``r`` on the surface (``d_r = sqrt(r^2 + z^2)``,
``z_v = z + 2 z_b``, ``d_v = sqrt(r^2 + z_v^2)``):
``phi = (e^{-sigma_tr d_r}/d_r - e^{-sigma_tr d_v}/d_v) / (4 pi D)`` and
``E_n = D d phi/dz |_0 = (z (1 + sigma_tr d_r) e^{-sigma_tr d_r}/d_r^3``
``+ z_v (1 + sigma_tr d_v) e^{-sigma_tr d_v}/d_v^3) / (4 pi)``.
All in optical units here (``sigma_t' = 1``): lengths in mean free paths.
"""

from functools import cache

import numpy as np

from ..fresnel import fresnel_moment


@cache
def boundary(eta):
    """``(c_phi, c_E, A)`` of a boundary of relative index ``eta`` (module docstring)."""
    c1, c2 = fresnel_moment(1.0 / eta, 1), fresnel_moment(1.0 / eta, 2)
    return (1.0 - 2.0 * c1) / 4.0, (1.0 - 3.0 * c2) / 2.0, (1.0 + 3.0 * c2) / (1.0 - 2.0 * c1)


def grosjean(albedo):
    """``(D, sigma_tr)`` in optical units for reduced albedo ``albedo`` (Grosjean's ``D``, d'Eon 2012 Eq. 5)."""
    albedo = np.asarray(albedo, dtype=np.float64)
    d = (2.0 * (1.0 - albedo) + albedo) / 3.0
    return d, np.sqrt((1.0 - albedo) / d)


def point_source_exitance(r, z, albedo, eta):
    """Exitance ``c_phi phi + c_E E_n`` at surface radius ``r`` from a unit isotropic source at depth ``z``.

    Parameters
    ----------
    r, z : array_like
        Radius on the surface and source depth, in mean free paths (broadcast together).
    albedo : float
        Reduced albedo ``alpha'``.
    eta : float
        Relative index of the boundary.

    Returns
    -------
    numpy.ndarray
        Exitance per unit source power, per mfp^2 (the broadcast shape of ``r`` and ``z``).
    """
    c_phi, c_e, a = boundary(float(eta))
    d, sigma_tr = grosjean(albedo)
    z_v = z + 4.0 * a * d  # the image source, 2 z_b = 4 A D above the real one's mirror
    d_r = np.sqrt(r * r + z * z)
    d_v = np.sqrt(r * r + z_v * z_v)
    e_r, e_v = np.exp(-sigma_tr * d_r), np.exp(-sigma_tr * d_v)
    phi = (e_r / d_r - e_v / d_v) / (4.0 * np.pi * d)
    e_n = (z * (1.0 + sigma_tr * d_r) * e_r / d_r**3 + z_v * (1.0 + sigma_tr * d_v) * e_v / d_v**3) / (4.0 * np.pi)
    return c_phi * phi + c_e * e_n
