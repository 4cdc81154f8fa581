"""Ground truth for a scene: the same scene rendered with Mitsuba's volumetric path tracer ``volpathmis``.

``volpathmis`` handles a different ``sigma_t`` per channel; Russian roulette is switched off (``rr_depth`` huge; at
albedo ~1 it fires fireflies) and paths are unbounded (``max_depth = -1``), so the estimate is unbiased. Where a
translucent surface is open (``roulette``), Russian roulette is on from depth :data:`OPEN_RR_DEPTH` (still unbiased,
noisier): a path in the medium behind an open surface, nothing closing it, could otherwise wander without end (an
open 10 mm marble triangle: 14 s for 32², 16 spp without, issue 62). The render
runs in passes of ``pass_spp`` samples with different seeds; after each pass the running mean is handed to a
callback, so a long run can be stopped and what it has so far is kept.

Mind (docs/architecture.md): a point light behind a smooth dielectric cannot be reached by a unidirectional path
tracer, so such a scene renders black here; use a ``null`` boundary with point lights, or area / environment lights. A
pass that is black over every pixel where the camera sees a translucent object raises a :class:`BlackPassWarning`.
"""

import warnings

import drjit as dr
import numpy as np

from ..backend import load_mitsuba
from ..errors import ConvsssError
from ..signals import mitsuba_render
from .parts import pass_seed, shares

#: Russian roulette starts at this depth, i.e. never in practice.
NO_RUSSIAN_ROULETTE = 1 << 30
#: Where a translucent surface is open: Russian roulette from this depth (Mitsuba's default).
OPEN_RR_DEPTH = 5


class BlackPassWarning(UserWarning):
    """A ``volpathmis`` pass is black over every pixel where the camera sees a translucent object."""


class NonFiniteWarning(UserWarning):
    """``volpathmis`` wrote pixels that are not finite (left out of their pixel's mean)."""


def translucent_pixels(scene, sensor=0):
    """(H, W) bool over the sensor's crop window: pixels whose centre ray first hits a shape with an interior medium.

    Parameters
    ----------
    scene : mitsuba.Scene
    sensor : int or mitsuba.Sensor

    Returns
    -------
    numpy.ndarray, shape (H, W), bool
    """
    from .camera import pixel_centre_rays

    mi = load_mitsuba()
    sensor = scene.sensors()[sensor] if isinstance(sensor, int) else sensor
    width, height = (int(n) for n in sensor.film().crop_size())
    ray, _ = pixel_centre_rays(sensor)
    si = scene.ray_intersect(ray)
    inside = si.is_valid() & (dr.reinterpret_array(mi.UInt32, si.shape.interior_medium()) != 0)
    return inside.numpy().reshape(height, width)


def reference_integrator(roulette=False):
    """A ``volpathmis`` integrator with unbounded paths, without Russian roulette (with it from
    :data:`OPEN_RR_DEPTH` where ``roulette``)."""
    mi = load_mitsuba()
    return mi.load_dict({"type": "volpathmis", "max_depth": -1,
                         "rr_depth": OPEN_RR_DEPTH if roulette else NO_RUSSIAN_ROULETTE})


def render_reference(scene, spp, pass_spp=16, seed=0, on_pass=None, sensor=0, roulette=False):
    """Render ``scene`` with ``spp`` samples per pixel of ``volpathmis``, in passes; returns the mean (H, W, 3).

    Parameters
    ----------
    scene : mitsuba.Scene
    spp : int
        Total samples per pixel.
    pass_spp : int
        Samples per pixel of each pass (the last one may have fewer).
    seed : int
        Pass ``k`` uses the seed :func:`~.parts.pass_seed` ``(seed, k)``, as the passes of a ``convsss`` render: the
        same seed gives the same image up to the order in which Mitsuba's threads add samples into the film (about
        1e-7 relative).
    on_pass : callable, optional
        ``on_pass(mean_image, spp_done, pass_index, n_passes)`` after each pass (e.g. to save it).
    sensor : int or mitsuba.Sensor
        The sensor rendered (default: the first).
    roulette : bool
        Russian roulette on (module doc): for scenes with an open translucent surface.

    Returns
    -------
    numpy.ndarray, shape (H, W, 3), float64
        The mean over all passes of the film's linear RGB (the scene's radiance unit).

    Warns
    -----
    BlackPassWarning
        Once, for the first pass that is zero over every pixel where the camera sees a translucent object
        (:func:`translucent_pixels`), before ``on_pass`` gets it; turned into an error it stops the run there.
    """
    spp, pass_spp = int(spp), int(pass_spp)
    if spp < 1 or pass_spp < 1:
        raise ConvsssError(f"spp={spp} and pass_spp={pass_spp} are not allowed: both must be >= 1")
    mi = load_mitsuba()
    integrator = reference_integrator(roulette)
    parts = shares(spp, most=pass_spp)
    n_passes = len(parts)
    objects = translucent_pixels(scene, sensor)
    total, weight, done, warned, broken = None, None, 0, False, 0
    for k, this in enumerate(parts):
        with mitsuba_render(integrator):  # Ctrl-C: no partial pass is averaged in
            image = np.array(mi.render(scene, sensor=sensor, integrator=integrator, spp=this,
                                       seed=pass_seed(seed, k)), dtype=np.float64)[..., :3]
        if not warned and objects.any() and not np.any(image[objects] > 0):
            warned = True
            warnings.warn(f"volpathmis pass {k + 1} of {n_passes} is black over all {int(objects.sum())} pixels "
                          "where the camera sees a translucent object: a path tracer cannot reach a point light "
                          "through a smooth dielectric; use a null boundary with point lights, or area or "
                          "environment lights", BlackPassWarning, stacklevel=2)
        finite = np.all(np.isfinite(image), axis=-1, keepdims=True)  # a pixel Mitsuba wrote NaN or inf into
        broken += int((~finite).sum())
        image = np.where(finite, image, 0.0)
        total = image * this if total is None else total + image * this
        weight = finite * this if weight is None else weight + finite * this
        done += this
        if on_pass is not None:
            on_pass(_mean(total, weight), done, k, n_passes)
    if broken:
        warnings.warn(f"volpathmis wrote {broken} pixel(s) that are not finite over {n_passes} passes (its spectral "
                      "MIS does on some heterogeneous media): each is the mean of its finite passes (0 where none "
                      "was)", NonFiniteWarning, stacklevel=2)
    return _mean(total, weight)


def _mean(total, weight):
    """Each pixel's mean over the passes where it was finite (``weight``: their samples), 0 where none was."""
    return np.divide(total, weight, out=np.zeros_like(total), where=weight > 0)


def volpath_slab_albedo(material, occluder_mm=0.0, spp=1 << 16, seed=0):
    """Mitsuba ``volpathmis`` (Russian roulette off) on a flat box of ``material`` (a smooth dielectric boundary of
    its ``eta``, 40 diffusion lengths wide, 20 deep, at least 200 and 100 mean free paths) under a uniform sky of
    radiance 1: a radiance meter just above the centre looking straight down reads, by reciprocity, the albedo at
    normal incidence; with ``occluder_mm > 0`` a black disk of that radius just above the meter hides the exits
    within it (and the specular reflection).

    Returns
    -------
    numpy.ndarray, shape (3,)
    """
    from ..media.dicts import translucent

    mi = load_mitsuba()
    T = mi.ScalarTransform4f
    mfp = float(np.max(material.mfp_mm))
    reach = float(np.max(np.where(material.sigma_tr > 0, 1.0 / np.maximum(material.sigma_tr, 1e-300), np.inf)))
    width = min(max(40.0 * reach, 200.0 * mfp), 2000.0 * mfp)
    depth = 0.5 * width
    box = translucent({"type": "cube", "to_world": T().translate([0, 0, -0.5 * depth]).scale(
        [0.5 * width, 0.5 * width, 0.5 * depth])}, material, boundary="dielectric")
    lift = 1e-4 * mfp
    scene = {
        "type": "scene",
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
        "slab": box,
        "meter": {"type": "radiancemeter", "origin": [0.0, 0.0, lift], "direction": [0.0, 0.0, -1.0],
                  "film": {"type": "hdrfilm", "width": 1, "height": 1, "rfilter": {"type": "box"},
                           "pixel_format": "rgb"},
                  "sampler": {"type": "independent", "sample_count": int(spp)}},
    }
    if occluder_mm > 0:
        scene["occluder"] = {"type": "disk", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb",
                                                                                         "value": [0.0] * 3}},
                             "to_world": T().translate([0.0, 0.0, 2.0 * lift]).scale(float(occluder_mm))}
    integrator = reference_integrator()
    with mitsuba_render(integrator):
        image = mi.render(mi.load_dict(scene), integrator=integrator, seed=int(seed), spp=int(spp))
    return np.array(image, dtype=np.float64).reshape(-1)[:3]
