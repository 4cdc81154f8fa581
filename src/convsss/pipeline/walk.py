"""The random walk: paths through the translucent objects' own media, the path tracer's volumetric estimator.

Where diffusion does not hold (thin parts, back light, objects a few mean free paths across, low albedo, anisotropic
scattering) the light under the surface is found by following it: a path that refracts into an object walks through
its interior medium (Mitsuba's: homogeneous or heterogeneous, its own phase function) and leaves it through the
boundary's BSDF, then goes on as any path does. With nothing cut short this is a volumetric path tracer, the same
estimator as Mitsuba's ``volpathmis`` (Miller, Georgiev and Jarosz 2019, spectral MIS) but for a surface offset:

* **free flights** drawn by one channel's extinction per path (the hero channel ``c``, uniform over R, G, B), and
  in a heterogeneous medium by its majorant with null collisions (delta tracking);
* every event's probability kept for **every** channel: the path's weight in channel ``i`` is

      w_i = f_i / mean_j p_j,                                                                           (Eq. W1)

  ``f_i`` the path's contribution in channel ``i`` and ``p_j`` its density had channel ``j`` drawn it (the one-sample
  balance heuristic over channels), tracked as the ratios ``p_j / f_i`` (rank one: two products, :mod:`.spectral_mis`);
* at a scattering vertex, **next-event estimation** through null boundaries and the media between: at a path's
  first, to each emitter of the scene (:attr:`lights`, as at an opaque surface: one sample each; past
  :data:`~.path_tracer.MAX_EMITTERS_SUMMED` emitters, and in ``volpathmis``'s estimator, to one the scene chooses),
  at the next ones to one the scene chooses (a walk has many vertices, whose choices average out; an absorbing
  object's light comes from its first: 96², 32 spp, efficiency against each emitter everywhere 0.95x on a ketchup
  bunny under two point lights, 1.18x on a 4 mm milk bunny, 1.14x and 1.96x on a jade Lucy and a skin armadillo
  behind glass under an area light and a sky; one chosen everywhere 0.64x, 1.13x, 1.23x, 1.42x), combined with
  **phase-function sampling** by the balance heuristic on the same ratios
  (Eq. W2: a hit on an emitter weighs with that emitter's own density then, its choice's probability included
  otherwise); a dielectric boundary stops the shadow ray (the light there comes by the sampled directions,
  as in ``volpathmis``); through a homogeneous medium the shadow ray takes the transmittance ``e^{-sigma_t t}`` per
  channel whole (no collision drawn), going on with odds ``max_c T_c /`` :data:`~.walk_shadows.SHADOW_ROULETTE`
  below it (Russian roulette), except where the walk is ``volpathmis``'s estimator (an explicit ``walk_depth`` inf;
  the shadow rays are :mod:`.walk_shadows`'s);
* at a boundary, the scene's BSDF: a smooth or rough dielectric refracts out or reflects back in, a null one lets
  the path through into the next medium;
* a light behind a translucent object's smooth dielectric boundary reaches a scattering vertex by the path that
  refracts to it (**manifold next-event estimation**, Eq. W5 of :mod:`.manifold`: Newton's method on Snell's law
  for the direction at the vertex, the generalized geometry term in its density, ``eta^2 F_t`` in its weight): a
  delta light (point, spot, directional), which no path can reach (``volpathmis`` renders it black), always; where
  walks end in the field (``walk_depth`` finite) and in ``auto``'s walks, every emitter but an environment without a
  sun (one with a sun as a directional light, :func:`~.walk_shadows.solved_environments`). A path
  that refracts straight out of the object after a scattering vertex and hits such an emitter weighs against it by
  the balance heuristic, the solve's density counted only where the solve from that vertex to that point of the
  light finds that very path: the light the solver misses (a second refracted path, a fold of the mesh) is left to
  the paths that hit it, so that an area light is unbiased and found by light sampling, not by the chance hits that
  make ``volpathmis`` noisy there; a delta light loses what the solver misses (on a sphere, none). Where no
  refracted path to the light sample exists (behind a caustic) it gives no light. An environment without a sun (a
  uniform one, a sky) is left to the paths that hit it, which find it as well at less cost. A shadow ray from a surface
  inside the object (an opaque inclusion), and every one with the parameter ``refraction`` straight (less noise on a
  detailed mesh, whose many refracted paths the solver misses), crosses the boundary straight, with

      F_t(eta, mu) (mu / mu') e^{-sigma_t s (mu / mu' - 1)}                                              (Eq. W4)

  times the straight ray's own transmittance (``s`` the length inside, ``mu'`` the cosine inside and ``mu``
  outside: the Fresnel transmittance, the beam's compression and the refracted path's length, exact for a plane
  boundary only; it read 0.84-0.90 of ``volpathmis`` on a 1 mm sphere where it served the vertices too);
* a medium may be **weighed by other coefficients than it is drawn by** (:attr:`RandomWalk.evaluated`: a fit's
  trial material, :mod:`convsss.fitting`): its flights and events are drawn by the medium's own extinction as always
  and only ``f_i`` takes the trial's transmittance ``e^{-sigma_t t}`` and ``sigma_s`` (Eq. W1's densities unchanged:
  unbiased for any trial, noisier as its extinction falls below the drawn one), so that the image moves smoothly
  with the trial, each channel's with its own coefficients only;
* a flight from a surface starts on it (Mitsuba offsets a spawned ray's origin by ``(1 + |p|) 1.8e-4``, more than a
  mean free path in dense media or far from the origin: they went dark, issue 62); that origin only finds surfaces;
* Russian roulette on the path's weight from ``rr_depth``, below :data:`ROULETTE_WEIGHT` only (a weight window: at
  albedo ~1 a cut would only add fireflies, and where light is found only deep, behind an absorbing object lit from
  the back, the roulette on the weight itself had cut the paths that find it), ``max_depth`` bounces (on
  opaque surfaces, and one per walk through a medium at its first scattering, as the transport's exitance is one:
  1 shows the emitters alone, 2 adds the light under the surface) and at most :data:`MAX_WALK` events in media; a
  survivor's ``1/q`` weighs both of Eq. W2's techniques for the light it finds next; a vertex in an object's medium
  outside every bounding box of that medium's objects ends its path (``leaked``: it left them unseen, a vertex a
  rounding error past the boundary; 0-25 paths in a million on ``bench walk``'s scenes);
* an object that its transport renders (``auto`` where diffusion holds on it but fails on another:
  :attr:`~.params.RenderMode.transported`) is never entered: a path that meets it finds its light there as an
  emitter's, ``(1/pi) F_t M`` (paper Eq. 7, the hit recorded in the loop and its ``M`` looked up after it, as the
  surface path tracer does) and its single scattering (Eq. S2), and takes its boundary's reflection alone;
* in ``auto``'s walks, deep inside an object of isotropic scattering, a **jump** across the largest ball that fits
  (shell tracing, Eq. J1 of :mod:`.jumps`) takes the place of the vertex's light sampling and of the phase
  function's next direction: the walk leaves the ball's sphere where and as a homogeneous sphere's exit table says;
* **derivatives** with respect to the media's coefficients (:mod:`.derivatives`): each path carries its events'
  scores beside its ratios and each sample a Jacobian (Eq. G1, G2), or a replayed walk sends each event's score times
  the radiance still to come into Mitsuba's AD (Eq. G3).
"""

import weakref
from dataclasses import dataclass

import drjit as dr

from ..backend import import_mitsuba
from .derivatives import accumulate, add_length, add_scattering, replay_bsdf, replay_scattering, zero_scores
from .jumps import MIN_SCATTERINGS, Jumps
from .lookups import HitRecords
from .manifold import refract_toward
from .shadow import classify
from .spectral_mis import ended, mis, ones, update, where
from .walk_shadows import ShadowRays, shadow_odds, solved_environments, through_boundary

mi = import_mitsuba()

#: The most scattering events a path makes inside media (the walk's cap; a path past it ends there).
MAX_WALK = 100_000
#: Russian roulette's window: a path whose weight (times eta^2) falls below it goes on with odds its weight over it,
#: its survivors weighing it; above it a path is never cut. 96², 32 spp, 32 seeds, one process, efficiency
#: 1 / (relative MSE x seconds) on the back-lit 40 mm skin1 bunny: 4.7 with the odds the weight itself (1), 6.6 at
#: 0.5, 7.6 at 0.3, 7.8 at 0.1; within noise on ``bench walk``'s other walked scenes.
ROULETTE_WEIGHT = 0.3


def _interaction(source):
    """A plain :class:`mitsuba.Interaction3f` of a surface or medium interaction (where the last scattering was)."""
    it = dr.zeros(mi.Interaction3f, dr.width(source.p))
    it.t, it.time, it.wavelengths, it.p = source.t, source.time, source.wavelengths, source.p
    it.n = source.n if isinstance(source, mi.SurfaceInteraction3f) else dr.zeros(mi.Normal3f, dr.width(source.p))
    return it


@dataclass
class _Path:
    """The state of a batch of walks between events (the loop's variables, a Dr.Jit PyTree): the ray and the medium
    it is in, the last surface hit, the last scattering vertex, the hero channel, the radiance found, the density
    ratios of Eq. W1 (as drawn, and as light sampling would have drawn the last vertex's light), the product of the
    boundaries' eta, and the flags and counts the steps read."""

    ray: object
    medium: object
    offset: object  # where the surface's spawned ray began, from the ray's origin on the surface (_flight)
    si: object
    last_scatter: object
    channel: object
    result: object
    ratios: tuple
    ratios_nee: tuple
    eta: object
    last_null: object
    needs_intersection: object
    specular_chain: object
    after_scatter: object  # the last event was a scattering in a medium
    chose_light: object  # the last vertex's light was one emitter the scene chose (scattering vertices but the first)
    straight_out: object  # and then the path refracted out through a smooth boundary
    scattered: object  # the direction the last scattering sent it (Eq. W5's weight where it hits a light)
    valid: object
    depth: object  # bounces: on opaque surfaces, and one per walk through a medium (its first scattering)
    walking: object  # scattered in the medium it is in (since it entered it)
    events: object  # scattering events in media, reflections and refractions at their boundaries
    scatterings: object
    jumps: object  # across balls of the deep interior (:mod:`.jumps`)
    refracted: object  # light samples Eq. W5 found the refracted path for, and those it found none for
    unsolved: object
    ended: object
    leaked: object  # left its object's medium unseen (_flight)
    active: object
    scores: tuple  # per differentiated medium, d log f / d sigma_t and d sigma_s so far (Eq. G1)
    jacobian: tuple  # and the radiance's derivatives (Eq. G2)

    @staticmethod
    def start(sampler, ray, medium, differentiated=()):
        """Walks along ``ray`` from ``medium`` (None: from outside every medium), the hero channel drawn; with the
        ``differentiated`` media's scores (:mod:`.derivatives`)."""
        n = dr.width(ray)
        start = dr.zeros(mi.MediumPtr, n) if medium is None else dr.full(mi.MediumPtr, medium, n)
        return _Path(ray=mi.Ray3f(ray), medium=mi.MediumPtr(start), offset=dr.zeros(mi.Vector3f, n),
                     si=dr.zeros(mi.SurfaceInteraction3f, n),
                     last_scatter=dr.zeros(mi.Interaction3f, n),
                     channel=dr.minimum(mi.UInt32(sampler.next_1d() * 3.0), 2), result=dr.zeros(mi.Color3f, n),
                     ratios=ones(n), ratios_nee=ones(n), eta=dr.full(mi.Float, 1.0, n),
                     last_null=dr.full(mi.Bool, False, n), needs_intersection=dr.full(mi.Bool, True, n),
                     specular_chain=dr.full(mi.Bool, True, n), after_scatter=dr.full(mi.Bool, False, n),
                     straight_out=dr.full(mi.Bool, False, n), chose_light=dr.full(mi.Bool, False, n),
                     scattered=dr.zeros(mi.Vector3f, n),
                     valid=dr.full(mi.Bool, False, n), depth=dr.zeros(mi.UInt32, n),
                     walking=dr.full(mi.Bool, False, n), events=dr.zeros(mi.UInt32, n),
                     scatterings=dr.zeros(mi.UInt32, n), jumps=dr.zeros(mi.UInt32, n),
                     refracted=dr.zeros(mi.UInt32, n),
                     unsolved=dr.zeros(mi.UInt32, n), ended=dr.full(mi.Bool, False, n),
                     leaked=dr.full(mi.Bool, False, n), active=dr.full(mi.Bool, True, n),
                     scores=zero_scores(differentiated, n), jacobian=zero_scores(differentiated, n))


class RandomWalk(ShadowRays):
    """The volumetric paths of one scene whose translucent objects are ``objects`` (module doc): a sibling of the
    surface path tracer (:class:`~.path_tracer.PathTracer`) that the integrator picks where ``walk_depth`` > 0;
    :meth:`trace` gives their radiance."""

    def __init__(self, scene, objects, params, mode, each_emitter=True, tracer=None):
        self.scene, self.objects = scene, objects
        #: Per object, whether its transport renders it (``mode``'s :attr:`~.params.RenderMode.transported`; [] where
        #: none of ``objects`` is): a path that meets one reads its light from ``tracer``, the surface path tracer
        #: that owns this walk (its exitance and single scattering, paper Eq. 7 and S2), and takes its boundary's
        #: reflection alone (the tracer's contexts); it never walks inside. A weak reference: a cycle through
        #: Mitsuba's objects would be freed by the garbage collector at any time, inside a later kernel's recording
        #: too (it aborted the process).
        transported = [bool(mode.transported) and mode.transports(obj) for obj in objects]
        self.transported = transported if any(transported) else []
        self.tracer = weakref.proxy(tracer) if self.transported else None
        #: The hits on transported objects that the kernel being traced records (:class:`~.lookups.HitRecords`).
        self.hits = None
        self.max_depth = params.max_depth if params.max_depth > 0 else 2**31 - 1
        self.rr_depth = params.rr_depth
        #: Every emitter's light but a sunless environment's reaches a vertex through a smooth boundary (Eq. W5, or W4)
        #: where ``mode`` says so; at an explicit ``inf`` only a delta light's, so that the walk stays ``volpathmis``.
        self.straight_through = mode.straight
        #: A light sample behind a smooth dielectric boundary is reached by Eq. W5's refracted path (the parameter
        #: ``refraction`` manifold, and some object's boundary is one), else by Eq. W4's straight shadow ray.
        self.refracting = params.refraction == "manifold" and any(obj.boundary == "dielectric" for obj in objects)
        #: The environments whose light Eq. W5 takes through a smooth boundary (where it solves): those whose light is
        #: concentrated (:func:`~.walk_shadows.solved_environments`); the others are left to the paths that hit them.
        self.environments = solved_environments(scene) if self.refracting and self.straight_through else []
        #: Jumps across the deep interior (:mod:`.jumps`, the parameter ``jumps``) in ``auto``'s walks, where walks
        #: go to their end (not in the field's, nor in ``volpathmis``'s estimator); None: none.
        jumping = params.jumps == "on" and mode.straight and not mode.field
        walked = [obj for k, obj in enumerate(objects) if not (self.transported and self.transported[k])]
        self.jumps = (Jumps(scene, walked, params.unit_mm, self.environments) or None) if jumping and walked else None
        #: Shadow rays take a homogeneous medium's transmittance whole (module doc), but in ``volpathmis``'s estimator
        #: and without path roulette (a fit's walks: its closed loop read 3.3 % off in mfp with it, 1.5 % without).
        self.analytic = not mode.plain and self.rr_depth < MAX_WALK
        #: The emitters a surface and a path's first scattering vertex sample one by one (``each_emitter``: a shadow
        #: ray each, and a shadow-ray loop each in the walk's kernel), or ``[None]``: one the scene chooses, as
        #: ``volpathmis`` does (``mode.plain``), and as the later vertices do (module doc; ``_Path.chose_light``).
        self.lights = list(scene.emitters()) if each_emitter and not mode.plain and scene.emitters() else [None]
        #: ``(medium, lo, hi)`` per object: its interior and its world bounding box (scene units), grown by 1e-3.
        self.boxes = []
        for obj in objects:
            lo, hi = obj.bbox_mm / params.unit_mm
            grow = 1e-3 * (hi - lo).max()
            self.boxes.append((mi.MediumPtr(obj.shape.interior_medium()), mi.Point3f(*(lo - grow).tolist()),
                               mi.Point3f(*(hi + grow).tolist())))
        #: ``(medium, rough)`` per medium all of whose objects are closed behind a dielectric boundary (``rough``: all
        #: of them rough), which stops a shadow ray from a vertex inside toward a light outside their boxes
        #: (:meth:`~.walk_shadows.ShadowRays._sealed`).
        self.sealed, media = [], []
        for medium, _, _ in self.boxes:  # each medium once
            if not any(dr.all(medium == m) for m in media):
                media.append(medium)
        for medium in media:
            owners = [obj for obj, (other, _, _) in zip(objects, self.boxes) if dr.all(other == medium)]
            if all(obj.closed and obj.boundary != "null" for obj in owners):
                self.sealed.append((medium, all(obj.boundary == "roughdielectric" for obj in owners)))
        #: The diffusion field walks end in (:class:`~.field.DiffusionField`), None: every walk goes to its end.
        self.field = None
        #: ``(medium, sigma_t, sigma_s)`` of the homogeneous media whose paths are weighed by these coefficients
        #: (Color3f per scene unit) instead of the medium's own, which still draw them (module doc; a fit's trial).
        self.evaluated = []
        #: The media whose coefficients the walk differentiates (Mitsuba media; :meth:`differentiate`).
        self.differentiated = []
        #: A :class:`~.derivatives.Replay` while a walk is replayed for a heterogeneous medium's albedo or a boundary's
        #: roughness (Eq. G3 of :mod:`.derivatives`), else None.
        self.replayed = None
        #: Counts since :meth:`reset`: ``paths`` traced, scattering ``events`` in media, paths ``ended`` in the
        #: field (in some channel), ``capped`` at :data:`MAX_WALK` events and ``leaked`` out of their object unseen.
        self.counts = {}
        self.reset()

    def _outside(self, medium, p):
        """Per lane, whether ``p`` lies outside the bounding boxes of every object whose interior is ``medium`` (a
        MediumPtr) while it is some object's (the boxes grown by a thousandth of their size)."""
        ours, inside = dr.full(mi.Bool, False, dr.width(p)), dr.full(mi.Bool, False, dr.width(p))
        for medium_k, lo, hi in self.boxes:
            here = medium == medium_k
            ours |= here
            inside |= here & dr.all((p >= lo) & (p <= hi))
        return ours & ~inside

    def classify(self, si):
        """Per lane, the translucent object hit and its eta (:func:`.shadow.classify`)."""
        return classify(self.objects, si)

    def weigh(self, medium, sigma_t, sigma_s):
        """Weigh the paths in ``medium`` (a Mitsuba medium) by ``sigma_t`` and ``sigma_s`` (Color3f per scene unit)
        from now on, its own coefficients still drawing them (:attr:`evaluated`: a fit's trial material)."""
        self.evaluated = [(mi.MediumPtr(medium), sigma_t, sigma_s)]

    def differentiate(self, media):
        """From now on, :meth:`trace_derivatives` gives the radiance's derivatives with respect to ``media``'s
        coefficients (Mitsuba's homogeneous media; [] for none: :mod:`.derivatives`)."""
        self.differentiated = [mi.MediumPtr(m) for m in media]

    def reset(self):  # the counts (:attr:`counts`) start again
        self.counts = {"paths": 0, "events": 0, "jumps": 0, "ended": 0, "capped": 0, "leaked": 0, "refracted": 0,
                       "unsolved": 0}

    @property
    def stats(self):
        """The counts and what they say: mean scattering events per path, the share of paths ended in the field and
        cut by the cap, and of the light samples through a smooth boundary Eq. W5 found no refracted path for."""
        c, paths = self.counts, max(self.counts["paths"], 1)
        return {**c, "events_per_path": c["events"] / paths, "jumps_per_path": c["jumps"] / paths,
                "ended_share": c["ended"] / paths,
                "capped_share": c["capped"] / paths,
                "unsolved_share": c["unsolved"] / max(c["refracted"] + c["unsolved"], 1)}

    def trace(self, sampler, ray, medium=None):
        """Radiance (mi.Color3f) and first-hit mask (mi.Bool) of rays ``ray`` (camera rays, or rays from points in
        ``medium``, a Mitsuba medium they start in), drawing from ``sampler``: one symbolic loop, each pass an event
        of every path (a free flight in a medium, or a surface), in the steps below."""
        path = self._traced(sampler, ray, medium)
        return path.result, path.valid

    def trace_derivatives(self, sampler, ray, medium=None):
        """:meth:`trace`'s radiance and mask, and the radiance's derivatives with respect to each of
        :attr:`differentiated`'s ``sigma_t`` and ``sigma_s`` per channel (a tuple of Color3f, two per medium: Eq. G2 of
        :mod:`.derivatives`)."""
        path = self._traced(sampler, ray, medium)
        return path.result, path.valid, path.jacobian

    def _traced(self, sampler, ray, medium):
        """:meth:`_walk`'s paths, counted; where some objects are transported (:attr:`transported`), their exitance at
        the hits the loop recorded added afterwards (:meth:`~.lookups.ExitanceLookups.add_recorded`), the paths
        traced again from a copy of the sampler should more hits need recording than there was room for."""
        if not self.transported:
            return self._count(self._walk(sampler, ray, medium))

        def recording(sampler, hits):
            self.hits = hits
            return self._walk(sampler, ray, medium)

        path, hits = HitRecords.traced(recording, sampler, dr.width(ray.o))
        self.hits = None  # room for every lane: not kept between kernels
        self.tracer.lookups.add_recorded(path.result, hits, camera=ray if medium is None else None)
        return self._count(path)

    @dr.syntax
    def _walk(self, sampler, ray, medium):
        path = _Path.start(sampler, ray, medium, self.differentiated)
        while path.active:
            path = self._roulette(path, sampler)
            path, mei, in_medium, escaped, scatter = self._flight(path, sampler)
            path, scatter = self._field_ends(path, mei, scatter)
            # Symbolic branches: a packet of lanes none of which scatters (or meets a surface) skips that step's work
            if scatter:
                path = self._scatter(path, mei, scatter, sampler)
            if (path.active & (path.medium == None)) | escaped:  # noqa: E711 (a Dr.Jit pointer array)
                path = self._surface(path, in_medium, escaped, sampler)
        dr.eval(path.result, path.valid, path.scatterings, path.jumps, path.refracted, path.unsolved, path.ended,
                path.events, path.leaked, path.jacobian)
        return path

    def _count(self, path):
        """Adds ``path``'s walks to :attr:`counts`."""
        self.counts["paths"] += dr.width(path.active)
        self.counts["events"] += int(dr.sum(mi.UInt64(path.scatterings))[0])
        self.counts["jumps"] += int(dr.sum(mi.UInt64(path.jumps))[0])
        self.counts["refracted"] += int(dr.sum(mi.UInt64(path.refracted))[0])
        self.counts["unsolved"] += int(dr.sum(mi.UInt64(path.unsolved))[0])
        self.counts["ended"] += int(dr.count(path.ended)[0])
        self.counts["capped"] += int(dr.count(path.events >= MAX_WALK)[0])
        self.counts["leaked"] += int(dr.count(path.leaked)[0])
        return path

    def _roulette(self, path, sampler):
        """Russian roulette on the path's weight (eta^2: radiance's scaling across a boundary) below
        :data:`ROULETTE_WEIGHT`, the odds the weight over it; paths past ``max_depth``, :data:`MAX_WALK` events or of
        no weight end."""
        q = dr.minimum(dr.max(mis(path.ratios)) * dr.square(path.eta) / ROULETTE_WEIGHT, 1.0)
        roulette = path.active & ~path.last_null & (path.depth + path.events > self.rr_depth)
        path.active &= ~(roulette & (sampler.next_1d(path.active) >= q))
        path.ratios = update(path.ratios, q, 1.0, roulette)
        # The survivors' 1/q weighs an emitter they hit next whichever technique Eq. W2 credits it to: the light
        # sampled at the last vertex (before this roulette) too, else the two weights sum below 1 (it read 0.2 % low,
        # its derivatives 3 %).
        path.ratios_nee = update(path.ratios_nee, q, 1.0, roulette)
        path.last_null = dr.full(mi.Bool, False, dr.width(path.active))
        path.active &= (path.depth < self.max_depth) & (path.events < MAX_WALK) & dr.any(mis(path.ratios) != 0.0)
        return path

    def _flight(self, path, sampler):
        """In a medium: a free flight (Eq. W1's densities for every channel), then a null collision or a scattering.
        Returns ``(path, mei, in_medium, escaped, scatter)``: the medium interaction, the lanes that were in a medium
        and are still (``in_medium``) or left it through a surface (``escaped``), and those that scatter."""
        ray, medium, si = path.ray, path.medium, path.si
        active_medium = path.active & (medium != None)  # noqa: E711 (a Dr.Jit pointer array)
        mei = medium.sample_interaction(ray, sampler.next_1d(active_medium), path.channel, active_medium)
        ray.maxt[active_medium & medium.is_homogeneous() & mei.is_valid()] = mei.t
        intersect = path.needs_intersection & active_medium
        # From a surface, the flight starts on it; the surfaces are found from Mitsuba's offset origin, which lies
        # (1 + |p|) x 1.8e-4 scene units off it: more than a mean free path in a dense medium, which had lost light.
        skipped = dr.dot(path.offset, ray.d)
        hit = mi.Ray3f(ray.o + path.offset, ray.d, dr.maximum(ray.maxt - skipped, 0.0), ray.time, ray.wavelengths)
        si[intersect] = self.scene.ray_intersect(hit, intersect)
        si.t[intersect] += skipped
        path.offset[active_medium] = 0.0
        path.needs_intersection &= ~active_medium
        mei.t[active_medium & (si.t < mei.t)] = dr.inf
        path.scores = add_length(path.scores, self.differentiated, medium, dr.minimum(mei.t, si.t) - mei.mint,
                                 active_medium)  # Eq. G1
        spectral = active_medium & medium.has_spectral_extinction()
        trial, trial_t, trial_s = self._evaluated(medium, active_medium)
        spectral |= trial
        transmittance, flight_pdf = medium.transmittance_eval_pdf(mei, si, spectral)
        transmittance[trial] = dr.exp(-trial_t * (dr.minimum(mei.t, si.t) - mei.mint))
        path.ratios = update(path.ratios, flight_pdf, transmittance, spectral)
        escaped = active_medium & ~mei.is_valid()
        whole = escaped & medium.is_homogeneous() & self.analytic  # light sampling's density: the shadow's odds
        drawn = dr.exp(-mei.combined_extinction * (si.t - mei.mint))  # the odds by the drawn medium, not a trial's
        passed = dr.select(trial, dr.exp(-trial_t * (si.t - mei.mint)), drawn)
        path.ratios_nee = update(path.ratios_nee, flight_pdf, transmittance, spectral & ~whole)
        path.ratios_nee = update(path.ratios_nee, shadow_odds(drawn), passed, whole)
        active_medium &= mei.is_valid()
        spectral &= active_medium
        grey = active_medium & ~spectral

        null_probability = dr.sum(mei.sigma_n / mei.combined_extinction) / 3.0  # dr.mean: the width, a literal
        null = active_medium & (sampler.next_1d(active_medium) < null_probability)
        scatter = active_medium & ~null
        # A vertex in an object's medium outside every box of the objects of that medium left them unseen (a vertex
        # a rounding error past the boundary, a crack in the mesh) and would go on scattering through empty space to
        # MAX_WALK events (10 paths in 2.4 million on a 4 mm milk bunny: a third of its render's time without
        # roulette, which cut them sooner): it ends there.
        leaked = scatter & self._outside(medium, mei.p)
        path.leaked |= leaked
        path.active &= ~leaked
        scatter &= ~leaked
        path.last_null = null
        path.events[scatter] += 1
        path.scatterings[scatter] += 1
        path.depth[scatter & ~path.walking] += 1  # a walk is one bounce, as the transport's exitance is (max_depth)
        path.walking |= scatter
        path.last_scatter[scatter] = _interaction(mei)
        path.specular_chain &= ~scatter
        path.after_scatter |= scatter
        path.straight_out &= ~scatter  # a refraction out of an earlier vertex's object is no longer its last event
        path.ratios = update(path.ratios, null_probability, mei.sigma_n, spectral & null)
        path.ratios_nee = update(path.ratios_nee, 1.0, mei.sigma_n, spectral & null)
        path.ratios_nee = update(path.ratios_nee, 1.0, null_probability, grey & null)
        ray.o[null] = mei.p
        si.t[null] = si.t - mei.t
        sigma_s = dr.select(trial, trial_s, mei.sigma_s)
        path.scores = add_scattering(path.scores, self.differentiated, medium, sigma_s, scatter)  # Eq. G1
        path.ratios = update(path.ratios, 1.0 - null_probability, sigma_s, spectral & scatter)
        path.ratios = update(path.ratios, mei.sigma_t, mei.sigma_s, grey & scatter)
        return path, mei, active_medium, escaped, scatter

    def _field_ends(self, path, mei, scatter):
        """Deep enough: the channels where diffusion holds end in its field (Eq. W3); ``(path, scatter)`` with the
        lanes that still scatter (every lane where walks go to their end)."""
        if self.field is not None:
            scatter &= path.depth < self.max_depth  # the walk's light, within max_depth (the others end next step)
            ends, scattered = self.field.ending(mei, path.medium, scatter)
            path.ended |= scatter & (dr.max(ends) > 0.0)
            path.result[scatter] += mis(path.ratios) * scattered
            path.ratios = ended(path.ratios, ends)
            scatter &= dr.any(mis(path.ratios) != 0.0)
        return path, scatter

    def _scatter(self, path, mei, scatter, sampler):
        """A scattering vertex: next-event estimation (Eq. W2) and the phase function's next direction."""
        phase_ctx = mi.PhaseFunctionContext(sampler)
        phase = mei.medium.phase_function()
        phase[~scatter] = dr.zeros(mi.PhaseFunctionPtr)
        path.valid |= scatter
        if self.replayed is not None:
            replay_scattering(self.replayed, path.medium, mei, path.result, scatter)  # Eq. G3
        lit = scatter & (path.depth < self.max_depth)  # the vertex's light ends a path of depth + 1 segments
        if self._jumps_taken:  # a jump's own light is the straight paths out of its ball
            jumping = self.jumps.fit(path.medium, mei.p, scatter & (path.scatterings >= MIN_SCATTERINGS))
            lit &= ~jumping[0]
        vertex = _interaction(mei)
        path.chose_light |= scatter
        if len(self.lights) > 1:  # each emitter at a path's first scattering vertex, one chosen at the next (doc)
            each = lit & (path.scatterings <= 1)
            path = self._next_events(path, vertex, sampler, each, lambda d: phase.eval_pdf(phase_ctx, mei, d, each))
            path.chose_light &= ~each
            lit &= ~each
        path = self._next_events(path, vertex, sampler, lit, lambda d: phase.eval_pdf(phase_ctx, mei, d, lit),
                                 lights=[None])
        path.ratios_nee = where(scatter, path.ratios, path.ratios_nee)
        if self._jumps_taken:
            path, scatter = self._jump(path, mei, scatter, sampler, *jumping)
        wo, phase_weight, phase_pdf = phase.sample(phase_ctx, mei, sampler.next_1d(scatter),
                                                   sampler.next_2d(scatter), scatter)
        path.ray[scatter] = mei.spawn_ray(wo)
        path.scattered[scatter] = wo
        path.needs_intersection |= scatter
        path.ratios = update(path.ratios, phase_pdf, phase_weight * phase_pdf, scatter)
        path.ratios_nee = update(path.ratios_nee, 1.0, phase_weight * phase_pdf, scatter)
        return path

    @property
    def _jumps_taken(self):
        """Whether walks jump (:mod:`.jumps`): not where the coefficients are a trial's or differentiated (a replayed
        walk jumps as its radiance's pass does: a jump's weight holds none of the parameters it replays)."""
        return self.jumps is not None and self.field is None and not self.differentiated and not self.evaluated

    def _jump(self, path, mei, scatter, sampler, jumped, radius, index):
        """Across a ball in one step where one fits (:meth:`.jumps.Jumps.fit`; :mod:`.jumps`, Eq. J1) instead of the
        phase function's next direction: ``(path, scatter)`` with the lanes that still take it. A path that leaves
        the object straight from the ball finds the light it hits with its whole weight (no light was sampled inside
        it, nor at its centre)."""
        exit_point, direction, pdf, f = self.jumps.sample(mei.p, path.channel, sampler, jumped, radius, index)
        path.ray[jumped] = mi.Ray3f(exit_point, direction, mei.time, mei.wavelengths)
        path.needs_intersection |= jumped
        path.ratios = update(path.ratios, pdf, f, jumped)  # Eq. J1 in Eq. W1's ratios
        path.ratios_nee = where(jumped, path.ratios, path.ratios_nee)
        path.specular_chain |= jumped
        path.after_scatter &= ~jumped
        path.scattered[jumped] = 0.0
        path.jumps[jumped] += 1
        return path, scatter & ~jumped

    def _surface(self, path, in_medium, escaped, sampler):
        """At a surface (the lanes not in a medium, and those that flew out of one): the emission seen, weighed
        against next-event estimation (Eq. W2), then the light sampled from the surface and its BSDF's next
        direction; a boundary leads into the medium on its other side."""
        scene, si, ray = self.scene, path.si, path.ray
        active_surface = (path.active & (path.medium == None)) | escaped  # noqa: E711
        intersect = active_surface & path.needs_intersection
        si[intersect] = scene.ray_intersect(ray, intersect)
        first = active_surface & (path.depth == 0) & (path.events == 0)
        path.valid[first] = si.is_valid()
        emitter = si.emitter(scene)
        seen = active_surface & (emitter != None)  # noqa: E711
        # Refracted straight out of the last vertex to a light it sampled by Eq. W5: weighed against that, not direct
        bent = path.straight_out & through_boundary(emitter, self.environments)
        direct = first | (path.specular_chain & ~bent)
        to_emitter = mi.DirectionSample3f(scene, si, path.last_scatter)
        # One emitter the scene chose: its choice's probability in its density; each emitter sampled: its own
        chose = path.chose_light | (self.lights[0] is None)
        emitter_pdf = scene.pdf_emitter_direction(path.last_scatter, to_emitter, seen & ~direct & chose)
        emitter_pdf[~chose] = emitter.pdf_direction(path.last_scatter, to_emitter, seen & ~direct & ~chose)
        if self.straight_through and self.refracting:  # Eq. W5's density of this light
            bent &= seen & ~direct
            to_emitter.pdf = emitter_pdf
            refraction = refract_toward(scene, self.classify, path.last_scatter.p, to_emitter, bent)
            # where the solve from that vertex to this point of the light finds this path, and none elsewhere
            same = refraction.found & (dr.dot(refraction.d, path.scattered) > 1.0 - 1e-5)
            emitter_pdf[bent] = dr.select(same, refraction.pdf, 0.0)
        elif self.straight_through:  # Eq. W4 took this light at the last vertex (refraction straight)
            seen &= ~bent
        path.ratios_nee = update(path.ratios_nee, emitter_pdf, 1.0, seen & ~direct)
        radiance = emitter.eval(si, seen)
        found = dr.select(direct, mis(path.ratios), mis(path.ratios, path.ratios_nee)) * radiance
        path.result[seen] += found
        path.jacobian = accumulate(path.jacobian, path.scores, found, seen)  # Eq. G2
        active_surface &= si.is_valid()
        path, held = self._transported(path, si, first, active_surface, sampler)

        bsdf = si.bsdf(ray)
        lit = active_surface & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth) & (path.depth + 1 < self.max_depth)
        path = self._next_events(path, si, sampler, lit, lambda d: self._bsdf(bsdf, si, lit, held, d), (bsdf, si))
        bs, bsdf_weight = self._bsdf(bsdf, si, active_surface, held, sample=(sampler.next_1d(active_surface),
                                                                             sampler.next_2d(active_surface)))
        active_surface &= bs.pdf > 0.0
        if self.replayed is not None:  # Eq. G3: the light still to come through the sampled direction
            replay_bsdf(self.replayed, bsdf, si, si.to_world(bs.wo), self.replayed.radiance - path.result,
                        active_surface)
        path.eta[active_surface] *= bs.eta
        ray[active_surface] = si.spawn_ray(si.to_world(bs.wo))
        path.needs_intersection |= active_surface
        solid = active_surface & ~mi.has_flag(bs.sampled_type, mi.BSDFFlags.Null)
        path.specular_chain |= solid & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
        path.specular_chain &= ~(active_surface & mi.has_flag(bs.sampled_type, mi.BSDFFlags.Smooth))
        boundary = active_surface & si.is_medium_transition()
        if self.straight_through:
            out = boundary & path.after_scatter & mi.has_flag(bs.sampled_type, mi.BSDFFlags.DeltaTransmission)
            path.straight_out[solid] = out & (self.classify(si)[0] >= 0)
            path.after_scatter &= ~solid
        path.depth[solid & ~boundary] += 1
        path.events[solid & boundary] += 1
        # The light sampled here, or at the last vertex if it refracts straight out toward it (Eq. W5)
        path.last_scatter[solid & ~path.straight_out] = _interaction(si)
        path.chose_light &= ~(solid & ~path.straight_out)
        path.ratios_nee = where(solid & ~path.straight_out, path.ratios, path.ratios_nee)
        path.ratios = update(path.ratios, bs.pdf, bsdf_weight * bs.pdf, active_surface)
        path.ratios_nee = update(path.ratios_nee, 1.0, bsdf_weight * bs.pdf, solid)
        entered = si.target_medium(ray.d)
        path.walking &= ~(boundary & (entered != path.medium))
        path.medium[boundary] = entered
        into = active_surface & (path.medium != None)  # noqa: E711 (a flight from the surface itself)
        path.offset[into], ray.o[into] = ray.o - si.p, si.p
        path.active &= active_surface | in_medium
        return path

    def _transported(self, path, si, first, active, sampler):
        """``(path, held)``: the ``active`` lanes at an object its transport renders (:attr:`transported`), its light
        found there as an emitter's would be (weight ``mis(ratios)``): the exitance ``(1/pi) F_t M`` (paper Eq. 7,
        recorded in :attr:`hits` for the lookup after the loop) and the single scattering (Eq. S2), within
        ``max_depth`` as a walk's first scattering would be."""
        held = dr.full(mi.Bool, False, dr.width(active))
        if not self.transported:
            return path, held
        which, eta = self.classify(si)
        for k, transported in enumerate(self.transported):
            if transported:
                held |= active & (which == k)
        lit = held & (path.depth + 1 < self.max_depth)
        weight = mis(path.ratios) * self.tracer.exit_weight(which, eta, si.wi.z)
        self.hits.add(lit, (which, si.p, mi.Vector3f(si.n), weight, dr.arange(mi.UInt32, dr.width(active)), first,
                            si.prim_index))
        if self.tracer.single:
            path.result[lit] += mis(path.ratios) * self.tracer.single_scattering(
                si, which, eta, sampler.next_1d(lit), sampler.next_2d(lit), lit)
        return path, held

    def _bsdf(self, bsdf, si, active, held, direction=None, sample=None):
        """The boundary's BSDF towards ``direction`` (``(value, pdf)``) or, with ``sample`` (``(u_lobe, u_dir)``), its
        sample and weight: the whole BSDF, and on the lanes ``held`` (a transported object, whose light under the
        surface is its exitance) its reflection lobe alone."""
        def one(ctx, mask):
            if sample is None:
                return bsdf.eval_pdf(ctx, si, si.to_local(direction), mask)
            return bsdf.sample(ctx, si, *sample, mask)

        if not self.transported:
            return one(mi.BSDFContext(), active)
        out, reflected = one(self.tracer.ctx, active & ~held), one(self.tracer.ctx_reflect, active & held)
        return tuple(dr.select(held, r, o) for r, o in zip(reflected, out))

    def _evaluated(self, medium, active):
        """Per lane in ``medium`` (where ``active``): whether its paths are weighed by :attr:`evaluated`'s
        coefficients, and those ``sigma_t``, ``sigma_s`` (Color3f per scene unit; 0 elsewhere)."""
        n = dr.width(active)
        trial, sigma_t, sigma_s = dr.full(mi.Bool, False, n), dr.zeros(mi.Color3f, n), dr.zeros(mi.Color3f, n)
        for weighed, weighed_t, weighed_s in self.evaluated:
            here = active & (medium == weighed)
            trial |= here
            sigma_t[here], sigma_s[here] = weighed_t, weighed_s
        return trial, sigma_t, sigma_s

    def _next_events(self, path, origin, sampler, active, evaluate, surface=None, lights=None):
        """``path`` with, where ``active``, the light of each of ``lights`` (:attr:`lights`; ``[None]``: one the scene
        chooses) sampled from ``origin`` (a scattering vertex or a surface in the path's medium) and weighed against
        the path's own sampling there by the balance heuristic (Eq. W2) added to its radiance; ``evaluate(direction)``
        is that sampling's ``(value, pdf)``: the phase function's or the BSDF's (``surface``: ``(bsdf, si)``, for a
        replayed walk's Eq. G3)."""
        for light in self.lights if lights is None else lights:
            end_nee, end_uni, emitted, ds, crossed, scores, refraction = self._emitter(
                origin, path.medium, path.ratios, path.channel, sampler, active, light)
            path.refracted[refraction.found] += 1
            path.unsolved[refraction.tried & ~refraction.found] += 1
            value, pdf = evaluate(ds.d)
            end_nee = update(end_nee, 1.0, value, active)
            end_uni = update(end_uni, dr.select(ds.delta | crossed, 0.0, pdf), value, active)
            found = mis(end_nee, end_uni) * emitted  # Eq. W2
            path.result[active] += found
            path.jacobian = accumulate(path.jacobian, path.scores, found, active, scores)  # Eq. G2
            if self.replayed is not None and surface is not None:
                replay_bsdf(self.replayed, *surface, ds.d, found, active)  # Eq. G3
        return path
