"""``convsss render``: a Mitsuba scene (or a mesh and a material) rendered with the ``convsss`` integrator.

Writes ``OUT.exr`` (linear; with ``--aovs``, the integrator's AOV channels beside R, G, B), ``OUT.png``
(tone-mapped), with ``--mask`` ``OUT-mask.png`` (the translucent objects' coverage), and with ``--stats`` a JSON file of
parameters, per-stage seconds, grid/FFT shapes and the object's size in mean free paths. The files are written
together or not at all, and never over an input of the render (the scene and every file it names, the mesh, the
profile).
"""

import sys
import time

import click

from .. import pipeline
from .main import cli
from .options import PROGRESS, integrator_options, scene_source_options, tonemap_options

#: The command's stages: the scene loaded, the render's own (:data:`convsss.pipeline.STAGES`), the files written.
STAGES = ("scene_load", *pipeline.STAGES, "write")


class StageProgress:
    """The render's stages on stderr: a tqdm bar on a terminal, else one plain line per stage as it starts (a log
    without carriage returns); ``__call__(stage)`` moves it on. A render in passes (the integrator's ``pass k/n``)
    counts passes instead, with the time left estimated from those done."""

    def __init__(self, enabled=True, terminal=None, stages=STAGES):
        from tqdm import tqdm

        terminal = sys.stderr.isatty() if terminal is None else terminal
        self.lines = enabled and not terminal
        self.start = time.perf_counter()
        self.stages = stages
        self.bar = tqdm(total=len(stages), desc="render", unit="stage", disable=not enabled or self.lines,
                        leave=True, bar_format="{desc}: {n_fmt}/{total_fmt} stages |{bar:20}| {elapsed} {postfix}")
        self.done = set()
        self.passes = None  # (this pass, of how many), once the integrator names passes

    def __call__(self, stage):
        if ": " in stage:  # what a long stage does now ("transport: the field of 'bunny' (1/1): solving ...")
            self.bar.set_postfix_str(stage)
            if self.lines:
                self._line(stage)
            return
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
            self.bar.n = min(len(self.done), len(self.stages))
            self.bar.refresh()
            if self.lines:
                self._line(f"{stage} ({len(self.done)}/{len(self.stages)})")

    def _line(self, text):
        click.echo(f"render: {text} at {time.perf_counter() - self.start:.1f} s", err=True)

    def close(self, failed=False):
        """Finish the bar: all stages done, or left where it stopped, marked ``failed``."""
        if not failed:
            self.bar.n = len(self.stages) if self.passes is None else self.passes[0]
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
@click.option("--denoise", is_flag=True,
              help="Also write OUT.denoised.exr and OUT.denoised.png: the image denoised by Intel Open Image Denoise, "
                   "guided by the albedo and normal AOVs (added to OUT.exr). OUT.exr and OUT.png stay the raw render; "
                   "compare and the stats use the raw image. With --mesh the film then uses a box pixel filter "
                   "(independent pixel noise, which the denoiser removes); a scene file's wider filter is warned "
                   "about.")
@integrator_options
@tonemap_options
@click.option("--stats", "stats_path", type=click.Path(dir_okay=False),
              help="Write a JSON file: parameters, per-stage seconds, grid and FFT shapes, pairs per layer, sample "
                   "count, and the object's size in mean free paths and diffusion lengths.")
@PROGRESS
def render(source, spp, sensor, seed, output, write_mask, denoise, tonemap, key, exposure, exposure_from, stats_path,
           progress, **integrator):
    """Render SCENE_FILE (a Mitsuba 3 XML scene) with the convsss integrator, whatever integrator the file names.

    A translucent object is a shape with an interior 'homogeneous' medium (or a 'convsss_medium' naming a preset
    or a colour, docs/guide/scene-files.md) and a null, dielectric or roughdielectric BSDF; scene units are mm
    unless --unit-mm says otherwise. Without a scene file,
    --mesh/--material/--size-mm build a scene around the mesh (with --specular phong, the paper's highlight, unless
    given); --color/--mfp-mm give the material by its colour and mean free path instead of a preset.

    AOVs (--aovs exitance,irradiance,object,mask,depth,normal,albedo) are extra channels of OUT.exr, named as Mitsuba's
    aov integrator names them (exitance.R, object.I, ...), each taken at the camera ray's first hit.

    \b
    Examples:
      convsss render scene.xml -o out/scene --spp 16 --stats out/scene.json
      convsss render --mesh bunny --material wholemilk --size-mm 40 --floor -o out/bunny
      convsss render --mesh bunny --color 0.8,0.5,0.4 --mfp-mm 2 --size-mm 40 -o out/colour
      convsss render scene.xml -o out/scene --aovs exitance,object --mask
      convsss render scene.xml -o out/scene --spp 4 --denoise
    """
    from ..outputs import render_to_files

    bar = StageProgress(progress, stages=(*STAGES[:-1], "denoise", STAGES[-1]) if denoise else STAGES)
    try:
        stats = render_to_files(source, output, spp=spp, sensor=sensor, seed=seed, mask=write_mask,
                                denoise=denoise, tonemap=tonemap, key=key, exposure=exposure,
                                exposure_from=exposure_from, stats_path=stats_path, progress=bar, **integrator)
    except BaseException:
        bar.close(failed=True)
        raise
    bar.close()
    outputs = [stats["outputs"][k] for k in ("exr", "png", "mask", "denoised_exr", "denoised_png")
               if k in stats["outputs"]]
    written = f"{', '.join(outputs[:-1])} and {outputs[-1]}"
    click.echo(f"wrote {written} ({stats['seconds']['total']:.1f} s)")
