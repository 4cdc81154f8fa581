"""``convsss profile``: the diffusion profile models, plotted (``plot``) and checked against a path-traced slab
(``validate``)."""

import contextlib
import json
import time
import warnings
from pathlib import Path

import click

from ..errors import ConvsssError
from ..files import check_outputs, json_ready, text_writer, write_files
from ..materials import DEFAULT_ETA
from ..scene.source import parse_triple
from .main import cli
from .options import COLOR_MODEL, MODEL_NAMES, PROGRESS

MODEL_CHOICE = click.Choice(MODEL_NAMES)


@cli.group()
def profile():
    """Diffusion profile models: plot them, and validate them against a path-traced semi-infinite slab."""


def _presets(names, every):
    from ..materials import OpticallyThinWarning, catalog, material

    with warnings.catch_warnings():  # thin channels are what the table reports
        warnings.simplefilter("ignore", OpticallyThinWarning)
        if every:
            if names:
                raise ConvsssError("give material names or --all, not both")
            return catalog()
        if not names:
            raise ConvsssError("nothing to validate: give material names (see `convsss materials`) or --all")
        return [material(n) for n in names]


@profile.command()
@click.argument("materials", nargs=-1)
@click.option("--all", "every", is_flag=True, help="Every preset of `convsss materials` (47).")
@click.option("--model", "models", type=MODEL_CHOICE, multiple=True,
              help="A model to compare (repeat for several). Default: all four.")
@click.option("--photons", type=click.IntRange(min=1000), default=1 << 19, show_default=True,
              help="Photons traced per channel into the slab (the noise of the total falls as 1/sqrt).")
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="Seed of the slab tally: the same seed gives the same numbers.")
@click.option("--plots/--no-plots", default=True, show_default=True,
              help="Write one PNG per material: r R(r) of the slab and every model on log axes, and the relative "
                   "error per channel.")
@click.option("-o", "--output", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Output folder: validate.md (the table), validate.json (every number), MATERIAL.png per "
                   "material; slab tallies cached in OUT/cache and reused by the next run.")
@click.option("--json", "as_json", is_flag=True, help="Print the summary per model as JSON instead of the table.")
@PROGRESS
def validate(materials, every, models, photons, seed, plots, output, as_json, progress):
    """Compare every profile model with a path-traced semi-infinite slab of each MATERIAL (preset names).

    The slab: the material's homogeneous medium (reduced coefficients, isotropic phase) under a smooth boundary of
    its eta, lit by a narrow beam at normal incidence, its radial exitance tallied by a light tracer of the same
    physics as Mitsuba's volpathmis (checked against volpathmis in the tests). R(r) and the total are in the
    normalization of paper Eq. 1 (exitance per transmitted flux over T_d(eta)). Printed per material and channel:
    the slab's total reflectance, the relative error of the exact half-space total (what every model is scaled to
    with profile_total exact, the render default) and each model's relative error of its own total and of the
    profile (mean over radii, weighted by energy).
    """
    from ..profiles.validate import EXACT, plot_validation, summary, validate_material, validation_table

    models = list(dict.fromkeys(models)) or ["dipole", "better-dipole", "pbd", "burley"]
    chosen = _presets(materials, every)
    table, report = output / "validate.md", output / "validate.json"
    pngs = {m.name: output / f"{m.name.lower().replace(' ', '_')}.png" for m in chosen} if plots else {}
    check_outputs([table, report, *pngs.values()])
    start = time.perf_counter()
    results = []
    bar = click.progressbar(chosen, label="slab tallies", file=click.get_text_stream("stderr")) if progress \
        else contextlib.nullcontext(chosen)
    with bar as items:
        for m in items:
            results.append(validate_material(m, models, photons, seed, cache=output / "cache"))
    stats = summary(results, models)
    text = (f"# Profiles against a path-traced semi-infinite slab\n\n{photons} photons per channel, seed {seed}. "
            "Total error: model / slab - 1 of the total reflectance (exact: the exact half-space total, every model's "
            "under profile_total exact); profile error: mean |model / slab - 1| over "
            "radii, weighted by the slab's energy.\n\n" + validation_table(results, models))
    writers = {table: text_writer(text),
               report: text_writer(json.dumps(json_ready({"photons": photons, "seed": seed, "summary": stats,
                                                           "materials": [_compact(r) for r in results]}), indent=1))}
    for r in results:
        if r["name"] in pngs:
            writers[pngs[r["name"]]] = (lambda res: lambda tmp: plot_validation(res, tmp))(r)
    write_files(writers)
    if as_json:
        click.echo(json.dumps(stats, indent=1))
        return
    click.echo(validation_table(results, models), nl=False)
    click.echo(f"\nper model, channels with alpha' > 0.5 (|total error|: max, mean, within 2 %; profile error mean) "
               f"and the others (max, mean); {EXACT!r}: every model's total in renders (profile_total exact):")
    for m, s in stats.items():
        click.echo(f"  {m:<14} {_pct(s['thick_max'])} {_pct(s['thick_mean'])} {s['thick_within_2pct']:3d}/"
                   f"{s['thick_channels']:<3d} {_pct(s['thick_profile_error_mean'])}   |   "
                   f"{_pct(s['thin_max'])} {_pct(s['thin_mean'])} ({s['thin_channels']} channels)")
    click.echo(f"wrote {table}, {report}" + (f" and {len(pngs)} plots" if pngs else "") +
               f" ({time.perf_counter() - start:.0f} s)")


def _pct(value):
    return "    n/a" if value is None else f"{value:7.2%}"


def _compact(result):
    """A material's result for the JSON report: totals and errors, not the histograms."""
    return {"name": result["name"], "albedo_prime": result["albedo_prime"], "eta": result["eta"],
            "slab_total": result["slab"]["total"], "slab_total_stderr": result["slab"]["total_stderr"],
            "exact_total": result["exact"]["total"], "exact_total_error": result["exact"]["total_error"],
            "models": {m: {k: v for k, v in r.items() if k != "profile"} for m, r in result["models"].items()}}


@profile.command()
@click.argument("names", nargs=-1, required=True)
@click.option("--model", "models", type=MODEL_CHOICE, multiple=True,
              help="A model to draw for every preset (repeat for several). Default: all four. A CSV is drawn as "
                   "it is.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The PNG to write.")
def plot(names, models, output):
    """Plot r R_d(r) (log axes) of each NAME, a preset (see `convsss materials`) or a CSV file r_mm, R, G, B,
    for each model: one panel per NAME, one colour per channel, one line style per model; one PNG.
    """
    from ..materials import OpticallyThinWarning, material
    from ..profiles import TabulatedProfile
    from ..profiles.models import model_profile
    from ..profiles.plot import plot_profiles

    models = list(dict.fromkeys(models)) or ["dipole", "better-dipole", "pbd", "burley"]
    csvs = [Path(n) for n in names if n.lower().endswith(".csv")]
    check_outputs([output], csvs)
    panels = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OpticallyThinWarning)
        for name in names:
            if name.lower().endswith(".csv"):
                panels.append((Path(name).name, [("tabulated", TabulatedProfile.from_csv(name))]))
            else:
                m = material(name)
                panels.append((m.name, [(k, model_profile(k, m)) for k in models]))
    write_files({output: lambda tmp: plot_profiles(panels, tmp)})
    click.echo(f"wrote {output}")


@profile.command()
@click.option("--color", required=True, metavar="R,G,B",
              help="Total diffuse reflectance per channel (the surface colour, linear), e.g. 0.8,0.5,0.3.")
@click.option("--mfp-mm", required=True, metavar="D|R,G,B",
              help="Reduced mean free path 1/sigma_t' in mm, one number or one per channel.")
@click.option("--eta", type=float, default=DEFAULT_ETA, show_default=True, help="Relative index of refraction.")
@COLOR_MODEL
@click.option("--unit-mm", type=float, default=1.0, show_default=True,
              help="mm per scene unit, for the Mitsuba medium parameters.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of text.")
def invert(color, mfp_mm, eta, color_model, unit_mm, as_json):
    """A material from its colour and mean free path (pbrt's reflectance + mfp, Cycles' colour + radius): the
    sigma_s' and sigma_a (1/mm) whose total reflectance (--color-model's) is that colour, and the Mitsuba
    homogeneous medium (sigma_t, scale, albedo) that renders it.
    """
    from ..media.dicts import medium_parameters
    from ..profiles.models import DEFAULT_COLOR_MODEL, color_of, material_from_color

    model = color_model or DEFAULT_COLOR_MODEL
    m = material_from_color(parse_triple(color, "--color"), parse_triple(mfp_mm, "--mfp-mm"), eta, model)
    medium = medium_parameters(m, unit_mm)
    report = {"model": model, "eta": m.eta, "color": color_of(m, model),
              "sigma_s_prime": m.sigma_s_prime, "sigma_a": m.sigma_a, "albedo_prime": m.albedo_prime,
              "medium": medium}
    if as_json:
        click.echo(json.dumps(json_ready(report), indent=1))
        return

    def show(values):
        return ", ".join(f"{x:.6g}" for x in values)

    click.echo(f"{model} profile, eta {m.eta:g}: total reflectance {show(report['color'])}")
    click.echo(f"sigma_s' = {show(m.sigma_s_prime)} 1/mm")
    click.echo(f"sigma_a  = {show(m.sigma_a)} 1/mm")
    click.echo(f"Mitsuba homogeneous medium ({unit_mm:g} mm per unit): sigma_t = {show(medium['sigma_t'])}, "
               f"scale = {medium['scale']:.6g}, albedo = {show(medium['albedo'])}")
