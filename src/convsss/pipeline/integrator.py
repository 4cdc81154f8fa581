"""The ``convsss`` Mitsuba integrator: the plugin, thin glue over the render session (docs/architecture.md).

A :class:`ConvsssIntegrator` holds a :class:`~.session.RenderSession`, which runs the render's stages (samples,
irradiance, indirect, transport, screen: :data:`~.session.STAGES`) and keeps what they built; the plugin reads its
parameters (:mod:`.params`), shades the camera's samples with the session's path tracer
(:class:`.path_tracer.PathTracer`) through the film (:mod:`.film`: Mitsuba's render loop, step for step, with a
reconstruction that gives the same bits on any number of threads), so the film, its reconstruction filter, crop
window, sampler and sample count behave as for any Mitsuba integrator,
and renders one process's renders one at a time. Per-stage seconds and everything a user needs to judge the run are
in :attr:`ConvsssIntegrator.stats`.
"""

import functools
import math
import threading
import warnings

import drjit as dr
import numpy as np

from ..backend import load_mitsuba
from ..errors import ConvsssError
from ..media.named import register_medium
from ..signals import mitsuba_render
from ..timing import StageTimer
from . import derivatives
from . import film as films
from .params import (
    IgnoredParameterWarning,
    RenderParams,
    aov_channels,
    integrator_parameters,
    parse_aovs,
    plugin_parameters,
)
from .parts import as_seed, render_passes, samples_per_pixel
from .plan import check_film
from .session import RenderSession

mi = load_mitsuba()
#: The variant this module's classes were built in (a Mitsuba class belongs to one variant).
VARIANT = mi.variant()


#: One render stage at a time in a process: an integrator's prepared state and the thread count the shading sets in
#: Dr.Jit are shared, so a second thread waits for the first (two threads rendering one scene at once failed).
RENDER_LOCK = threading.RLock()
#: Camera paths per kernel of random walks (:meth:`ConvsssIntegrator._shade`): Ctrl-C waits for at most one.
WALK_LANES = 1 << 21


def _one_at_a_time(method):
    """``method`` under :data:`RENDER_LOCK` (re-entrant: a render calls back into the integrator)."""

    @functools.wraps(method)
    def serialized(*args, **kwargs):
        with RENDER_LOCK:
            return method(*args, **kwargs)

    return serialized


class ConvsssIntegrator(mi.SamplingIntegrator):
    """Convolution-based subsurface scattering (Munoz et al. 2011) as a Mitsuba 3 integrator; see the module doc.

    ``<integrator type="convsss">`` (call :func:`register` first). Parameters, besides Mitsuba's own
    ``samples_per_pass`` (the table is generated from the declarations, :mod:`convsss.parameters`):

    {table}

    **AOVs.** ``aovs`` (e.g. ``"exitance,irradiance,object,mask,depth,normal"``) adds channels to the film through
    Mitsuba's AOV mechanism (:meth:`aov_names`, the list :meth:`sample` returns), ``<aov>.<channel>`` as Mitsuba's
    ``aov`` integrator names them, each at the camera ray's first hit (:mod:`convsss.pipeline.aovs`): ``exitance``
    (``.R/.G/.B``) the transport's ``M`` on a translucent object, whose subsurface radiance is ``(1/pi) F_t M``
    (paper Eq. 7); ``irradiance`` (``.R/.G/.B``) the ``E`` its samples carry there (Eq. 2); ``object`` (``.I``) the
    translucent object's index + 1 (0: none); ``mask`` (``.Y``) 1 on a translucent object (a pixel's coverage);
    ``depth`` (``.T``) and ``normal`` (``.X/.Y/.Z``) as Mitsuba's ``depth`` and ``sh_normal``. They follow R, G, B
    (and A) in the rendered tensor, work under Mitsuba's ``aov`` integrator too, and leave the radiance unchanged.

    **Stats and stages.** After a render, :attr:`stats` holds ``seconds`` per stage (:data:`~.session.STAGES`),
    ``parameters``, ``objects`` (per object: material, sample count, cell size, flux direct / indirect / from
    translucent objects, size in mean free paths), ``transports`` (each transport's own statistics), ``samples``,
    ``hidden``, ``film``, ``screen_exitance``, ``exitance_lookups`` and ``translucent_passes``, ``reused`` the stages
    a render of a prepared scene skipped. :meth:`prepare` runs every stage but the shading (kept in :attr:`prepared`,
    a :class:`~.session.PreparedState`, until :meth:`release`, and reused by later renders where they still hold),
    :meth:`render_prepared` shades them, :meth:`retransport` rebuilds the transports; a convolution transport's
    :meth:`~convsss.transport.convolution.ConvolutionTransport.layer_image`
    shows one layer's exitance ``M_l``.
    """

    def __init__(self, props):
        super().__init__(props)
        #: The render's stages and what they built (:class:`~.session.RenderSession`).
        self.session = RenderSession(RenderParams.from_properties(props), stop=self.should_stop,
                                     announce=self._announce)
        ignored = self.params.ignored()
        if ignored:
            owners = {p.name: owner for p, owner in integrator_parameters()}
            warnings.warn(f"{', '.join(f'{n} ({owners[n]} transport)' for n in ignored)}: not a parameter of the "
                          f"{self.params.transport} transport this integrator renders with, so it has no effect (set "
                          f"transport={owners[ignored[0]]!r} to use it)", IgnoredParameterWarning, stacklevel=2)
        self.samples_per_pass = int(props["samples_per_pass"]) if "samples_per_pass" in props else -1
        #: Optional callable ``progress(stage)`` told when a stage starts (the command line's progress display).
        self.progress = None

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

    # --- the session's state, as the plugin's --------------------------------------------------------------------
    @property
    def params(self):
        """The :class:`~.params.RenderParams` the next render uses (settable)."""
        return self.session.params

    @params.setter
    def params(self, value):
        self.session.params = value

    @property
    def stats(self):
        """The last render's stats (the class doc)."""
        return self.session.stats

    @property
    def prepared(self):
        """The :class:`~.session.PreparedState` of the last :meth:`prepare` (a render's own is dropped when it is done
        with it; one :meth:`prepare` made is kept, and renders reuse it, until :meth:`release`)."""
        return self.session.prepared

    @property
    def walk(self):
        """The prepared state's random walk (:class:`~.walk.RandomWalk`; :meth:`~.walk.RandomWalk.weigh` sets a fit's
        trial material), None where the camera's paths do not walk."""
        return None if self.session.tracer is None else self.session.tracer.walk

    def _announce(self, stage):
        if self.progress is not None:
            self.progress(stage)

    @_one_at_a_time
    def prepare(self, scene, sensor, seed=0):
        """Stages 1-5 for ``sensor`` (:meth:`~.session.RenderSession.prepare`): translucent objects, their irradiance
        samples, transports and screen table, kept (in :attr:`prepared`) until :meth:`release`. A later ``mi.render``
        of the same scene and sensor reuses what still holds (:meth:`~.session.RenderSession.reuse`): all but the
        shading for another ``spp`` (same seed), the survey for another seed, the samples and transports for another
        crop window that sees the same objects (same seed); a changed scene parameter, camera or integrator parameter
        prepares again. The state holds the scene: :meth:`release` lets both go. Returns the path tracer."""
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        self.session.keep = True
        return self.session.prepare(scene, sensor, seed)

    def release(self):
        """Drop what :meth:`prepare` kept: renders start from nothing again, and the scene can be freed."""
        self.session.release()

    @_one_at_a_time
    def retransport(self, objects=None, params=None):
        """The transports built again on the prepared samples: :meth:`~.session.RenderSession.retransport`."""
        return self.session.retransport(objects, params)

    @_one_at_a_time
    def reprepare(self, objects, replan=False):
        """The irradiance drawn again for new materials on the prepared plan:
        :meth:`~.session.RenderSession.reprepare`."""
        return self.session.reprepare(objects, replan)

    def checkpoint(self):
        """The session's state, for :meth:`restore` (an edit applied whole or not at all)."""
        return self.session.checkpoint()

    def restore(self, checkpoint):
        """Back to a :meth:`checkpoint`."""
        self.session.restore(checkpoint)

    # --- Mitsuba's interface ------------------------------------------------------------------------------------------
    @_one_at_a_time
    def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
        """Mitsuba's ``render``: the image (H, W, channels), its parts evaluated as they are drawn (``evaluate`` is
        Mitsuba's and has no effect)."""
        check_render_call(scene, sensor, seed, spp)
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        film = sensor.film()
        size = film.crop_size()
        spp_used = samples_per_pixel(spp, sensor)
        per_pass = min(spp_used, self.samples_per_pass) if self.samples_per_pass > 0 else spp_used
        check_film(size[0], size[1], per_pass, len(self.aov_names()))
        if self.params.passes > 1 and not develop:
            raise ConvsssError("passes > 1 needs develop=True: the passes' images are averaged")
        session = self.session
        kept = (session.prepared, session.tracer, session.aovs) if session.keep else None
        try:
            if self.params.passes > 1:
                return render_passes(session, scene, sensor, as_seed(seed), spp_used,
                                             lambda share, own: self.render_prepared(spp=share, seed=own))
            reused = session.reuse(scene, sensor, as_seed(seed))
            image = self.render_prepared(spp=spp, seed=seed, develop=develop)
            self.stats["reused"] = reused
            return image
        finally:  # a render keeps its samples and transports only for a prepared scene (prepare, render_prepared)
            if not session.keep:  # nothing of the scene stays either: it owns this integrator, and a cycle
                session.release()  # through Mitsuba's objects is never freed (every later kernel then slows)
            elif self.params.passes > 1:  # the passes' states were their shares'
                session.prepared, session.tracer, session.aovs = kept

    @_one_at_a_time
    def render_forward(self, scene, params, sensor=0, seed=0, spp=0):
        """The image's derivative along the gradients set on ``params`` (Mitsuba's ``dr.forward`` through
        ``mi.render``): a walked render's with respect to its homogeneous media's ``albedo`` and ``sigma_t``
        (:mod:`.derivatives`); anything else refused in one line."""
        check_render_call(scene, sensor, seed, spp)
        sensor = scene.sensors()[sensor] if isinstance(sensor, int) else sensor
        return derivatives.render_forward(self, scene, params, sensor, as_seed(seed), spp)

    @_one_at_a_time
    def render_backward(self, scene, params, grad_in, sensor=0, seed=0, spp=0):
        """``grad_in`` (the image's gradient) into the gradients of ``params`` (Mitsuba's ``dr.backward`` through
        ``mi.render``), as :meth:`render_forward` differentiates (:mod:`.derivatives`)."""
        check_render_call(scene, sensor, seed, spp)
        sensor = scene.sensors()[sensor] if isinstance(sensor, int) else sensor
        derivatives.render_backward(self, scene, params, grad_in, sensor, as_seed(seed), spp)

    @_one_at_a_time
    def render_prepared(self, spp=0, seed=None, develop=True):
        """The shading stage alone: shade the camera rays of the last :meth:`prepare` (or :meth:`retransport`) through
        the film (:mod:`.film`), keeping the prepared state, so that an edit can rebuild what it changed and shade
        again. ``seed`` defaults to the prepared one. Returns the image as :meth:`render` does."""
        state, tracer = self.prepared, self.session.tracer
        if state is None or tracer is None:
            raise ConvsssError("nothing is prepared to shade: call prepare() first")
        scene, sensor = state.scene, state.sensor
        seed = state.seed if seed is None else seed
        film = sensor.film()
        size = film.crop_size()
        spp_used = samples_per_pixel(spp, sensor)
        self._announce("shading")
        timer = StageTimer(sync=dr.sync_thread)
        if tracer.walk is not None:
            tracer.walk.reset()
        try:
            with timer("shading"), mitsuba_render():
                image = self._shade(scene, sensor, seed, spp_used, develop, tracer.walk is not None)
        except KeyboardInterrupt:  # no partial image, nor a walk stopped midway, leaves here
            self.session.tracer = None
            raise
        if self.should_stop():  # cancelled (Integrator.cancel) between parts: no partial image leaves here
            self.session.tracer = None
            raise KeyboardInterrupt
        self.stats["seconds"].update(timer)
        self.stats["film"] = {"size": [int(x) for x in film.size()], "crop_size": [int(x) for x in size],
                              "spp": int(spp_used)}
        self.stats["transports"] = [t.stats for t in tracer.lookups.transports if t is not None]
        self.stats["exitance_lookups"] = tracer.lookups.count
        if tracer.walk is not None:
            self.stats["walk"] = tracer.walk.stats
        return image

    def _shade(self, scene, sensor, seed, spp, develop, walks):
        """The camera rays shaded through the film (:func:`.film.render`): with random ``walks`` (one kernel each, as
        long as its longest walk) in parts of about :data:`WALK_LANES` paths, each of its own seed, so that Ctrl-C
        stops between them; in parts of Mitsuba's ``samples_per_pass`` where it is set."""
        film = sensor.film()
        film.prepare(self.aov_names())
        most = max(1, WALK_LANES // math.prod(films.sampled_extent(film)[0])) if walks else spp
        if self.samples_per_pass > 0:
            most = min(most, self.samples_per_pass)
        return films.render(lambda sampler, rays: self.sample(scene, sampler, rays), sensor, seed,
                            spp, most, self.should_stop, develop)

    def sample(self, scene, sampler, ray, medium=None, active=True):
        session = self.session
        if session.tracer is None or session.tracer.scene is not scene:
            # Called by another integrator's loop (e.g. Mitsuba's `aov`) without our render(): first sensor.
            session.prepare(scene, scene.sensors()[0], 0)
        # Camera rays hold the film's size as literals: evaluated apart, the strategy's kernel is the same at any
        # image size (a warm kernel cache serves it).
        dr.make_opaque(ray)
        if session.tracer.scene.emitters():
            radiance, valid = session.tracer.strategy.trace(sampler, ray)
        else:  # nothing is lit: black, the first hits' mask alone (the walk's loops broke on it, issue 62)
            radiance, valid = dr.zeros(mi.Color3f, dr.width(ray.o)), scene.ray_intersect(ray).is_valid()
        aovs = session.aovs(ray)
        return radiance, valid, aovs


ConvsssIntegrator.__doc__ = ConvsssIntegrator.__doc__.replace("{table}", plugin_parameters().replace("\n", "\n    "))


def scene_parameters(scene):
    """The parameters (a dict) of the ``convsss`` integrator a loaded scene names, or None when it names another or
    none. (Mitsuba reports a Python plugin's ``class_name()`` as ``SamplingIntegrator``: ask the object's type.)"""
    named = scene.integrator()
    return named.params.to_dict() if isinstance(named, ConvsssIntegrator) else None


def register():
    """Register ``convsss`` with Mitsuba (``<integrator type="convsss">`` and ``<medium type="convsss_medium">``,
    :mod:`convsss.media.named`); call before loading a scene."""
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
