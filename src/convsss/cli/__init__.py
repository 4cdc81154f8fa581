"""The ``convsss`` command line: one module per command, each registering its command on :data:`cli` when the group
looks it up (:data:`~.main.COMMANDS`)."""

from .main import cli


def main(argv=None):
    """Console entry point."""
    return cli.main(args=argv, prog_name="convsss")


__all__ = ["cli", "main"]
