"""The medium of the diffusion solve: its coefficients on a grid of spacing ``h`` (Eq. D1-D5) from the object's
material, and the grid's spacing (:mod:`convsss.transport.volume`)."""

from dataclasses import dataclass

import numpy as np

from ...errors import ConvsssError
from ...profiles.dipole import DipoleProfile

#: A channel is corrected where its diffusion length is at least this many cells (where it is shorter, what the
#: grid resolves of the shape is several diffusion lengths wide, and Eq. 1 stands).
RESOLVED_LENGTH = 2.0


def medium_of(material):
    """The classic dipole of the object's :class:`~convsss.materials.Material` (``sigma_s'``, ``sigma_a``,
    ``eta``): it names ``D``, ``z_r`` and ``A``; a one-line error without one."""
    if material is None:
        raise ConvsssError("the volume transport needs the object's material (sigma_s', sigma_a, eta) beside its "
                           "profile: make_transport(..., material=...)")
    return DipoleProfile(material.sigma_s_prime, material.sigma_a, material.eta)


@dataclass(frozen=True)
class Coefficients:
    """Per channel (3,) each, on a grid of spacing ``h``: ``diffusion`` ``D`` and the grid's ``absorption`` (1/mm,
    Eq. D3) of Eq. D1, ``sigma_tr`` (1/mm), ``z_r`` and ``z_b`` (mm), ``beta`` of Eq. D4; where sources sit (Eq.
    D5): their distance inside the extrapolated boundary ``source_depth`` (mm) and gain ``source_gain``; the reads of
    Eq. D4: their two distances inside the extrapolated boundary ``read_depths`` (2, 3) (mm) and weights
    ``read_weights`` (2, 3) (1/mm)."""

    diffusion: np.ndarray
    absorption: np.ndarray
    sigma_tr: np.ndarray
    z_r: np.ndarray
    z_b: np.ndarray
    beta: np.ndarray
    source_depth: np.ndarray
    source_gain: np.ndarray
    read_depths: np.ndarray
    read_weights: np.ndarray

    def key(self):
        return np.concatenate([self.diffusion, self.absorption, self.source_depth, self.read_depths.ravel()]).tobytes()


def coefficients(profile, material, h, reflection=None):
    """The :class:`Coefficients` of ``material`` on a grid of spacing ``h``, its sources' strength that of
    ``profile``'s total reflectance; ``reflection``: the boundary's ``A`` of ``z_b = 2 A D`` (default the classic
    dipole's, whose half-space the transport's correction is calibrated on).

    The grid's absorption makes the discrete equation decay along a grid axis at the continuous rate ``sigma_tr``
    (a lattice decays as ``cosh(kappa h) = 1 + sigma_a h^2 / (2 D)``, slower than ``sigma_tr`` by a relative
    ``(sigma_tr h)^2 / 24``, a 14 % excess ten diffusion lengths out at ``h`` half of one):

        sigma_a,h = (2 D / h^2) (cosh(sigma_tr h) - 1).                                                  (Eq. D3)

    The exitance is Fick's flux through the real surface, ``z_b`` inside the extrapolated boundary, of the field
    of sources of strength ``alpha'`` (the dipole's):

        M = beta du/dd (z_b),   beta = s alpha' D,                                                         (Eq. D4)

    ``d`` the distance inside the extrapolated boundary along the normal, ``s`` the profile's total over the
    classic dipole's (1 for the dipole; the scale of a model, or of the exact total). The slope is that of
    ``u = g(d) (a + b d)`` through the field at two depths, ``d_1 = max(z_b, 0.75 h)`` and ``d_2 = d_1 + h``:
    ``du/dd (z_b) = w_1 u(d_1) + w_2 u(d_2)``, with ``g(d) = sinh(sigma_tr d) / sigma_tr`` the depth profile of a
    field uniform along the surface (``b = 0``; ``b`` takes the field's variation along it: a parabola in ``d``
    instead would miss the uniform field's slope). A fixed ratio of flux to fluence would be right only for a
    uniform field: around a point source, the flux at the surface over ``D sigma_tr coth(sigma_tr z_b)`` times the
    fluence is above 1 near the source and below it farther out, and the half-space's response read that way sat
    above the dipole's.

    The boundary layer (``z_r + z_b``, about one mean free path) is often thinner than a cell; a source in it
    would then depend on where the boundary falls within the cell (by a factor of two on a half-space). Only the
    field away from the source matters to the correction of Eq. D2, and there a source at distance ``d`` inside a
    boundary acts in proportion to ``g(d) = sinh(sigma_tr d) / sigma_tr``. So sources are put at least 1.5 cells
    inside the extrapolated boundary, with the gain that keeps the field they make:

        d_s = max(z_r + z_b, 1.5 h),   gain g(z_r + z_b) / g(d_s).                                       (Eq. D5)
    """
    dipole = medium_of(material)
    sigma_t_prime = dipole.sigma_s_prime + dipole.sigma_a
    diffusion = 1.0 / (3.0 * sigma_t_prime)
    sigma_tr = np.asarray(dipole.sigma_tr, dtype=np.float64)
    with np.errstate(over="ignore"):  # a spacing of many diffusion lengths: no channel is solved (RESOLVED_LENGTH)
        absorption = (2.0 * diffusion / h**2) * (np.cosh(sigma_tr * h) - 1.0)  # Eq. D3
    own = np.asarray(dipole.total_reflectance, dtype=np.float64)
    scale = np.divide(np.asarray(profile.total_reflectance, dtype=np.float64), own, out=np.zeros(3), where=own > 0)
    z_b = 2.0 * (dipole.A if reflection is None else reflection) * diffusion

    def g(d):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return np.where(sigma_tr * d > 1e-8, np.sinh(sigma_tr * d) / np.where(sigma_tr > 0, sigma_tr, 1.0), d)

    source_depth = np.maximum(dipole.z_r + z_b, 1.5 * h)  # Eq. D5
    d_1 = np.maximum(z_b, 0.75 * h)  # Eq. D4: u = g (a + b d) through u(d_1), u(d_2), sloped at z_b
    d_2 = d_1 + h
    lever = np.cosh(sigma_tr * z_b) * (z_b - d_1) + g(z_b)
    w_1 = (np.cosh(sigma_tr * z_b) - lever / h) / g(d_1)
    w_2 = lever / (h * g(d_2))
    return Coefficients(diffusion, absorption, sigma_tr, dipole.z_r, z_b, scale * dipole.alpha_prime * diffusion,
                        source_depth, g(dipole.z_r + z_b) / g(source_depth), np.stack([d_1, d_2]),
                        np.stack([w_1, w_2]))


def auto_spacing(material, extent):
    """The grid spacing (mm) for an object of largest ``extent`` (mm): half the shortest diffusion length (the far
    field's scale), within [extent / 64, extent / 24], and no finer than a quarter of the shortest transport mean free
    path (an object far smaller than one, where diffusion means nothing, would otherwise ask a grid of its boundary
    layer's thousands of cells a side)."""
    dipole = medium_of(material)
    with np.errstate(divide="ignore"):
        length = float(np.min(1.0 / dipole.sigma_tr))
    mfp = float(np.min(1.0 / (dipole.sigma_s_prime + dipole.sigma_a)))
    return max(float(np.clip(0.5 * length, extent / 64.0, extent / 24.0)), 0.25 * mfp)
