"""``convsss reference``: the same scene with Mitsuba's ``volpathmis`` (ground truth), in passes that are each saved."""

import json
import sys
import time
import warnings

import click

from ..files import check_outputs, text_writer, write_files
from ..scene.quick import SPP
from .main import cli
from .options import (
    PROGRESS,
    exposure_anchor,
    output_paths,
    pick_sensor,
    scene_source_options,
    tonemap_options,
)


@cli.command()
@scene_source_options
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output stem: OUT.exr (linear), OUT.png (tone-mapped) and OUT.json (passes, spp, seconds), "
                   "rewritten together after every pass.")
@click.option("--pass-spp", type=click.IntRange(1), default=16, show_default=True,
              help="Samples per pixel of each pass; the image so far is saved after each pass.")
@click.option("--strict", is_flag=True,
              help="A pass black over every pixel of the translucent objects is an error (exit code 1, nothing "
                   "written) instead of a warning.")
@tonemap_options
@PROGRESS
def reference(source, spp, sensor, seed, output, pass_spp, strict, tonemap, key, exposure, exposure_from, progress):
    """Render SCENE_FILE with Mitsuba's volumetric path tracer volpathmis: the ground truth of `convsss render`.

    Russian roulette is off and paths are unbounded. --spp is the total (default: the scene's sampler), rendered in
    passes of --pass-spp; after every pass OUT.exr/OUT.png hold the mean so far, so a long run can be stopped
    (Ctrl-C keeps the last complete pass).
    A point light behind a smooth dielectric renders black in a path tracer: use a null boundary with point lights.
    A pass black over every pixel where the camera sees a translucent object warns (with --strict: exit code 1).

    \b
    Example:
      convsss reference scene.xml -o out/scene-ref --spp 1024 --width 256 --height 256
    """
    from tqdm import tqdm

    from ..image import exr_writer, png_writer
    from ..pipeline.reference import BlackPassWarning, render_reference

    start = time.perf_counter()
    exr, png, info = output_paths(output, ".exr", ".png", ".json")
    check_outputs([exr, png, info], [*source.inputs(), *([exposure_from] if exposure_from else [])])
    anchor = exposure_anchor(exposure_from, tonemap)
    scene = source.load()
    camera = pick_sensor(scene, sensor)
    total_spp = spp if spp is not None else (SPP if source.quick else camera.sampler().sample_count())
    lines = progress and not sys.stderr.isatty()  # a log: one line a pass, no carriage returns
    bar = tqdm(total=total_spp, desc="volpathmis", unit="spp", disable=not progress or lines)
    if lines:
        click.echo(f"volpathmis: {total_spp} spp in passes of {pass_spp}", err=True)

    def save(image, done, index, n_passes):
        text = json.dumps({
            "command": "reference", "scene": None if source.quick else str(source.scene_file),
            "integrator": "volpathmis", "rr_depth": "off", "max_depth": -1, "spp_done": done,
            "spp_requested": total_spp, "passes_done": index + 1, "passes": n_passes, "seed": seed,
            "seconds": time.perf_counter() - start}, indent=1)
        write_files({exr: exr_writer(image), png: png_writer(image, tonemap, key, exposure, anchor=anchor),
                     info: text_writer(text)})
        bar.update(done - bar.n)
        if lines:
            click.echo(f"volpathmis: {done}/{total_spp} spp (pass {index + 1}/{n_passes}) at "
                       f"{time.perf_counter() - start:.1f} s", err=True)

    try:
        with warnings.catch_warnings():
            if strict:
                warnings.simplefilter("error", BlackPassWarning)
            render_reference(scene, total_spp, pass_spp, seed, save, sensor=camera)
    except BlackPassWarning as black:
        bar.close()
        click.echo(f"error: {black}", err=True)
        click.get_current_context().exit(1)
    finally:
        bar.close()
    click.echo(f"wrote {exr} and {png} "
               f"({total_spp} spp, {time.perf_counter() - start:.1f} s)")
