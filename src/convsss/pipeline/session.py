"""The render session: what the render's stages built for one sensor, and when it may be used again.

The stages (docs/architecture.md, the data flow), in the order they run and with the names the stats, the command
line, the benchmarks and the progress display use (:data:`convsss.pipeline.STAGES`):

1. ``samples``: the translucent objects (:func:`.objects.find_translucent_objects`), what the camera sees of them
   (:func:`.camera.first_hits`) and the sampling plan (:func:`.plan.plan_samples`: per object the layer cell, the
   sample count, the memory and time they and the transport need, refused before anything is drawn), then the
   samples themselves (:func:`.irradiance.object_samples`);
2. ``irradiance``: their direct irradiance from every emitter (paper Eq. 2);
3. ``indirect``: their indirect irradiance, path traced into the scene by the render's path tracer
   (:class:`.path_tracer.PathTracer`), whose hits on translucent objects wait for the transports, and the passes
   that resolve them (:func:`.passes.translucent_passes`);
4. ``transport``: each object's transport in the camera's frame (:func:`.passes.build_transports`, paper Eq. 1);
5. ``screen``: the exitance at the visible pixel centres (:class:`.screen.ScreenExitance`);
6. ``shading``: the camera rays, shaded by the path tracer through Mitsuba's render loop (the plugin,
   :mod:`.integrator`).

A :class:`RenderSession` runs stages 1-5 (:meth:`RenderSession.prepare`), keeps what they built
(:class:`PreparedState`) with the one :class:`~.path_tracer.PathTracer` of that state, and knows what of it a later
render may reuse (:meth:`RenderSession.reuse`), what an edit rebuilds (:meth:`RenderSession.retransport`,
:meth:`RenderSession.reprepare`) and how to go back (:meth:`RenderSession.checkpoint`). The Mitsuba plugin
(:class:`.integrator.ConvsssIntegrator`) holds one and shades with its tracer.
"""

import hashlib
import math
import warnings
from dataclasses import dataclass, field

import drjit as dr
import numpy as np

from ..backend import import_mitsuba
from ..errors import ConvsssError
from ..fresnel import same_eta
from ..materials import OpticallyThinWarning
from ..timing import StageTimer
from .aovs import FirstHitAOVs
from .camera import check_camera, first_hits, sensor_frame
from .checks import check_lights_outside, warn_near_delta_boundaries
from .field import diffusion_field
from .irradiance import keeps_irradiance
from .lighting import light_samples
from .objects import find_translucent_objects
from .params import (
    IgnoredParameterWarning,
    RenderMode,
    parse_aovs,
    render_mode,
    render_parameters,
    walk_ignored,
    walks_alone,
)
from .parts import as_seed
from .passes import build_transports, translucent_passes
from .path_tracer import PathTracer
from .plan import plan_samples
from .screen import ScreenExitance
from .shadow import Shadows
from .stages import STAGES

mi = import_mitsuba()

def _digest(params):
    """A digest of a Mitsuba object's traversed parameters (``mi.traverse``): their names and values."""
    digest = hashlib.blake2b(digest_size=16)
    for name in sorted(params.keys()):
        value = params[name]
        value = value.matrix if isinstance(value, (mi.Transform4f, mi.AffineTransform4f)) else value
        try:
            array = np.asarray(value)
        except (TypeError, ValueError, RuntimeError):
            array = None
        data = repr(value).encode() if array is None or array.dtype == object else array.tobytes()
        digest.update(name.encode() + b"=" + data + b";")
    return digest.hexdigest()


def scene_fingerprint(scene, sensor):
    """``(world, crop)``: digests of every traversable parameter of the scene's shapes (with their BSDFs and media),
    its emitters and ``sensor``, and of the sensor's crop window alone: what a kept render state must still match
    (:meth:`RenderSession.reuse`). Cheap next to any stage of a render, so every render can check it."""
    crop_keys = ("film.crop_size", "film.crop_offset")
    camera = mi.traverse(sensor)
    crop = tuple(tuple(np.asarray(camera[k]).reshape(-1).tolist()) for k in crop_keys if k in camera)
    world = [_digest(mi.traverse(s)) for s in scene.shapes()] + [_digest(mi.traverse(e)) for e in scene.emitters()]
    for key in crop_keys:
        if key in camera:
            camera.keep([k for k in camera.keys() if k != key])
    return hashlib.blake2b("".join(world + [_digest(camera)]).encode(), digest_size=16).hexdigest(), crop


@dataclass(eq=False)
class PreparedState:
    """What :meth:`RenderSession.prepare` built for one sensor, kept so that :meth:`RenderSession.retransport` can
    rebuild the transports alone (new profiles or transport parameters) on the same samples and irradiance.

    ``objects``, ``visible`` and ``cells`` hold one entry per object seen by the camera: the object, its visible
    points, the pixel footprint at its depth (mm); ``lighting`` their samples and irradiance (:class:`~.lighting.
    Lighting`: the samples with their direct irradiance, direct + indirect without the light of translucent objects,
    the indirect paths' hits on translucent objects), ``transports`` theirs, ``diffusion`` the field the random walk
    ends in (:func:`~.field.diffusion_field`, None without one); ``survey`` what
    :meth:`RenderSession.survey` found (all objects, the frame, what each pixel centre sees, the plan);
    ``params`` the parameters it was built with (``RenderParams.to_dict()``) and ``fingerprint`` the scene's and the
    crop window's :func:`scene_fingerprint` then, so that a later render knows what of it still holds.
    """

    scene: object
    sensor: object
    seed: int
    frame: object
    objects: list
    visible: list
    cells: list
    lighting: object
    transports: list = field(default_factory=list)
    diffusion: object = None
    survey: tuple = None
    params: dict = None
    fingerprint: tuple = None

    @property
    def samples(self):
        """Each object's :class:`~convsss.samples.IrradianceSamples`, with the direct irradiance."""
        return self.lighting.samples

    @property
    def irradiance(self):
        """Each object's direct + indirect irradiance (N, 3), without the light of translucent objects."""
        return self.lighting.irradiance


class RenderSession:
    """Stages 1-5 of a render (module doc) and what they built, for the shading to use and later renders to reuse.

    Parameters
    ----------
    params : RenderParams
    stop : callable
        ``stop()`` is True once the render should wind down (Ctrl-C); asked between chunks of work.
    announce : callable
        ``announce(stage)`` is told when a stage starts (the command line's progress display).

    Attributes
    ----------
    prepared : PreparedState or None
        What the last :meth:`prepare` built.
    tracer : PathTracer or None
        Its path tracer, with its transports and screen table attached; ``aovs`` its :class:`~.aovs.FirstHitAOVs`.
    keep : bool
        Whether :attr:`prepared` outlives the render that made it (``prepare()`` by the user: renders reuse it).
    stats : dict
        The last run's stats (the integrator's :attr:`~.integrator.ConvsssIntegrator.stats`).
    """

    def __init__(self, params, stop, announce):
        self.params, self.stop, self.announce = params, stop, announce
        #: What the last :meth:`prepare` renders the objects with (:class:`~.params.RenderMode`, resolved once by
        #: :meth:`survey`; an edit's :meth:`retransport` decides it anew for its materials).
        self.mode = RenderMode(0.0)
        self.prepared = self.tracer = self.aovs = None
        self.keep = False
        self.stats = {}

    def _timed(self):
        """A :class:`~convsss.timing.StageTimer` and ``stage(name)``, which announces the stage and times it."""
        timer = StageTimer(sync=dr.sync_thread)

        def stage(name):
            self.announce(name)
            return timer(name)

        return timer, stage

    def _note(self, stage):
        """``note(text)``: what ``stage`` does now, for the progress display (``announce("stage: text")``)."""
        return lambda text: self.announce(f"{stage}: {text}")

    def release(self):
        """Drop what was prepared: renders start from nothing again, and the scene can be freed."""
        self.prepared = self.tracer = self.aovs = None
        self.keep = False

    def survey(self, scene, sensor):
        """What the camera sees, whatever the seed: the translucent objects, the view frame, each object's points
        seen through the pixel centres, and the sampling plan (one-line errors before anything is drawn)."""
        p = self.params
        with warnings.catch_warnings():
            if p.walk_depth == math.inf:  # walks to the end: how well diffusion holds is nobody's concern
                warnings.simplefilter("ignore", OpticallyThinWarning)
            objects = find_translucent_objects(mi, scene, p.unit_mm, p.profile, p.profile_total, p.orders,
                                               lights_inside=p.walk_depth in ("auto", math.inf))
        mode = render_mode(p, objects)  # resolved here, once: the plan carries it (prepare renders with it)
        if p.walk_depth == "auto" and not mode.walks:  # the transport after all
            check_lights_outside(mi, scene, objects, p.unit_mm)
        check_camera(sensor)
        frame = sensor_frame(sensor, p.unit_mm)
        seen = first_hits(scene, sensor, frame, p.unit_mm, objects)
        return objects, frame, seen, plan_samples(scene, sensor, frame, objects, seen, p, mode)

    @property
    def walks_alone(self):
        """Whether the render needs none of stages 2-5: every walk goes to its end (``walk_depth`` inf) and no AOV
        asks for the transports' exitance or the samples' irradiance."""
        return walks_alone(self.params, self.mode)

    def _attach(self, tracer, transports, screen, diffusion=None):
        """``tracer`` reads ``transports``, ``screen`` and the ``diffusion`` field from now on; the AOVs read the
        tracer."""
        self.tracer = tracer.attach(transports, screen, diffusion)
        self.aovs = FirstHitAOVs(tracer, parse_aovs(self.params.aovs))
        return self.tracer

    def prepare(self, scene, sensor, seed=0, survey=None):
        """Stages 1-5 for ``sensor``; ``survey``: a :meth:`survey` of the same scene, sensor and parameters to reuse
        (the passes of one render share it). Returns the path tracer, its transports attached."""
        asked = self.params.to_dict()
        fingerprint = scene_fingerprint(scene, sensor) if self.keep else None  # only a kept state is reused
        timer, stage = self._timed()
        with stage("samples"):
            objects, frame, seen, plan = survey if survey is not None else self.survey(scene, sensor)
        p, mode = self.params, plan.mode
        self.mode = mode
        shown = [objects[q.index] for q in plan.objects]
        shown_at = [seen[q.index] for q in plan.objects]
        cells = [q.pixel_footprint_mm for q in plan.objects]
        per_object = [{**obj.summary(), **q.summary(obj.area_mm2)} for obj, q in zip(shown, plan.objects)]
        tracer = PathTracer(scene, shown, p, mode, stop=self.stop, shadows=Shadows(scene, objects, p.unit_mm))
        if mode.walks:
            warn_near_delta_boundaries(scene, shown)
        if self.walks_alone:  # the walk reaches every interior itself: no samples, irradiance or transports
            ignored = walk_ignored(p)
            if ignored:
                warnings.warn(f"{', '.join(ignored)}: every translucent object walks to its end (walk_depth {mode}), "
                              "which renders their media themselves: these parameters of the transports have no "
                              "effect", IgnoredParameterWarning, stacklevel=2)
            self._attach(tracer, [None] * len(shown), None)
            self.stats = {"parameters": asked, "walk_depth": str(mode), "seconds": dict(timer),
                          "objects": per_object, "hidden": list(plan.hidden), "samples": 0, "translucent_passes": 0,
                          "screen_exitance": {"usable": False, "queries": 0}}
            self.prepared = PreparedState(scene, sensor, as_seed(seed), frame, shown, shown_at, cells, None,
                                          [None] * len(shown), survey=(objects, frame, seen, plan),
                                          params=asked, fingerprint=fingerprint)
            return self.tracer
        lighting = light_samples(scene, objects, plan, p, as_seed(seed), tracer, stage, self.stop)
        transports = build_transports(lighting.samples, lighting.irradiance, shown, cells, frame, p, stage)
        transports, from_translucent, passes = translucent_passes(transports, lighting, tracer, p.indirect_passes,
                                                                  stage, self.stop)
        for k, s in enumerate(lighting.samples):  # flux = sum_i A_i E_i, as area @ E (no (N, 3) temporaries)
            flux_direct, flux_translucent = s.area @ s.irradiance, s.area @ from_translucent[k]
            total = s.area @ lighting.irradiance[k] + flux_translucent
            per_object[k].update(samples=len(s), flux=total.tolist(), flux_direct=flux_direct.tolist(),
                                 flux_indirect=(total - flux_direct).tolist(),
                                 flux_from_translucent=flux_translucent.tolist())
        with stage("transport"):
            diffusion = diffusion_field(shown, transports, mode, p.unit_mm, self._note("transport"))
        with stage("screen"):
            screen = ScreenExitance(sensor, shown, shown_at, transports, p.unit_mm)
        self._attach(tracer, transports, screen, diffusion)
        self.stats = {"parameters": asked, "walk_depth": str(mode), "seconds": dict(timer),
                      "transported": [obj.name for obj in shown if mode.walks and mode.transports(obj)],
                      "objects": per_object, "hidden": list(plan.hidden),
                      "samples": int(sum(o["samples"] for o in per_object)), "translucent_passes": passes,
                      "screen_exitance": {"usable": screen.usable, "queries": screen.queries}}
        self.prepared = PreparedState(scene, sensor, as_seed(seed), frame, shown, shown_at, cells, lighting,
                                      transports, diffusion, survey=(objects, frame, seen, plan), params=asked,
                                      fingerprint=fingerprint)
        return self.tracer

    def reuse(self, scene, sensor, seed):
        """Make the prepared state the one a render of ``scene``, ``sensor`` and ``seed`` needs, from what a kept
        :meth:`prepare` built that still holds; returns the stages reused.

        The same scene (every traversable parameter of its shapes, emitters and sensor: :func:`scene_fingerprint`),
        parameters and seed keep all but the shading. Another crop window draws the survey again (what each pixel
        centre sees) and, where the plan is the same (the same objects seen; the cells follow the film and the
        objects' depth, not the crop: :meth:`~.plan.SamplingPlan.draws_like`), keeps the samples and transports: the
        samples cover each object's whole surface. Another seed keeps the survey alone."""
        state = self.prepared
        kept = (state is not None and self.keep and state.scene is scene and state.sensor is sensor
                and state.params == self.params.to_dict())
        fingerprint = scene_fingerprint(scene, sensor) if kept else None
        if not kept or state.fingerprint[0] != fingerprint[0]:
            self.prepare(scene, sensor, seed)
            return []
        if state.fingerprint[1] == fingerprint[1]:
            if state.seed == seed:
                self.stats["seconds"] = {}
                return list(STAGES[:-1])
            self.prepare(scene, sensor, seed, survey=state.survey)
            return ["survey"]
        timer = StageTimer(sync=dr.sync_thread)
        with timer("samples"):
            survey = self.survey(scene, sensor)
        if state.seed != seed or not survey[3].draws_like(state.survey[3]):
            self.prepare(scene, sensor, seed, survey=survey)
            self.stats["seconds"]["samples"] += timer["samples"]
            return []
        objects, _, seen, plan = survey
        state.visible = [seen[q.index] for q in plan.objects]
        with timer("screen"):
            screen = None if state.lighting is None else ScreenExitance(sensor, state.objects, state.visible,
                                                                         state.transports, self.params.unit_mm)
        self._attach(self.tracer, state.transports, screen, state.diffusion)
        state.survey, state.fingerprint = survey, fingerprint
        self.stats.update(seconds=dict(timer), screen_exitance={"usable": screen is not None and screen.usable,
                                                                "queries": 0 if screen is None else screen.queries})
        return ["irradiance", "indirect", "transport"]

    def retransport(self, objects=None, params=None):
        """Stage 4 again on the prepared state: the transports, the light between translucent objects and the
        screen's exitance, for new ``objects`` and/or new ``params``; returns the path tracer.

        The geometry, the samples and their irradiance (direct, and indirect off opaque surfaces) do not depend on the
        profile (paper Eq. 2 has only ``F_t(eta)`` of the material, and with ``incidence = oblique`` the gain of its
        reduced albedo), so a new material of the same ``eta`` (and reduced albedo), another profile model or another
        transport accuracy needs only the transports (Eq. 1) built again. A new ``eta`` changes ``F_t`` at every
        sample, a new albedo the gain: that needs :meth:`prepare`.

        Parameters
        ----------
        objects : list of TranslucentObject, optional
            The prepared objects (``prepared.objects``), in that order, with other materials or profiles
            (``dataclasses.replace(obj, material=..., profile=...)``); same shapes, same ``eta`` (and, with
            ``incidence = oblique``, the same reduced albedo).
        params : RenderParams, optional
            New parameters differing from the session's only in the transport and its parameters (not in what
            sets the samples: ``sample_density``, ``downsample``, ``irradiance_samples``, ...) or ``profile``.

        After it, :attr:`stats` ``seconds`` holds this rebuild's stages only.
        """
        state = self.prepared
        if state is None:
            raise ConvsssError("nothing is prepared to rebuild: call prepare() (or render_prepared after it) first")
        objects = list(state.objects if objects is None else objects)
        same = len(objects) == len(state.objects) and all(
            new.shape is old.shape and new.instance_index == old.instance_index and same_eta(new.eta, old.eta)
            for new, old in zip(objects, state.objects))
        if not same:
            raise ConvsssError("retransport keeps the prepared objects and their eta (Fresnel's F_t at the samples "
                               "depends on it): call prepare() for a new eta or other objects")
        if params is not None:
            self._check_same_samples(params)
            self.params = params
        if state.lighting is None:  # prepared for walks alone: the stages it skipped, now
            return self.reprepare(objects)
        p = self.params
        mode = self.mode = render_mode(p, objects)  # the edit's materials decide it anew
        if not all(keeps_irradiance(old.material, new.material, p.incidence, p.orders)
                   for new, old in zip(objects, state.objects)):  # the same eta: only the albedo can differ
            raise ConvsssError("retransport keeps the samples' irradiance, which weights the light by the albedo's "
                               "gain (incidence = oblique, or single scattering traced): call prepare() for a new "
                               "reduced albedo")
        timer, stage = self._timed()
        tracer = PathTracer(state.scene, objects, p, mode, stop=self.stop)
        transports = build_transports(state.samples, state.irradiance, objects, state.cells, state.frame, p, stage)
        transports, _, passes = translucent_passes(transports, state.lighting, tracer, p.indirect_passes, stage,
                                                   self.stop)
        with stage("transport"):
            diffusion = diffusion_field(objects, transports, mode, p.unit_mm, self._note("transport"))
        with stage("screen"):
            screen = ScreenExitance(state.sensor, objects, state.visible, transports, p.unit_mm)
        self._attach(tracer, transports, screen, diffusion)
        state.objects, state.transports, state.diffusion = objects, transports, diffusion
        state.params = self.params.to_dict()
        for summary, obj in zip(self.stats.get("objects", []), objects):
            summary.update(obj.summary())
        self.stats.update(parameters=self.params.to_dict(), walk_depth=str(mode), seconds=dict(timer),
                          translucent_passes=passes,
                          screen_exitance={"usable": screen.usable, "queries": screen.queries})
        return self.tracer

    def reprepare(self, objects, replan=False):
        """Stages 1-5 again for the prepared scene, sensor and seed with ``objects`` (the prepared objects, in that
        order, with other materials: the same shapes), keeping its plan: the same sample count and positions, their
        irradiance drawn again (a new reduced albedo changes its entry gain, a new ``eta`` its Fresnel
        transmittance; a new ``eta`` should be the boundary BSDF's too, which the caller sets). What a fit needs
        between materials (:mod:`convsss.fitting`): the image then changes smoothly with the material where the
        objects keep one ``sampling`` material (the paths' choices do not move with it), where a new :meth:`prepare`
        would size the samples by the new profile. With ``replan`` the plan is made again for the new objects (the
        samples sized by their profiles, :func:`~.plan.plan_samples`), what the camera sees kept. Returns the path
        tracer."""
        state = self.prepared
        if state is None:
            raise ConvsssError("nothing is prepared to redo: call prepare() first")
        every, frame, seen, plan = state.survey
        every = list(every)
        if len(objects) != len(plan.objects) or not all(new.shape is every[q.index].shape
                                                        for new, q in zip(objects, plan.objects)):
            raise ConvsssError("reprepare keeps the prepared objects: call prepare() for other ones")
        for new, q in zip(objects, plan.objects):
            every[q.index] = new
        if replan:
            plan = plan_samples(state.scene, state.sensor, frame, every, seen, self.params,
                                render_mode(self.params, every))
        return self.prepare(state.scene, state.sensor, state.seed, survey=(every, frame, seen, plan))

    def checkpoint(self):
        """What :meth:`prepare`, :meth:`retransport` and a shading change, for :meth:`restore` (an edit applied
        whole or not at all)."""
        state = self.prepared
        kept = None if state is None else (state.objects, state.transports)
        return self.params, self.prepared, kept, self.tracer, self.aovs, self.stats

    def restore(self, checkpoint):
        """Back to a :meth:`checkpoint`."""
        self.params, self.prepared, kept, self.tracer, self.aovs, self.stats = checkpoint
        if kept is not None:
            self.prepared.objects, self.prepared.transports = kept

    def _check_same_samples(self, params):
        """A one-line error when ``params`` would place or light the samples differently from the prepared ones."""
        kept = [q.name for q in render_parameters() if q.name not in ("transport", "profile", "aovs")]
        changed = [n for n in kept if getattr(params, n) != getattr(self.params, n)]
        cell = [q.transport_class().layer_cell(1.0, q.transport_params()) for q in (params, self.params)]
        if cell[0] != cell[1]:
            changed.append("the layer cell (downsample)")
        if changed:
            raise ConvsssError(f"retransport cannot change {', '.join(changed)}: the samples depend on it; call "
                               "prepare() with the new parameters")
