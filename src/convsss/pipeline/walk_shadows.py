"""The random walk's shadow rays (:mod:`.walk`): from a scattering vertex or a surface to a light sample, through null
boundaries and the media between by ratio tracking (a homogeneous medium's transmittance taken whole where the walk
is not ``volpathmis``'s estimator, with Russian roulette below :data:`SHADOW_ROULETTE`), every channel's density kept
for Eq. W1 and W2, and out through a smooth dielectric boundary: from a vertex along the refracted path to the light
(Eq. W5, :mod:`.manifold`), from a surface straight (Eq. W4). :class:`ShadowRays` is the walk's part that casts them
(:class:`~.walk.RandomWalk` derives from it).
"""

from dataclasses import dataclass

import drjit as dr
import numpy as np

from ..backend import import_mitsuba
from .derivatives import add_length, zero_scores
from .irradiance import fresnel_transmittance, refracted_cosine
from .manifold import Refraction, refract_toward
from .spectral_mis import mis, update

mi = import_mitsuba()


#: An environment is solved through a smooth boundary (Eq. W5) where the second moment of its radiance over the
#: sphere is at least this many times its mean squared (1: uniform). Measured on a 40 mm potato bunny behind glass,
#: 64², 16 spp (efficiency, 1 / (relative variance x seconds), solved over left to the hits): a sky of two halves
#: (1.67) 0.43, suns of 3x3 pixels on a 64x128 sky (8.6, 61, 250, 883) 2.7, 5.2, 8.7, 11.5.
CONCENTRATION = 4.0


def concentration(emitter):
    """``E[L^2] / E[L]^2`` of an environment's radiance over the sphere (its luminance, each pixel of a latitude-
    longitude map weighed by its solid angle): 1 for a uniform one, large where a sun gives most of its light;
    infinite for an environment whose radiance cannot be read (a sun-and-sky model)."""
    params = mi.traverse(emitter)
    if "data" not in params:
        return 1.0 if "radiance.value" in params else float("inf")
    data = np.asarray(params["data"])
    luminance = data.mean(axis=-1, dtype=np.float64) if data.ndim == 3 else data.astype(np.float64)
    theta = (np.arange(luminance.shape[0]) + 0.5) / luminance.shape[0] * np.pi
    weight = np.sin(theta)[:, None] * np.ones_like(luminance)
    mean = (luminance * weight).sum() / weight.sum()
    return float((luminance**2 * weight).sum() / weight.sum() / mean**2) if mean > 0.0 else 1.0


def solved_environments(scene):
    """The environments of ``scene`` whose light Eq. W5 takes through a smooth boundary (:func:`through_boundary`):
    those of :func:`concentration` at least :data:`CONCENTRATION`."""
    flags = mi.EmitterFlags
    return [e for e in scene.emitters()
            if mi.has_flag(e.flags(), flags.Infinite) and not mi.has_flag(e.flags(), flags.Delta)
            and concentration(e) >= CONCENTRATION]


def through_boundary(emitter, environments):
    """Per lane, whether a smooth boundary takes ``emitter``'s light straight (Eq. W4, W5) where the walk lets it
    (:attr:`~.walk.RandomWalk.straight_through`): every emitter but an environment, and the ``environments`` given
    (:func:`solved_environments`, where Eq. W5 solves), as a directional light: a sun in a few pixels of a map, which
    chance hits through the boundary find rarely. An environment whose light comes from everywhere (a uniform one,
    Mitsuba's ``constant``; a sky) is left to the paths that refract out and hit it, which find it as well at less
    cost; Eq. W4's straight ray read a uniform one 2-3 % low."""
    flags, kind = emitter.flags(), mi.EmitterFlags
    environment = mi.has_flag(flags, kind.Infinite) & ~mi.has_flag(flags, kind.Delta)
    chosen = dr.full(mi.Bool, False, dr.width(environment))
    for solved in environments:
        chosen |= emitter == mi.EmitterPtr(solved)
    return ~environment | chosen


#: Below this transmittance (largest channel) a shadow ray's homogeneous segment goes on with odds T / this.
SHADOW_ROULETTE = 0.5


def shadow_odds(transmittance):
    """The odds a shadow ray's segment through a homogeneous medium goes on with (:data:`SHADOW_ROULETTE`)."""
    return dr.minimum(dr.max(transmittance) / SHADOW_ROULETTE, 1.0)


@dataclass
class _Shadow:
    """The state of a batch of the walk's shadow rays (a Dr.Jit PyTree): the ray, the distance to the light and the
    distance covered, the medium it is in, the last surface hit, where it crossed a boundary by Eq. W4, the
    density ratios as light sampling drew the light and as the path's own sampling would have, and Eq. W5's
    refraction."""

    ray: object
    max_dist: object
    medium: object
    total: object
    si: object
    needs_intersection: object
    crossed: object
    with_nee: tuple
    with_uni: tuple
    active: object
    scores: tuple  # the differentiated media's d log f / d sigma_t (and d sigma_s: 0) along it (Eq. G1)
    bent: object  # it leaves the object where Eq. W5 refracts it toward the light (manifold NEE)
    out: object  # the refracted direction there
    straight: object  # straight through a smooth boundary by Eq. W4: a surface's, or with refraction straight


class ShadowRays:
    """Next-event estimation's shadow rays of a :class:`~.walk.RandomWalk` (which holds ``scene``, ``analytic``,
    ``straight_through``, ``refracting``, ``sealed``, ``classify``, ``_outside`` and ``_evaluated``)."""

    def _sealed(self, origin, medium, ds):
        """Per lane, whether the light sample ``ds`` lies beyond the dielectric boundary around a scattering vertex
        ``origin`` inside an object of ``medium`` that stops its shadow ray (:attr:`~.walk.RandomWalk.sealed`: a
        rough one always, a smooth one where it does not take the light straight, :meth:`_straight`): the sample
        outside every box of the closed objects of that medium, whose boundary the ray crosses on its way. No shadow
        ray is cast there: it would bring no light (``volpathmis`` casts it)."""
        sealed = dr.full(mi.Bool, False, dr.width(ds.pdf))
        if isinstance(origin, mi.SurfaceInteraction3f) or not self.sealed:
            return sealed
        straight = self._straight(ds)
        for sealed_medium, rough in self.sealed:
            sealed |= (medium == sealed_medium) & (rough | ~straight)
        return sealed & self._outside(medium, ds.p)

    @dr.syntax
    def _emitter(self, origin, medium, ratios, channel, sampler, active, light=None):
        """Next-event estimation from ``origin`` (an interaction in ``medium``): a sample of emitter ``light`` (None:
        one the scene chooses) and its shadow ray through null boundaries and the media between (a ratio-tracking
        transmittance, every channel's density kept); ``(ratios as light sampling drew it, as the path's own sampling
        would, emitted L, the sample (its direction at ``origin``), where it crossed a smooth boundary by Eq. W4 or W5,
        its scores, the :class:`~.manifold.Refraction`)`` (no path's own sampling reaches the light that way; the
        scores: Eq. G1 of :mod:`.derivatives`). From a scattering vertex, a light the boundary would take straight
        (:meth:`_shadow_surface`) is reached by the refracted path to it (Eq. W5, :mod:`.manifold`) where that solve
        converges."""
        if light is None:
            ds, weight = self.scene.sample_emitter_direction(origin, sampler.next_2d(active), False, active)
        else:
            ds, weight = light.sample_direction(origin, sampler.next_2d(active), active)
        emitted = dr.select(ds.pdf == 0.0, 0.0, weight * ds.pdf)
        active = mi.Bool(active & (ds.pdf != 0.0))
        medium = mi.MediumPtr(medium)
        sealed = active & self._sealed(origin, medium, ds)
        emitted[sealed] = 0.0
        active &= ~sealed
        ray = origin.spawn_ray_to(ds.p)
        n = dr.width(ray.maxt)
        ds, ray, emitted, refraction, si, intersect = self._refracted(origin, ds, ray, emitted, active)
        active &= ~refraction.tried | refraction.found  # no refracted path to the light: none of its light
        if isinstance(origin, mi.SurfaceInteraction3f):
            medium[origin.is_medium_transition()] = origin.target_medium(ray.d)
        shadow = _Shadow(ray=ray, max_dist=mi.Float(ray.maxt), medium=medium, total=dr.zeros(mi.Float, n),
                         si=si, needs_intersection=intersect,
                         crossed=dr.full(mi.Bool, False, n),
                         with_nee=update(ratios, dr.select(refraction.found, refraction.pdf, ds.pdf), 1.0, active),
                         with_uni=ratios, active=active, scores=zero_scores(self.differentiated, n),
                         bent=refraction.found, out=refraction.out,
                         straight=dr.full(mi.Bool, isinstance(origin, mi.SurfaceInteraction3f)
                                          or not self.refracting, n))
        while shadow.active:
            remaining = shadow.max_dist - shadow.total
            shadow, mei, in_medium, escaped, trial, trial_t = self._shadow_flight(shadow, sampler, channel, ds,
                                                                                  remaining)
            shadow = self._shadow_surface(shadow, mei, in_medium, escaped, trial, trial_t, ds, remaining)
        return shadow.with_nee, shadow.with_uni, emitted, ds, shadow.crossed, shadow.scores, refraction

    def _refracted(self, origin, ds, ray, emitted, active):
        """``(ds, ray, emitted, refraction, si, intersect)``: from a scattering vertex, the light sample, shadow ray
        and emission moved onto the refracted path to the light where Eq. W5 found it
        (:func:`~.manifold.refract_toward`; from a surface as they are, none found), and the shadow ray's first
        surface where the solve's straight ray found it already (``intersect``: where it is still to find)."""
        n = dr.width(ray.maxt)
        if isinstance(origin, mi.SurfaceInteraction3f) or not self.refracting:
            return ds, ray, emitted, Refraction.none(n), dr.zeros(mi.SurfaceInteraction3f, n), dr.full(mi.Bool, True, n)
        cast = active & self._straight(ds)
        refraction = refract_toward(self.scene, self.classify, origin.p, ds, cast)
        bent = refraction.found
        ds.d[bent] = refraction.d
        ray.d[bent] = refraction.d
        ray.maxt[bent] = refraction.length
        emitted[refraction.tried] = refraction.emitted  # none where no refracted path was found
        si = refraction.straight  # the same ray as the shadow's, unbounded: no surface past the light counts
        si.t[si.t >= ray.maxt] = dr.inf
        return ds, ray, emitted, refraction, si, ~cast | bent

    def _straight(self, ds):
        """The light samples a smooth boundary takes straight (Eq. W4, W5): a delta light's, which no path can reach,
        and with :attr:`straight_through` every light's but a sunless environment's (:func:`through_boundary`)."""
        return ds.delta | (self.straight_through & through_boundary(ds.emitter, self.environments))

    def _shadow_flight(self, shadow, sampler, channel, ds, remaining):
        """One step of the shadow ray in a medium (``remaining`` the distance left to the light): ratio tracking to
        the next null collision or surface, or in a homogeneous medium with :attr:`analytic` its transmittance to the
        surface or the light."""
        ray, si, medium = shadow.ray, shadow.si, shadow.medium
        ray.maxt = remaining
        shadow.active &= remaining > 0.0
        active_medium = shadow.active & (medium != None)  # noqa: E711
        analytic = active_medium & medium.is_homogeneous() & self.analytic
        mei = medium.sample_interaction(ray, sampler.next_1d(active_medium), channel, active_medium)
        ray.maxt[active_medium & medium.is_homogeneous() & mei.is_valid() & ~analytic] = dr.minimum(mei.t, remaining)
        intersect = shadow.needs_intersection & active_medium
        si[intersect] = self.scene.ray_intersect(ray, intersect)
        mei.t[analytic] = dr.inf  # no collision drawn: the transmittance to the surface or the light, whole
        mei.t[active_medium & (si.t < mei.t)] = dr.inf
        shadow.needs_intersection &= ~active_medium
        trial, trial_t, _ = self._evaluated(medium, active_medium)
        spectral = active_medium & (medium.has_spectral_extinction() | trial)
        grey = active_medium & ~spectral
        t = dr.minimum(remaining, dr.minimum(mei.t, si.t)) - mei.mint
        shadow.scores = add_length(shadow.scores, self.differentiated, medium, t, active_medium)  # Eq. G1
        transmittance = dr.exp(-t * mei.combined_extinction)
        flight_pdf = dr.select((si.t < mei.t) | (mei.t > remaining), transmittance,
                               transmittance * mei.combined_extinction)
        odds = shadow_odds(transmittance)  # by the drawn medium, not a trial's
        transmittance[trial] = dr.exp(-t * trial_t)
        transmittance[analytic & (sampler.next_1d(analytic) >= odds)] = 0.0
        # Light sampling drew it whole where analytic (its density: the odds); a flight passes it with e^{-sigma_t t}
        shadow.with_nee = update(shadow.with_nee, dr.select(analytic, odds, flight_pdf), transmittance,
                                 spectral | analytic)
        shadow.with_uni = update(shadow.with_uni, flight_pdf, transmittance, spectral)
        shadow.total[active_medium & (mei.t > remaining) & mei.is_valid()] = shadow.max_dist
        mei.t[active_medium & (mei.t > remaining)] = dr.inf
        escaped = active_medium & ~mei.is_valid()
        active_medium &= mei.is_valid()
        spectral &= active_medium
        grey &= active_medium
        shadow.total[active_medium] += mei.t
        ray.o[active_medium] = mei.p
        si.t[active_medium] = si.t - mei.t
        shadow.with_nee = update(shadow.with_nee, 1.0, mei.sigma_n, spectral)
        shadow.with_uni = update(shadow.with_uni, dr.sum(mei.sigma_n / mei.combined_extinction) / 3.0, mei.sigma_n,
                                  spectral)
        shadow.with_nee = update(shadow.with_nee, 1.0, mei.sigma_n / mei.combined_extinction, grey)
        return shadow, mei, active_medium, escaped, trial, trial_t

    def _shadow_surface(self, shadow, mei, in_medium, escaped, trial, trial_t, ds, remaining):
        """The shadow ray at a surface: through a null one, blocked by any other, except a smooth dielectric boundary
        of a translucent object that a delta light (every light but a sunless environment where
        :attr:`straight_through`) crosses: refracted toward it where Eq. W5 found the path, straight out by Eq. W4 from
        a surface."""
        ray, si, medium = shadow.ray, shadow.si, shadow.medium
        active_surface = shadow.active & (medium == None)  # noqa: E711
        intersect = active_surface & shadow.needs_intersection
        si[intersect] = self.scene.ray_intersect(ray, intersect)
        active_surface |= escaped
        shadow.total[active_surface] += si.t
        inside = active_surface & (medium != None)  # noqa: E711 (leaving a medium here)
        active_surface &= si.is_valid() & shadow.active & ~in_medium
        bsdf = si.bsdf(ray)
        passed = bsdf.eval_null_transmission(si, active_surface)
        # A delta light through a translucent object's smooth dielectric boundary, which no path can reach (with
        # straight_through, every light but a sunless environment): refracted toward the light where Eq. W5 solved the
        # path from a vertex (bent), or from a surface straight out, times the Fresnel transmittance, the beam's
        # compression and, in a homogeneous medium, the refracted path's length inside (Eq. W4). A rough one is left
        # to the next-event estimation at the boundary, where its BSDF takes the light.
        which, eta = self.classify(si)
        smooth = ~mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
        cos = dr.dot(si.n, ray.d)  # > 0: leaving along the outward normal
        through = (inside & (cos > 0.0) & active_surface & self._straight(ds) & (which >= 0) & smooth
                   & (dr.max(passed) == 0.0))
        bent = through & shadow.bent
        through &= shadow.straight
        shadow.crossed |= through
        cos_out = dr.abs(cos)
        compression = cos_out / dr.maximum(refracted_cosine(eta, cos_out), 1e-6)
        sigma_t = dr.select(medium.is_homogeneous(), mi.Color3f(mei.combined_extinction), 0.0)
        sigma_t[trial] = trial_t
        passed[through] = (fresnel_transmittance(eta, cos_out) * compression
                           * dr.exp(-sigma_t * shadow.total * (compression - 1.0)))  # Eq. W4
        shadow.scores = add_length(shadow.scores, self.differentiated, medium, shadow.total * (compression - 1.0),
                                   through)  # Eq. G1 of Eq. W4's refracted path
        # Eq. W5: eta^2 F_t (its geometry in its density; its path inside stepped already), which the path's own
        # sampling reaches too, choosing the refraction with odds F_t
        transmitted = fresnel_transmittance(eta, dr.dot(shadow.out, si.sh_frame.n))
        passed[bent] = dr.square(eta) * transmitted
        ray.d[bent] = shadow.out
        shadow.with_nee = update(shadow.with_nee, 1.0, passed, active_surface)
        shadow.with_uni = update(shadow.with_uni, dr.select(bent, transmitted, 1.0), passed, active_surface)
        ray[active_surface] = si.spawn_ray(ray.d)
        ray.maxt = remaining
        shadow.needs_intersection |= active_surface
        shadow.active &= (in_medium | active_surface) & dr.any(mis(shadow.with_uni) != 0.0)
        crossing = active_surface & si.is_medium_transition()
        medium[crossing] = si.target_medium(ray.d)
        return shadow
