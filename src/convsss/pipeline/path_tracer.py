"""The render's path tracer: one per prepared state, the service the stages share.

It shades the camera rays (:meth:`PathTracer.trace`, the shading stage, inside Mitsuba's render loop) and traces
the light that reaches the irradiance samples off the scene (:meth:`PathTracer.incident`, the indirect part of paper
Eq. 2, before any transport exists); where it reads ``M`` (the screen and mesh tables, the transports, the hits of
paths traced before the transports existed) is :mod:`.lookups`, whose transports are attached when they are built
(:meth:`PathTracer.attach`).

A path vertex on a **translucent** object adds (paper Eq. 7)

    L_sss = (1/pi) F_t(eta, w_o) M(x),

with ``M`` the transport's exitance at ``x`` (mm) and ``F_t`` the Fresnel transmittance towards the viewer (with
``incidence`` oblique times the exit gain ``g(mu_o) / k`` of the object's medium, Eq. O4 of
:mod:`convsss.profiles.incidence`: the reciprocal of the entry gain), plus the boundary's reflection, by the
integrator's ``specular`` mode:

- ``bsdf``: the scene's dielectric restricted to its reflection lobe: direct light by emitter sampling (for a rough
  boundary) and a reflected ray (weight ``F_r`` for a smooth one) that continues the path, up to ``max_depth``;
- ``phong``: the paper's highlight, a normalized Phong lobe ``F_r(eta, w_l) (e+2)/(2 pi) cos^e(alpha)`` lit by
  emitter sampling (``alpha`` between the mirrored light direction and the viewer);
- ``none``: nothing.

With ``single_scattering`` traced, the vertex also adds the light scattered once inside the object, traced through
its own shape (Jensen et al. 2001's single-scattering term; ``M`` then carries the rest, Eq. S1 of
:mod:`convsss.profiles.incidence`):

    L_1 = F_t(eta, w_o)/eta^2 ∫_0^{t_max} sigma_s' e^{-sigma_t' t} (1/(4 pi)) sum_lights E_in(x_t) dt,    (Eq. S2)
    E_in = F_t(eta, mu_b) (mu_b / mu_b') L_e e^{-sigma_t' s mu_b / mu_b'},

``x_t`` at distance ``t`` along the refracted view ray (``t_max`` where it leaves the object), ``L_e`` an emitter
sample's ``L/pdf`` at ``x_t``, ``s`` the straight distance from ``x_t`` to the boundary towards the emitter, met at
cosine ``mu_b`` (``mu_b'`` refracted inside: the path inside is ``s mu_b / mu_b'`` long, exact for a plane, and
``mu_b / mu_b'`` the beam's compression); one distance sample, drawn from one channel's ``sigma_t'`` chosen at random
(the object's sampling material's, ``TranslucentObject.sampling``: its own unless a fit keeps the scene's), weighted
by the channels' mean density (spectral MIS), and one emitter sample per emitter; a ``t`` past ``t_max``
is found by the ray towards the emitter, which then does not first leave the object (closed, oriented surfaces). On
a half-space it is the once-scattered part of Eq. O2, ``alpha' E / (4 pi (mu + mu_0))`` when index-matched. The
single scattering of light that arrives after a bounce stays in the profile (:class:`.irradiance.Entry`).

Light that crosses the object without scattering is neither: on an index-matched or thin part, a low-albedo
medium, or under an environment seen through the body, it is most of what arrives. A path that reaches a closed
translucent object continues through it, unscattered,

    L_0 = F_t(eta, w_o) e^{-sigma_t' l} L_behind,                                                           (Eq. S3)

``l`` the chord its transmitted direction cuts through the object and ``L_behind`` what the path finds beyond the far
side, where the boundary's BSDF (seen from inside) refracts it out or reflects it back in; the crossing is chosen
against the reflection lobe by the light's odds of getting through (:meth:`PathTracer._bounce`), nothing is scattered or
lit inside, and with ``sigma_t'`` as in Eq. S2 (the similarity relation, exact for isotropic media). Scattered light
that refracts into the object is otherwise in ``M``, so a path ends there. Every **other** shape is shaded by
an ordinary unidirectional path tracer: emitter sampling and BSDF sampling combined by the power heuristic, Russian
roulette from ``rr_depth``, so floors, shadows and backgrounds look as in Mitsuba's ``path``. A bounce that reaches
a translucent object picks up its ``L_sss`` too.

The path loop is one symbolic Dr.Jit loop (a single kernel for all bounces, as Mitsuba's own integrators). ``M`` is
read inside it from the screen table where that knows it; the other hits on translucent objects are recorded in the
loop and looked up through numpy afterwards, their ``beta (1/pi) F_t M`` added to their lanes (:mod:`.lookups`).

The same path tracer gives the light that reaches a translucent object after bouncing off the scene
(:meth:`PathTracer.incident`, the indirect part of paper Eq. 2): paths start on the object's surface as at depth 1 of a
camera path, and the emission their first segment sees is left out (direct light is estimated on its own). An object
whose transport is not built yet (``None``) has no ``M`` to give: a path that reaches it records the point and its
weight, which :meth:`PathTracer.incident` returns beside the radiance, to be looked up once the transport exists
(:meth:`.lookups.ExitanceLookups.resolve`).
"""

import math

import drjit as dr
import numpy as np

from ..backend import import_mitsuba, to_numpy3
from .irradiance import Leaving, fresnel_transmittance, refracted_cosine
from .lookups import ExitanceLookups, HitRecords
from .mis import power_heuristic
from .shadow import Shadows, classify
from .walk import RandomWalk

mi = import_mitsuba()

MAX_EMITTERS_SUMMED = 8
#: A path crosses a translucent object (Eq. S3) with the boundary's transmittance as probability where the chord
#: transmits at least this fraction of the light in some channel; below, by Russian roulette on the transmittance.
THROUGH_ROULETTE = 0.1
#: Light that a chord dims below this fraction in every channel is not followed through the object (Eq. S3).
CROSSING_FLOOR = 1e-3


class PathTracer:
    """The path tracer of one scene's prepared state (module doc): built once its translucent objects are known,
    given their transports by :meth:`attach` once they exist.

    Parameters
    ----------
    scene : mitsuba.Scene
    objects : list of TranslucentObject
    params : RenderParams
    stop : callable, optional
        Asked between bounces; when it returns True the paths end there (Ctrl-C during Mitsuba's render).
    mode : RenderMode
        What renders the objects (:class:`~.params.RenderMode`): walks, or this path tracer with the transports.
    shadows : Shadows, optional
        The scene's shadow rays (:class:`.shadow.Shadows`) when ``objects`` are not all its translucent objects.
    """

    def __init__(self, scene, objects, params, mode, stop=None, shadows=None):
        self.scene, self.objects, self.params = scene, objects, params
        self.stop = stop
        #: Each object's exit gain (:class:`Leaving`), ``None`` with ``incidence`` normal (paper Eq. 7 alone).
        self.leaving = [Leaving(obj.eta, obj.material.albedo_prime, params.orders) if params.incidence == "oblique"
                        else None for obj in objects]
        #: Whether the paths trace single scattering (Eq. S2), and each object's sigma_t', sigma_s' per scene unit.
        self.single = params.single_scattering == "traced"
        self.coefficients = [(mi.Color3f(*(obj.material.sigma_t_prime * params.unit_mm).tolist()),
                              mi.Color3f(*(obj.material.sigma_s_prime * params.unit_mm).tolist())) for obj in objects]
        #: Each object's sigma_t' per scene unit that draws the paths' choices (``TranslucentObject.sampling``).
        self.sampling = [mi.Color3f(*((obj.sampling or obj.material).sigma_t_prime * params.unit_mm).tolist())
                         for obj in objects]
        self.ctx = mi.BSDFContext()
        self.ctx_reflect = mi.BSDFContext()
        self.ctx_reflect.type_mask = int(mi.BSDFFlags.Reflection)
        self.ctx_transmit = mi.BSDFContext()
        self.ctx_transmit.type_mask = int(mi.BSDFFlags.Transmission)
        #: Up to this many emitters, direct light samples each of them (else one chosen by the scene).
        self.per_emitter = len(scene.emitters()) <= MAX_EMITTERS_SUMMED
        #: The shadow rays, through every translucent object of the scene (``shadows``, or this tracer's ``objects``).
        self.shadows = shadows or Shadows(scene, objects, params.unit_mm)
        #: Where ``mode`` walks, the camera's paths walk through the objects' media (:mod:`.walk`).
        self.walk = RandomWalk(scene, objects, params, mode, self.per_emitter, self) if mode.walks else None
        #: Where the paths read ``M``: the screen table, the mesh tables and the transports (:mod:`.lookups`).
        self.lookups = ExitanceLookups(objects, params.unit_mm, stop)
        self.attach([None] * len(objects))

    def attach(self, transports, screen=None, field=None):
        """Read ``M`` from ``transports`` (one per object, None where not built yet: :meth:`incident` returns its
        hits) and the ``screen`` table from now on (:meth:`.lookups.ExitanceLookups.attach`); the walk ends in the
        ``field`` (:class:`~.field.DiffusionField`, optional)."""
        self.lookups.attach(transports, screen)
        if self.walk is not None:
            self.walk.field = field
        return self

    # --- per-bounce pieces ----------------------------------------------------------------------------------------
    def classify(self, si):
        """Per lane, the index of the translucent object hit (mi.Int32, -1: none) and its eta (mi.Float)
        (:func:`.shadow.classify`)."""
        return classify(self.objects, si)

    def exit_weight(self, which, eta, cos):
        """Per lane, the weight of ``M`` towards the viewer at ``cos`` on the object ``which`` of index ``eta``:
        ``(1/pi) F_t(eta, cos)`` (paper Eq. 7) times the object's exit gain (Eq. O4, :class:`Leaving`) if it has one."""
        cos = dr.abs(cos)
        gain = dr.full(mi.Color3f, 1.0, dr.width(cos))
        for k, leaving in enumerate(self.leaving):
            if leaving is not None:
                gain = dr.select(which == k, leaving(cos), gain)
        return gain * fresnel_transmittance(eta, cos) / dr.pi

    def _phong(self, si, ray_d, eta, ds, light):
        """The paper's Phong highlight from one emitter sample: ``F_r (e+2)/(2 pi) cos^e(alpha) cos_l L/pdf``."""
        wo = -ray_d
        n = mi.Vector3f(si.sh_frame.n)
        n = dr.select(dr.dot(n, wo) < 0, -n, n)
        cos_l = dr.dot(n, ds.d)
        mirrored = 2.0 * cos_l * n - ds.d
        cos_a = dr.maximum(dr.dot(mirrored, wo), 0.0)
        e = self.params.phong_exponent
        lobe = mi.fresnel(dr.abs(cos_l), eta)[0] * (e + 2.0) / (2.0 * dr.pi) * dr.power(cos_a, e)
        return dr.select(cos_l > 0, light * lobe * cos_l, 0.0)

    def _light_samples(self, it, u, active, test_visibility=True):
        """Emitter samples ``(ds, L/pdf)`` at ``it``: one per emitter when there are few (no selection noise), else
        one emitter picked by the scene (as Mitsuba's ``path`` does); with ``test_visibility``, ``L/pdf`` is what
        a shadow ray from ``it`` (a surface interaction) lets through (:meth:`.shadow.Shadows.visibility`)."""
        if not self.per_emitter:
            if not self.shadows.any_passes:
                return [self.scene.sample_emitter_direction(it, u, test_visibility, active)]
            ds, light = self.scene.sample_emitter_direction(it, u, False, active)
            return [(ds, light * self.shadows.visibility(it, ds, active & (ds.pdf > 0)) if test_visibility else light)]
        out = []
        for emitter in self.scene.emitters():
            ds, light = emitter.sample_direction(it, u, active)
            if test_visibility:
                light = light * self.shadows.visibility(it, ds, active & (ds.pdf > 0))
            out.append((ds, light))
        return out

    def _direct_light(self, si, bsdf, ray_d, eta, u_light, translucent, opaque, alive):
        """Direct light by emitter sampling: :meth:`_direct` of each of :meth:`_light_samples`."""
        direct_light = dr.zeros(mi.Color3f, dr.width(si.p))
        for ds, light in self._light_samples(si, u_light, alive):
            direct_light += self._direct(si, bsdf, ray_d, eta, translucent, opaque, alive, ds, light)
        return direct_light

    def _direct(self, si, bsdf, ray_d, eta, translucent, opaque, alive, ds, light):
        """One emitter sample's contribution: the BSDF (power-heuristic MIS) on opaque shapes; on translucent ones the
        boundary's reflection lobe (``bsdf``) or the Phong highlight (``phong``)."""
        wo_local = si.to_local(ds.d)
        value, pdf = bsdf.eval_pdf(self.ctx, si, wo_local, opaque)
        value = dr.select(opaque, value, 0.0)
        pdf = dr.select(opaque, pdf, 0.0)
        if self.params.specular == "bsdf":
            reflect = alive & translucent
            value_r, pdf_r = bsdf.eval_pdf(self.ctx_reflect, si, wo_local, reflect)
            value = dr.select(reflect, value_r, value)
            pdf = dr.select(reflect, pdf_r, pdf)
        result = light * value * dr.select(ds.delta, 1.0, power_heuristic(ds.pdf, pdf))
        if self.params.specular == "phong":
            result = dr.select(translucent, self._phong(si, ray_d, eta, ds, light), result)
        return dr.select(alive, result, 0.0)

    def single_scattering(self, si, which, eta, u_distance, u_emitter, active):
        """Light scattered once inside the translucent object ``which`` towards the viewer at ``si``, by Eq. S2: one
        distance sample along the refracted view ray, one emitter sample per emitter from there."""
        n_lanes = dr.width(si.p)
        sigma_t, sigma_s = dr.zeros(mi.Color3f, n_lanes), dr.zeros(mi.Color3f, n_lanes)
        orientation = dr.zeros(mi.Float, n_lanes)
        for k, (extinction, scattering) in enumerate(self.coefficients):
            sigma_t = dr.select(which == k, extinction, sigma_t)
            sigma_s = dr.select(which == k, scattering, sigma_s)
            orientation = dr.select(which == k, self.objects[k].orientation, orientation)
        wo = si.to_world(si.wi)
        n = mi.Vector3f(si.n)
        n = dr.select(dr.dot(n, wo) < 0, -n, n)  # towards the viewer, outside
        cos_o = dr.dot(n, wo)
        cos_in = refracted_cosine(eta, cos_o)
        inward = dr.normalize(-wo / eta + (cos_o / eta - cos_in) * n)
        # The distance: a channel at random, then its exponential; pdf the channels' mean (spectral MIS). Drawn with
        # the sampling material's sigma_t' (the estimate is the material's all the same), so that x_t does not move
        # with the material a fit tries.
        drawn = self._extinction(which, sampling=True)
        pick = u_distance * 3.0
        channel = dr.minimum(mi.UInt32(pick), 2)
        chosen = dr.select(channel == 0, drawn[0], dr.select(channel == 1, drawn[1], drawn[2]))
        t = -dr.log(1.0 - (pick - mi.Float(channel))) / chosen
        pdf = (drawn[0] * dr.exp(-drawn[0] * t) + drawn[1] * dr.exp(-drawn[1] * t)
               + drawn[2] * dr.exp(-drawn[2] * t)) / 3.0
        ray = si.spawn_ray(inward)
        inside = active & (cos_o > 0)  # and x_t in the object: checked below, where the ray to the light leaves it
        it = dr.zeros(mi.Interaction3f, n_lanes)
        it.p, it.time, it.wavelengths = ray(t), si.time, si.wavelengths
        scattered = sigma_s * dr.exp(-sigma_t * t) / pdf * fresnel_transmittance(eta, cos_o) / (4.0 * dr.pi * eta * eta)
        out = dr.zeros(mi.Color3f, n_lanes)
        for ds, light in self._light_samples(it, u_emitter, inside, test_visibility=False):
            lit = inside & (ds.pdf > 0)
            boundary = self.scene.ray_intersect(mi.Ray3f(it.p, ds.d), lit)
            # x_t is inside the object (closed, oriented) iff the ray towards the light first leaves it.
            leaves = (self.classify(boundary)[0] == which) & (orientation * dr.dot(boundary.n, ds.d) > 0)
            lit &= leaves & (boundary.t < ds.dist)
            lit &= ~self.scene.ray_test(boundary.spawn_ray_to(ds.p), lit)
            cos_b = dr.abs(dr.dot(boundary.n, ds.d))
            cos_b_in = dr.maximum(refracted_cosine(eta, cos_b), 1e-6)
            entering = light * fresnel_transmittance(eta, cos_b) * cos_b / cos_b_in  # Eq. S2's E_in
            out += dr.select(lit, entering * dr.exp(-sigma_t * boundary.t * cos_b / cos_b_in) * scattered, 0.0)
        return out

    # --- the path loop ----------------------------------------------------------------------------------------------
    @property
    def strategy(self):
        """What shades the camera rays: the random walk where ``walk_depth`` > 0 (:class:`~.walk.RandomWalk`), else
        this path tracer (:meth:`trace`); the integrator asks it."""
        return self.walk if self.walk is not None else self

    def trace(self, sampler, ray):
        """Radiance (mi.Color3f) and hit mask (mi.Bool) for a batch of camera rays, drawing from ``sampler``: the
        surface path tracer's loop (:meth:`_paths`)."""
        return self._trace(sampler, ray, 0)

    def incident(self, sampler, ray, weight, tags):
        """Radiance arriving along ``ray`` after at least one bounce, times ``weight``: ``(radiance, deferred)``, (K, 3)
        numpy and the hits on objects without a transport.

        The rays leave a translucent object's surface, so their first hit is at depth 1 of a camera path (``max_depth``
        and ``rr_depth`` count as for the camera's paths); emission seen at that hit is left out (it is direct light).
        Hits on objects without a transport are returned in ``deferred`` with their lane's ``tags`` and ``weight``
        (:meth:`.lookups.ExitanceLookups.resolve` looks them up once the transports exist).

        Parameters
        ----------
        sampler : mitsuba.Sampler
            Seeded for ``K`` lanes.
        ray : mitsuba.Ray3f
            ``K`` rays from the surface.
        weight : (K, 3) numpy
            Each lane's factor (e.g. ``F_t pi / paths`` of a cosine-sampled estimate of Eq. 2).
        tags : (K,) numpy int
            Each lane's label in ``deferred`` (e.g. the surface sample it belongs to).

        Returns
        -------
        radiance : numpy.ndarray
            (K, 3) ``weight`` times the radiance.
        deferred : list
            ``(object, tags, points_mm, normals, faces, weight)`` per object and batch reached without a transport.
        """
        weight, deferred = np.asarray(weight, dtype=np.float64), []
        radiance, _ = self._trace(sampler, ray, 1, (deferred, np.asarray(tags), weight))
        return to_numpy3(radiance, np.float64) * weight, deferred

    def _trace(self, sampler, ray, first_depth, incident=None):
        """The paths from ``first_depth`` (0: camera rays; 1: rays leaving a translucent surface, whose first hit's
        emission is left out; ``incident``: :meth:`incident`'s deferred hits, tags and weights): radiance and the first
        hit's mask.

        One symbolic Dr.Jit loop (:meth:`_paths`) traces every bounce; the hits whose ``M`` the screen table does not
        know are recorded there and asked of the transports afterwards (:meth:`.lookups.ExitanceLookups.add_recorded`).
        Should more hits need recording than there is room for, the paths are traced again from a copy of the sampler
        taken before (the same paths) with room for all of them.
        """
        (total, valid), hits = HitRecords.traced(lambda s, h: self._paths(s, ray, first_depth, h), sampler,
                                                 dr.width(ray.o))
        self.lookups.add_recorded(total, hits, incident, camera=ray if first_depth == 0 else None)
        dr.eval(total, valid)
        return total, valid

    @dr.syntax
    def _paths(self, sampler, ray, first_depth, hits):
        """The path tracer's loop: ``(radiance, first hit's mask)``, the hits on translucent objects whose ``M`` is not
        in the screen table recorded in ``hits`` (:class:`~.lookups.HitRecords`)."""
        scene, params = self.scene, self.params
        n_lanes = dr.width(ray.o)
        max_depth = params.max_depth if params.max_depth > 0 else 2**31 - 1
        lane = dr.arange(mi.UInt32, n_lanes)
        ray = mi.Ray3f(ray)
        total = dr.zeros(mi.Color3f, n_lanes)
        throughput = dr.full(mi.Color3f, 1.0, n_lanes)
        prev_p = mi.Point3f(ray.o)
        prev_n = dr.zeros(mi.Vector3f, n_lanes)
        prev_pdf = dr.full(mi.Float, 1.0, n_lanes)
        prev_delta = dr.full(mi.Bool, True, n_lanes)
        valid = dr.zeros(mi.Bool, n_lanes)
        depth = dr.full(mi.UInt32, first_depth, n_lanes)
        active = dr.full(mi.Bool, True, n_lanes)
        inside = dr.full(mi.Int32, -1, n_lanes)  # the translucent object a ballistic ray crosses (Eq. S3), or -1
        while active:
            si = scene.ray_intersect(ray, active)
            valid = dr.select(depth == first_depth, si.is_valid(), valid)
            interior = active & (inside >= 0)
            # A ray crossing an object arrives at its far side unscattered: e^{-sigma_t' l} (Eq. S3).
            throughput = dr.select(interior, throughput * dr.exp(-self._extinction(inside) * si.t), throughput)
            # Emission seen here (not on the first hit of a path that starts on a surface: that is direct light).
            seen = active & ((depth > first_depth) | (depth == 0))
            contribution = dr.select(seen, self._emission(si, prev_p, prev_n, prev_pdf, prev_delta) * throughput,
                                     0.0)
            alive = active & si.is_valid() & (depth + 1 < max_depth)
            which, eta = self.classify(si)
            leaving = alive & interior & (which == inside)  # the far side, seen from inside: no M, no light sampled
            alive &= ~interior
            translucent = alive & (which >= 0)
            weight = throughput * self.exit_weight(which, eta, si.wi.z)  # times M: paper Eq. 7 (or O4)
            known, sss = self.lookups.on_screen(si, which, translucent, weight)
            contribution += sss
            hits.add(translucent & ~known, (which, si.p, mi.Vector3f(si.n), weight, lane, depth == 0, si.prim_index))

            bsdf = si.bsdf(ray)
            sampled = alive | leaving
            u_light, u_lobe, u_dir = sampler.next_2d(alive), sampler.next_1d(sampled), sampler.next_2d(sampled)
            u_rr, u_through = sampler.next_1d(sampled), sampler.next_1d(translucent)

            opaque = alive & (which < 0)
            contribution += throughput * self._direct_light(si, bsdf, ray.d, eta, u_light, translucent, opaque, alive)
            if self.single:  # the distance's sample, then the emitters'
                contribution += throughput * self.single_scattering(si, which, eta, sampler.next_1d(translucent),
                                                                    sampler.next_2d(translucent), translucent)

            bs, bsdf_weight, continues, entering, exiting = self._bounce(si, bsdf, which, eta, u_lobe, u_dir, u_through,
                                                                         opaque, translucent, leaving)
            throughput = throughput * dr.select(continues, bsdf_weight, 0.0)
            continues &= (bs.pdf > 0) & (dr.max(throughput) > 0)
            roulette = continues & (depth + 1 >= params.rr_depth)
            q = dr.minimum(dr.max(throughput), 0.95)
            continues &= ~roulette | (u_rr < q)
            throughput = dr.select(roulette & continues, throughput / q, throughput)

            total += contribution
            ray = si.spawn_ray(si.to_world(bs.wo))
            prev_p, prev_n, prev_pdf = mi.Point3f(si.p), mi.Vector3f(si.n), mi.Float(bs.pdf)
            # Emission after a crossing has full weight: no light is sampled inside an object or on its far side.
            prev_delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta) | leaving
            inside = dr.select(entering, which, dr.select(exiting, -1, inside))
            active = continues
            depth += 1
        dr.eval(total, valid, hits.recorded)
        return total, valid

    def _bounce(self, si, bsdf, which, eta, u_lobe, u_dir, u_through, opaque, translucent, leaving):
        """The next direction: ``(sample, weight, continues, entering, exiting)``.

        Opaque shapes sample their BSDF. On a translucent object's outside the path crosses the object unscattered
        (Eq. S3) with probability ``p = F_t(eta, mu) min(1, T / THROUGH_ROULETTE)``, ``T`` the largest channel of
        ``e^{-sigma_t' l}`` along the chord the transmitted direction cuts through it (``sigma_t'`` of the object's
        sampling material, ``TranslucentObject.sampling``), weight ``f / (pdf p)`` (the
        chord's own ``e^{-sigma_t' l}`` is applied where the ray arrives); else, in ``bsdf`` mode, it takes the
        reflection lobe, weight ``f / (pdf (1 - p))``. Chords longer than :meth:`_reach` are not followed. On the
        far side seen from inside (``leaving``) the boundary's whole BSDF chooses between leaving and reflecting back
        in."""
        bs, weight = bsdf.sample(self.ctx, si, u_lobe, u_dir, opaque | leaving)
        continues = opaque | leaving
        exiting = leaving & (bs.wo.z * si.wi.z < 0)
        bs_t, weight_t = bsdf.sample(self.ctx_transmit, si, u_lobe, u_dir, translucent)
        ray = si.spawn_ray(si.to_world(bs_t.wo))
        ray.maxt = self._reach(which)
        chord = self.scene.ray_intersect(ray, translucent & (bs_t.pdf > 0))
        crosses = translucent & (bs_t.pdf > 0) & self._closed(which) & (self.classify(chord)[0] == which)
        transmittance = dr.max(dr.exp(-self._extinction(which, sampling=True) * chord.t))
        p_through = dr.select(crosses, fresnel_transmittance(eta, si.wi.z)
                              * dr.minimum(transmittance / THROUGH_ROULETTE, 1.0), 0.0)
        entering = translucent & (u_through < p_through)
        bs = dr.select(entering, bs_t, bs)
        weight = dr.select(entering, weight_t / p_through, weight)
        continues |= entering
        if self.params.specular == "bsdf":
            reflect = translucent & ~entering
            bs_r, weight_r = bsdf.sample(self.ctx_reflect, si, u_lobe, u_dir, reflect)
            bs = dr.select(reflect, bs_r, bs)
            weight = dr.select(reflect, weight_r / (1.0 - p_through), weight)
            continues |= reflect
        return bs, weight, continues, entering, exiting

    def _closed(self, which):
        """Per lane, whether ``which`` is a translucent object known to bound a volume (a ray can cross it)."""
        out = dr.zeros(mi.Bool, dr.width(which))
        for k, obj in enumerate(self.objects):
            if obj.closed:
                out |= which == k
        return out

    def _reach(self, which):
        """Per lane, the longest chord through object ``which`` that transmits ``CROSSING_FLOOR`` of the light in its
        clearest channel (its sampling material's; scene units; 0 where none)."""
        out = dr.zeros(mi.Float, dr.width(which))
        for k, extinction in enumerate(self.sampling):
            out = dr.select(which == k, -math.log(CROSSING_FLOOR) / dr.min(extinction), out)
        return out

    def _extinction(self, which, sampling=False):
        """Per lane, ``sigma_t'`` (per scene unit) of the translucent object ``which`` (0 where none): its
        material's, or with ``sampling`` its sampling material's (:attr:`sampling`)."""
        out = dr.zeros(mi.Color3f, dr.width(which))
        for k, extinction in enumerate(self.sampling if sampling else [e for e, _ in self.coefficients]):
            out = dr.select(which == k, extinction, out)
        return out

    def _emission(self, si, prev_p, prev_n, prev_pdf, prev_delta):
        """Emitted radiance seen at ``si``, MIS-weighted against emitter sampling after a non-delta BSDF sample (a
        camera ray counts as a delta one)."""
        emitter = si.emitter(self.scene)
        radiance = emitter.eval(si)
        prev = dr.zeros(mi.Interaction3f, dr.width(prev_p))
        prev.p, prev.n = prev_p, prev_n
        ds = mi.DirectionSample3f(self.scene, si, prev)
        if self.per_emitter:
            pdf_light = emitter.pdf_direction(prev, ds)
        else:
            pdf_light = self.scene.pdf_emitter_direction(prev, ds)
        return radiance * dr.select(prev_delta, 1.0, power_heuristic(prev_pdf, pdf_light))
