"""A scene rendered to files: the work of ``convsss render`` and ``convsss reference`` as library functions, called
by the CLI and by a batch's workers (:mod:`convsss.batch`) alike.

:func:`render_to_files` writes ``OUT.exr`` (linear; the AOV channels beside R, G, B), ``OUT.png`` (tone-mapped), with
``mask`` ``OUT-mask.png``, with ``denoise`` ``OUT.denoised.exr`` and ``OUT.denoised.png`` (:mod:`convsss.denoise`,
beside the raw image, never instead of it) and with ``stats_path`` a JSON file of the render's parameters and
per-stage seconds.
:func:`reference_to_files` renders the same scene with ``volpathmis`` in passes, rewriting ``OUT.exr``, ``OUT.png``
and ``OUT.json`` after each. Every file is written together with its siblings or not at all, and never over an
input (the scene and every file it names, the mesh, a profile, the ``exposure_from`` image).
"""

import dataclasses
import json
import sys
import time
import warnings
from pathlib import Path

from .errors import ConvsssError
from .files import check_outputs, json_ready, output_paths, text_writer, write_files
from .pipeline.parts import samples_per_pixel
from .scene.quick import SPP


def pick_sensor(scene, sensor=None):
    """The scene's sensor number ``sensor`` (None: the first, with a note on stderr when there are others), or a
    one-line error."""
    sensors = scene.sensors()
    if sensor is None:
        if len(sensors) > 1:
            print(f"note: the scene has {len(sensors)} sensors; rendering sensor 0 (--sensor picks another)",
                  file=sys.stderr)
        return sensors[0]
    if not 0 <= sensor < len(sensors):
        raise ConvsssError(f"--sensor {sensor} is not allowed: the scene has {len(sensors)} sensor(s), 0 to "
                           f"{len(sensors) - 1}")
    return sensors[sensor]


def exposure_anchor(exposure_from, tonemap):
    """The image ``exposure_from`` names (linear RGB), or None; one-line errors for a missing file or a tone
    mapping it cannot key."""
    if exposure_from is None:
        return None
    if tonemap != "reinhard":
        raise ConvsssError(f"--exposure-from keys the Reinhard operator: it needs --tonemap reinhard, not {tonemap}")
    from .image import read_image

    return read_image(exposure_from)


def _spp(spp, source, camera):
    """The samples per pixel asked for, else the quick scene's, else the scene's sampler's."""
    return spp if spp is not None else (SPP if source.quick else samples_per_pixel(0, camera))


def render_to_files(source, output, *, spp=None, sensor=None, seed=0, mask=False, denoise=False, tonemap="reinhard",
                    key=0.18, exposure=0.0, exposure_from=None, stats_path=None, progress=None, **integrator):
    """Render ``source`` (a :class:`~convsss.scene.source.SceneSource`) with the ``convsss`` integrator and write
    the files named after the stem ``output`` (module doc); returns the stats (a dict: ``outputs``, ``seconds`` per
    stage and ``total``, parameters, shapes), also written to ``stats_path`` when given.

    ``integrator``: integrator parameters by name (None or absent: the scene's, else the default; the quick scene
    defaults to ``specular="phong"``); bad values, outputs that would overwrite an input and a missing profile or
    ``exposure_from`` file are refused before anything is loaded. ``progress(stage)`` hears each stage as it starts
    (``scene_load``, the render's :data:`~convsss.pipeline.STAGES`, ``write``).
    """
    from .pipeline.params import render_params, with_aovs
    from .profiles import TabulatedProfile
    from .profiles.models import profile_files

    start = time.perf_counter()
    progress = progress or (lambda stage: None)
    defaults = {"specular": "phong"} if source.quick else {}
    render_params(integrator, defaults)  # bad values fail before anything is loaded
    profiles = profile_files(integrator.get("profile") or "")
    for csv in profiles:
        TabulatedProfile.from_csv(csv)
    exr, png, mask_png, denoised_exr, denoised_png = output_paths(output, ".exr", ".png", "-mask.png",
                                                                  ".denoised.exr", ".denoised.png")
    denoised = [denoised_exr, denoised_png] if denoise else []
    check_outputs([exr, png, *([mask_png] if mask else []), *denoised, *([stats_path] if stats_path else [])],
                  [*source.inputs(), *profiles, *([exposure_from] if exposure_from else [])])
    anchor = exposure_anchor(exposure_from, tonemap)
    if denoise and source.quick:  # uncorrelated pixel noise, which the denoiser removes (convsss.denoise)
        source = dataclasses.replace(source, rfilter="box")

    from .backend import load_mitsuba
    from .pipeline.integrator import scene_parameters

    mi = load_mitsuba()
    seconds = {}
    progress("scene_load")
    t = time.perf_counter()
    scene = source.load()
    base = scene_parameters(scene) or dict(defaults)
    params = render_params(integrator, base)
    source.warn_color_model(params.profile, params.profile_total)
    if mask or denoise:  # the AOVs asked for (given, else the scene's), the mask, the denoiser's guides
        from .denoise import GUIDES

        extra = ("mask",) * mask + GUIDES * denoise
        params = render_params({**integrator, "aovs": with_aovs(params.aovs, extra)}, base)
    seconds["scene_load"] = time.perf_counter() - t
    integ = mi.load_dict(params.integrator_dict())
    integ.progress = progress
    camera = pick_sensor(scene, sensor)
    if denoise:
        from .denoise import check_pixel_filter

        check_pixel_filter(camera)
    spp = _spp(spp, source, camera)
    from .pipeline.aovs import film_channels

    aovs = integ.aov_names()
    image, channels = film_channels(integ.render(scene, camera, seed=seed, spp=spp), aovs)
    seconds.update(integ.stats["seconds"])
    if denoise:
        from .denoise import denoise as denoised_image
        from .denoise import guides_of

        progress("denoise")
        t = time.perf_counter()
        clean = denoised_image(image[..., :3], *guides_of(image, channels))
        seconds["denoise"] = time.perf_counter() - t
    progress("write")
    t = time.perf_counter()
    from .image import exr_writer, mask_png_writer, png_writer

    stats = {"command": "render", "scene": None if source.quick else str(source.scene_file),
             "quick": source.summary(), "seed": seed, "spp": spp, "sensor": scene.sensors().index(camera),
             "light_scale": source.light_scale, "orbit_deg": source.orbit_deg,
             "outputs": {"exr": str(exr), "png": str(png), **({"mask": str(mask_png)} if mask else {}),
                         **({"denoised_exr": str(denoised_exr), "denoised_png": str(denoised_png)} if denoise
                            else {}),
                         **({"stats": str(stats_path)} if stats_path else {})},
             "denoised": "Intel Open Image Denoise (pyoidn), guided by the albedo and normal AOVs: the "
                         "denoised files only" if denoise else None,
             "aovs": aovs, "tonemap": {"method": tonemap, "key": key, "exposure": exposure,
                                       "exposure_from": exposure_from},
             **integ.stats, "seconds": seconds}

    def finish(tmp=None):
        """Time the writes and the whole run; with ``tmp``, save the stats there (the last file written)."""
        seconds.setdefault("write", time.perf_counter() - t)
        seconds.setdefault("total", time.perf_counter() - start)
        if tmp is not None:
            Path(tmp).write_text(json.dumps(json_ready(stats), indent=1))

    writers = {exr: exr_writer(image, channels), png: png_writer(image, tonemap, key, exposure, anchor=anchor)}
    if mask:
        writers[mask_png] = mask_png_writer(image[..., channels.index("mask.Y")])
    if denoise:  # the raw image's tone mapping: the two PNGs differ by the noise alone
        writers[denoised_exr] = exr_writer(clean, ["R", "G", "B"])
        writers[denoised_png] = png_writer(clean, tonemap, key, exposure, anchor=image[..., :3] if anchor is None
                                           else anchor)
    if stats_path:
        writers[stats_path] = finish
    write_files(writers)
    finish()
    return stats


def reference_to_files(source, output, *, spp=None, sensor=None, seed=0, pass_spp=16, strict=False,
                       tonemap="reinhard", key=0.18, exposure=0.0, exposure_from=None, progress=None):
    """Render ``source`` with Mitsuba's ``volpathmis`` (:func:`~convsss.pipeline.reference.render_reference`):
    ``spp`` in all (None: the scene's sampler, or the quick scene's), in passes of ``pass_spp``, ``OUT.exr``,
    ``OUT.png`` and ``OUT.json`` rewritten together after every pass (a run stopped keeps its last complete pass).
    Returns the last ``OUT.json``'s contents (a dict, with ``outputs``).

    ``progress(spp_done, spp_total, pass_index, n_passes)`` hears each pass saved, and ``progress(0, spp_total, -1,
    n_passes)`` once before the first. A pass black over every pixel of the translucent objects warns
    (:class:`~convsss.pipeline.reference.BlackPassWarning`); with ``strict`` it is raised, before anything is
    written.
    """
    from .backend import load_mitsuba
    from .image import exr_writer, png_writer
    from .pipeline.checks import check_surfaces
    from .pipeline.reference import OPEN_RR_DEPTH, BlackPassWarning, render_reference

    start = time.perf_counter()
    exr, png, info = output_paths(output, ".exr", ".png", ".json")
    check_outputs([exr, png, info], [*source.inputs(), *([exposure_from] if exposure_from else [])])
    anchor = exposure_anchor(exposure_from, tonemap)
    scene = source.load()
    open_surfaces = check_surfaces(load_mitsuba(), scene)  # an open mesh warns, as in `render`
    if open_surfaces:
        warnings.warn(f"Russian roulette is on from depth {OPEN_RR_DEPTH} (noisier, still unbiased): behind the open "
                      f"translucent surface {open_surfaces[0]!r} paths could wander without end", stacklevel=2)
    camera = pick_sensor(scene, sensor)
    total_spp = _spp(spp, source, camera)
    progress = progress or (lambda *args: None)
    record = {}

    def save(image, done, index, n_passes):
        record.update({
            "command": "reference", "scene": None if source.quick else str(source.scene_file),
            "integrator": "volpathmis", "rr_depth": OPEN_RR_DEPTH if open_surfaces else "off", "max_depth": -1,
            "spp_done": done,
            "spp_requested": total_spp, "passes_done": index + 1, "passes": n_passes, "seed": seed,
            "seconds": time.perf_counter() - start})
        write_files({exr: exr_writer(image), png: png_writer(image, tonemap, key, exposure, anchor=anchor),
                     info: text_writer(json.dumps(record, indent=1))})
        progress(done, total_spp, index, n_passes)

    progress(0, total_spp, -1, -(-total_spp // pass_spp))
    with warnings.catch_warnings():
        if strict:
            warnings.simplefilter("error", BlackPassWarning)
        render_reference(scene, total_spp, pass_spp, seed, save, sensor=camera, roulette=bool(open_surfaces))
    return {**record, "outputs": {"exr": str(exr), "png": str(png), "json": str(info)}}
