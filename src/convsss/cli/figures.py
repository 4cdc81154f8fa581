"""``convsss figures``: the paper's test cases (Figs. 2–6) regenerated, with contact sheets and one report."""

import time
from pathlib import Path

import click

from ..files import check_outputs
from .main import cli
from .options import PROGRESS, dask_options


@cli.command()
@click.option("--quick", is_flag=True,
              help="Everything small: 128x128 panels at 2 spp, short path-traced references.")
@click.option("--resolution", type=click.IntRange(16, 4096), metavar="N",
              help="Panel width and height in pixels. [default: 800; 128 with --quick] Errors are measured on the "
                   "panels themselves at N <= 256, else on 256x256 renders of the same panels.")
@click.option("--only", metavar="FIGS", help="Comma-separated figures to render, e.g. fig2,fig5 (or 2,5).")
@click.option("-o", "--output", "out_dir", type=click.Path(file_okay=False), default="out/figures", show_default=True,
              help="Output folder: one sub-folder per figure, report.md, figures.json; references cached in "
                   "OUT/cache and reused by the next run.")
@dask_options("the path-traced references, rendered first (the panels then render here one at a time: their "
              "seconds are part of the figures)", "none, all here")
@PROGRESS
def figures(quick, resolution, only, out_dir, workers, scheduler, progress):
    """Regenerate the paper's figures: per figure a contact sheet PNG (captions: parameters, seconds,
    convolutions per layer c, errors against the exact sum and volpathmis), the panels' EXRs, and one report.md.

    \b
    Fig. 2  threshold t = 0, 0.1 %, 5 % on a 40 mm and a 4 mm wholemilk bunny, 8 layers
    Fig. 3  layer resolution 1, 1/2, 1/4
    Fig. 4  material gallery (bunny, bust, dragon)
    Fig. 5  2, 4, 8, 16 layers, the hierarchical method, the exact sum and volpathmis
    Fig. 6  apple, marble, skin1: convolution, hierarchical, exact, volpathmis

    The full run renders 800x800 panels like the paper and measures errors on 256x256 renders of the same
    panels (the exact sum costs pixels x samples); it takes long, mostly for the references, which are cached.

    \b
    Examples:
      convsss figures --quick -o out/figures-quick
      convsss figures --only fig2,fig5
      convsss figures --workers 2                         # the references on two worker processes
    """
    from ..figures import FULL, QUICK, render_figures
    from ..figures.run import select

    names = select(only)
    if scheduler:
        from ..batch.runner import check_scheduler

        check_scheduler(scheduler)
    check_outputs([Path(out_dir) / "report.md", Path(out_dir) / "figures.json"])
    settings = QUICK if quick else FULL
    if resolution is not None:
        settings = settings.at(resolution)
    start = time.perf_counter()
    report, run = render_figures(names, settings, out_dir, progress, scheduler, workers)
    click.echo(f"wrote {report} ({len(names)} figures, {sum(len(f['panels']) for f in run['figures'])} panels, "
               f"{run['cache']['hits']} cached references reused, {time.perf_counter() - start:.0f} s)")
