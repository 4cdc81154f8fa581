"""``convsss bench``: benchmarks that print tables (never part of the tests' pass/fail)."""

import json

import click

from .main import cli
from .options import PROGRESS


@cli.group()
def bench():
    """Benchmarks: medians of several runs per stage, with ratios measured in the same run."""


@bench.command("transport")
@click.option("--quick", is_flag=True,
              help="One configuration (512² grid, 8 layers, t = 0.1 %), 3 runs: about a minute.")
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


@bench.command("accuracy")
@click.option("--quick", is_flag=True,
              help="A tiny run: 96² image, layers 2 and 8, downsample 1 and 1/2, t = 0.1 %, each as published and "
                   "with the plane correction, epsilon 0.01, 0.1, 1, 5 (well under a minute).")
@click.option("--runs", type=click.IntRange(1), default=3, show_default=True,
              help="Timed runs per configuration (the median is reported).")
@click.option("--width", type=click.IntRange(16, 4096), default=None,
              help="Image width and height in pixels (square): the visible points are its pixel centres on the "
                   "object. [default: 256; 96 with --quick]")
@click.option("--size-mm", "size_mm", type=click.FloatRange(0, min_open=True), default=40.0, show_default=True,
              help="The bunny's largest side in mm.")
@click.option("--material", default="wholemilk", show_default=True, help="A preset name (see `convsss materials`).")
@click.option("--boundary", "scenes", type=click.Choice(["null", "dielectric", "both"]), default="both",
              show_default=True,
              help="null: index-matched boundary, two point lights; dielectric: smooth dielectric, area light and a "
                   "dim environment.")
@click.option("--sample-density", type=click.FloatRange(0, min_open=True), default=4.0, show_default=True,
              help="Surface samples per full-resolution pixel footprint (as the integrator's sample_density).")
@click.option("-o", "--output", "out_dir", type=click.Path(file_okay=False),
              help="Write accuracy.png (Pareto plot), accuracy.json (rows, facts, headline) and accuracy.txt (table) "
                   "into this folder.")
@click.option("--json", "as_json", is_flag=True,
              help="Print {meta, rows, headline} as JSON instead of the table.")
@PROGRESS
def bench_accuracy_command(quick, runs, width, size_mm, material, scenes, sample_density, out_dir, as_json, progress):
    """Error against the exact sum versus wall time: convolution and hierarchical transports on a bunny.

    Both transports get the same irradiance samples (prepared as a render does) and are queried at the same visible
    points (camera rays through the pixel centres); the error is the relative L2 error of the exitance M against
    the exact direct sum. Timed: constructing the transport and one exitance() call (kernels cold). Convolution:
    layers 2/4/8/16 x downsample 1, 1/2, 1/4 x threshold 0, 0.1 %, 5 %, as published and with the plane
    correction (beyond the paper); hierarchical: epsilon 0.01 to 5. Prints the table (* marks a method's Pareto
    front) and the time ratio convolution / hierarchical at equal error, for each convolution method.
    """
    from pathlib import Path

    from ..bench.accuracy import accuracy_plot, bench_accuracy, report_text
    from ..files import check_outputs, json_ready, text_writer, write_files
    from ..materials import material as lookup_material

    lookup_material(material)  # an unknown name fails before anything is loaded
    outputs = {suffix: Path(out_dir) / f"accuracy.{suffix}" for suffix in ("png", "json", "txt")} if out_dir else {}
    check_outputs(outputs.values())
    chosen = ("null", "dielectric") if scenes == "both" else (scenes,)
    options = dict(scenes=chosen, size_mm=size_mm, material=material, runs=runs, sample_density=sample_density,
                   progress=progress)
    if quick:
        result = bench_accuracy(resolution=width or 96, layer_counts=(2, 8), downsamples=(1.0, 0.5),
                                thresholds=(0.001,), epsilons=(0.01, 0.1, 1.0, 5.0), **options)
    else:
        result = bench_accuracy(resolution=width or 256, **options)
    result = json_ready(result)
    text = report_text(result)
    if outputs:
        data = json.dumps(result, indent=1)
        write_files({outputs["png"]: lambda tmp: accuracy_plot(result, tmp),
                     outputs["json"]: text_writer(data),
                     outputs["txt"]: text_writer(text + "\n")})
        result["meta"]["outputs"] = {suffix: str(path) for suffix, path in outputs.items()}
    click.echo(json.dumps(result, indent=1) if as_json else text)
