"""The ``convsss`` command group and its error handling.

Every command turns bad input (a :class:`~convsss.errors.ConvsssError` or a bad option value) into
``error: <one line>`` on stderr and exit code 2, Ctrl-C into ``interrupted`` and exit code 130 and SIGTERM into
``terminated`` and 143, an allocation that fails all the same (:mod:`convsss.memory` refuses what it can foresee)
into one line and 2, without a traceback; outputs are written all together or not at all
(:func:`convsss.files.write_files`), so an interrupted command leaves none half-written.
"""

import importlib
import warnings

import click

from .. import __version__
from ..errors import ConvsssError
from ..signals import TERMINATED, Terminated, terminate_as_interrupt

#: Exit code of a command stopped by Ctrl-C (128 + SIGINT, as shells report it).
INTERRUPTED = 130


#: The commands, each the module of :mod:`convsss.cli` of its name that registers it on :data:`cli` when imported.
COMMANDS = ("batch", "bench", "compare", "edit", "figures", "fit", "materials", "profile", "reference", "render",
            "scene")


class _ConvsssGroup(click.Group):
    """A click group that reports bad input in one line (exit code 2) and Ctrl-C as ``interrupted`` (130), and
    imports a command's module only when the command is looked up (``convsss --version`` imports none of them, so
    it does not wait for numpy, scipy, numba and the transports to load)."""

    def list_commands(self, ctx):
        return sorted(COMMANDS)

    def get_command(self, ctx, name):
        if name in COMMANDS and name not in self.commands:
            importlib.import_module(f"{__package__}.{name}")
        return super().get_command(ctx, name)

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except ConvsssError as error:
            click.echo(f"error: {error}", err=True)
            ctx.exit(2)
        except click.UsageError as error:
            hint = f" (see '{error.ctx.command_path} --help')" if error.ctx is not None else ""
            click.echo(f"error: {' '.join(error.format_message().split())}{hint}", err=True)
            ctx.exit(2)
        except MemoryError:
            click.echo("error: out of memory (the machine's, or the process's limit: ulimit -v, a container's); "
                       "give a coarser --accuracy, a smaller --width or fewer samples", err=True)
            ctx.exit(2)
        except Terminated:
            click.echo("terminated", err=True)
            ctx.exit(TERMINATED)
        except KeyboardInterrupt:
            click.echo("interrupted", err=True)
            ctx.exit(INTERRUPTED)


def _show_warning(message, category, filename, lineno, file=None, line=None):
    click.echo(f"warning: {message}", err=True)


@click.group(cls=_ConvsssGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", "-V", prog_name="convsss")
def cli():
    """convsss: translucent objects rendered by layered convolutions (Munoz et al. 2011).

    Run `convsss COMMAND --help` for the options of each command.
    """
    warnings.showwarning = _show_warning
    terminate_as_interrupt()
