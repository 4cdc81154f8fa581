"""``convsss reference``: the same scene with Mitsuba's ``volpathmis`` (ground truth), in passes that are each saved."""

import json
import time

import click

from ..errors import ConvsssError
from ..files import write_text
from ..image import TONEMAPS
from .main import cli
from .render import load_source, output_stem, scene_source_options


@cli.command()
@scene_source_options
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output stem: OUT.exr (linear), OUT.png (tone-mapped) and OUT.json (passes, spp, seconds), "
                   "rewritten after every pass.")
@click.option("--pass-spp", type=int, default=16, show_default=True,
              help="Samples per pixel of each pass; the image so far is saved after each pass.")
@click.option("--tonemap", type=click.Choice(TONEMAPS), default="reinhard", show_default=True,
              help="PNG tone mapping (see `convsss render --help`).")
@click.option("--key", type=float, default=0.18, show_default=True, help="Key value of the Reinhard operator.")
@click.option("--exposure", type=float, default=0.0, show_default=True, help="Exposure in stops.")
@click.option("--progress/--no-progress", default=True, show_default=True, help="Show a progress bar on stderr.")
def reference(scene_file, mesh, material, size_mm, floor, boundary, width, height, spp, seed, output, pass_spp,
              tonemap, key, exposure, progress):
    """Render SCENE_FILE with Mitsuba's volumetric path tracer volpathmis: the ground truth of `convsss render`.

    Russian roulette is off and paths are unbounded. --spp is the total (default: the scene's sampler), rendered in
    passes of --pass-spp; after every pass OUT.exr/OUT.png hold the mean so far, so a long run can be stopped.
    A point light behind a smooth dielectric renders black in a path tracer: use a null boundary with point lights.

    \b
    Example:
      convsss reference scene.xml -o out/scene-ref --spp 1024 --width 256 --height 256
    """
    from tqdm import tqdm

    from ..image import write_exr, write_png
    from ..scene.reference import render_reference

    if pass_spp < 1:
        raise ConvsssError(f"--pass-spp {pass_spp} is not allowed: it must be >= 1")
    if spp is not None and spp < 1:
        raise ConvsssError(f"--spp {spp} is not allowed: it must be >= 1")
    start = time.perf_counter()
    scene = load_source(scene_file, mesh, material, size_mm, floor, boundary, width, height)
    total_spp = spp if spp is not None else (16 if scene_file is None else scene.sensors()[0].sampler().sample_count())
    stem = output_stem(output)
    bar = tqdm(total=total_spp, desc="volpathmis", unit="spp", disable=not progress)

    def save(image, done, index, n_passes):
        write_exr(stem.with_suffix(".exr"), image)
        write_png(stem.with_suffix(".png"), image, tonemap, key, exposure)
        write_text(stem.with_suffix(".json"), json.dumps({
            "command": "reference", "scene": str(scene_file) if scene_file else None, "integrator": "volpathmis",
            "rr_depth": "off", "max_depth": -1, "spp_done": done, "spp_requested": total_spp,
            "passes_done": index + 1, "passes": n_passes, "seed": seed,
            "seconds": time.perf_counter() - start}, indent=1))
        bar.update(done - bar.n)

    try:
        render_reference(scene, total_spp, pass_spp, seed, save)
    finally:
        bar.close()
    click.echo(f"wrote {stem.with_suffix('.exr')} and {stem.with_suffix('.png')} "
               f"({total_spp} spp, {time.perf_counter() - start:.1f} s)")
