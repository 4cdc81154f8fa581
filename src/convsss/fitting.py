"""Materials from images: the translucent object's material that makes a render match a target image.

The inverse problem of the renderer: given a scene (its geometry, lights and camera as the user modelled them) and
a target image of it, find one translucent object's reduced albedo ``alpha'`` and reduced mean free path
``1/sigma_t'`` per channel (``eta`` as the scene has it) such that the ``convsss`` render matches the target over the
object's pixels. SciPy's bounded trust-region least squares (:func:`scipy.optimize.least_squares`, a robust
``soft_l1`` loss against highlights) works on ``logit(alpha')`` and ``log(mfp)``; the residual per object pixel
and channel is ``(s I - T) / (T + f)``, ``f`` 1 % of the target's channel mean, ``s`` the exposure (fitted with
``fit_exposure``, else 1). With ``fit_eta`` the boundary's relative index is one more variable, ``log(eta - 1)``,
shared by the channels; it moves the material's ``eta`` (the light's entry and exit, Eqs. 1-2) and the boundary
BSDF's (its reflection, the highlight) together.

The forward model (:class:`~convsss.forward.Forward`) is the default render's: where that walks (``walk_depth`` inf,
or ``auto`` on an object where diffusion fails, :func:`~convsss.pipeline.params.render_mode`, decided once by the
scene's material) the random walk's, else the transport's. Each walk draws its paths by its own material (the same
seed), and the Jacobian's renders keep those paths and only weigh them by the moved material
(:attr:`~convsss.pipeline.walk.RandomWalk.evaluated`; without Russian roulette, whose choices would move with it),
so that its differences are smooth, each channel's with its own coefficients only. (Paths drawn by one material for
a whole least-squares run, as the transport's choices are, weigh too far from it: a long walk's weight is a product
of as many ratios as it has events. From the benchmark's start, 3x the mean free path, a 20 mm whole-milk bunny so
fitted ended 12-102 % off in mfp, against 16-42 % with each render drawn by its own.) A walk's residuals compare
means over squares of :data:`WALK_BLOCK` pixels: its noise is part of a residual's square, and a material whose
render is less noisy would otherwise fit better for that alone. The transport's reuses what the material does not
change: the scene is surveyed and planned once, and every evaluation draws the same samples (the same seed and
count) and their irradiance again for the new material (``reprepare``: it depends on ``alpha'`` through the entry
gain and on ``sigma_t'`` through the light that crosses thin parts). The paths' random choices that depend on the
material (the distance of traced single scattering, Eq. S2; whether a path crosses a thin part, Eq. S3) are drawn
with one material for a whole least-squares run, the scene's at first (``TranslucentObject.sampling``; the estimate
is each trial material's), so the image moves smoothly with the material instead of in small jumps
(docs/guide/fit.md); a fit that ends far from the scene's material is made again with samples sized by the fitted
one (:data:`REPLAN_FACTOR`, :meth:`~convsss.forward.Forward.replan`). The channels are rendered independently, so
one evaluation with every channel's ``alpha'`` moved gives the Jacobian's ``alpha'`` columns of all three (and one
more its ``mfp`` columns): two evaluations per Jacobian instead of six. Uncertainties come from the Jacobian at the
solution, ``cov = s^2 (J^T J)^-1`` with ``s^2`` the residuals' variance.
"""

import dataclasses
import math
import time

import numpy as np

from .errors import ConvsssError
from .forward import Forward, medium_values, restore_medium, set_boundary_eta

#: Bounds of the fit: reduced albedo, reduced mean free path (mm) and the boundary's relative index.
ALBEDO_BOUNDS = (1e-3, 0.9999)
MFP_BOUNDS_MM = (1e-4, 1e4)
ETA_BOUNDS = (1.001, 2.5)
#: The start's mean free path times these, per channel the best kept (:func:`_initial_mfp`).
MFP_START_FACTORS = (1.0 / 9.0, 1.0 / 3.0, 1.0, 3.0, 9.0)
#: With ``fit_eta``, the boundary's indices tried beside the start's, the best kept (:func:`_initial_eta`).
ETA_START_VALUES = (1.2, 1.3, 1.4, 1.5, 1.6)
#: A fit that ends with a mean free path this factor or more from the one its samples were sized by (the scene's
#: material's, in a channel) is made again from there, its samples sized by the fitted material
#: (:meth:`~convsss.forward.Forward.replan`).
REPLAN_FACTOR = 1.1
#: At most this many fits made again so.
MAX_REPLANS = 3
#: The relative step of the finite differences, in the fit's variables.
STEP = 1e-3
#: The floor of the relative residual, as a share of the target's channel mean (as convsss.compare's).
FLOOR = 0.01
#: The ``rr_depth`` of a fit's walks: no Russian roulette, whose choices would move with the trial material.
NO_ROULETTE = 2**30
#: The renders' samples per pixel unless given: the transport's, and the walks' (noisier; a 20 mm skin1 bunny
#: against a 64-spp walk at 48^2: mean free paths 40 % off at 4 spp, within 15 % at 16).
TRANSPORT_SPP, WALK_SPP = 4, 16
#: A fit's walks compare the render with the target over squares of this many pixels a side: a residual's noise
#: is part of its square, and a material whose render is less noisy would otherwise fit better for that alone.
WALK_BLOCK = 4


@dataclasses.dataclass
class FitResult:
    """What :func:`fit` found: the ``material`` (a :class:`~convsss.materials.Material`), per channel
    ``reduced_albedo`` and ``mfp_mm`` with their standard deviations, ``eta_std`` (NaN unless ``eta`` was fitted),
    the ``exposure``, the ``render`` (H, W, 3) at the fitted material, the object ``mask``, ``history`` (cost per
    evaluation), ``evaluations``, ``seconds`` and ``success`` / ``message`` of the optimizer."""

    material: object
    reduced_albedo: np.ndarray
    reduced_albedo_std: np.ndarray
    mfp_mm: np.ndarray
    mfp_mm_std: np.ndarray
    eta_std: float
    exposure: float
    render: np.ndarray
    mask: np.ndarray
    history: list
    evaluations: int
    seconds: float
    success: bool
    message: str

    def to_dict(self):
        """JSON-ready: the material per channel, the exposure, the optimizer's counts and seconds."""
        return {"material": {"reduced_albedo": self.reduced_albedo.tolist(),
                             "reduced_albedo_std": self.reduced_albedo_std.tolist(),
                             "mfp_mm": self.mfp_mm.tolist(), "mfp_mm_std": self.mfp_mm_std.tolist(),
                             "eta": float(self.material.eta), "eta_std": self.eta_std,
                             "sigma_s_prime_per_mm": self.material.sigma_s_prime.tolist(),
                             "sigma_a_per_mm": self.material.sigma_a.tolist()},
                "exposure": self.exposure, "evaluations": self.evaluations, "seconds": self.seconds,
                "seconds_per_evaluation": self.seconds / max(self.evaluations, 1), "success": self.success,
                "message": self.message, "history": self.history}


def material_of(albedo, mfp_mm, eta, name="fitted"):
    """The :class:`~convsss.materials.Material` of reduced albedo ``albedo`` and reduced mean free path ``mfp_mm``
    (per channel), ``sigma_t' = 1 / mfp``, ``sigma_s' = albedo sigma_t'``, ``sigma_a = sigma_t' - sigma_s'``."""
    from .materials import Material

    albedo, sigma_t = np.asarray(albedo, dtype=np.float64), 1.0 / np.asarray(mfp_mm, dtype=np.float64)
    return Material(albedo * sigma_t, (1.0 - albedo) * sigma_t, eta, name)


class _Variables:
    """The fit's variables: ``logit(R / R_max)`` of the colour ``R`` (the exact total reflectance of ``alpha'`` at
    ``eta``, what the image's brightness fixes) and ``log(mfp)`` (what its blur fixes), nearly apart where
    ``(alpha', mfp)`` trade one for the other; ``R_max`` the colour of the largest albedo (below 1)."""

    def __init__(self, eta):
        from .profiles.models import exact_total

        self.eta = eta
        # A colour is a reflectance, below 1, where the exact total of the largest albedo is not (1.02 at eta 1.35).
        self.top = min(float(exact_total(np.array([ALBEDO_BOUNDS[1]]), eta)[0]), 1.0 - 1e-6)
        self.bottom = float(exact_total(np.array([ALBEDO_BOUNDS[0]]), eta)[0])

    def encode(self, albedo, mfp):
        from .profiles.models import exact_total

        share = np.clip(exact_total(np.asarray(albedo, dtype=np.float64), self.eta) / self.top, 1e-9, 1 - 1e-9)
        return np.concatenate([np.log(share / (1.0 - share)), np.log(mfp)])

    def decode(self, x):
        from .profiles.models import albedo_from_reflectance

        colour = self.top / (1.0 + np.exp(-x[:3]))
        colour = np.clip(colour, self.bottom * (1 + 1e-9), self.top * (1 - 1e-9))
        return np.clip(albedo_from_reflectance("exact", colour, self.eta), *ALBEDO_BOUNDS), np.exp(x[3:6])

    def bounds(self):
        return (np.concatenate([np.full(3, -25.0), np.full(3, np.log(MFP_BOUNDS_MM[0]))]),
                np.concatenate([np.full(3, 25.0), np.full(3, np.log(MFP_BOUNDS_MM[1]))]))


def _checked_images(target, mask, width, height):
    """The target's RGB (float64) and the mask (bool, or None), one-line errors for either not of the film's
    ``width`` x ``height``, a target not finite, a mask without a pixel."""
    target = np.asarray(target, dtype=np.float64)[..., :3]
    if target.shape[:2] != (height, width):
        raise ConvsssError(f"the target is {target.shape[1]}x{target.shape[0]} pixels and the sensor's film "
                           f"{width}x{height}: render the target at the film's size or resize the film")
    if not np.all(np.isfinite(target)):
        raise ConvsssError("the target holds NaN or infinite pixels: give a finite linear image")
    if np.any(target < 0):
        y, x, c = np.argwhere(target < 0)[0]
        raise ConvsssError(f"the target holds negative pixels (e.g. {'RGB'[c]} = {target[y, x, c]:.3g} at x={x}, "
                           f"y={y}): give a linear image of light, every value >= 0")
    if mask is not None:
        mask = np.asarray(mask) != 0
        if mask.shape != (height, width):
            raise ConvsssError(f"the mask is {mask.shape[1]}x{mask.shape[0]} pixels and the film {width}x{height}")
        if not mask.any():
            raise ConvsssError("the mask holds no pixel: nothing to fit")
    return target, mask


def _object_to_fit(objects, name, fit_eta):
    """The name of the translucent object to fit among ``objects``: ``name``, or the only one; one-line errors."""
    found = {o.name: o for o in objects}
    every = list(found)
    if name is None and len(every) > 1:
        raise ConvsssError(f"the scene has {len(every)} translucent objects ({', '.join(every)}): name one to fit "
                           "(--object)")
    if name is not None and name not in every:
        raise ConvsssError(f"no translucent object {name!r}: the scene has {', '.join(every)}")
    name = name or every[0]
    if fit_eta and found[name].boundary == "null":
        raise ConvsssError(f"translucent object {name!r} has a null (index-matched) boundary, whose eta is 1: "
                           "fitting eta needs a dielectric or roughdielectric boundary")
    return name


class _Problem:
    """The least-squares problem of a fit: its variables ``x`` (logit colour (3), log mfp (3), then log exposure and
    log(eta - 1) where fitted), the residuals of the render against ``target`` over the pixels ``inside``, each
    weighted by the target's value there (a relative error, floored at :data:`FLOOR` of the mean), and their
    Jacobian: where the render walks, the walk's own derivatives (:meth:`~convsss.forward.Forward.derivatives`), else
    forward differences of ``STEP``, each channel's albedo at once, then each channel's mfp."""

    def __init__(self, forward, base, inside, target, fit_exposure, fit_eta, progress, block=1):
        self.forward, self.base, self.inside, self.progress = forward, base, inside, progress
        self.fit_exposure, self.fit_eta = fit_exposure, fit_eta
        # The pixels ``inside`` pooled in squares of ``block`` pixels a side (:meth:`pool`).
        y, x = np.nonzero(inside)
        cells = np.unique((y // block) * (inside.shape[1] // block + 1) + x // block, return_inverse=True)[1]
        self.cells, self.cell_count = cells, np.bincount(cells).astype(np.float64)[:, None]
        self.goal = self.pool(target)
        floor = FLOOR * np.maximum(self.goal.mean(axis=0), 1e-12)
        self.weight = 1.0 / (self.goal + floor)
        self.variables = _Variables(base.eta)
        self.exposure_at, self.eta_at = 6, 6 + int(fit_exposure)
        self.history, self.cache = [], {}
        lower, upper = self.variables.bounds()
        if fit_exposure:
            lower, upper = np.append(lower, -20.0), np.append(upper, 20.0)
        if fit_eta:
            lower, upper = np.append(lower, np.log(ETA_BOUNDS[0] - 1.0)), np.append(upper, np.log(ETA_BOUNDS[1] - 1.0))
        self.lower, self.upper = lower, upper

    def pool(self, image):
        """The mean of ``image`` (H, W, 3) over each square of pixels inside (the residuals' cells), (cells, 3)."""
        values = image[self.inside]
        return np.stack([np.bincount(self.cells, values[:, c]) for c in range(3)], axis=1) / self.cell_count

    def shape_cost(self, material):
        """Per channel, :func:`_brightness_free_cost` of ``material``'s render (one evaluation)."""
        return _brightness_free_cost(self.pool(self.forward(material)), self.goal, self.weight)

    def split(self, x):
        """``(albedo, mfp, exposure, eta)`` of the variables ``x``."""
        albedo, mfp = self.variables.decode(x)
        scale = float(np.exp(x[self.exposure_at])) if self.fit_exposure else 1.0
        return albedo, mfp, scale, (1.0 + float(np.exp(x[self.eta_at])) if self.fit_eta else self.base.eta)

    def start(self, albedo, mfp, eta):
        """The variables of a start."""
        x0 = self.variables.encode(albedo, mfp)
        if self.fit_exposure:
            x0 = np.append(x0, 0.0)
        if self.fit_eta:
            x0 = np.append(x0, np.log(eta - 1.0))
        return x0

    def replan(self, albedo, mfp, eta):
        """The samples sized, and the paths' choices drawn, by this material from the next render on
        (:meth:`~convsss.forward.Forward.replan`); the renders kept are of the old plan, so forgotten."""
        self.forward.replan(material_of(albedo, mfp, eta, self.base.name))
        self.cache.clear()

    def render(self, albedo, mfp, eta):
        """The render of a material (the last one kept: the Jacobian starts where the residuals were)."""
        key = (tuple(albedo), tuple(mfp), eta)
        if key not in self.cache:
            self.cache.clear()
            self.cache[key] = self.forward(material_of(albedo, mfp, eta, self.base.name))
        return self.cache[key]

    def residuals(self, x):
        albedo, mfp, scale, eta = self.split(x)
        r = (scale * self.pool(self.render(albedo, mfp, eta)) - self.goal) * self.weight
        self.history.append(float(0.5 * np.sum(r**2)))
        if self.progress is not None:
            self.progress(self.forward.evaluations, self.history[-1])
        return r.ravel()

    def jacobian(self, x):
        albedo, mfp, scale, eta = self.split(x)
        here = self.pool(self.render(albedo, mfp, eta))
        n = here.shape[0]
        columns = np.zeros((n, 3, len(x)))

        def moved(block, width):
            x_moved = x.copy()
            x_moved[block:block + width] += STEP
            a, m, _, e = self.split(x_moved)
            moved_render = self.forward(material_of(a, m, e, self.base.name), drawn=material_of(albedo, mfp, eta))
            return (self.pool(moved_render) - here) * scale * self.weight / STEP

        if self.forward.walks:  # the walk's own derivatives (Eq. G2) and the variables' chain: no more renders
            _, d_albedo, d_log_mfp = self.forward.derivatives(material_of(albedo, mfp, eta, self.base.name))
            x_moved = x.copy()
            x_moved[:3] += STEP
            slope = (self.variables.decode(x_moved)[0] - albedo) / STEP  # d alpha' / d(the colour's logit)
            blocks = (self.pool(d_albedo) * slope * scale * self.weight, self.pool(d_log_mfp) * scale * self.weight)
        else:  # every channel's alpha' at once, then every channel's mfp: the channels are apart
            blocks = (moved(0, 3), moved(3, 3))
        for block, derivative in zip((0, 3), blocks):
            for c in range(3):
                columns[:, c, block + c] = derivative[:, c]
        if self.fit_exposure:
            columns[:, :, self.exposure_at] = scale * here * self.weight
        if self.fit_eta:  # one index for every channel: one more render
            columns[:, :, self.eta_at] = moved(self.eta_at, 1)
        return columns.reshape(n * 3, len(x))

    def solve(self, x, max_evaluations):
        """SciPy's least squares from ``x`` (:meth:`start`, or where a solve ended) within the bounds; the variables
        to 1e-5, far below what the image's noise constrains."""
        from scipy.optimize import least_squares

        return least_squares(self.residuals, x, jac=self.jacobian, bounds=(self.lower, self.upper), loss="soft_l1",
                             f_scale=0.1, x_scale="jac", max_nfev=max_evaluations, xtol=1e-5, ftol=1e-6)


def fit(scene, target, object=None, mask=None, start=None, fit_exposure=False, fit_eta=False, seed=0, spp=None,
        max_evaluations=60, progress=None):
    """Fit one translucent object's material so that ``scene``'s render matches ``target``; a :class:`FitResult`.

    Parameters
    ----------
    scene : mitsuba.Scene
        Loaded, with its own lights, geometry and camera (the first sensor); its integrator's parameters are used
        when it names ``convsss``.
    target : (H, W, 3) array_like
        Linear RGB, the sensor's crop size.
    object : str, optional
        The translucent shape's id (required when the scene has several).
    mask : (H, W) array_like, optional
        The pixels to match (nonzero); default: where the camera sees the object first.
    start : Material, optional
        The starting material (default: the scene's); its ``eta`` is the start's with ``fit_eta``, else unused.
    fit_exposure : bool
        Also fit a scale of the render (a photo of unknown exposure).
    fit_eta : bool
        Also fit the boundary's relative index (a dielectric or rough dielectric boundary; the scene's BSDF is
        given its own index back after the fit).
    seed, spp : int
        The renders' seed and samples per pixel (the same for every evaluation); ``spp`` by default 4 for the
        transport's renders, :data:`WALK_SPP` for walks.
    max_evaluations : int
        Evaluations of the least squares at most, each one render, per solve; each Jacobian adds one render per
        block of variables (the albedos, the mean free paths, eta), and a fit that replans solves again (at most
        :data:`MAX_REPLANS` times), so the renders can exceed it (:attr:`FitResult.evaluations` counts them).
    progress : callable, optional
        ``progress(evaluation, cost)`` after each evaluation.
    """
    from .pipeline.integrator import register

    mi = register()
    sensor = scene.sensors()[0]
    width, height = (int(n) for n in sensor.film().crop_size())
    target, mask = _checked_images(target, mask, width, height)
    forward = _forward_model(mi, scene, sensor, object, fit_eta, seed, spp)
    inside = _pixels_to_fit(forward, target, mask, (height, width))
    base = forward.obj.material
    start = base if start is None else start
    eta0 = float(np.clip(start.eta, *ETA_BOUNDS)) if fit_eta else base.eta
    albedo0 = np.clip(start.albedo_prime, *ALBEDO_BOUNDS)
    mfp0 = np.clip(start.mfp_mm, *MFP_BOUNDS_MM)
    block = WALK_BLOCK if forward.walks else 1
    problem = _Problem(forward, base, inside, target, fit_exposure, fit_eta, progress, block)
    begun = time.perf_counter()
    held = medium_values(forward.obj.shape.interior_medium()) if forward.walks else {}
    try:
        solution = _solve(problem, albedo0, mfp0, eta0, max_evaluations)
        albedo, mfp, _, eta = problem.split(solution.x)
        image = problem.render(albedo, mfp, eta)
    finally:
        if fit_eta:
            set_boundary_eta(forward.obj.shape, base.eta)
        if held:
            restore_medium(forward.obj.shape.interior_medium(), held)
    return _result(problem, solution, image, begun)


def _forward_model(mi, scene, sensor, object, fit_eta, seed, spp):
    """The :class:`~convsss.forward.Forward` of the object to fit (``object``, or the only one: :func:`_object_to_fit`)
    through ``sensor``, its integrator prepared: the default render's forward model (module doc), walks where it walks
    to the end, else the transport's; ``spp`` by default :data:`WALK_SPP` or :data:`TRANSPORT_SPP`. A one-line error
    where the camera does not see the object."""
    from .pipeline.integrator import ConvsssIntegrator
    from .pipeline.objects import find_translucent_objects
    from .pipeline.params import RenderParams, render_mode

    named = scene.integrator()
    params = named.params.to_dict() if isinstance(named, ConvsssIntegrator) else {}
    asked = RenderParams(**params)
    found = find_translucent_objects(mi, scene, asked.unit_mm)
    name = _object_to_fit(found, object, fit_eta)
    # The default render's forward model (module doc): walks where it walks to the end, else the transport's.
    chosen = next(o for o in found if o.name == name)
    mode = render_mode(asked, found)
    walks = mode.walk_depth == math.inf and not mode.transports(chosen) and chosen.classes is None
    # Where auto keeps the transport on other objects, their exitance has no derivatives: the fit walks every object.
    walked = {"rr_depth": NO_ROULETTE, **({"walk_depth": "inf"} if mode.transported else {})}
    integrator = mi.load_dict({"type": "convsss", **params, **(walked if walks else {"walk_depth": 0.0})})
    spp = spp or (WALK_SPP if walks else TRANSPORT_SPP)
    forward = Forward(scene, integrator, sensor, 0, seed, spp, walks)
    integrator.prepare(scene, sensor, seed)
    names = [o.name for o in integrator.prepared.objects]
    if name not in names:
        raise ConvsssError(f"the camera does not see translucent object {name!r}: nothing to fit")
    forward.index = names.index(name)
    return forward


def _pixels_to_fit(forward, target, mask, shape):
    """The pixels to match, (H, W) bool: ``mask``, or where the camera sees the object of ``forward`` first; one-line
    errors for a mask off the object and a target black over the pixels."""
    name = forward.obj.name
    seen = _object_mask(forward.integrator, forward.index, shape)
    if mask is not None and not (mask & seen).any():
        raise ConvsssError(f"the mask holds none of the pixels where the camera sees {name!r}: nothing to fit")
    inside = seen if mask is None else mask
    if not np.any(target[inside] > 0):
        raise ConvsssError(f"the target is black where the camera sees {name!r}: nothing to fit (is it a linear "
                           "render of this scene?)")
    return inside


def _solve(problem, albedo0, mfp0, eta0, max_evaluations):
    """The least squares' solution (SciPy's) from the start ``albedo0``, ``mfp0``, ``eta0``, its mean free paths (and
    with ``fit_eta`` its index) first chosen by the scans of :func:`_initial_mfp` and :func:`_initial_eta`; solved
    again from where it ended, its samples sized by the fitted material, while that is :data:`REPLAN_FACTOR` or more
    from the one that sized them (at most :data:`MAX_REPLANS` times; never for walks)."""
    mfp0 = _initial_mfp(eta0, albedo0, mfp0, problem)
    if problem.fit_eta:
        eta0 = _initial_eta(eta0, albedo0, mfp0, problem)
    solution = problem.solve(problem.start(albedo0, mfp0, eta0), max_evaluations)
    albedo, mfp, _, eta = problem.split(solution.x)
    planned = problem.base.mfp_mm
    for _ in range(0 if problem.forward.walks else MAX_REPLANS):  # walks draw each render's paths by its own material
        # The scene's material sized the samples (their spacing follows its profile) and drew the paths'
        # choices; far from it, the fit is made again from where it ended, with both the fitted material's.
        if not np.any(np.abs(np.log(mfp / planned)) > np.log(REPLAN_FACTOR)):
            break
        planned = mfp
        problem.replan(albedo, mfp, eta)
        solution = problem.solve(solution.x, max_evaluations)
        albedo, mfp, _, eta = problem.split(solution.x)
    return solution


def _result(problem, solution, image, begun):
    """The :class:`FitResult` of ``solution``, ``image`` its render at exposure 1, the fit begun at ``begun``
    (``time.perf_counter``)."""
    albedo, mfp, scale, eta = problem.split(solution.x)
    forward, base, fit_eta = problem.forward, problem.base, problem.fit_eta
    variables, eta_at, history = problem.variables, problem.eta_at, problem.history
    std = _deviations(solution, variables, albedo, mfp)
    eta_std = float(std[2][eta_at] * (eta - 1.0)) if fit_eta else float("nan")
    return FitResult(material_of(albedo, mfp, eta, base.name), albedo, std[0], mfp, std[1], eta_std, scale,
                     scale * image, problem.inside, history, forward.evaluations, time.perf_counter() - begun,
                     bool(solution.success), str(solution.message))


def _brightness_free_cost(image, goal, weight):
    """Per channel, the weighted squared misfit of ``image`` to ``goal`` once each channel is scaled to the goal's
    brightness (what a wrong colour cannot explain: the blur, the highlight, the light's change with the angle)."""
    scale = np.sum(image * goal * weight**2, axis=0) / np.maximum(np.sum((image * weight) ** 2, axis=0), 1e-30)
    return np.sum(((scale * image - goal) * weight) ** 2, axis=0)


def _initial_eta(eta, albedo, mfp, problem):
    """The start's boundary index or one of :data:`ETA_START_VALUES`, whichever renders the target's shape best
    (:func:`_brightness_free_cost`, summed over the channels): one evaluation each. Fitted from one index only, the
    albedo can take up the brightness the index should explain and the fit end in a valley beside the start (as a
    small skin1 bunny started below its true index did)."""
    candidates = sorted({float(np.clip(e, *ETA_BOUNDS)) for e in (eta, *ETA_START_VALUES)})
    costs = [np.sum(problem.shape_cost(material_of(albedo, mfp, e))) for e in candidates]
    return candidates[int(np.argmin(costs))]


def _initial_mfp(eta, albedo, mfp, problem):
    """Per channel, the start's mean free path times the one of :data:`MFP_START_FACTORS` whose render matches the
    target's shape best (:func:`_brightness_free_cost`, so that a wrong colour does not pick the blur): the channels
    render together, one evaluation per factor. A least-squares fit from a mean free path far off can settle where
    the image no longer depends on it (an object looking opaque, or clear)."""
    best, chosen = np.full(3, np.inf), np.array(mfp, dtype=np.float64)
    for factor in MFP_START_FACTORS:
        cost = problem.shape_cost(material_of(albedo, mfp * factor, eta))
        better = cost < best
        best[better], chosen[better] = cost[better], (mfp * factor)[better]
    return np.clip(chosen, *MFP_BOUNDS_MM)


def _deviations(solution, variables, albedo, mfp):
    """Standard deviations of alpha' and mfp from the Jacobian at the solution, carried from the fit's variables
    to ``alpha'`` by a finite difference of :meth:`_Variables.decode`, and every variable's own; NaN where the image
    does not constrain them."""
    jac, r = solution.jac, solution.fun
    dof = max(len(r) - len(solution.x), 1)
    variance = float(np.sum(r**2)) / dof
    with np.errstate(invalid="ignore", divide="ignore"):
        try:
            sd = np.sqrt(np.diag(np.linalg.inv(jac.T @ jac) * variance))
        except np.linalg.LinAlgError:
            sd = np.full(len(solution.x), np.nan)
    moved = solution.x.copy()
    moved[:3] += STEP
    slope = np.abs(variables.decode(moved)[0] - albedo) / STEP
    return sd[:3] * slope, sd[3:6] * mfp, sd



def _object_mask(integrator, index, shape):
    """Where the camera sees object ``index`` first (its visible pixel centres), (H, W) bool."""
    mask = np.zeros(shape[0] * shape[1], dtype=bool)
    mask[integrator.prepared.visible[index].pixel] = True
    return mask.reshape(shape)
