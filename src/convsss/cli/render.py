"""``convsss render``: a Mitsuba scene (or a mesh and a material) rendered with the ``convsss`` integrator.

Writes ``OUT.exr`` (linear) and ``OUT.png`` (tone-mapped), and with ``--stats`` a JSON file of parameters, per-stage
seconds, grid/FFT shapes and the object's size in mean free paths. The files are written together or not at all,
and never over an input of the render (the scene and every file it names, the mesh, the profile).
"""

import json
import time
import warnings
from pathlib import Path

import click
import numpy as np

from ..errors import ConvsssError
from ..files import check_outputs, json_ready, write_files
from ..image import TONEMAPS, check_tonemap
from .main import cli

STAGES = ("scene_load", "samples", "irradiance", "transport", "shading", "write")

#: Random seeds: Mitsuba's are unsigned 32-bit integers.
SEED = click.IntRange(0, 2**32 - 1)


def output_stem(output):
    """``OUT`` from ``OUT``, ``OUT.exr`` or ``OUT.png``: the stem both images share."""
    path = Path(output)
    return path.with_suffix("") if path.suffix.lower() in (".exr", ".png") else path


def scene_source_options(func):
    """The options that say what to render: a scene file, or ``--mesh/--material/--size-mm`` (shared by commands)."""
    options = [
        click.argument("scene_file", required=False, type=click.Path(dir_okay=False)),
        click.option("--mesh", type=click.Path(dir_okay=False),
                     help="Without a scene file: a mesh (.obj, .ply, .serialized, y up) framed with a camera, a key "
                          "light and a back light. 'bunny' is the bundled Stanford bunny."),
        click.option("--material", help="With --mesh: a preset name (see `convsss materials`), e.g. wholemilk."),
        click.option("--size-mm", type=float, help="With --mesh: the object's largest side in mm."),
        click.option("--floor", is_flag=True, help="With --mesh: add a grey floor under the object."),
        click.option("--boundary", type=click.Choice(["dielectric", "roughdielectric", "null"]), default="dielectric",
                     show_default=True,
                     help="With --mesh: the object's surface: a smooth or rough dielectric with the material's index "
                          "of refraction, or index-matched (null)."),
        click.option("--width", type=int, help="Film width in pixels (default: the scene's; 800 with --mesh)."),
        click.option("--height", type=int, help="Film height in pixels (default: the scene's; 800 with --mesh)."),
        click.option("--spp", type=int, help="Samples per pixel (default: the scene's sampler; 16 with --mesh)."),
        click.option("--seed", type=SEED, default=0, show_default=True,
                     help="Random seed, 0 to 2^32 - 1: the same seed gives the same image."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def source_inputs(scene_file, mesh):
    """The files the scene-source options read: the scene file and every file it names, or the mesh."""
    from ..scene.loading import scene_inputs
    from ..scene.quick import demo_mesh

    inputs = scene_inputs(scene_file) if scene_file else []
    if mesh:
        inputs.append(demo_mesh() if mesh == "bunny" else Path(mesh))
    return inputs


def _check_tonemap_option(ctx, param, value):
    check_tonemap(**{param.name: value})
    return value


def tonemap_options(func):
    """``--tonemap``, ``--key`` and ``--exposure`` for the PNG (shared by commands); bad values fail at once."""
    options = [
        click.option("--tonemap", type=click.Choice(TONEMAPS), default="reinhard", show_default=True,
                     help="PNG tone mapping: Reinhard's photographic operator, exposure only, or none (clipped)."),
        click.option("--key", type=float, default=0.18, show_default=True, callback=_check_tonemap_option,
                     help="Key value of the Reinhard operator (> 0)."),
        click.option("--exposure", type=float, default=0.0, show_default=True, callback=_check_tonemap_option,
                     help="Exposure in stops, applied before tone mapping."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def load_source(scene_file, mesh, material, size_mm, floor, boundary, width, height):
    """The loaded scene for the scene-source options; one-line errors for bad combinations."""
    from ..materials import OpticallyThinWarning
    from ..materials import material as lookup_material
    from ..scene.loading import load_scene

    if scene_file and (mesh or material or size_mm is not None):
        raise ConvsssError("give a scene file or --mesh/--material/--size-mm, not both")
    if scene_file:
        return load_scene(scene_file, width, height)
    if not (mesh and material and size_mm is not None):
        raise ConvsssError("nothing to render: give a scene file, or all of --mesh, --material and --size-mm")
    from ..scene.quick import demo_mesh, quick_scene

    mesh_path = demo_mesh() if mesh == "bunny" else Path(mesh)
    with warnings.catch_warnings():  # the scene's object says it once, by its own name
        warnings.simplefilter("ignore", OpticallyThinWarning)
        preset = lookup_material(material)
    scene = quick_scene(mesh_path, preset, size_mm, width or 800, height or 800, floor=floor,
                        boundary=boundary)
    return load_scene(scene)


def integrator_options(func):
    """Options mirroring the integrator's parameters; unset ones keep the scene's (or the defaults)."""
    from ..scene.params import SPECULARS
    from ..transport.convolution import CORRECTIONS, DOWNSAMPLES, SPLATS

    options = [
        click.option("--layers", type=int, help="Layers parallel to the image plane (paper §4). [default: 8]"),
        click.option("--threshold", type=float,
                     help="Skip layer pairs whose profile is below this fraction of R_d(0) (paper Eq. 8). "
                          "[default: 0.001]"),
        click.option("--downsample", type=click.Choice([str(d).rstrip("0").rstrip(".") for d in DOWNSAMPLES]),
                     help="Layer resolution relative to the image (paper §5). [default: 1]"),
        click.option("--transport", type=click.Choice(["convolution", "exact", "hierarchical"]),
                     help="convolution: the paper's layered FFTs; exact: the direct sum (slow, a reference); "
                          "hierarchical: Jensen & Buhler 2002. [default: convolution]"),
        click.option("--splat", type=click.Choice(SPLATS),
                     help="Irradiance into the two nearest layers: by depth (linear) or half and half (the paper). "
                          "[default: linear]"),
        click.option("--correction", type=click.Choice(CORRECTIONS),
                     help="plane: correct the layers' depth discretization with their exact response to the "
                          "surface's tangent plane (beyond the paper); none: the paper's method as published. "
                          "[default: plane]"),
        click.option("--irradiance-samples", type=int,
                     help="Directions per surface point for area and environment lights. [default: 16]"),
        click.option("--sample-density", type=float, help="Surface samples per layer cell. [default: 4]"),
        click.option("--specular", type=click.Choice(SPECULARS),
                     help="Boundary reflection: the scene's BSDF, the paper's Phong lobe, or none. "
                          "[default: bsdf; phong with --mesh]"),
        click.option("--phong-exponent", type=float, help="Phong exponent for --specular phong. [default: 64]"),
        click.option("--max-depth", type=int,
                     help="Longest path (Mitsuba's convention, -1: unbounded). [default: 6]"),
        click.option("--unit-mm", type=float, help="mm per scene unit. [default: 1]"),
        click.option("--profile", "profile_csv", type=click.Path(dir_okay=False),
                     help="CSV with columns r_mm,R,G,B: a user-defined radial profile replacing the dipole."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


INTEGRATOR_OPTIONS = {"layers": "layers", "threshold": "threshold", "downsample": "downsample",
                      "transport": "transport", "splat": "splat", "correction": "correction",
                      "irradiance_samples": "irradiance_samples",
                      "sample_density": "sample_density", "specular": "specular", "phong_exponent": "phong_exponent",
                      "max_depth": "max_depth", "unit_mm": "unit_mm", "profile_csv": "profile"}


def render_params(options, base=None):
    """:class:`RenderParams` from the command's options (only those given) over ``base`` (a dict)."""
    from ..scene.params import RenderParams

    values = dict(base or {})
    for option, name in INTEGRATOR_OPTIONS.items():
        if options.get(option) is not None:
            values[name] = float(options[option]) if option == "downsample" else options[option]
    return RenderParams(**values)


class StageProgress:
    """A tqdm bar over the render's stages (stderr); ``__call__(stage)`` moves it on."""

    def __init__(self, enabled=True):
        from tqdm import tqdm

        self.bar = tqdm(total=len(STAGES), desc="render", unit="stage", disable=not enabled, leave=True,
                        bar_format="{desc}: {n_fmt}/{total_fmt} stages |{bar:20}| {elapsed} {postfix}")
        self.done = set()

    def __call__(self, stage):
        self.bar.set_postfix_str(stage)
        if stage not in self.done:
            self.done.add(stage)
            self.bar.n = min(len(self.done), len(STAGES))
            self.bar.refresh()

    def close(self, failed=False):
        """Finish the bar: all stages done, or left where it stopped, marked ``failed``."""
        if not failed:
            self.bar.n = len(STAGES)
        self.bar.set_postfix_str("failed" if failed else "done")
        self.bar.close()


@cli.command()
@scene_source_options
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output stem: writes OUT.exr (linear) and OUT.png (tone-mapped).")
@integrator_options
@tonemap_options
@click.option("--stats", "stats_path", type=click.Path(dir_okay=False),
              help="Write a JSON file: parameters, per-stage seconds, grid and FFT shapes, pairs per layer, sample "
                   "count, and the object's size in mean free paths and diffusion lengths.")
@click.option("--progress/--no-progress", default=True, show_default=True, help="Show a progress bar on stderr.")
def render(scene_file, mesh, material, size_mm, floor, boundary, width, height, spp, seed, output, tonemap, key,
           exposure, stats_path, progress, **integrator):
    """Render SCENE_FILE (a Mitsuba 3 XML scene) with the convsss integrator, whatever integrator the file names.

    A translucent object is a shape with an interior 'homogeneous' medium and a null, dielectric or
    roughdielectric BSDF; scene units are mm unless --unit-mm says otherwise. Without a scene file,
    --mesh/--material/--size-mm build a scene around the mesh.

    \b
    Examples:
      convsss render scene.xml -o out/scene --spp 16 --stats out/scene.json
      convsss render --mesh bunny --material wholemilk --size-mm 40 --floor -o out/bunny
    """
    if spp is not None and spp < 1:
        raise ConvsssError(f"spp={spp} is not allowed: it must be >= 1")
    start = time.perf_counter()
    quick = scene_file is None
    defaults = {"specular": "phong"} if quick else {}
    render_params(integrator, defaults)  # bad values fail before anything is loaded
    profile = integrator["profile_csv"]
    if profile:
        from ..profiles import TabulatedProfile

        TabulatedProfile.from_csv(profile)
    stem = output_stem(output)
    exr, png = stem.with_suffix(".exr"), stem.with_suffix(".png")
    check_outputs([exr, png, *([stats_path] if stats_path else [])],
                  [*source_inputs(scene_file, mesh), *([profile] if profile else [])])

    from ..backend import load_mitsuba

    mi = load_mitsuba()
    seconds = {}
    bar = StageProgress(progress)
    try:
        bar("scene_load")
        t = time.perf_counter()
        scene = load_source(scene_file, mesh, material, size_mm, floor, boundary, width, height)
        base = dict(defaults)
        named = scene.integrator()
        if named is not None and named.class_name() == "ConvsssIntegrator":
            base = named.params.to_dict()
        params = render_params(integrator, base)
        seconds["scene_load"] = time.perf_counter() - t
        integ = mi.load_dict(params.integrator_dict())
        integ.progress = bar
        spp_used = spp if spp is not None else (16 if quick else scene.sensors()[0].sampler().sample_count())
        image = np.array(integ.render(scene, scene.sensors()[0], seed=seed, spp=spp_used), dtype=np.float64)[..., :3]
        seconds.update(integ.stats["seconds"])
        bar("write")
        t = time.perf_counter()
        from ..image import exr_writer, png_writer

        stats = {"command": "render", "scene": str(scene_file) if scene_file else None,
                 "quick": {"mesh": str(mesh), "material": material, "size_mm": size_mm, "floor": floor,
                           "boundary": boundary} if quick else None,
                 "seed": seed, "spp": spp_used, "outputs": {"exr": str(exr), "png": str(png)},
                 "tonemap": {"method": tonemap, "key": key, "exposure": exposure},
                 **integ.stats, "seconds": seconds}

        def finish(tmp=None):
            """Time the writes and the whole run; with ``tmp``, save the stats there (the last file written)."""
            seconds.setdefault("write", time.perf_counter() - t)
            seconds.setdefault("total", time.perf_counter() - start)
            if tmp is not None:
                Path(tmp).write_text(json.dumps(json_ready(stats), indent=1))

        writers = {exr: exr_writer(image), png: png_writer(image, tonemap, key, exposure)}
        if stats_path:
            writers[stats_path] = finish
        write_files(writers)
        finish()
    except BaseException:
        bar.close(failed=True)
        raise
    bar.close()
    click.echo(f"wrote {exr} and {png} ({seconds['total']:.1f} s)")
