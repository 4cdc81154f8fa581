"""An edit session: one scene kept prepared while one translucent object's material, profile model and the
transport's accuracy change, each edit rebuilding only what depends on it (the engine of ``convsss edit``; no HTTP).

Along the data flow scene -> samples -> irradiance -> transport -> shading (docs/architecture.md):

- ``sigma_s'`` and ``sigma_a`` (given directly, by colour and mean free path, or as a preset of the same ``eta``),
  the profile model and the transport's ``accuracy`` change the profile ``R_d`` of paper Eq. 1 (or how it is summed)
  only: the scene, the samples and their irradiance (Eq. 2, direct and indirect off opaque surfaces) are kept, the
  transports are built again (:meth:`~convsss.pipeline.integrator.ConvsssIntegrator.retransport`) and the camera rays
  shaded again (:meth:`~convsss.pipeline.integrator.ConvsssIntegrator.render_prepared`);
- ``eta`` changes the Fresnel transmittance ``F_t(eta, w_i)`` at every sample (Eq. 2) and the boundary's reflection:
  the samples are prepared again (same seed: same points) and shaded;
- the editor renders what ``convsss render`` renders (``walk_depth`` auto by default: random walks where diffusion
  fails): where the render may walk (``walk_depth`` auto or above 0), a new material prepares again, so that auto's
  choice is made again and the walks read the medium written into the scene. The state says what renders the objects
  and why (``renders``).

Every edit is written into the loaded scene too (the medium's ``sigma_t``/``albedo``/``scale`` and the dielectric's
``eta``, through ``mi.traverse``), so the scene stays the one source of truth. One object is edited; an instanced one
edits every instance of its shapegroup (they share the medium). Images are tone-mapped by one Reinhard operator fixed
by the first render, so a brighter material shows brighter.

The preview converges while the user is idle: :meth:`EditSession.refine` renders one more pass of ``spp`` (each its own
seed, :func:`~convsss.pipeline.parts.pass_seed`) and averages it into the image; an edit starts again from one pass.
The session is driven from one thread (:class:`~convsss.editor.loop.RenderLoop`: the one that loaded the scene); what
the page reads (:meth:`~EditSession.state`, :meth:`~EditSession.image_png`) is a snapshot published after each pass, so
any thread may read it while the next pass renders.
"""

import io
import threading
import time
import warnings

import numpy as np

from ..denoise import GUIDES, check_pixel_filter, denoise, guides_of
from ..errors import ConvsssError
from ..materials import Material, OpticallyThinWarning, catalog
from ..materials import material as preset_material
from ..pipeline.aovs import film_channels
from ..pipeline.params import IgnoredParameterWarning, with_aovs
from ..pipeline.parts import pass_seed, samples_per_pixel
from ..profiles import ScaledProfile, TabulatedProfile, material_from_color
from ..profiles.models import (
    PROFILE_MODELS,
    check_model,
    color_of,
    model_profile,
    model_total,
    parse_profile_spec,
    rendered_total_of,
)

#: The pseudo-model of an object that came with a tabulated (CSV) profile: kept as it is, whatever the coefficients.
TABULATED = "tabulated"
#: What an edit may set (the JSON API's keys).
FIELDS = ("preset", "color", "mfp_mm", "sigma_s_prime", "sigma_a", "eta", "model", "accuracy")
#: The largest relative index an edit may set (no transparent material reaches 4 in the visible).
MAX_ETA = 4.0


def model_name(profile):
    """The :data:`~convsss.profiles.models.PROFILE_MODELS` name of ``profile``'s class (of its shape's, when it is
    scaled to another total), or ``"tabulated"``."""
    profile = profile.base if isinstance(profile, ScaledProfile) else profile
    for name, cls in PROFILE_MODELS.items():
        if type(profile) is cls:
            return name
    if isinstance(profile, TabulatedProfile):
        return TABULATED
    raise ConvsssError(f"the editor does not know the profile {profile!r}")


def _check_types(changes):
    """A one-line error for a change of the wrong JSON type: names are strings, numbers are numbers (not
    booleans), colours and coefficients one number or a list of three."""

    def number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool)

    for key, value in changes.items():
        if value is None:
            continue
        if key in ("preset", "model"):
            ok, kind = isinstance(value, str), "a name"
        elif key in ("eta", "accuracy"):
            ok, kind = number(value), "a number"
        else:
            ok = number(value) or (isinstance(value, list) and len(value) == 3 and all(map(number, value)))
            kind = "one number or three (R, G, B)"
        if not ok:
            raise ConvsssError(f"{key}={value!r} is not allowed: give {kind}")


def _triple(value, name):
    try:
        out = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()
    except (TypeError, ValueError):
        raise ConvsssError(f"{name}={value!r} is not allowed: give one number or three (R, G, B)") from None
    if not np.all(np.isfinite(out)):
        raise ConvsssError(f"{name}={value!r} is not allowed: the values must be finite")
    return out


class EditSession:
    """A loaded scene rendered by the ``convsss`` integrator, kept prepared for edits of one translucent object.

    Parameters
    ----------
    scene : mitsuba.Scene
        Loaded (:func:`convsss.scene.loading.load_scene`), its film at the preview's size.
    params : RenderParams, optional
        The integrator's parameters (default: the scene's ``convsss`` integrator's, or the defaults).
    target : str or int, optional
        The object edited: a name (shape id) or an index among the translucent objects the camera sees (default 0).
    spp : int, optional
        Samples per pixel of the preview (default: the scene's sampler).
    seed : int
    sensor : mitsuba.Sensor, optional
        The sensor previewed (default: the scene's first).

    Attributes
    ----------
    integrator : ConvsssIntegrator
    material : Material        the edited object's material (1/mm)
    model : str                its profile model (or ``"tabulated"``)
    version : int              one more per edit rendered (the first render is 1)
    last : dict                the last edit's render: ``rebuilt`` ("prepare" or "transport") and ``seconds`` per stage
    passes : Passes            the passes averaged into :attr:`image` since the last edit
    channels : list of str     their channels: R, G, B and the AOVs (the denoiser's guides among them)
    image : numpy.ndarray      (H, W, 3) their mean
    """

    def __init__(self, scene, params=None, target=None, spp=None, seed=0, sensor=None):
        from ..pipeline.integrator import register, scene_parameters
        from ..pipeline.params import RenderParams

        self.mi = register()
        self.scene, self.seed = scene, int(seed)
        self.sensor = scene.sensors()[0] if sensor is None else sensor
        self.spp = samples_per_pixel(spp, self.sensor)
        if params is None:
            params = RenderParams(**(scene_parameters(scene) or {}))
        # Edits render as `convsss render` does (walk_depth auto by default: walks where diffusion fails): an edit
        # writes the material into the scene's medium, which the walks and the survey's choice read.
        # The denoiser's guides (convsss.denoise) ride along as AOVs: one more ray per camera sample.
        self.integrator = self.mi.load_dict(params.replace(aovs=with_aovs(params.aovs, GUIDES)).integrator_dict())
        self.denoisable = check_pixel_filter(self.sensor)
        self.version, self.last = 0, None
        self._shown = None  # (state, PNG, profile, film): what the page reads, published after each pass
        self._profile_lock, self._profile_png = threading.Lock(), None
        self._denoise_lock, self._denoised = threading.Lock(), None
        self._tonemap = None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OpticallyThinWarning)
            start = time.perf_counter()
            self.integrator.prepare(scene, self.sensor, self.seed)
            objects = self.integrator.prepared.objects
            if not objects:
                raise ConvsssError("the camera sees no translucent object to edit")
            self.target = self._pick(objects, target)
            if self.target.classes is not None:
                raise ConvsssError(f"translucent shape {self.target.name!r} has a heterogeneous interior: the editor "
                                   "edits one homogeneous medium (edit its volumes in the scene file)")
            self.material, self.model = self.target.material, model_name(self.target.profile)
            self._tabulated = self.target.profile if self.model == TABULATED else None
            self._render("prepare", start)

    @staticmethod
    def _pick(objects, target):
        if target is None:
            return objects[0]
        if isinstance(target, int) or str(target).isdigit():
            k = int(target)
            if not 0 <= k < len(objects):
                raise ConvsssError(f"object #{k} does not exist: the camera sees {len(objects)} translucent object(s)")
            return objects[k]
        for obj in objects:
            if obj.name == target or obj.name.split("/")[0] == target:
                return obj
        raise ConvsssError(f"no translucent object {target!r} is seen by the camera: choose one of "
                           f"{', '.join(repr(o.name) for o in objects)}")

    # ---- what the page shows --------------------------------------------------------------------------------------
    @property
    def objects(self):
        return self.integrator.prepared.objects

    @property
    def eta_editable(self):
        return self.target.boundary != "null"

    def profile(self):
        """The edited object's profile."""
        if self.model == TABULATED:
            return self._tabulated
        return model_profile(self.model, self.material, self.integrator.params.profile_total,
                             self.integrator.params.orders)

    def state(self):
        """JSON-ready: the object, its material, model, the transport's accuracy, the choices, the last edit's timings,
        the samples per pixel averaged so far (``spp_reached``) and the image's ``noise`` (published after each pass;
        any thread)."""
        return self._shown[0]

    def _state(self):
        m, p = self.material, self.integrator.params
        accuracy = p.transport_params().get("accuracy")
        models = list(PROFILE_MODELS) + ([TABULATED] if self._tabulated is not None else [])
        color_model = rendered_total_of(self.model, p.profile_total) or "dipole"
        return {
            "version": self.version,
            "object": self.target.name, "objects": [o.name for o in self.objects], "boundary": self.target.boundary,
            "eta_editable": self.eta_editable,
            "material": {"name": m.name, "sigma_s_prime": m.sigma_s_prime.tolist(), "sigma_a": m.sigma_a.tolist(),
                         "eta": m.eta, "color": color_of(m, color_model).tolist(),
                         "mfp_mm": m.mfp_mm.tolist(), "albedo_prime": m.albedo_prime.tolist(),
                         "thin_channels": m.thin_channels()},
            "color_max": model_total(color_model, 1.0, m.eta), "model": self.model, "models": models,
            "transport": p.transport, "accuracy": accuracy, "renders": self._renders(),
            "presets": [x.name for x in catalog()],
            "film": [int(x) for x in self.sensor.film().crop_size()], "spp": self.spp,
            "spp_reached": self.passes.count * self.spp, "noise": self.passes.noise(),
            "denoisable": self.denoisable,
            "last": self.last,
        }

    def _renders(self):
        """What renders the objects, and why: one line (the render mode the survey resolved)."""
        p, mode = self.integrator.params, self.integrator.session.mode
        if not mode.walks:
            why = ("diffusion holds on every object" if p.walk_depth == "auto" else "walk_depth 0")
            return f"the {p.transport} transport ({why})"
        if p.walk_depth == "auto":
            kept = self.integrator.session.stats.get("transported") or []
            return ("random walks to their end where diffusion fails (walk_depth auto: thin or small in transport "
                    "mean free paths, or of low albedo)" + (f"; the {p.transport} transport on {', '.join(kept)}, "
                                                            "where it holds" if kept else ""))
        return f"random walks (walk_depth {mode})"

    def image_png(self):
        """The image (the mean of the passes so far), tone-mapped, as PNG bytes (any thread)."""
        return self._shown[1]

    def profile_png(self):
        """``r R_d(r)`` of the edited object's profile (:func:`convsss.profiles.plot.plot_profiles`) as PNG bytes, drawn
        once per edit when first asked (any thread)."""
        version, title, model, profile = self._shown[2]
        with self._profile_lock:
            if self._profile_png is None or self._profile_png[0] != version:
                from ..profiles.plot import plot_profiles

                buffer = io.BytesIO()
                plot_profiles([(title, [(model, profile)])], buffer, panel_size=(4.6, 3.2))
                self._profile_png = (version, buffer.getvalue())
            return self._profile_png[1]

    # ---- edits ----------------------------------------------------------------------------------------------------
    def update(self, **changes):
        """Apply ``changes`` (keys of :data:`FIELDS`), rebuild what depends on them, render; returns :meth:`state`.

        ``preset`` (a name of ``convsss materials``; its eta on a dielectric boundary) is applied first, then
        ``color``/``mfp_mm`` (:func:`~convsss.profiles.material_from_color` under the current model; the one not
        given is kept), then ``sigma_s_prime``/``sigma_a`` (1/mm), then ``eta``; ``model`` and ``accuracy`` as they
        are. A bad value is a :class:`ConvsssError` and changes nothing.
        """
        unknown = sorted(set(changes) - set(FIELDS))
        if unknown:
            raise ConvsssError(f"the editor cannot set {unknown[0]!r}: it sets {', '.join(FIELDS)}")
        _check_types(changes)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OpticallyThinWarning)
            warnings.simplefilter("ignore", IgnoredParameterWarning)  # the profile the editor sets per object
            kept, checkpoint = (self.material, self.model, self.target), self.integrator.checkpoint()
            try:
                return self._update(changes)
            except BaseException:  # applied whole or not at all: the scene, the material and the prepared state
                self._write_scene(kept[0], eta=True)
                self.material, self.model, self.target = kept
                self.integrator.restore(checkpoint)
                raise

    def _update(self, changes):
        """:meth:`update`; an exception leaves the caller to restore what it changed."""
        from ..pipeline.irradiance import keeps_irradiance

        start = time.perf_counter()
        model = self.model if changes.get("model") is None else changes["model"]
        if model != TABULATED or self._tabulated is None:
            check_model(model)
        material = self._material(changes, model)
        params = self._params(changes.get("accuracy"))
        coefficients = (np.array_equal(material.sigma_s_prime, self.material.sigma_s_prime)
                        and np.array_equal(material.sigma_a, self.material.sigma_a))  # as they were
        if params.walk_depth != 0.0 and not (coefficients and material.eta == self.material.eta):
            rebuilt = "prepare"  # what renders each object (auto), and the walks' medium, change
        elif not keeps_irradiance(self.material, material, params.incidence, params.orders):
            rebuilt = "prepare"
        elif model != self.model or params.to_dict() != self.integrator.params.to_dict() or not coefficients:
            rebuilt = "transport"
        else:
            rebuilt = None
        if rebuilt is None:
            return self.state()
        self._write_scene(material)
        self.material, self.model = material, model
        profile = self.profile()
        if rebuilt == "prepare":
            default, per_object = parse_profile_spec(params.profile)
            if model != TABULATED:
                per_object.update({o.name: model for o in self.objects if o.shape is self.target.shape})
            spec = ",".join([default] + [f"{k}={v}" for k, v in per_object.items()])
            self.integrator.params = params.replace(profile=spec)
            self.integrator.prepare(self.scene, self.sensor, self.seed)  # reads the material from the scene
        else:
            self.integrator.retransport([o.with_material(material, profile)
                                         if o.shape is self.target.shape else o for o in self.objects], params)
        self.target = self._pick(self.objects, self.target.name)
        self._render(rebuilt, start)
        return self.state()

    def _material(self, changes, model):
        m = self.material
        eta = m.eta
        if changes.get("preset"):
            preset = preset_material(changes["preset"])
            eta = preset.eta if self.eta_editable else 1.0
            m = Material(preset.sigma_s_prime, preset.sigma_a, eta, preset.name)
        if changes.get("color") is not None or changes.get("mfp_mm") is not None:
            color_model = rendered_total_of(model, self.integrator.params.profile_total) or "dipole"
            color = (_triple(changes["color"], "color") if changes.get("color") is not None
                     else color_of(m, color_model))
            mfp = _triple(changes["mfp_mm"], "mfp_mm") if changes.get("mfp_mm") is not None else m.mfp_mm
            m = material_from_color(color, mfp, eta, color_model)
        if changes.get("sigma_s_prime") is not None or changes.get("sigma_a") is not None:
            s = _triple(changes["sigma_s_prime"], "sigma_s'") if changes.get("sigma_s_prime") is not None \
                else m.sigma_s_prime
            a = _triple(changes["sigma_a"], "sigma_a") if changes.get("sigma_a") is not None else m.sigma_a
            m = Material.from_reduced(s, a, eta)
        if changes.get("eta") is not None:
            eta = float(changes["eta"])
            if not 1.0 <= eta <= MAX_ETA:
                raise ConvsssError(f"eta={changes['eta']!r} is not allowed: a translucent object's relative index "
                                   f"is between 1 and {MAX_ETA:g}")
            if not self.eta_editable and eta != 1.0:
                raise ConvsssError(f"object {self.target.name!r} has a null (index-matched) boundary: its eta is 1; "
                                   "give it a dielectric boundary in the scene to edit eta")
            m = Material(m.sigma_s_prime, m.sigma_a, eta, m.name)
        return m

    def _params(self, accuracy):
        p = self.integrator.params
        if accuracy is None:
            return p
        if "accuracy" not in p.transport_params():
            raise ConvsssError(f"the {p.transport} transport has no accuracy knob (the multiscale transport has)")
        return p.replace(accuracy=float(accuracy))

    def _write_scene(self, material, eta=False):
        """The edited object's medium (``sigma_t``, ``albedo``, ``scale`` per scene unit, its phase's ``g`` kept) and
        boundary ``eta`` (when it changes, or with ``eta``), in the loaded scene."""
        from ..media.named import forget

        mi, obj = self.mi, self.target
        unit = self.integrator.params.unit_mm
        forget(obj.shape.interior_medium())  # a <medium type="convsss_medium"> edited is no longer its preset or colour
        medium = mi.traverse(obj.shape.interior_medium())
        g = float(np.asarray(medium["phase_function.g"]).reshape(-1)[0]) if "phase_function.g" in medium else 0.0
        sigma_s = material.sigma_s_prime / (1.0 - g)  # the similarity relation, sigma_s' = sigma_s (1 - g)
        sigma_t = (sigma_s + material.sigma_a) * unit
        scale = float(np.max(sigma_t))
        medium["sigma_t.value.value"] = mi.Color3f(*[float(x) for x in sigma_t / scale])
        medium["albedo.value.value"] = mi.Color3f(*[float(x) for x in sigma_s * unit / sigma_t])
        medium["scale"] = scale
        medium.update()
        if self.eta_editable and (eta or material.eta != self.material.eta):
            bsdf = mi.traverse(obj.shape.bsdf())
            bsdf["eta"] = material.eta
            bsdf.update()

    def _render(self, rebuilt, start):
        """The edit's first pass: the passes start again from it."""
        image = self.integrator.render_prepared(spp=self.spp, seed=self.seed)
        seconds = dict(self.integrator.stats["seconds"])
        t = time.perf_counter()
        film, self.channels = film_channels(image, self.integrator.aov_names())
        self.passes = Passes(film)
        self.version += 1
        self.last = {"rebuilt": rebuilt, "seconds": seconds}
        self._publish()
        seconds = {**seconds, "encode": time.perf_counter() - t, "total": time.perf_counter() - start}
        self.last = {"rebuilt": rebuilt, "seconds": seconds}
        state, *rest = self._shown
        self._shown = ({**state, "last": self.last}, *rest)  # one assignment: a reader sees either

    def refine(self):
        """One more pass of :attr:`spp` (its own seed), averaged into the image, and published; returns :meth:`state`.
        The render loop calls it while no edit waits."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OpticallyThinWarning)
            image = self.integrator.render_prepared(spp=self.spp, seed=pass_seed(self.seed, self.passes.count))
        self.passes.add(film_channels(image, self.integrator.aov_names())[0])
        self._publish()
        return self.state()

    @property
    def image(self):
        """(H, W, 3): the mean of the passes so far."""
        return self.passes.mean[..., :3]

    def _publish(self):
        """Tone-map and encode the image; make it, the state and the profile what the page reads, in one step."""
        from ..image import Reinhard

        film = self.passes.mean
        if self._tonemap is None:
            self._tonemap = Reinhard(film[..., :3])
        profile = (self.version, f"{self.target.name}: {self.material.name}", self.model, self.profile())
        self._shown = (self._state(), self._encode(film[..., :3]), profile, film)

    def _encode(self, rgb):
        from ..image import srgb_encode

        stream = self.mi.MemoryStream()
        self.mi.Bitmap(srgb_encode(self._tonemap(rgb))).write(stream, self.mi.Bitmap.FileFormat.PNG)
        return bytes(stream.raw_buffer())

    def denoised_png(self):
        """The image denoised (:func:`convsss.denoise.denoise`, guided by the passes' mean albedo and normal), in the
        raw image's tone mapping, as PNG bytes: denoised once per pass published, when first asked (any thread; the
        render loop is not held up)."""
        state, _, _, film = self._shown
        key = (state["version"], state["spp_reached"])
        with self._denoise_lock:
            if self._denoised is None or self._denoised[0] != key:
                self._denoised = (key, self._encode(denoise(film[..., :3], *guides_of(film, self.channels))))
            return self._denoised[1]


class Passes:
    """Passes of one image, averaged (Welford's running mean and variance per pixel and channel); each pass makes new
    arrays (one published stays as it was).

    Parameters
    ----------
    first : numpy.ndarray
        (H, W, C): the first pass, R, G, B first (the noise is theirs).
    """

    def __init__(self, first):
        self.count, self.mean, self._m2 = 1, first.copy(), np.zeros_like(first)

    def add(self, image):
        self.count += 1
        delta = image - self.mean
        self.mean = self.mean + delta / self.count
        self._m2 = self._m2 + delta * (image - self.mean)

    def noise(self):
        """The image's relative noise: the root mean square over pixels of each pixel's standard error (the passes'
        variance over their count, R, G and B) over the root mean square of the image; None before two passes."""
        if self.count < 2:
            return None
        signal = float(np.sqrt(np.mean(self.mean[..., :3] ** 2)))
        error = float(np.sqrt(np.mean(self._m2[..., :3] / (self.count - 1) / self.count)))
        return error / signal if signal > 0 else 0.0
