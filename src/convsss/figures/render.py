"""Rendering for the figures: the ``convsss`` integrator through its Python path (as ``convsss render`` does), and
the two references, cached: the ``exact`` transport (the direct sum over the same kind of irradiance samples) and
``volpathmis`` (Mitsuba's volumetric path tracer, :mod:`convsss.pipeline.reference`).

Seconds: ``seconds`` is the integrator's wall time for the whole image (irradiance samples, transport, shading of
the camera rays); ``sss_seconds`` is the subsurface part alone, what the paper times as its "simulation of light
transport": building the transport (splat, kernels and forward FFTs, or the octree) plus the exitance lookups of
the visible points (mixing and inverse FFTs of the lazily computed layers included). Ray tracing is not in it.
"""

import time
import warnings

import numpy as np

from ..backend import load_mitsuba
from ..pipeline.params import RenderParams
from ..profiles.models import PROFILE_MODELS
from .scenes import load, scene_dict

#: Integrator parameters every figure panel shares unless it says otherwise (the paper's Phong highlights).
#: The paper's method as published (``correction="none"``); panels that go beyond it say so in their params.
#: The paper's setting for every panel: Phong highlights, no plane correction, and surface samples by the image's
#: cells alone (``profile_samples`` 0: the paper deposits irradiance per layer cell; the noise rule would draw
#: millions of samples for its exact-sum references), every direction as a normal beam, the model's own total with
#: single scattering in the profile, and the transports alone (walk_depth 0: no random walk).
BASE_PARAMS = {"specular": "phong", "correction": "none", "profile_samples": 0, "incidence": "normal",
               "profile_total": "model", "single_scattering": "profile", "walk_depth": 0.0}


#: The exact sums a figure compared with path tracing also reports against ``volpathmis``, one column each: every
#: profile model at the paper's setting, and the renderer's own physics (its defaults for the parameters the paper's
#: setting pins: the default model at the exact total, oblique incidence, single scattering traced).
PROFILE_COLUMNS = {**{model: {"profile": model} for model in PROFILE_MODELS},
                   "renderer": {name: RenderParams().to_dict()[name]
                                for name in ("incidence", "profile_total", "single_scattering")}}


def panel_params(method, params):
    """:class:`RenderParams` for a panel rendered by the ``convsss`` integrator with transport ``method``."""
    return RenderParams(**{**BASE_PARAMS, **params, "transport": method})


def sss_seconds(stats):
    """Seconds of subsurface transport in a render's ``integrator.stats`` (see the module docstring)."""
    build = float(stats["seconds"].get("transport", 0.0))
    lookups = sum(float(t["seconds"].get("lookup", 0.0)) for t in stats.get("transports", []))
    return build + lookups


def render_convsss(scene, params, spp, seed=0, progress=None):
    """Render a loaded scene with the ``convsss`` integrator; returns ``(image (H, W, 3), summary dict)``.

    ``summary``: ``seconds``, ``sss_seconds``, per-stage ``stage_seconds``, ``samples``, ``c`` (the paper's
    convolutions per layer, for the convolution transport), ``pairs_per_layer``, ``layers_computed``,
    ``mean_free_paths`` and the transport's own stats.

    Parameters
    ----------
    scene : mitsuba.Scene
    params : RenderParams
    spp : int
        Samples per pixel.
    seed : int
    progress : callable, optional
        Set as the integrator's ``progress`` (called with each stage's name).

    Returns
    -------
    image : numpy.ndarray, shape (H, W, 3), float64
        The film's linear RGB (the scene's radiance unit).
    summary : dict
        As above; seconds of wall time, ``mean_free_paths`` of the first object per RGB channel.
    """
    mi = load_mitsuba()
    integrator = mi.load_dict(params.integrator_dict())
    integrator.progress = progress
    start = time.perf_counter()
    image = np.array(integrator.render(scene, scene.sensors()[0], seed=seed, spp=spp), dtype=np.float64)[..., :3]
    seconds = time.perf_counter() - start
    stats = integrator.stats
    transport = stats["transports"][0] if stats.get("transports") else {}
    summary = {"seconds": seconds, "sss_seconds": sss_seconds(stats), "stage_seconds": dict(stats["seconds"]),
               "samples": int(stats["samples"]),
               "c": transport.get("convolutions_per_layer"), "pairs_per_layer": transport.get("pairs_per_layer"),
               "layers_computed": transport.get("layers_computed"),
               "mean_free_paths": stats["objects"][0].get("mean_free_paths") if stats.get("objects") else None,
               "transport_stats": {k: v for k, v in transport.items() if k not in ("kernel_energy",)}}
    return image, summary


def exact_reference(spec, cache, resolution, spp, seed=0, specular="phong", overrides=None):
    """The ``exact``-transport render of ``spec`` (full-resolution samples), from ``cache`` or rendered now.

    Returns ``(image, meta, hit)``.

    Parameters
    ----------
    spec : SceneSpec
    cache : ReferenceCache
    resolution : int
        Film width and height (pixels).
    spp, seed : int
    specular : str
        The integrator's specular term (``phong`` as the figures' panels).
    overrides : dict, optional
        Integrator parameters over the paper's setting (:data:`BASE_PARAMS`), e.g. a column of
        :data:`PROFILE_COLUMNS`.

    Returns
    -------
    image : numpy.ndarray, shape (resolution, resolution, 3), float64
        Linear RGB, rounded through float32 (as stored).
    meta : dict
        :meth:`ReferenceCache.get`'s metadata, plus ``render_seconds``, ``sss_seconds`` and ``samples`` of the
        original render.
    hit : bool
        Whether it came from the cache.
    """
    params = RenderParams(**{**BASE_PARAMS, **(overrides or {}), "specular": specular, "transport": "exact"})

    def render():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = load(spec, resolution, resolution, spp)
        image, summary = render_convsss(scene, params, spp, seed)
        return image, {"render_seconds": summary["seconds"], "sss_seconds": summary["sss_seconds"],
                       "samples": summary["samples"]}

    settings = {"renderer": "convsss", "params": params.to_dict(), "spp": spp, "seed": seed,
                "resolution": resolution}
    return cache.get("exact", scene_dict(spec, resolution, resolution, spp), settings, render,
                     f"exact transport, {spec.describe()}, {resolution}², {spp} spp")


def path_traced_reference(spec, cache, resolution, spp, pass_spp=16, seed=0, progress=True):
    """The ``volpathmis`` render of ``spec`` (Russian roulette off, unbounded paths), cached; ``(image, meta, hit)``.

    Parameters
    ----------
    spec : SceneSpec
    cache : ReferenceCache
    resolution : int
        Film width and height (pixels).
    spp, pass_spp, seed : int
        As in :func:`~convsss.pipeline.reference.render_reference`.
    progress : bool
        Show a progress bar.

    Returns
    -------
    image : numpy.ndarray, shape (resolution, resolution, 3), float64
        Linear RGB, rounded through float32 (as stored).
    meta : dict
        :meth:`ReferenceCache.get`'s metadata.
    hit : bool
        Whether it came from the cache.
    """
    from tqdm import tqdm

    from ..pipeline.reference import render_reference

    def render():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = load(spec, resolution, resolution, spp)
        bar = tqdm(total=spp, desc="  volpathmis", unit="spp", leave=False, disable=not progress)
        try:
            image = render_reference(scene, spp, pass_spp, seed,
                                     on_pass=lambda _image, done, _k, _n: bar.update(done - bar.n))
        finally:
            bar.close()
        return image, {}

    settings = {"renderer": "volpathmis", "max_depth": -1, "rr_depth": "off", "spp": spp, "pass_spp": pass_spp,
                "seed": seed, "resolution": resolution}
    return cache.get("volpathmis", scene_dict(spec, resolution, resolution, spp), settings, render,
                     f"volpathmis, {spec.describe()}, {resolution}², {spp} spp")
