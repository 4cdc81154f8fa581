"""Guided flights for the random walk (:mod:`.walk`): zero-variance-based (Dwivedi) sampling of a scattering vertex's
direction and of its next free flight towards the scene's lights (incident-light guiding: Meng, Hanika and
Dachsbacher 2016, after Křivánek and d'Eon 2014), mixed with the classic technique (the phase function and
``e^{-sigma_t t}``) by one-sample MIS.

In a half-space of single-scattering albedo ``alpha`` the radiance deep inside decays as ``e^{-sigma_t z / nu0}``,
``nu0 > 1`` the root of

    alpha nu0 atanh(1 / nu0) = 1                                                                          (Eq. G1)

(Case's discrete eigenvalue). The zero-variance walk towards the lit side then draws the cosine ``mu`` between its
direction and the *axis* (the way to the light) with density

    p(mu) = 1 / ((nu0 - mu) ln((nu0 + 1) / (nu0 - 1)))    on [-1, 1]; p(mu) / (2 pi) per steradian          (Eq. G2)

and its flight with the extinction ``sigma_t (1 - mu / nu0)``: longer towards the light, shorter away from it
(Eq. G3). A back-lit object's light reaches the camera's side by the paths that come near its back, which the
classic walk draws rarely and weighs heavily; these draw them more often, with less weight.

A vertex has one axis per guiding light ``k`` (:data:`GUIDE_SAMPLE` of each finite emitter and each directional
light, seen from the vertex: a deterministic function of the vertex, so that every density below is known). It draws
with probability ``P`` the guided pair about axis ``k`` (chosen uniformly among the ``K``), else the classic pair;
the pair's density for channel ``j`` is the mixture

    (1 - P) p_phase p_flight,j + (P / K) sum_k p_G2(mu_k; nu_j) p_G3,j(t; mu_k)                           (Eq. G4)

which is the classic pair's times :func:`correction`. The walk keeps its classic ratios (Eq. W1) and multiplies in
Eq. G4's factor where the pair ends: at the next event, and in next-event estimation for the path that would have
flown to the light (Eq. W2). Unbiased for any ``P`` and axes; the classic technique always in the mix, so that the
guided density leaves no fireflies where it is wrong. ``nu0`` per channel from the object's reduced albedo (the
similarity relation), held to [:data:`NU_MIN`, :data:`NU_MAX`].
"""

import drjit as dr
import numpy as np

from ..backend import import_mitsuba

mi = import_mitsuba()

#: The probability ``P`` that a scattering vertex draws the guided pair (0: the classic walk; 0.5 and 0.8 measured no
#: better, see the commit that removes this module).
GUIDED_PROBABILITY = 0.0
#: ``nu0`` is held to this range: near 1 (albedo near 0) Eq. G2 is a spike along the axis, and at albedo 1 it is
#: infinite (the uniform sphere, the classic walk).
NU_MIN, NU_MAX = 1.01, 1e3
#: The light sample that gives a vertex its axis towards a light: a point light's position, an area light's centre.
GUIDE_SAMPLE = (0.5, 0.5)


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


def guiding_lights(scene):
    """The emitters a walk is guided towards: every one but the environment (an infinite emitter that is not a
    directional light has no one way to it)."""
    flags = mi.EmitterFlags
    return [e for e in scene.emitters()
            if not mi.has_flag(e.flags(), flags.Infinite) or mi.has_flag(e.flags(), flags.DeltaDirection)]


def axes(lights, it, active):
    """Per guiding light, the unit direction from ``it`` (an Interaction3f) towards its :data:`GUIDE_SAMPLE`."""
    sample = mi.Point2f(*GUIDE_SAMPLE)
    return [light.sample_direction(it, sample, active)[0].d for light in lights]


def _log_ratio(nu):
    return dr.log((nu + 1.0) / (nu - 1.0))


def sample_direction(axis, nu, sample):
    """A direction drawn by Eq. G2 about ``axis`` (unit) with ``nu`` (mi.Float) from ``sample`` (mi.Point2f)."""
    mu = nu - (nu + 1.0) * dr.exp(-sample.x * _log_ratio(nu))  # the inverse of Eq. G2's distribution
    mu = dr.clip(mu, -1.0, 1.0)
    sin = dr.safe_sqrt(1.0 - mu * mu)
    phi = 2.0 * dr.pi * sample.y
    return mi.Frame3f(axis).to_world(mi.Vector3f(sin * dr.cos(phi), sin * dr.sin(phi), mu))


def direction_pdf(nu, mu):
    """Eq. G2 per steradian at cosine ``mu`` to the axis, for each channel's ``nu`` (mi.Color3f)."""
    return 1.0 / (2.0 * dr.pi * (nu - mu) * _log_ratio(nu))


def correction(nu, sigma_t, mus, phase_pdf, t, collided, probability):
    """Eq. G4 over the classic pair's density, per channel (mi.Color3f): ``(1 - P) + (P / K) sum_k (p_G2 / p_phase)
    (p_G3 / p_flight)``, the direction at cosines ``mus`` (one per axis) to the axes and ``phase_pdf`` the phase
    function's density there, the flight ``t`` long ending in a collision (``collided``) or passing on (its
    transmittance's ratio ``e^{sigma_t mu t / nu}``)."""
    guided = dr.zeros(mi.Color3f, dr.width(t))
    for mu in mus:
        flight = dr.exp(dr.minimum(sigma_t * mu * t / nu, 80.0))
        flight = dr.select(collided, flight * (1.0 - mu / nu), flight)
        guided += direction_pdf(nu, mu) / phase_pdf * flight
    return (1.0 - probability) + probability / len(mus) * guided
