"""Output files are written whole or not at all; values made ready for JSON.

Every file the project writes (images, stats, reports, caches) goes through :func:`atomic_write`: the content is
written to a temporary file in the target folder and renamed over the target only when complete, so an interrupted
or failed write leaves no partial file behind.
"""

import math
import os
import tempfile
from pathlib import Path

import numpy as np


def atomic_write(path, write):
    """Call ``write(tmp_path)`` on a temporary file beside ``path``, then rename it over ``path``; return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes private files; a written output is an ordinary one
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(path, text):
    """Write ``text`` to ``path`` whole or not at all."""
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def json_ready(value):
    """``value`` with numpy arrays and scalars as lists and numbers, and NaN or infinities as None, recursively."""
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value
