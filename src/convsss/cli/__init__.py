"""The ``convsss`` command line: one module per command, all registered on :data:`cli`."""

from . import bench, compare, edit, figures, materials, profile, reference, render, scene  # noqa: F401  (registers the commands)
from .main import cli


def main(argv=None):
    """Console entry point."""
    return cli.main(args=argv, prog_name="convsss")


__all__ = ["cli", "main"]
