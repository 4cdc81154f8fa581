"""``convsss bench``: benchmarks that print tables (never part of the tests' pass/fail)."""

import json
from pathlib import Path

import click

from ..bench.fit import CASES as FIT_CASES
from ..bench.scenes import REFERENCE_POINTS, SCENES
from .main import cli
from .options import PROGRESS

#: ``bench walk``'s scenes (the keys of :data:`convsss.bench.walk.WALK_SCENES`, named here so that the command line
#: does not import that module): ``bench walk`` and ``bench cost`` take them.
WALK_SCENE_NAMES = ("skin40-back", "armadillo30-area", "milk4", "ketchup20", "marble40-area", "dragon40-sun",
                    "lucy40-side", "potato40-env", "potato40-map", "marble40+skin10")

#: The objects' profile in a benchmark: the integrator's ``profile`` parameter (checked as a render checks it).
PROFILE = click.option("--profile", default="", metavar="SPEC",
                       help="The object's diffusion profile, as the integrator's profile parameter: a model (dipole, "
                            "better-dipole, pbd, burley) or a CSV file r_mm, R, G, B. [default: the renderer's]")


@cli.group()
def bench():
    """Benchmarks: medians of several runs per stage, with ratios measured in the same run."""


@bench.command("transport")
@click.option("--quick", is_flag=True,
              help="One configuration (512² grid, 8 layers, t = 0.1 %), 3 runs.")
@click.option("--runs", type=click.IntRange(1), default=None,
              help="Runs per configuration (default 5; 3 with --quick).")
@click.option("--json", "as_json", is_flag=True,
              help="Print the rows as a JSON list with the keys grid, layers, threshold, stage_median_s, fft_floor_s, "
                   "ratio (and fft_shape, pairs_per_layer, samples).")
@PROGRESS
def bench_transport_command(quick, runs, as_json, progress):
    """Layered convolution transport per stage against the bare FFT floor.

    Grids of 256², 512² and 1024² cells across a lit wholemilk sphere, 4 / 8 / 16 layers, thresholds 0 and 0.1 %.
    Stages: splat, kernels (cold, then cached), forward FFT, mixing, inverse FFT, lookup. The floor is the same
    count and size of rfft2/irfft2 alone; ratio = cached-kernel total / floor.
    """
    from ..bench.transport import bench_transport, transport_table

    if quick:
        rows = bench_transport(grids=(512,), layer_counts=(8,), thresholds=(0.001,), runs=runs or 3,
                               progress=progress)
    else:
        rows = bench_transport(runs=runs or 5, progress=progress)
    click.echo(json.dumps(rows, indent=1) if as_json else transport_table(rows))


@bench.command("render")
@click.option("--quick", is_flag=True, help="256² at 1 and 4 spp, 3 runs, no command lines.")
@click.option("--runs", type=click.IntRange(1), default=None,
              help="Timed renders per configuration and integrator, after one warm-up (default 5; 3 with --quick).")
@click.option("--commands/--no-commands", default=None,
              help="Also time whole command lines in fresh processes: convsss --version, the demo at 64² and at "
                   "800², 1 spp. [default: on; off with --quick]")
@click.option("--scaling", is_flag=True,
              help="Instead: whole render commands in fresh processes (warm caches), 4 spp, against the image size "
                   "(the demo at 64² to 1600²) and the object's size in mean free paths (10 to 10 000, the bunny "
                   "at 256²), per stage, with their peak memory; --runs per configuration (default 3).")
@click.option("--json", "as_json", is_flag=True,
              help="Print {rows, commands} as JSON: per row width, spp, stages_s, convsss_s, path_s, shading_ratio, "
                   "total_ratio, screen_queries, exitance_lookups (with --scaling: {scaling} rows of axis, value, "
                   "seconds, stages_s, peak_bytes, samples, pixels).")
@PROGRESS
def bench_render_command(quick, runs, commands, scaling, as_json, progress):
    """The demo scene rendered per stage beside Mitsuba's path integrator on the same scene.

    The demo of `make demo` (40 mm wholemilk bunny, dielectric boundary, floor, key and back light) at 256², 512²
    and 800², 1, 4 and 16 spp, in one process: after a warm-up render of each, medians of --runs renders of each
    (alternating) of every convsss stage, of its whole render and of Mitsuba's path. The headline is shading / path
    at equal spp.
    """
    from ..bench.render import bench_commands, bench_render, bench_scaling, render_table, scaling_table

    if scaling:
        rows = bench_scaling(runs=runs or 3, progress=progress)
        click.echo(json.dumps({"scaling": rows}, indent=1) if as_json else scaling_table(rows))
        return
    if quick:
        rows = bench_render(resolutions=(256,), spps=(1, 4), runs=runs or 3, progress=progress)
    else:
        rows = bench_render(runs=runs or 5, progress=progress)
    timed = bench_commands(runs=runs or 5, progress=progress) if (commands if commands is not None else not quick) \
        else {}
    click.echo(json.dumps({"rows": rows, "commands": timed}, indent=1) if as_json else render_table(rows, timed))


@bench.command("noise")
@click.option("--width", type=click.IntRange(16, 4096), default=128, show_default=True,
              help="Image width and height (square).")
@click.option("--spp", type=click.IntRange(1), default=4, show_default=True,
              help="Samples per pixel of each pass (a render of k passes has k times as many).")
@click.option("--passes", "passes", default="1,2,4,8", show_default=True,
              help="Pass counts, comma-separated, increasing.")
@click.option("--walk-depth", type=click.FloatRange(0.0), default=0.0, show_default=True,
              help="The renders' walk_depth (transport mean free paths; 0: the transport alone, inf: every walk to "
                   "its end): the random walk's noise against passes.")
@click.option("--json", "as_json", is_flag=True,
              help="Print the rows as JSON: passes, spp, samples, pixels, seconds, median, p95, rms, "
                   "median_sqrt_passes.")
@PROGRESS
def bench_noise_command(width, spp, passes, walk_depth, as_json, progress):
    """The image's sample noise against passes: it should fall as 1/sqrt(passes).

    The demo scene (40 mm whole-milk bunny, dielectric, floor, two lights), rendered in k passes of a default
    render's budget each (sample density, profile samples and --spp times k), twice with different seeds. Per object
    pixel and channel, the noise is |a - b| / sqrt(2) relative to the pair's mean; printed are its median, 95th
    percentile and root mean square over the object and the median x sqrt(k), constant where the noise falls as it
    should. At --passes 1 and the demo's size (--width 800 --spp 16), the demo's own noise. With --walk-depth, the
    noise of the random walk's render.
    """
    from ..bench.noise import bench_noise, noise_table
    from ..errors import ConvsssError

    try:
        counts = tuple(int(v) for v in passes.split(","))
    except ValueError:
        raise ConvsssError(f"--passes {passes!r}: give whole numbers of passes, e.g. 1,2,4") from None
    if not counts or any(v < 1 for v in counts) or list(counts) != sorted(set(counts)):
        raise ConvsssError(f"--passes {passes!r}: give increasing whole numbers >= 1")
    rows = bench_noise(width, spp, counts, progress, walk_depth)
    click.echo(json.dumps(rows, indent=1) if as_json else noise_table(rows, width, walk_depth))


@bench.command("fit")
@click.option("--case", "cases", multiple=True,
              type=click.Choice([c[0] for c in FIT_CASES]),
              help="A case (repeat for several) [default: all]: the 20 mm bunny in whole milk, marble, skin1, "
                   "ketchup, potato, an orange colour (0.7, 0.5, 0.3) at 1.5 mm and a jade one (0.4, 0.6, 0.8) at "
                   "4 mm, under two point lights (NAME) or a constant environment (NAME-env).")
@click.option("--width", type=click.IntRange(16, 4096), default=128, show_default=True,
              help="Image width and height (square).")
@click.option("--reference-spp", type=click.IntRange(1), default=1024, show_default=True,
              help="Samples per pixel of the two volpathmis references (seeds 1 and 2).")
@click.option("--json", "as_json", is_flag=True, help="Print the rows as JSON.")
@PROGRESS
def bench_fit_command(cases, width, reference_spp, as_json, progress):
    """Materials from images on ground truth: convsss fit of volpathmis renders of known materials.

    Per case, two references (their difference is the reference's noise) and a fit of the first from reduced
    albedo x 0.7 and mean free path x 3; printed: truth, fitted and their errors per channel, the renders and
    seconds of the fit, the fitted render's mean against the target's and the true material's (convsss's bias).
    """
    from ..bench.fit import bench_fit, fit_table

    chosen = tuple(c for c in FIT_CASES if not cases or c[0] in cases)
    rows = bench_fit(chosen, width, reference_spp, progress=progress)
    click.echo(json.dumps(rows, indent=1) if as_json else fit_table(rows))


@bench.command("media")
@click.option("--scene", "scenes", multiple=True,
              type=click.Choice(["veins-block", "veins-bunny", "milk-skin-sphere", "skin-over-milk",
                                 "textured-bunny", "constant-block"]),
              help="A scene (repeat for several) [default: all]: a marble block and a 20 mm marble bunny with dark "
                   "gridvolume veins, a 20 mm sphere fading from whole milk to skin1, a sphere of 1.5 mm of skin1 "
                   "over whole milk, a 20 mm bunny painted with a colour map (convsss_medium), and the block with "
                   "a constant albedo volume (against the homogeneous block, pixel for pixel).")
@click.option("--width", type=click.IntRange(16, 4096), default=128, show_default=True,
              help="Image width and height (square).")
@click.option("--reference-spp", type=click.IntRange(1), default=512, show_default=True,
              help="Samples per pixel of the two volpathmis references (seeds 1 and 2).")
@click.option("--runs", type=click.IntRange(1), default=3, show_default=True,
              help="Fresh render commands per scene and per homogeneous twin (the medians are reported).")
@click.option("--folder", type=click.Path(file_okay=False),
              help="Keep the scenes, volumes, renders and references here; references already there at the same "
                   "spp and size are reused. [default: a temporary folder]")
@click.option("--json", "as_json", is_flag=True, help="Print {meta, rows} as JSON instead of the table.")
@PROGRESS
def bench_media_command(scenes, width, reference_spp, runs, folder, as_json, progress):
    """Heterogeneous interiors against path tracing, and their cost against the homogeneous object.

    Per scene, as commands in fresh processes on one scene file: two volpathmis references, and convsss render of
    the scene and of its homogeneous twin (same object, one homogeneous medium), --runs times each. Printed per
    scene: the classes and samples, the medians and their ratio, per channel the ratio of the object's mean to the
    reference's, the mean relative error beside the second reference's (the reference's own noise), and the
    relative MSE less the reference's noise beside that noise.
    """
    from ..bench.media import MEDIA_SCENES, bench_media, media_table

    result = bench_media(scenes or MEDIA_SCENES, width, reference_spp, runs, folder, progress)
    click.echo(json.dumps(result, indent=1) if as_json else media_table(result))


@bench.command("volpath")
@click.option("--scene", "scenes", multiple=True, type=click.Choice(["milk40", "marble40", "skin40", "ketchup40",
                                                                      "milk40-area"]),
              help="A scene (repeat for several) [default: all]: the 40 mm bunny in whole milk, marble, skin1 and "
                   "ketchup under the key and back point lights (null boundary), and in whole milk behind a smooth "
                   "dielectric under an area light and a dim environment (milk40-area).")
@click.option("--width", "widths", multiple=True, type=click.IntRange(16, 4096),
              help="Image width and height (square; repeat for several) [default: 128].")
@click.option("--reference-spp", type=click.IntRange(1), default=1024, show_default=True,
              help="Samples per pixel of the two references (seeds 1 and 2).")
@click.option("--ladder", default="4,16,64,256", show_default=True,
              help="Samples per pixel of the path tracer's runs, comma-separated, increasing.")
@click.option("--walk-depth", type=click.FloatRange(0.0, min_open=True), default=None,
              help="Also render with the random walk ended at this depth (transport mean free paths; inf: walks to "
                   "their end) at each spp of --ladder, and print per rung the time the walk needs to reach "
                   "volpathmis's error there, over volpathmis's time, with the scattering events per camera path "
                   "beside a walk's to its end. [default: the default render only]")
@click.option("-o", "--output", "out_file", type=click.Path(dir_okay=False),
              help="Also write the result as JSON to this file.")
@click.option("--json", "as_json", is_flag=True, help="Print {meta, rows} as JSON instead of the table.")
@PROGRESS
def bench_volpath_command(scenes, widths, reference_spp, ladder, walk_depth, out_file, as_json, progress):
    """Equal error against path tracing: the time volpathmis needs to reach a default convsss render's error.

    Per scene and size, all as commands in fresh processes on one scene file: two references (convsss reference,
    seeds 1 and 2; half their relative MSE is the reference's own noise), convsss render with its defaults, and
    convsss reference at each spp of --ladder. Errors are the relative MSE over the object's pixels (convsss's mask
    AOV), the reference's noise subtracted; volpathmis's time at convsss's error is interpolated on the ladder
    (log-log; beyond its ends, slope -1). Prints per row the errors and seconds and the speed-up at equal error.
    With --walk-depth, the walk's own ladder and, per volpathmis rung, the walk's time to the same error.
    """
    from ..bench.volpath import VOLPATH_SCENES, bench_volpath, volpath_table
    from ..errors import ConvsssError

    try:
        spps = tuple(int(v) for v in ladder.split(","))
    except ValueError:
        raise ConvsssError(f"--ladder {ladder!r}: give whole numbers of samples per pixel, e.g. 4,16,64") from None
    if len(spps) < 2 or any(v < 1 for v in spps) or list(spps) != sorted(set(spps)):
        raise ConvsssError(f"--ladder {ladder!r}: give at least two increasing whole numbers >= 1")
    result = bench_volpath(scenes or tuple(VOLPATH_SCENES), widths or (128,), reference_spp, spps, progress,
                           walk_depth)
    if out_file:
        from ..files import atomic_write

        atomic_write(out_file, lambda tmp: Path(tmp).write_text(json.dumps(result, indent=1)))
    click.echo(json.dumps(result, indent=1) if as_json else volpath_table(result))


@bench.command("walk")
@click.option("--scene", "scenes", multiple=True,
              type=click.Choice(WALK_SCENE_NAMES),
              help="A scene (repeat for several) [default: all]: the 40 mm skin1 bunny lit from behind, a 30 mm skin1 "
                   "armadillo behind a smooth dielectric under an area light, a 4 mm whole-milk bunny, a 20 mm "
                   "ketchup bunny (null boundary, the key and back lights), a 40 mm marble bunny behind a "
                   "dielectric under an area light, a 40 mm skim-milk dragon behind a rough dielectric under a sun "
                   "and a sky, a 40 mm Lucy of a jade colour (0.4, 0.6, 0.8 at 4 mm) behind glass under a side "
                   "light, a 40 mm potato bunny behind a dielectric under an environment, the same under an "
                   "environment map with a small sun, and the marble bunny with a 10 mm skin1 sphere before it (auto "
                   "renders each its own way).")
@click.option("--width", type=click.IntRange(16, 4096), default=64, show_default=True,
              help="Image width and height (square).")
@click.option("--spp", type=click.IntRange(1), default=64, show_default=True,
              help="Samples per pixel of the walks and of volpathmis beside them.")
@click.option("--reference-spp", type=click.IntRange(1), default=1024, show_default=True,
              help="Samples per pixel of the two references (seeds 1 and 2).")
@click.option("--depths", default="0,2,4,8,16,inf", show_default=True,
              help="The walk depths, comma-separated (transport mean free paths; 0: the transport alone, inf: "
                   "every walk to its end, auto: what the default render chooses, shown as auto=0 or auto=inf).")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False),
              help="Also draw bias and seconds against the depth, a line per scene, to this PNG.")
@click.option("-o", "--output", "out_file", type=click.Path(dir_okay=False),
              help="Also write the result as JSON to this file.")
@click.option("--json", "as_json", is_flag=True, help="Print {meta, scenes} as JSON instead of the table.")
@PROGRESS
def bench_walk_command(scenes, width, spp, reference_spp, depths, plot_path, out_file, as_json, progress):
    """How deep a walk should go: per scene, convsss render at each --depths (fresh processes), against two
    volpathmis references, with volpathmis at the same spp beside them.

    Prints per scene and depth the mean over the object against the reference per channel (the references' own
    ratio on the first line), the relative MSE less the reference's noise, the command's seconds, the walk's mean
    scattering events per path and the share of paths ended in the diffusion field.
    """
    import math

    from ..bench.walk import WALK_SCENES, bench_walk, walk_plot, walk_table
    from ..errors import ConvsssError

    bad = ConvsssError(f"--depths {depths!r}: give numbers >= 0, inf or auto, e.g. 0,4,inf,auto")
    try:
        values = tuple(v.strip() if v.strip() == "auto" else float(v) for v in depths.split(","))
    except ValueError:
        raise bad from None
    if not values or any(v != "auto" and (math.isnan(v) or v < 0) for v in values):
        raise bad
    result = bench_walk(scenes or tuple(WALK_SCENES), width, spp, reference_spp, values, progress)
    if out_file:
        from ..files import atomic_write

        atomic_write(out_file, lambda tmp: Path(tmp).write_text(json.dumps(result, indent=1, default=str)))
    if plot_path:
        walk_plot(result, plot_path)
    click.echo(json.dumps(result, indent=1, default=str) if as_json else walk_table(result))


@bench.command("cost")
@click.option("--scene", "scenes", multiple=True,
              type=click.Choice(WALK_SCENE_NAMES),
              help="A scene of bench walk (repeat for several) [default: milk4, skin40-back, ketchup20, "
                   "armadillo30-area].")
@click.option("--width", type=click.IntRange(16, 4096), default=192, show_default=True,
              help="Image width and height (square).")
@click.option("--spp", type=click.IntRange(1), default=64, show_default=True, help="Samples per pixel.")
@click.option("--runs", type=click.IntRange(1), default=3, show_default=True,
              help="Timed runs of each render and command (after one untimed run each); their median is shown.")
@click.option("--commands/--no-commands", default=True, show_default=True,
              help="Also time the whole commands in fresh processes (convsss render at inf and auto, mitsuba).")
@click.option("-o", "--output", "out_file", type=click.Path(dir_okay=False),
              help="Also write the result as JSON to this file.")
@click.option("--json", "as_json", is_flag=True, help="Print {meta, rows} as JSON instead of the table.")
@PROGRESS
def bench_cost_command(scenes, width, spp, runs, commands, out_file, as_json, progress):
    """What a sample and a command cost where the render walks: convsss at walk_depth inf (volpathmis's
    estimator) against volpathmis, warm in one process, with convsss's kernels and the time outside them; and the
    whole commands in fresh processes beside Mitsuba's own on the same scene file. Both renderers with their defaults
    (Russian roulette from depth 5), and both without roulette. Run it alone on the machine."""
    from ..bench.cost import bench_cost, cost_table

    chosen = scenes or ("milk4", "skin40-back", "ketchup20", "armadillo30-area")
    result = bench_cost(chosen, width, spp, runs, commands, progress)
    if out_file:
        from ..files import atomic_write

        atomic_write(out_file, lambda tmp: Path(tmp).write_text(json.dumps(result, indent=1)))
    click.echo(json.dumps(result, indent=1) if as_json else cost_table(result))


@bench.command("battery")
@click.option("--json", "as_json", is_flag=True, help="Print the rows as JSON instead of the table.")
@PROGRESS
def bench_battery_command(as_json, progress):
    """The reliability battery's render matrix: every emitter type x boundary x transport on a tiny scene (a 1 mm
    whole-milk sphere above a floor, 16x16, 1 spp), each ending in a finite, non-negative image with the sphere lit.
    Prints a Markdown table and the count of cases that ended well; exits 1 when one did not."""
    from tqdm import tqdm

    from ..bench.battery import battery_table, bench_battery, matrix

    with tqdm(total=len(matrix()), desc="bench battery", unit="case", disable=not progress) as bar:
        rows = bench_battery(bar=bar)
    click.echo(json.dumps([{**row.__dict__, "ok": row.ok} for row in rows], indent=1) if as_json
               else battery_table(rows))
    if not all(row.ok for row in rows):
        raise SystemExit(1)


@bench.command("lights")
@click.option("--material", "materials", multiple=True, type=click.Choice(["ketchup", "skin1", "potato", "marble"]),
              help="A medium (repeat for several) [default: all]: low (ketchup), middle (skin1) and high albedo "
                   "(potato, marble).")
@click.option("--emitter", "emitters", multiple=True,
              type=click.Choice(["point", "spot", "directional", "area", "constant", "envmap"]),
              help="A Mitsuba emitter type (repeat for several) [default: all]; behind a dielectric only area, "
                   "constant and envmap (a path tracer cannot reach the others through it).")
@click.option("--boundary", "boundaries", multiple=True, type=click.Choice(["null", "dielectric"]),
              help="The sphere's boundary (repeat for both) [default: both].")
@click.option("--radius-mm", type=click.FloatRange(0, min_open=True), default=100.0, show_default=True,
              help="The sphere's radius in mm.")
@click.option("--width", type=click.IntRange(8, 1024), default=32, show_default=True,
              help="Image width and height (square).")
@click.option("--spp", type=click.IntRange(1), default=64, show_default=True,
              help="convsss's samples per pixel, for each of its two seeds.")
@click.option("--reference-spp", type=click.IntRange(1), default=256, show_default=True,
              help="volpathmis's samples per pixel, for each of its two seeds.")
@click.option("--json", "as_json", is_flag=True, help="Print the rows as JSON instead of the table.")
@PROGRESS
def bench_lights_command(materials, emitters, boundaries, radius_mm, width, spp, reference_spp, as_json, progress):
    """Each light alone: convsss against volpathmis on a sphere, per medium, emitter type and boundary.

    Per case, the ratio per channel of convsss's mean over the sphere's pixels to volpathmis's, each the mean of two
    seeds (whose difference is its noise), all rendered in this process. Prints a Markdown table.
    """
    from tqdm import tqdm

    from ..bench.lights import BOUNDARIES, EMITTERS, MATERIALS, bench_lights, cases, lights_table

    chosen = (materials or MATERIALS, emitters or EMITTERS, boundaries or BOUNDARIES)
    with tqdm(total=len(cases(*chosen)), desc="bench lights", unit="case", disable=not progress) as bar:
        rows = bench_lights(*chosen, bar=bar, radius=radius_mm, resolution=width, spp=spp, reference_spp=reference_spp)
    click.echo(json.dumps([row.__dict__ for row in rows], indent=1) if as_json else lights_table(rows))


@bench.command("accuracy")
@click.option("--quick", is_flag=True,
              help="A tiny run: 96² image, the 4 mm and 40 mm bunnies, multiscale accuracy 0.01 and 0.1, layers 4 "
                   "and 8 (t = 0.1 %, as published and with the plane correction), epsilon 0.05, 0.5, 2.")
@click.option("--runs", type=click.IntRange(1), default=3, show_default=True,
              help="Timed runs per configuration (the median is reported).")
@click.option("--width", type=click.IntRange(16, 4096), default=None,
              help="Image width and height in pixels (square): the visible points are its pixel centres on the "
                   "object. [default: 800; 96 with --quick]")
@click.option("--scene", "scenes", multiple=True, type=click.Choice(list(SCENES)),
              help="A benchmark scene (repeat for several) [default: all; bunny4 and bunny40 with --quick]: "
                   + "; ".join(f"{name}: {s.size_mm:g} mm {s.material} {s.mesh}, {s.lighting}"
                               for name, s in SCENES.items()) + ".")
@click.option("--reference-points", type=click.IntRange(1), default=REFERENCE_POINTS, show_default=True,
              help="Visible points (a fixed random subset) at which the exact sum is the reference.")
@click.option("--sample-density", type=click.FloatRange(0, min_open=True), default=4.0, show_default=True,
              help="Surface samples per full-resolution pixel footprint (as the integrator's sample_density).")
@PROFILE
@click.option("-o", "--output", "out_dir", type=click.Path(file_okay=False),
              help="Write accuracy.png (Pareto plot), accuracy.json (rows, facts, headline) and accuracy.txt (table) "
                   "into this folder.")
@click.option("--json", "as_json", is_flag=True,
              help="Print {meta, rows, headline} as JSON instead of the table.")
@PROGRESS
def bench_accuracy_command(quick, runs, width, scenes, reference_points, sample_density, profile, out_dir, as_json,
                           progress):
    """Error against the exact sum versus wall time of every transport, at render scale.

    Every transport gets the same irradiance samples (prepared as a render does) and is queried at the same visible
    points (camera rays through the pixel centres: one query per visible pixel). Timed: constructing the transport
    and one exitance() call at all visible points (kernels cold), median of --runs. Error: of the exitance M
    against the exact direct sum at a fixed random subset of the points (computed once, then kept in
    ~/.cache/convsss/exact). Methods: multiscale (accuracy 0.003 to 0.1), the paper's layers 4/8/16 (t = 0.1 %) as
    published and with the plane correction, hierarchical (epsilon 0.02 to 2). Prints the table (* marks a method's
    Pareto front) and each method's time / hierarchical time at equal error.
    """
    from pathlib import Path

    from ..bench.accuracy import accuracy_plot, bench_accuracy, report_text
    from ..files import check_outputs, json_ready, text_writer, write_files
    from ..profiles.models import parse_profile_spec

    parse_profile_spec(profile)  # a bad profile fails before anything is loaded
    outputs = {suffix: Path(out_dir) / f"accuracy.{suffix}" for suffix in ("png", "json", "txt")} if out_dir else {}
    check_outputs(outputs.values())
    options = dict(runs=runs, sample_density=sample_density, reference_points=reference_points, progress=progress,
                   profile=profile or "")
    if quick:
        result = bench_accuracy(scenes=scenes or ("bunny4", "bunny40"), resolution=width or 96,
                                layer_counts=(4, 8), accuracies=(0.01, 0.1), epsilons=(0.05, 0.5, 2.0), **options)
    else:
        result = bench_accuracy(scenes=scenes or tuple(SCENES), resolution=width or 800, **options)
    result = json_ready(result)
    text = report_text(result)
    if outputs:
        data = json.dumps(result, indent=1)
        write_files({outputs["png"]: lambda tmp: accuracy_plot(result, tmp),
                     outputs["json"]: text_writer(data),
                     outputs["txt"]: text_writer(text + "\n")})
        result["meta"]["outputs"] = {suffix: str(path) for suffix, path in outputs.items()}
    click.echo(json.dumps(result, indent=1) if as_json else text)
