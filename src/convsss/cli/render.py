"""``convsss render``: a Mitsuba scene (or a mesh and a material) rendered with the ``convsss`` integrator.

Writes ``OUT.exr`` (linear; with ``--aovs``, the integrator's AOV channels beside R, G, B), ``OUT.png``
(tone-mapped), with ``--mask`` ``OUT-mask.png`` (the translucent objects' coverage), and with ``--stats`` a JSON file of
parameters, per-stage seconds, grid/FFT shapes and the object's size in mean free paths. The files are written
together or not at all, and never over an input of the render (the scene and every file it names, the mesh, the
profile).
"""

import json
import sys
import time
from pathlib import Path

import click
import numpy as np

from .. import pipeline
from ..files import check_outputs, json_ready, write_files
from ..scene.quick import SPP
from .main import cli
from .options import (
    PROGRESS,
    exposure_anchor,
    integrator_options,
    output_paths,
    pick_sensor,
    render_params,
    scene_source_options,
    tonemap_options,
    warn_color_model,
)

#: The command's stages: the scene loaded, the render's own (:data:`convsss.pipeline.STAGES`), the files written.
STAGES = ("scene_load", *pipeline.STAGES, "write")


class StageProgress:
    """The render's stages on stderr: a tqdm bar on a terminal, else one plain line per stage as it starts (a log
    without carriage returns); ``__call__(stage)`` moves it on. A render in passes (the integrator's ``pass k/n``)
    counts passes instead, with the time left estimated from those done."""

    def __init__(self, enabled=True, terminal=None):
        from tqdm import tqdm

        terminal = sys.stderr.isatty() if terminal is None else terminal
        self.lines = enabled and not terminal
        self.start = time.perf_counter()
        self.bar = tqdm(total=len(STAGES), desc="render", unit="stage", disable=not enabled or self.lines,
                        leave=True, bar_format="{desc}: {n_fmt}/{total_fmt} stages |{bar:20}| {elapsed} {postfix}")
        self.done = set()
        self.passes = None  # (this pass, of how many), once the integrator names passes

    def __call__(self, stage):
        if stage.startswith("pass "):
            self.passes = tuple(int(k) for k in stage[len("pass "):].split("/"))
            self.bar.bar_format = "{desc}: {n_fmt}/{total_fmt} passes |{bar:20}| {elapsed}<{remaining} {postfix}"
            self.bar.total, self.bar.n = self.passes[1], self.passes[0] - 1
            self.bar.refresh()
            if self.lines:
                self._line(stage)
            return
        self.bar.set_postfix_str(stage if self.passes is None else f"pass {self.passes[0]}: {stage}")
        if self.passes is not None:
            if self.lines and stage not in self.done:
                self._line(stage)
            self.done.add(stage)
            return
        if stage not in self.done:
            self.done.add(stage)
            self.bar.n = min(len(self.done), len(STAGES))
            self.bar.refresh()
            if self.lines:
                self._line(f"{stage} ({len(self.done)}/{len(STAGES)})")

    def _line(self, text):
        click.echo(f"render: {text} at {time.perf_counter() - self.start:.1f} s", err=True)

    def close(self, failed=False):
        """Finish the bar: all stages done, or left where it stopped, marked ``failed``."""
        if not failed:
            self.bar.n = len(STAGES) if self.passes is None else self.passes[0]
        self.bar.set_postfix_str("failed" if failed else "done")
        self.bar.close()
        if self.lines:
            self._line("failed" if failed else "done")


@cli.command()
@scene_source_options
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output stem: writes OUT.exr (linear, with the --aovs channels) and OUT.png (tone-mapped).")
@click.option("--mask", "write_mask", is_flag=True,
              help="Also write OUT-mask.png, the translucent objects' mask: white where a camera ray first hits one, "
                   "grey where it covers part of the pixel (the mask AOV, also added to OUT.exr, where `convsss "
                   "compare` finds it).")
@integrator_options
@tonemap_options
@click.option("--stats", "stats_path", type=click.Path(dir_okay=False),
              help="Write a JSON file: parameters, per-stage seconds, grid and FFT shapes, pairs per layer, sample "
                   "count, and the object's size in mean free paths and diffusion lengths.")
@PROGRESS
def render(source, spp, sensor, seed, output, write_mask, tonemap, key, exposure, exposure_from, stats_path, progress,
           **integrator):
    """Render SCENE_FILE (a Mitsuba 3 XML scene) with the convsss integrator, whatever integrator the file names.

    A translucent object is a shape with an interior 'homogeneous' medium (or a 'convsss_medium' naming a preset
    or a colour, docs/guide/scene-files.md) and a null, dielectric or roughdielectric BSDF; scene units are mm
    unless --unit-mm says otherwise. Without a scene file,
    --mesh/--material/--size-mm build a scene around the mesh (with --specular phong, the paper's highlight, unless
    given); --color/--mfp-mm give the material by its colour and mean free path instead of a preset.

    AOVs (--aovs exitance,irradiance,object,mask,depth,normal) are extra channels of OUT.exr, named as Mitsuba's
    aov integrator names them (exitance.R, object.I, ...), each taken at the camera ray's first hit.

    \b
    Examples:
      convsss render scene.xml -o out/scene --spp 16 --stats out/scene.json
      convsss render --mesh bunny --material wholemilk --size-mm 40 --floor -o out/bunny
      convsss render --mesh bunny --color 0.8,0.5,0.4 --mfp-mm 2 --size-mm 40 -o out/colour
      convsss render scene.xml -o out/scene --aovs exitance,object --mask
    """
    start = time.perf_counter()
    quick = source.quick
    defaults = {"specular": "phong"} if quick else {}
    render_params(integrator, defaults)  # bad values fail before anything is loaded
    from ..profiles import TabulatedProfile
    from ..profiles.models import profile_files

    profiles = profile_files(integrator["profile"] or "")
    for csv in profiles:
        TabulatedProfile.from_csv(csv)
    exr, png, mask_png = output_paths(output, ".exr", ".png", "-mask.png")
    check_outputs([exr, png, *([mask_png] if write_mask else []), *([stats_path] if stats_path else [])],
                  [*source.inputs(), *profiles, *([exposure_from] if exposure_from else [])])
    anchor = exposure_anchor(exposure_from, tonemap)

    from ..backend import load_mitsuba
    from ..pipeline.integrator import scene_parameters

    mi = load_mitsuba()
    seconds = {}
    bar = StageProgress(progress)
    try:
        bar("scene_load")
        t = time.perf_counter()
        scene = source.load()
        base = scene_parameters(scene) or dict(defaults)
        params = render_params(integrator, base)
        if source.color is not None:
            warn_color_model(source.color_model, params.profile, params.profile_total)
        if write_mask:  # the AOVs asked for (on the command line, else in the scene) and the mask
            params = render_params({**integrator, "aovs": _with_mask(params.aovs)}, base)
        seconds["scene_load"] = time.perf_counter() - t
        integ = mi.load_dict(params.integrator_dict())
        integ.progress = bar
        camera = pick_sensor(scene, sensor)
        spp_used = spp if spp is not None else (SPP if quick else camera.sampler().sample_count())
        film = np.array(integ.render(scene, camera, seed=seed, spp=spp_used), dtype=np.float64)
        aovs = integ.aov_names()
        image = np.concatenate([film[..., :3], film[..., film.shape[2] - len(aovs):]], axis=2)  # RGB(A) + AOVs
        channels = ["R", "G", "B", *aovs]
        seconds.update(integ.stats["seconds"])
        bar("write")
        t = time.perf_counter()
        from ..image import exr_writer, mask_png_writer, png_writer

        stats = {"command": "render", "scene": None if quick else str(source.scene_file), "quick": source.summary(),
                 "seed": seed, "spp": spp_used, "sensor": scene.sensors().index(camera),
                 "light_scale": source.light_scale, "orbit_deg": source.orbit_deg,
                 "outputs": {"exr": str(exr), "png": str(png), "mask": str(mask_png) if write_mask else None},
                 "aovs": aovs,
                 "tonemap": {"method": tonemap, "key": key, "exposure": exposure, "exposure_from": exposure_from},
                 **integ.stats, "seconds": seconds}

        def finish(tmp=None):
            """Time the writes and the whole run; with ``tmp``, save the stats there (the last file written)."""
            seconds.setdefault("write", time.perf_counter() - t)
            seconds.setdefault("total", time.perf_counter() - start)
            if tmp is not None:
                Path(tmp).write_text(json.dumps(json_ready(stats), indent=1))

        writers = {exr: exr_writer(image, channels), png: png_writer(image, tonemap, key, exposure, anchor=anchor)}
        if write_mask:
            writers[mask_png] = mask_png_writer(image[..., channels.index("mask.Y")])
        if stats_path:
            writers[stats_path] = finish
        write_files(writers)
        finish()
    except BaseException:
        bar.close(failed=True)
        raise
    bar.close()
    written = f"{exr}, {png} and {mask_png}" if write_mask else f"{exr} and {png}"
    click.echo(f"wrote {written} ({seconds['total']:.1f} s)")


def _with_mask(aovs):
    """The ``aovs`` parameter with ``mask`` added (for ``--mask``) unless it names it already."""
    from ..pipeline.params import parse_aovs

    names = parse_aovs(aovs)
    return ",".join(names if "mask" in names else (*names, "mask"))
