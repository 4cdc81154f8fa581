"""``convsss reference``: the same scene with Mitsuba's ``volpathmis`` (ground truth), in passes that are each saved."""

import sys
import time

import click

from .main import cli
from .options import PROGRESS, scene_source_options, tonemap_options


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

    from ..outputs import reference_to_files
    from ..pipeline.reference import BlackPassWarning

    start = time.perf_counter()
    lines = progress and not sys.stderr.isatty()  # a log: one line a pass, no carriage returns
    bar = None

    def passed(done, total, index, n_passes):
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, desc="volpathmis", unit="spp", disable=not progress or lines)
            if lines:
                click.echo(f"volpathmis: {total} spp in passes of {pass_spp}", err=True)
            return
        bar.update(done - bar.n)
        if lines:
            click.echo(f"volpathmis: {done}/{total} spp (pass {index + 1}/{n_passes}) at "
                       f"{time.perf_counter() - start:.1f} s", err=True)

    try:
        record = reference_to_files(source, output, spp=spp, sensor=sensor, seed=seed, pass_spp=pass_spp,
                                    strict=strict, tonemap=tonemap, key=key, exposure=exposure,
                                    exposure_from=exposure_from, progress=passed)
    except BlackPassWarning as black:
        click.echo(f"error: {black}", err=True)
        click.get_current_context().exit(1)
    finally:
        if bar is not None:
            bar.close()
    click.echo(f"wrote {record['outputs']['exr']} and {record['outputs']['png']} "
               f"({record['spp_done']} spp, {time.perf_counter() - start:.1f} s)")
