"""``convsss bench``: benchmarks that print tables (never part of the tests' pass/fail)."""

import json

import click

from .main import cli


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
def bench_transport_command(quick, runs, as_json):
    """Layered convolution transport per stage against the bare FFT floor.

    Grids of 256², 512² and 1024² cells across a lit wholemilk sphere, 4 / 8 / 16 layers, thresholds 0 and 0.1 %.
    Stages: splat, kernels (cold, then cached), forward FFT, mixing, inverse FFT, lookup. The floor is the same
    count and size of rfft2/irfft2 alone; ratio = cached-kernel total / floor.
    """
    from ..bench.transport import bench_transport, transport_table

    if quick:
        rows = bench_transport(grids=(512,), layer_counts=(8,), thresholds=(0.001,), runs=runs or 3,
                               progress=not as_json)
    else:
        rows = bench_transport(runs=runs or 5, progress=not as_json)
    click.echo(json.dumps(rows, indent=1) if as_json else transport_table(rows))
