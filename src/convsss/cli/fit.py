"""``convsss fit``: a translucent object's material from a target image (:mod:`convsss.fitting`)."""

import json
from pathlib import Path

import click
import numpy as np

from ..files import output_paths
from .main import cli
from .options import PROGRESS


@cli.command()
@click.argument("scene_file", type=click.Path(dir_okay=False))
@click.argument("target", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output stem: OUT.json (the material per channel with uncertainties, the fit's evaluations and "
                   "seconds), OUT-medium.xml (the material as Mitsuba media), OUT.exr/OUT.png (the fitted render), "
                   "OUT-residual.png and OUT-convergence.png.")
@click.option("--object", "object_id", metavar="ID",
              help="The translucent shape's id to fit (needed when the camera sees several).")
@click.option("--mask", type=click.Path(dir_okay=False),
              help="A PNG or EXR of the film's size: the pixels to match (nonzero). [default: where the camera "
                   "sees the object first]")
@click.option("--start", metavar="PRESET",
              help="Start from this preset's reduced albedo and mean free path (and its eta, with --fit-eta). "
                   "[default: the scene's material]")
@click.option("--fit-exposure", is_flag=True,
              help="Also fit one scale of the render: a photo of unknown exposure.")
@click.option("--fit-eta", is_flag=True,
              help="Also fit the boundary's relative index (one for every channel; a dielectric or roughdielectric "
                   "boundary). [default: eta as the scene has it]")
@click.option("--spp", type=click.IntRange(1), default=None,
              help="Samples per pixel of every evaluation's render. [default: 4; 16 where the fit walks (the default "
                   "render's random walk, on an object where diffusion fails)]")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="The renders' seed (the same for every evaluation, so the fit sees no noise between them).")
@click.option("--max-evaluations", type=click.IntRange(4), default=80, show_default=True,
              help="Evaluations of the least squares at most, each a render; each Jacobian adds a render per block of "
                   "variables and a fit that replans solves again, so the renders can exceed it (the JSON's "
                   "evaluations counts them).")
@click.option("--check", is_flag=True,
              help="Also write OUT-check.png: the fitted render beside the target, tone-mapped alike.")
@PROGRESS
def fit(scene_file, target, output, object_id, mask, start, fit_exposure, fit_eta, spp, seed, max_evaluations,
        check, progress):
    """Fit a translucent object's material so that SCENE_FILE renders like TARGET (a linear EXR of the film's
    size): per channel its reduced albedo and reduced mean free path (eta as the scene has it, unless --fit-eta).

    The scene is taken as given: its lights, geometry and camera are what the user modelled of the photo or the
    render TARGET is. The fit matches the object's pixels only (--mask, or where the camera sees it), with a loss
    robust to highlights; the uncertainties come from the fit's Jacobian (NaN or large where the image does not
    constrain a value, e.g. a mean free path much longer than the object).

    \b
    Example:
      convsss fit scene.xml photo.exr -o out/fitted --fit-exposure --check
    """
    from ..files import check_outputs, write_files
    from ..image import read_image

    stem_outputs = output_paths(output, ".json", "-medium.xml", ".exr", ".png", "-residual.png",
                                "-convergence.png", *(["-check.png"] if check else []))
    check_outputs(stem_outputs, [scene_file, target, *([mask] if mask else [])])
    goal = read_image(target)
    weights = None
    if mask:
        weights = np.any(read_image(mask) > 0, axis=-1)
    from ..backend import load_mitsuba
    from ..fitting import fit as run_fit
    from ..fitting import material_of
    from ..materials import material as preset
    from ..pipeline.integrator import register
    from ..scene.loading import load_scene, scene_inputs

    register()
    load_mitsuba()
    check_outputs(stem_outputs, scene_inputs(scene_file))
    scene = load_scene(scene_file)
    first = None
    if start:
        found = preset(start, warn=False)
        first = material_of(found.albedo_prime, found.mfp_mm, found.eta, found.name)

    def report(evaluation, cost):
        if progress:
            click.echo(f"fit: evaluation {evaluation}, cost {cost:.5g}", err=True)

    result = run_fit(scene, goal, object_id, weights, first, fit_exposure=fit_exposure,
                     fit_eta=fit_eta, seed=seed, spp=spp, max_evaluations=max_evaluations, progress=report)
    _write(result, goal, stem_outputs, check, write_files)
    a, m = result.reduced_albedo, result.mfp_mm
    click.echo(f"fitted reduced albedo {np.round(a, 4).tolist()}, mean free path {np.round(m, 4).tolist()} mm "
               f"({result.evaluations} renders, {result.seconds:.1f} s); wrote {stem_outputs[0]}")


def _write(result, goal, paths, check, write_files):
    """Every output of the fit, written together or not at all."""
    from ..compare import error_image, tonemap_pair
    from ..image import display_png_writer, exr_writer, png_writer

    json_path, medium_path, exr, png, residual, convergence, *rest = paths
    record = {**result.to_dict(), "object_pixels": int(result.mask.sum())}
    medium = _medium_xml(result.material)

    def plot(tmp):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        figure, ax = plt.subplots(figsize=(5, 3.2), dpi=100)
        ax.semilogy(np.arange(1, len(result.history) + 1), np.maximum(result.history, 1e-30), marker=".")
        ax.set_xlabel("evaluation (residual calls)")
        ax.set_ylabel("cost (robust, relative)")
        ax.set_title("convsss fit: convergence")
        figure.tight_layout()
        figure.savefig(tmp, format="png")
        plt.close(figure)

    writers = {json_path: lambda tmp: Path(tmp).write_text(json.dumps(record, indent=1)),
               medium_path: lambda tmp: Path(tmp).write_text(medium),
               exr: exr_writer(result.render), png: png_writer(result.render),
               residual: png_writer(error_image(goal, result.render, mask=result.mask, limit=0.2), method="none"),
               convergence: plot}
    if check:
        target_shown, fitted_shown = tonemap_pair(goal, result.render, result.mask)
        shown = np.concatenate([target_shown, fitted_shown], axis=1)  # sRGB in [0, 1]
        writers[rest[0]] = display_png_writer(np.round(np.clip(shown, 0.0, 1.0) * 255.0))
    write_files(writers)


def _medium_xml(material):
    """The fitted material as Mitsuba media: a ``homogeneous`` medium (per mm; scale by your scene's unit) and the
    same as a ``convsss_medium`` by its colour (the exact total reflectance) and mean free path."""
    from ..profiles.models import color_of

    sigma_t = material.sigma_t_prime
    scale = float(np.max(sigma_t))
    rgb = ", ".join(f"{v:.6g}" for v in sigma_t / scale)
    albedo = ", ".join(f"{v:.6g}" for v in material.albedo_prime)
    color = ", ".join(f"{v:.6g}" for v in color_of(material, "exact"))
    mfp = ", ".join(f"{v:.6g}" for v in material.mfp_mm)
    return (f"<!-- convsss fit: reduced coefficients per mm (isotropic phase); scale by mm per scene unit -->\n"
            f'<medium type="homogeneous" id="fitted">\n'
            f'    <rgb name="sigma_t" value="{rgb}"/>\n    <float name="scale" value="{scale:.6g}"/>\n'
            f'    <rgb name="albedo" value="{albedo}"/>\n</medium>\n'
            f'<medium type="convsss_medium" id="fitted_by_colour">\n'
            f'    <rgb name="color" value="{color}"/>\n    <rgb name="mfp_mm" value="{mfp}"/>\n'
            f'    <float name="eta" value="{material.eta:.6g}"/>\n</medium>\n')
