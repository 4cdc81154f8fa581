"""``convsss batch``: every job of a SPEC rendered on Dask distributed, resumable, with a manifest and a contact
sheet (:mod:`convsss.batch`)."""

import shlex
from pathlib import Path

import click

from .main import cli
from .options import PROGRESS, dask_options


@cli.command()
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", required=True, type=click.Path(file_okay=False),
              help="The batch's folder: jobs/ID/ per job (image.exr, image.png, stats.json, job.json), "
                   "manifest.json and manifest.csv, contact_sheet.png, turntable*.png.")
@dask_options("the jobs", "the machine's cores")
@click.option("--retries", type=click.IntRange(0), default=3, show_default=True,
              help="How many times a job whose worker dies (killed, out of memory) runs again elsewhere before it "
                   "is marked failed.")
@click.option("--max-jobs", type=click.IntRange(1), default=10_000, show_default=True,
              help="Refuse a SPEC that makes more jobs than this.")
@click.option("--dry-run", is_flag=True, help="Check the SPEC and list its jobs; run nothing.")
@PROGRESS
def batch(spec, out, workers, scheduler, retries, max_jobs, dry_run, progress):
    """Render every job of SPEC (TOML): a scene and the axes swept, each combination one job.

    \b
    SPEC:
      command = "render"        # or "reference"
      [scene]                   # the command's options (see its --help): file = "scene.xml", or
      mesh = "bunny"            #   mesh, material (or color, mfp_mm), size_mm, ...
      size_mm = 40
      width = 64
      height = 64
      [axes]                    # every combination of these is a job
      material = ["wholemilk", "marble"]
      orbit_deg = [0, 90, 180, 270]
    A value may be a table setting several options ({color = "0.8,0.5,0.4", mfp_mm = 2}); [[jobs]] tables list
    jobs one by one instead of [axes].

    Every problem of the SPEC (unknown keys or options, empty axes, bad values, a scene that does not load, more
    than --max-jobs jobs) is reported before anything runs, one line each (exit code 2). Jobs whose folder is
    complete are skipped, so the same command resumes. A job that fails is marked failed in the manifest and the
    batch goes on (exit code 1 at the end); Ctrl-C stops the workers and leaves the manifest of what finished.

    \b
    Example:
      convsss batch examples/sweep.toml -o out/sweep --workers 2
    """
    from ..batch import SpecError, contact_sheet, read_spec, run_batch, turntables
    from ..batch.runner import check_scheduler, make_folder

    if scheduler:
        check_scheduler(scheduler)
    try:
        plan = read_spec(spec, command_parsers(), max_jobs)
    except SpecError as error:
        for problem in error.problems:
            click.echo(f"error: {problem}", err=True)
        raise click.exceptions.Exit(2) from None
    if dry_run:
        for job in plan.jobs:
            click.echo(f"{job.id}: convsss {plan.command} {shlex.join(_shown(plan, job))}")
        click.echo(f"{len(plan.jobs)} jobs")
        return
    make_folder(out)
    records = run_batch(plan, out, scheduler, workers, retries, echo=lambda text: click.echo(text, err=True),
                        progress=progress)
    sheet = contact_sheet(plan, records, Path(out) / "contact_sheet.png")
    movies = turntables(plan, records, out)
    failed = [r for r in records.values() if r.get("status") != "done"]
    click.echo(f"batch: {len(plan.jobs) - len(failed)} of {len(plan.jobs)} jobs done; {Path(out) / 'manifest.json'}"
               f", {sheet}" + "".join(f", {m}" for m in movies))
    if failed:
        raise click.exceptions.Exit(1)


def command_parsers():
    """The commands a batch job may run, by name: their parsers, which the SPEC's options are read with."""
    from ..batch.spec import COMMANDS

    return {name: cli.get_command(None, name) for name in COMMANDS}


def _shown(plan, job):
    from ..batch.spec import arguments

    return arguments(plan.parser, job.options)
