"""Guided flights for the random walk (:mod:`.walk`): zero-variance-based sampling of a scattering vertex's direction
and its next free flight towards the surface the path entered through (Křivánek and d'Eon 2014; Meng, Hanika and
Dachsbacher 2016), mixed with the classic technique (the phase function and ``e^{-sigma_t t}``) by one-sample MIS.

In a half-space of single-scattering albedo ``alpha`` the radiance deep inside decays as ``e^{-sigma_t z / nu0}``,
``nu0 > 1`` the root of

    alpha nu0 atanh(1 / nu0) = 1                                                                          (Eq. G1)

(the slowest mode of the transport equation, Case's discrete eigenvalue). The zero-variance walk towards the surface
then draws the cosine ``mu`` between its direction and the outward normal (the *axis*) with density

    p(mu) = 1 / ((nu0 - mu) ln((nu0 + 1) / (nu0 - 1)))    on [-1, 1], i.e. p(mu) / (2 pi) per steradian      (Eq. G2)

and its flight with the extinction ``sigma_t (1 - mu / nu0)``: longer towards the surface, shorter away from it
(Eq. G3). A walk chooses per vertex, with probability ``P``, the guided pair (Eq. G2, G3) or the classic pair; its
density is the mixture ``(1 - P) p_phase p_flight + P p_G2 p_G3`` for every channel ``j`` (``nu0`` and ``sigma_t``
of channel ``j``: Eq. W1's densities), which is the classic pair's times :func:`correction` (Eq. G4). The walk keeps
its classic ratios and multiplies in Eq. G4 where the pair ends: at the next event, and in next-event estimation
for the path that would have flown to the light. Unbiased for any ``P``, axis and ``nu0``; the classic technique
always in the mix, so that the guided density cannot leave fireflies where it is wrong. ``nu0`` is taken from the
reduced albedo (the similarity relation) and held to [:data:`NU_MIN`, :data:`NU_MAX`].
"""

import drjit as dr
import numpy as np

from ..backend import import_mitsuba

mi = import_mitsuba()

#: The probability ``P`` that a vertex samples the guided pair (0: the classic walk; 0.5 measured no better, see the
#: commit that removes this module).
GUIDED_PROBABILITY = 0.0
#: ``nu0`` is held to this range: near 1 (albedo near 0) Eq. G2 is a spike along the axis, and at albedo 1 it is
#: infinite (the uniform sphere).
NU_MIN, NU_MAX = 1.01, 1e3


def dwivedi_nu(albedo):
    """``nu0`` of Eq. G1 for each ``albedo`` (array-like in [0, 1]), held to [:data:`NU_MIN`, :data:`NU_MAX`].

    >>> [round(float(x), 4) for x in dwivedi_nu([0.5, 0.9, 0.99])]
    [1.0444, 1.9032, 5.7967]
    """
    albedo = np.clip(np.asarray(albedo, dtype=np.float64), 0.0, 1.0)
    lo, hi = np.full(albedo.shape, 1.0 + 1e-12), np.full(albedo.shape, NU_MAX)
    for _ in range(200):  # bisection on alpha nu atanh(1/nu) - 1, which falls from +inf at 1 to alpha - 1 < 0
        mid = np.sqrt(lo * hi)
        above = albedo * mid * np.arctanh(1.0 / mid) > 1.0
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    return np.clip(np.sqrt(lo * hi), NU_MIN, NU_MAX)


def _log_ratio(nu):
    return dr.log((nu + 1.0) / (nu - 1.0))


def sample_direction(axis, nu, sample):
    """A direction (world space) drawn by Eq. G2 around ``axis`` (unit, outward) with ``nu`` (mi.Float) from
    ``sample`` (mi.Point2f)."""
    mu = nu - (nu + 1.0) * dr.exp(-sample.x * _log_ratio(nu))  # (nu + 1) ((nu - 1) / (nu + 1))^u
    mu = dr.clip(mu, -1.0, 1.0)
    sin = dr.safe_sqrt(1.0 - mu * mu)
    phi = 2.0 * dr.pi * sample.y
    return mi.Frame3f(axis).to_world(mi.Vector3f(sin * dr.cos(phi), sin * dr.sin(phi), mu))


def direction_pdf(nu, mu):
    """Eq. G2 per steradian at cosine ``mu`` to the axis, for each channel's ``nu`` (mi.Color3f)."""
    return 1.0 / (2.0 * dr.pi * (nu - mu) * _log_ratio(nu))


def correction(nu, sigma_t, mu, t, collided, direction_ratio, probability=GUIDED_PROBABILITY):
    """Eq. G4: the mixture's density of a direction and flight over the classic pair's, per channel (mi.Color3f):
    ``(1 - P) + P (p_G2 / p_phase) (p_G3 / p_flight)``, the flight ``t`` long ending in a collision (``collided``)
    or passing on (its transmittance's ratio ``e^{sigma_t mu t / nu}``); ``direction_ratio`` is ``p_G2 / p_phase``
    per channel."""
    flight = dr.exp(dr.minimum(sigma_t * mu * t / nu, 80.0))
    flight = dr.select(collided, flight * (1.0 - mu / nu), flight)
    return (1.0 - probability) + probability * direction_ratio * flight
