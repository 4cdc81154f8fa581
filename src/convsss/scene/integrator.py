"""The ``convsss`` Mitsuba integrator: Mitsuba glue over the render's stages (docs/architecture.md, the data flow).

``render()`` does, for one sensor, each stage a public function passing plain data to the next:

1. the translucent objects (:func:`.objects.find_translucent_objects`) and what the camera sees of them
   (:func:`.camera.first_hits`);
2. the sampling plan (:func:`.plan.plan_samples`): per object the layer cell (the pixel footprint at its depth),
   ``N = max(sample_density A / h^2, profile_samples A / A_eff)`` surface samples, and the memory and time they and
   the transport need, refused before anything is drawn;
3. the samples and their irradiance (:func:`.lighting.light_samples`, paper Eq. 2): direct light from every
   emitter, and indirect light path traced into the scene from the samples (``indirect_samples`` paths each) with
   the shader's path tracer, whose hits on translucent objects wait for their transports;
4. each object's transport in the camera's frame, and the light between translucent objects
   (:func:`.passes.build_transports`, :func:`.passes.translucent_passes`, ``indirect_passes`` times);
5. the exitance at the visible pixel centres (:class:`.screen.ScreenExitance`), and the shading of the camera rays
   (:class:`.shading.Shader`) through Mitsuba's own render loop, so the film, its reconstruction filter, crop
   window, sampler and sample count behave as for any Mitsuba integrator.

Per-stage seconds and everything a user needs to judge the run are in :attr:`ConvsssIntegrator.stats`.
"""

import functools
import hashlib
import threading
import time
import warnings
from dataclasses import dataclass, field

import drjit as dr
import numpy as np

from ..backend import load_mitsuba, ordered_kernels
from ..errors import ConvsssError
from ..fresnel import same_eta
from ..signals import mitsuba_render
from ..timing import StageTimer
from .aovs import FirstHitAOVs
from .camera import check_camera, first_hits, sensor_frame
from .irradiance import keeps_irradiance
from .lighting import light_samples
from .objects import find_translucent_objects
from .params import (
    IgnoredParameterWarning,
    RenderParams,
    aov_channels,
    integrator_parameters,
    parse_aovs,
    plugin_parameters,
)
from .passes import build_transports, translucent_passes
from .plan import check_film, plan_samples
from .presets import register_medium
from .screen import ScreenExitance
from .shading import Shader

mi = load_mitsuba()
#: The variant this module's classes were built in (a Mitsuba class belongs to one variant).
VARIANT = mi.variant()


#: One render stage at a time in a process: an integrator's prepared state and the thread count the shading sets in
#: Dr.Jit are shared, so a second thread waits for the first (two threads rendering one scene at once failed).
RENDER_LOCK = threading.RLock()


def _one_at_a_time(method):
    """``method`` under :data:`RENDER_LOCK` (re-entrant: Mitsuba's loop calls back into the integrator)."""

    @functools.wraps(method)
    def serialized(*args, **kwargs):
        with RENDER_LOCK:
            return method(*args, **kwargs)

    return serialized


def _seed(seed):
    return int(np.asarray(seed, dtype=np.uint64).reshape(-1)[0]) if not isinstance(seed, int) else seed


def pass_seed(seed, k):
    """The seed of pass ``k`` of a render of ``seed``: ``seed`` itself for the first (one pass renders as before),
    then a 32-bit hash of both, so that passes draw independent samples and camera rays."""
    if k == 0:
        return seed
    return int.from_bytes(hashlib.blake2b(f"{seed}:{k}".encode(), digest_size=4).digest(), "little")


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
    (:meth:`ConvsssIntegrator.prepare`). A few milliseconds for a 70 k-triangle scene."""
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
    """What :meth:`ConvsssIntegrator.prepare` built for one sensor, kept so that :meth:`ConvsssIntegrator.retransport`
    can rebuild the transports alone (new profiles or transport parameters) on the same samples and irradiance.

    ``objects``, ``visible`` and ``cells`` hold one entry per object seen by the camera: the object, its visible
    points, the pixel footprint at its depth (mm); ``lighting`` their samples and irradiance (:class:`~.lighting.
    Lighting`: the samples with their direct irradiance, direct + indirect without the light of translucent objects,
    the indirect paths' hits on translucent objects), ``transports`` theirs; ``survey`` what
    :meth:`ConvsssIntegrator._survey` found (all objects, the frame, what each pixel centre sees, the plan);
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


class ConvsssIntegrator(mi.SamplingIntegrator):
    """Convolution-based subsurface scattering (Munoz et al. 2011) as a Mitsuba 3 integrator; see the module doc.

    ``<integrator type="convsss">`` (call :func:`register` first). Parameters, besides Mitsuba's own
    ``samples_per_pass`` (the table is generated from the declarations, :mod:`convsss.parameters`):

    {table}

    **AOVs.** ``aovs`` (e.g. ``"exitance,irradiance,object,mask,depth,normal"``) adds channels to the film through
    Mitsuba's AOV mechanism (:meth:`aov_names`, the list :meth:`sample` returns), ``<aov>.<channel>`` as Mitsuba's
    ``aov`` integrator names them, each at the camera ray's first hit (:mod:`convsss.scene.aovs`): ``exitance``
    (``.R/.G/.B``) the transport's ``M`` on a translucent object, whose subsurface radiance is ``(1/pi) F_t M``
    (paper Eq. 7); ``irradiance`` (``.R/.G/.B``) the ``E`` its samples carry there (Eq. 2); ``object`` (``.I``) the
    translucent object's index + 1 (0: none); ``mask`` (``.Y``) 1 on a translucent object (a pixel's coverage);
    ``depth`` (``.T``) and ``normal`` (``.X/.Y/.Z``) as Mitsuba's ``depth`` and ``sh_normal``. They follow R, G, B
    (and A) in the rendered tensor, work under Mitsuba's ``aov`` integrator too, and leave the radiance unchanged.

    **Stats and stages.** After a render, :attr:`stats` holds ``seconds`` per stage (``samples``, ``irradiance``,
    ``indirect``, ``transport``, ``screen``, ``shading``), ``parameters``, ``objects`` (per object: material, sample
    count, cell size, flux direct / indirect / from translucent objects, size in mean free paths), ``transports``
    (each transport's own statistics), ``samples``, ``hidden``, ``film``, ``screen_exitance``, ``exitance_lookups``
    and ``translucent_passes``, ``reused`` the stages a render of a prepared scene skipped. :meth:`prepare` runs
    stages 1-3 alone (objects, samples, transports; kept in :attr:`prepared`, a :class:`PreparedState`, until
    :meth:`release`, and reused by later renders where they still hold), :meth:`render_prepared` shades them,
    :meth:`retransport` rebuilds the transports; a convolution transport's
    :meth:`~convsss.transport.convolution.ConvolutionTransport.layer_image`
    shows one layer's exitance ``M_l``.
    """

    def __init__(self, props):
        super().__init__(props)
        self.params = RenderParams.from_properties(props)
        ignored = self.params.ignored()
        if ignored:
            owners = {p.name: owner for p, owner in integrator_parameters()}
            warnings.warn(f"{', '.join(f'{n} ({owners[n]} transport)' for n in ignored)}: not a parameter of the "
                          f"{self.params.transport} transport this integrator renders with, so it has no effect (set "
                          f"transport={owners[ignored[0]]!r} to use it)", IgnoredParameterWarning, stacklevel=2)
        self.samples_per_pass = int(props["samples_per_pass"]) if "samples_per_pass" in props else -1
        self.stats = {}
        #: Optional callable ``progress(stage)`` told when a stage starts (the command line's progress display).
        self.progress = None
        self._shader = None
        self._aovs = None
        self._nested = False
        self._keep = False
        self._threads = 1
        #: The :class:`PreparedState` of the last :meth:`prepare` (a render's own is dropped when it is done with it;
        #: one :meth:`prepare` made is kept, and renders reuse it, until :meth:`release`).
        self.prepared = None

    def to_string(self):
        return f"ConvsssIntegrator[{', '.join(f'{k}={v!r}' for k, v in self.params.to_dict().items())}]"

    def traverse(self, callback):
        """Mitsuba's parameter traversal (``mi.traverse(integrator)``): every numeric parameter of the renderer and
        of its transport (``accuracy``, ``sample_density``, ``layers``, ...), as a one-lane ``mi.Float`` or
        ``mi.Int32`` that ``params["accuracy"] = 0.003; params.update()`` sets (checked as at construction; the next
        render uses it). Names, models and choices are set with the integrator's dictionary."""
        self._traversed = {}
        for name, value in self.params.to_dict().items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                continue
            self._traversed[name] = (mi.Int32 if isinstance(value, int) else mi.Float)(value)
            callback.put(name, self._traversed[name], mi.ParamFlags.NonDifferentiable)

    def parameters_changed(self, keys=()):
        """After ``params.update()``: the changed numeric parameters, checked, become the integrator's."""
        values = self.params.to_dict()
        for name in keys:
            if name in getattr(self, "_traversed", {}):
                number = self._traversed[name].numpy().reshape(-1)[0]
                # float32 lanes: the shortest decimal that reads back as the same float32 (0.03, not 0.0299999993)
                values[name] = int(number) if isinstance(values[name], int) else float(str(np.float32(number)))
        self.params = RenderParams(**values)

    def aov_names(self):
        """The film channels of the ``aovs`` parameter (e.g. ``exitance.R``), Mitsuba's AOV mechanism (:mod:`.aovs`)."""
        return aov_channels(parse_aovs(self.params.aovs))

    # --- stages -----------------------------------------------------------------------------------------------------
    def _stage(self, name):
        if self.progress is not None:
            self.progress(name)

    def _survey(self, scene, sensor):
        """What the camera sees, whatever the seed: the translucent objects, the view frame, each object's points
        seen through the pixel centres, and the sampling plan (one-line errors before anything is drawn)."""
        p = self.params
        objects = find_translucent_objects(mi, scene, p.unit_mm, p.profile, p.profile_total, p.orders)
        check_camera(sensor)
        frame = sensor_frame(sensor, p.unit_mm)
        seen = first_hits(scene, sensor, frame, p.unit_mm, objects)
        return objects, frame, seen, plan_samples(scene, sensor, frame, objects, seen, p)

    @_one_at_a_time
    def prepare(self, scene, sensor, seed=0):
        """Stages 1–3 for ``sensor``: translucent objects, their irradiance samples and transports, kept (in
        :attr:`prepared`) until :meth:`release`. A later ``mi.render`` of the same scene and sensor reuses what still
        holds: all but the shading for another ``spp`` (same seed), the survey for another seed, the samples and
        transports for another crop window that sees the same objects (same seed); a changed scene parameter, camera
        or integrator parameter prepares again. The state holds the scene: :meth:`release` lets both go."""
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        self._keep = True
        return self._prepare(scene, sensor, seed)

    def release(self):
        """Drop what :meth:`prepare` kept: renders start from nothing again, and the scene can be freed."""
        self.prepared, self._shader, self._aovs, self._keep = None, None, None, False

    def _prepare(self, scene, sensor, seed=0, survey=None):
        """:meth:`prepare`'s stages; ``survey``: a :meth:`_survey` of the same scene, sensor and parameters to reuse
        (the passes of one render share it)."""
        p = self.params
        fingerprint = scene_fingerprint(scene, sensor)
        timer = StageTimer(sync=dr.sync_thread)

        def stage(name):
            self._stage(name)
            return timer(name)

        with stage("samples"):
            objects, frame, seen, plan = survey if survey is not None else self._survey(scene, sensor)
        shown = [objects[q.index] for q in plan.objects]
        shown_at = [seen[q.index] for q in plan.objects]
        cells = [q.pixel_footprint_mm for q in plan.objects]
        per_object = [{**obj.summary(), **q.summary(obj.area_mm2)} for obj, q in zip(shown, plan.objects)]
        lighting = light_samples(scene, objects, plan, p, _seed(seed), stage, self.should_stop)
        transports = build_transports(lighting.samples, lighting.irradiance, shown, cells, frame,
                                      p, stage)
        transports, from_translucent, passes = translucent_passes(transports, lighting, p.indirect_passes, stage,
                                                                  self.should_stop)
        for k, s in enumerate(lighting.samples):  # flux = sum_i A_i E_i, as area @ E (no (N, 3) temporaries)
            flux_direct, flux_translucent = s.area @ s.irradiance, s.area @ from_translucent[k]
            total = s.area @ lighting.irradiance[k] + flux_translucent
            per_object[k].update(samples=len(s), flux=total.tolist(), flux_direct=flux_direct.tolist(),
                                 flux_indirect=(total - flux_direct).tolist(),
                                 flux_from_translucent=flux_translucent.tolist())
        with stage("screen"):
            screen = ScreenExitance(sensor, shown, shown_at, transports, p.unit_mm)
        self._shader = Shader(scene, shown, transports, p, stop=self.should_stop, screen=screen)
        self._aovs = FirstHitAOVs(self._shader, parse_aovs(p.aovs))
        self.stats = {"parameters": p.to_dict(), "seconds": dict(timer), "objects": per_object,
                      "hidden": list(plan.hidden), "samples": int(sum(o["samples"] for o in per_object)),
                      "translucent_passes": passes,
                      "screen_exitance": {"usable": screen.usable, "queries": screen.queries}}
        self.prepared = PreparedState(scene, sensor, _seed(seed), frame, shown, shown_at, cells, lighting, transports,
                                      survey=(objects, frame, seen, plan), params=p.to_dict(), fingerprint=fingerprint)
        return self._shader

    @_one_at_a_time
    def retransport(self, objects=None, params=None):
        """Stage 3 again on the state of the last :meth:`prepare`: the transports, the light between translucent objects
        and the screen's exitance, for new ``objects`` and/or new ``params``; returns the new :class:`Shader`.

        The geometry, the samples and their irradiance (direct, and indirect off opaque surfaces) do not depend on the
        profile (paper Eq. 2 has only ``F_t(eta)`` of the material, and with ``incidence = oblique`` the gain of its
        reduced albedo), so a new material of the same ``eta`` (and reduced albedo), another profile model or another
        transport accuracy needs only the transports (Eq. 1) built again. A new ``eta`` changes ``F_t`` at every
        sample, a new albedo the gain: that needs :meth:`prepare`.

        Parameters
        ----------
        objects : list of TranslucentObject, optional
            The prepared objects (``self.prepared.objects``), in that order, with other materials or profiles
            (``dataclasses.replace(obj, material=..., profile=...)``); same shapes, same ``eta`` (and, with
            ``incidence = oblique``, the same reduced albedo).
        params : RenderParams, optional
            New parameters differing from the integrator's only in the transport and its parameters (not in what
            sets the samples: ``sample_density``, ``downsample``, ``irradiance_samples``, ...) or ``profile``.

        After it, :attr:`stats` ``seconds`` holds this rebuild's stages only; :meth:`render_prepared` shades.
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
        p = self.params
        if not all(keeps_irradiance(old.material, new.material, p.incidence, p.orders)
                   for new, old in zip(objects, state.objects)):  # the same eta: only the albedo can differ
            raise ConvsssError("retransport keeps the samples' irradiance, which weights the light by the albedo's "
                               "gain (incidence = oblique, or single scattering traced): call prepare() for a new "
                               "reduced albedo")
        timer = StageTimer(sync=dr.sync_thread)

        def stage(name):
            self._stage(name)
            return timer(name)

        transports = build_transports(state.samples, state.irradiance, objects, state.cells,
                                      state.frame, p, stage)
        transports, _, passes = translucent_passes(transports, state.lighting, p.indirect_passes, stage,
                                                   self.should_stop)
        with stage("screen"):
            screen = ScreenExitance(state.sensor, objects, state.visible, transports, p.unit_mm)
        self._shader = Shader(state.scene, objects, transports, p, stop=self.should_stop, screen=screen)
        self._aovs = FirstHitAOVs(self._shader, parse_aovs(p.aovs))
        state.objects, state.transports, state.params = objects, transports, p.to_dict()
        for summary, obj in zip(self.stats.get("objects", []), objects):
            summary.update(obj.summary())
        self.stats.update(parameters=p.to_dict(), seconds=dict(timer), translucent_passes=passes,
                          screen_exitance={"usable": screen.usable, "queries": screen.queries})
        return self._shader

    @_one_at_a_time
    def reprepare(self, objects, replan=False):
        """Stages 1–3 again for the last :meth:`prepare`'s scene, sensor and seed with ``objects`` (the prepared
        objects, in that order, with other materials: the same shapes), keeping its plan: the same sample count and
        positions, their irradiance drawn again (a new reduced albedo changes its entry gain, a new ``eta`` its
        Fresnel transmittance; a new ``eta`` should be the boundary BSDF's too, which the caller sets). What a fit
        needs between materials (:mod:`convsss.fitting`): the image then changes smoothly with the material where
        the objects keep one ``sampling`` material (the paths' choices do not move with it), where a new
        :meth:`prepare` would size the samples by the new profile. With ``replan`` the plan is made again for the new
        objects (the samples sized by their profiles, :func:`~.plan.plan_samples`), what the camera sees kept.
        Returns the new :class:`Shader`."""
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
            plan = plan_samples(state.scene, state.sensor, frame, every, seen, self.params)
        keep = self._keep
        try:
            return self._prepare(state.scene, state.sensor, state.seed, survey=(every, frame, seen, plan))
        finally:
            self._keep = keep

    def checkpoint(self):
        """What :meth:`prepare`, :meth:`retransport` and :meth:`render_prepared` change, for :meth:`restore` (an
        edit applied whole or not at all)."""
        state = self.prepared
        kept = None if state is None else (state.objects, state.transports)
        return self.params, self.prepared, kept, self._shader, self._aovs, self.stats

    def restore(self, checkpoint):
        """Back to a :meth:`checkpoint`."""
        self.params, self.prepared, kept, self._shader, self._aovs, self.stats = checkpoint
        if kept is not None:
            self.prepared.objects, self.prepared.transports = kept

    def _check_same_samples(self, params):
        """A one-line error when ``params`` would place or light the samples differently from the prepared ones."""
        from .params import render_parameters

        kept = [q.name for q in render_parameters() if q.name not in ("transport", "profile", "aovs")]
        changed = [n for n in kept if getattr(params, n) != getattr(self.params, n)]
        cell = [q.transport_class().layer_cell(1.0, q.transport_params()) for q in (params, self.params)]
        if cell[0] != cell[1]:
            changed.append("the layer cell (downsample)")
        if changed:
            raise ConvsssError(f"retransport cannot change {', '.join(changed)}: the samples depend on it; call "
                               "prepare() with the new parameters")

    # --- Mitsuba's interface ------------------------------------------------------------------------------------------
    @_one_at_a_time
    def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
        if self._nested:  # Mitsuba's own loop, called from below: let it run
            return mi.SamplingIntegrator.render(self, scene, sensor, seed, spp, develop, evaluate)
        check_render_call(scene, sensor, seed, spp)
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        film = sensor.film()
        size = film.crop_size()
        spp_used = spp if spp else sensor.sampler().sample_count()
        per_pass = min(spp_used, self.samples_per_pass) if self.samples_per_pass > 0 else spp_used
        check_film(size[0], size[1], per_pass, len(self.aov_names()))
        if self.params.passes > 1 and not develop:
            raise ConvsssError("passes > 1 needs develop=True: the passes' images are averaged")
        kept = (self.prepared, self._shader, self._aovs) if self._keep else None
        try:
            if self.params.passes > 1:
                return self._render_passes(scene, sensor, _seed(seed), spp_used)
            reused = self._reuse(scene, sensor, _seed(seed))
            image = self.render_prepared(spp=spp, seed=seed, develop=develop, evaluate=evaluate)
            self.stats["reused"] = reused
            return image
        finally:  # a render keeps its samples and transports only for a prepared scene (prepare, render_prepared)
            if not self._keep:
                self._shader = None
                self.prepared = None
            elif self.params.passes > 1:  # the passes' states were their shares'
                self.prepared, self._shader, self._aovs = kept

    def _reuse(self, scene, sensor, seed):
        """Make the prepared state the one a render of ``scene``, ``sensor`` and ``seed`` needs, from what
        :meth:`prepare` kept that still holds; returns the stages reused (:meth:`prepare`'s doc).

        The same scene (every traversable parameter of its shapes, emitters and sensor: :func:`scene_fingerprint`),
        parameters and seed keep all but the shading. Another crop window draws the survey again (what each pixel
        centre sees) and, where the plan is the same (the same objects seen; the cells follow the film and the
        objects' depth, not the crop: :meth:`~.plan.SamplingPlan.draws_like`), keeps the samples and transports: the
        samples cover each object's whole surface. Another seed keeps the survey alone."""
        state = self.prepared
        fingerprint = scene_fingerprint(scene, sensor)
        same = (state is not None and self._keep and state.scene is scene and state.sensor is sensor
                and state.params == self.params.to_dict() and state.fingerprint[0] == fingerprint[0])
        if not same:
            self._prepare(scene, sensor, seed)
            return []
        if state.fingerprint[1] == fingerprint[1]:
            if state.seed == seed:
                self.stats["seconds"] = {}
                return ["samples", "irradiance", "indirect", "transport", "screen"]
            self._prepare(scene, sensor, seed, survey=state.survey)
            return ["survey"]
        timer = StageTimer(sync=dr.sync_thread)
        with timer("samples"):
            survey = self._survey(scene, sensor)
        if state.seed != seed or not survey[3].draws_like(state.survey[3]):
            self._prepare(scene, sensor, seed, survey=survey)
            self.stats["seconds"]["samples"] += timer["samples"]
            return []
        objects, _, seen, plan = survey
        state.visible = [seen[q.index] for q in plan.objects]
        with timer("screen"):
            screen = ScreenExitance(sensor, state.objects, state.visible, state.transports, self.params.unit_mm)
        self._shader = Shader(scene, state.objects, state.transports, self.params, stop=self.should_stop,
                              screen=screen)
        self._aovs = FirstHitAOVs(self._shader, parse_aovs(self.params.aovs))
        state.survey, state.fingerprint = survey, fingerprint
        self.stats.update(seconds=dict(timer), screen_exitance={"usable": screen.usable, "queries": screen.queries})
        return ["irradiance", "indirect", "transport"]

    def _render_passes(self, scene, sensor, seed, spp):
        """:meth:`render` in ``passes`` passes: each prepares fresh samples (its share of ``sample_density`` and
        ``profile_samples``, seed :func:`pass_seed`) and shades its share of ``spp``; returns the passes' mean,
        weighted by their camera samples. Stops early at ``time_limit``. :attr:`stats` sums the stages' seconds
        and lists the passes; its ``objects`` are the last pass's."""
        p = self.params
        count = min(p.passes, spp)
        shares = [spp // count + (k < spp % count) for k in range(count)]
        share_params = RenderParams(**{**p.to_dict(), "sample_density": p.sample_density / count,
                                       "profile_samples": p.profile_samples / count})
        start, seconds, done, image, survey = time.perf_counter(), {}, [], None, None
        try:
            self.params = share_params
            for k, share in enumerate(shares):
                self._stage(f"pass {k + 1}/{count}")
                pass_start, own_seed = time.perf_counter(), pass_seed(seed, k)
                self._prepare(scene, sensor, own_seed, survey)
                survey = self.prepared.survey
                shaded = self.render_prepared(spp=share, seed=own_seed)
                image = shaded * share if image is None else image + shaded * share
                for name, t in self.stats["seconds"].items():
                    seconds[name] = seconds.get(name, 0.0) + t
                done.append({"seed": own_seed, "spp": share, "samples": self.stats["samples"],
                             "seconds": time.perf_counter() - pass_start})
                elapsed = time.perf_counter() - start
                if p.time_limit and k + 1 < count and elapsed * (k + 2) / (k + 1) > p.time_limit:
                    break
        finally:
            self.params = p
            # Mitsuba's render sets the sampler's count to each pass's share: leave it as a one-pass render would
            sensor.sampler().set_sample_count(spp)
        spp_done = sum(d["spp"] for d in done)
        self.stats.update(parameters=p.to_dict(), seconds=seconds, passes=done,
                          samples=sum(d["samples"] for d in done))
        self.stats["film"]["spp"] = spp_done
        return image * (1.0 / spp_done)

    @_one_at_a_time
    def render_prepared(self, spp=0, seed=None, develop=True, evaluate=True):
        """Stage 4 alone: shade the camera rays of the last :meth:`prepare` (or :meth:`retransport`) through
        Mitsuba's render loop, keeping the prepared state, so that an edit can rebuild what it changed and shade
        again. ``seed`` defaults to the prepared one. Returns the image as :meth:`render` does."""
        state = self.prepared
        if state is None or self._shader is None:
            raise ConvsssError("nothing is prepared to shade: call prepare() first")
        scene, sensor = state.scene, state.sensor
        seed = state.seed if seed is None else seed
        film = sensor.film()
        size = film.crop_size()
        spp_used = spp if spp else sensor.sampler().sample_count()
        self._stage("shading")
        timer = StageTimer(sync=dr.sync_thread)
        self._nested = True
        try:
            # Mitsuba's film kernel scatter-adds each sample to every pixel its reconstruction filter covers: it runs
            # on one thread, in lane order, so the image is bit-identical whatever the thread count; the shading
            # (sample) runs on all threads.
            with timer("shading"), mitsuba_render(), ordered_kernels() as self._threads:
                image = mi.SamplingIntegrator.render(self, scene, sensor, seed, spp, develop, evaluate)
                dr.eval(image)
        finally:
            self._nested = False
        if self.should_stop():  # Mitsuba's SIGINT handler cancelled the render: no partial image leaves here
            self._shader = None
            raise KeyboardInterrupt
        self.stats["seconds"].update(timer)
        self.stats["film"] = {"size": [int(x) for x in film.size()], "crop_size": [int(x) for x in size],
                              "spp": int(spp_used)}
        self.stats["transports"] = [t.stats for t in self._shader.transports]
        self.stats["exitance_lookups"] = self._shader.lookups
        return image

    def sample(self, scene, sampler, ray, medium=None, active=True):
        if self._shader is None or self._shader.scene is not scene:
            # Called by another integrator's loop (e.g. Mitsuba's `aov`) without our render(): first sensor.
            self._prepare(scene, scene.sensors()[0], 0)
        if self._nested:  # all threads for the shading, then one again for Mitsuba's film kernel (see render)
            dr.set_thread_count(self._threads)
        radiance, valid = self._shader.shade(sampler, ray)
        aovs = self._aovs(ray)
        if self._nested:
            dr.eval(radiance, valid, aovs)
            dr.set_thread_count(1)
        return radiance, valid, aovs


ConvsssIntegrator.__doc__ = ConvsssIntegrator.__doc__.replace("{table}", plugin_parameters().replace("\n", "\n    "))


def scene_parameters(scene):
    """The parameters (a dict) of the ``convsss`` integrator a loaded scene names, or None when it names another or
    none. (Mitsuba reports a Python plugin's ``class_name()`` as ``SamplingIntegrator``: ask the object's type.)"""
    named = scene.integrator()
    return named.params.to_dict() if isinstance(named, ConvsssIntegrator) else None


def register():
    """Register ``convsss`` with Mitsuba (``<integrator type="convsss">`` and ``<medium type="convsss_medium">``,
    :mod:`.presets`); call before loading a scene."""
    if mi.variant() != VARIANT:
        raise ConvsssError(f"convsss was loaded in Mitsuba variant {VARIANT!r} and this process now uses "
                           f"{mi.variant()!r}: one process renders in one variant; start a new one")
    mi.register_integrator("convsss", lambda props: ConvsssIntegrator(props))
    register_medium(mi)
    return mi


def check_render_call(scene, sensor=0, seed=0, spp=0):
    """One-line errors for what ``mi.render`` would answer with an assertion, an index error or a signature dump: a
    scene that is not a Mitsuba scene of this process's variant, a sensor index out of range, a seed outside
    ``[0, 2^32)`` (Mitsuba's seeds are 32-bit), a negative ``spp``."""
    if not isinstance(scene, mi.Scene):
        raise ConvsssError(f"render() takes a mitsuba.Scene of variant {VARIANT!r} (mi.load_file or mi.load_dict), "
                           f"not {type(scene).__module__}.{type(scene).__name__}")
    if isinstance(sensor, (int, np.integer)) and not 0 <= int(sensor) < len(scene.sensors()):
        raise ConvsssError(f"sensor={int(sensor)} is not allowed: the scene has {len(scene.sensors())} sensor(s), "
                           f"0 to {len(scene.sensors()) - 1}")
    if isinstance(seed, (int, np.integer)) and not 0 <= int(seed) < 2**32:
        raise ConvsssError(f"seed={int(seed)} is not allowed: Mitsuba's seeds are 32-bit, 0 to 2^32 - 1")
    if isinstance(spp, (int, np.integer)) and int(spp) < 0:
        raise ConvsssError(f"spp={int(spp)} is not allowed: samples per pixel are >= 1 (0: the sensor's sampler's)")


def render(scene, *args, **kwargs):
    """``mi.render(scene, ...)``, raising the integrator's own exception when its ``render`` fails, and a one-line
    :class:`~convsss.errors.ConvsssError` for a call ``mi.render`` would refuse without one (:func:`check_render_call`).

    In JIT variants ``mi.render`` runs the integrator inside ``drjit.custom``, which replaces any exception by a
    ``RuntimeError`` "drjit.custom(...): error while performing a custom differentiable operation. (see above)"
    whose ``__cause__`` is the real one (a :class:`~convsss.errors.ConvsssError` with its one-line message).
    """
    named = dict(zip(("params", "sensor", "integrator", "seed", "seed_grad", "spp"), args)) | kwargs
    check_render_call(scene, named.get("sensor", 0), named.get("seed", 0), named.get("spp", 0))
    try:
        return mi.render(scene, *args, **kwargs)
    except RuntimeError as error:
        cause = error.__cause__
        if cause is None or not str(error).startswith("drjit.custom("):
            raise
        raise cause.with_traceback(cause.__traceback__) from None
