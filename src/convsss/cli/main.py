"""The ``convsss`` command group and its error handling.

Every command turns a :class:`~convsss.errors.ConvsssError` into ``error: <one line>`` on stderr and exit code 2.
"""

import warnings

import click

from .. import __version__
from ..errors import ConvsssError


class _ConvsssGroup(click.Group):
    """A click group that reports bad input in one line (exit code 2) instead of a traceback."""

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except ConvsssError as error:
            click.echo(f"error: {error}", err=True)
            ctx.exit(2)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    click.echo(f"warning: {message}", err=True)


@click.group(cls=_ConvsssGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", "-V", prog_name="convsss")
def cli():
    """convsss: translucent objects rendered by layered convolutions (Munoz et al. 2011).

    Run `convsss COMMAND --help` for the options of each command.
    """
    warnings.showwarning = _show_warning
