"""Output files are written whole or not at all, and never over an input; values made ready for JSON.

Every file the project writes (images, stats, reports, caches) goes through :func:`write_files` (or
:func:`atomic_write`, its one-file form): each file's content is written to a temporary file in the target folder,
and the targets are replaced only once every temporary file is complete, so a failed or interrupted command leaves
neither a partial file nor a partial set of files behind. Commands call :func:`check_outputs` before any work: an
output that is one of the command's inputs, a folder, or in a folder that cannot be written is refused in one line.
"""

import math
import os
import re
import tempfile
from pathlib import Path

import numpy as np

from .errors import ConvsssError


def output_paths(output, *endings):
    """The files ``OUT + ending`` for ``OUT``, ``OUT.exr`` or ``OUT.png``, the stem every output shares (any other
    dot in the name is kept: ``-o sphere-0.5`` writes ``sphere-0.5.exr``).

    >>> [str(p) for p in output_paths("out/sphere-0.5.png", ".exr", "-mask.png")]
    ['out/sphere-0.5.exr', 'out/sphere-0.5-mask.png']
    """
    path = Path(output)
    stem = path.with_suffix("") if path.suffix.lower() in (".exr", ".png") else path
    return [stem.with_name(stem.name + ending) for ending in endings]


def check_outputs(outputs, inputs=()):
    """Refuse, before any work, output paths that cannot or must not be written.

    Parameters
    ----------
    outputs : iterable of str or Path
        The files the command will write.
    inputs : iterable of str or Path
        The files the command reads (scene, meshes, textures, profiles, images); none of them may be overwritten.

    Raises
    ------
    ConvsssError
        When an output is an input (the same resolved path, or the same file under another name), is named twice,
        is an existing folder, or lies in a folder that neither exists nor can be created, or cannot be written, or
        its name is not valid UTF-8.

    Examples
    --------
    >>> check_outputs(["a.png"], inputs=["x/../a.png"])
    Traceback (most recent call last):
    ...
    convsss.errors.ConvsssError: output 'a.png' is an input of this command ('x/../a.png'): choose another output path
    """
    outputs = [Path(p) for p in outputs]
    for out in outputs:
        try:
            str(out).encode("utf-8")
        except UnicodeEncodeError:
            raise ConvsssError(f"output {str(out).encode('utf-8', 'backslashreplace').decode()!r} is not a valid "
                               "UTF-8 name (Mitsuba writes UTF-8 paths only): choose another output path") from None
        for source in map(Path, inputs):
            if _same_file(out, source):
                raise ConvsssError(f"output {str(out)!r} is an input of this command ({str(source)!r}): "
                                   "choose another output path")
    for k, out in enumerate(outputs):
        if any(_same_file(out, other) for other in outputs[:k]):
            raise ConvsssError(f"output {str(out)!r} is named twice: give each output its own path")
    _refuse_folders(outputs)
    for folder in {out.parent for out in outputs}:
        _check_writable(folder)


def _same_file(a, b):
    if a.resolve() == b.resolve():
        return True
    return a.exists() and b.exists() and os.path.samefile(a, b)


def _refuse_folders(paths):
    for path in paths:
        if path.is_dir():
            raise ConvsssError(f"output {str(path)!r} is a folder: give a file path")


def _check_writable(folder):
    """``folder`` exists and takes a new file, or its nearest existing ancestor is a folder that does."""
    existing = folder.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ConvsssError(f"cannot write into {str(folder)!r}: {str(existing)!r} is a file, not a folder")
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as error:
        where = "" if existing == folder.absolute() else f" (cannot create a file or folder in {str(existing)!r})"
        raise ConvsssError(f"cannot write into {str(folder)!r}{where}: {error.strerror or error}") from None


def write_files(writers):
    """Write several files as one: all of them or none.

    Every file is first written to a temporary file beside its target, in order; only when all are complete are
    they renamed over their targets. If any write fails (or is interrupted), every temporary file is removed and
    no target is touched.

    Parameters
    ----------
    writers : dict
        ``{path: write}``, where ``write(tmp_path)`` writes the file's whole content to ``tmp_path`` (a str).

    Returns
    -------
    list of Path
        The paths written, in the order given.

    Raises
    ------
    ConvsssError
        When a target is an existing folder (before anything is written), or a file cannot be created.

    Examples
    --------
    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> [p.name for p in write_files({folder / "a.txt": text_writer("a"), folder / "b.txt": text_writer("b")})]
    ['a.txt', 'b.txt']
    """
    paths = [Path(p) for p in writers]
    _refuse_folders(paths)
    temps = []
    try:
        for path, write in zip(paths, writers.values()):
            path.parent.mkdir(parents=True, exist_ok=True)
            remove_stale_temporaries(path)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.{os.getpid()}.", suffix=path.suffix, dir=path.parent)
            os.close(fd)
            temps.append(tmp)
            write(tmp)
            os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes private files; a written output is an ordinary one
        for tmp, path in zip(temps, paths):
            os.replace(tmp, path)
    except BaseException as error:
        for tmp in temps:
            Path(tmp).unlink(missing_ok=True)
        if isinstance(error, OSError):
            raise ConvsssError(f"cannot write {str(path)!r}: {error.strerror or error}") from None
        if isinstance(error, RuntimeError) and str(error).startswith("[FileStream]"):  # Mitsuba's I/O errors
            raise ConvsssError(f"cannot write {str(path)!r}: {str(error).rsplit(': ', 1)[-1].strip()}") from None
        raise
    return paths


def remove_stale_temporaries(path):
    """Remove the temporary files of :func:`write_files` for ``path`` (``.STEM.PID.XXXXXXXX.SUFFIX`` beside it) left by
    a process that no longer runs (killed before it could clean up); those of a running process are kept."""
    pattern = re.compile(rf"\.{re.escape(path.stem)}\.(\d+)\.[A-Za-z0-9_]{{8}}{re.escape(path.suffix)}")
    try:
        entries = list(os.scandir(path.parent))
    except OSError:
        return
    for entry in entries:
        match = pattern.fullmatch(entry.name)
        if match is not None and not _running(int(match.group(1))):
            Path(entry.path).unlink(missing_ok=True)


def _running(pid):
    """Whether process ``pid`` exists (one of another user counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def atomic_write(path, write):
    """Call ``write(tmp_path)`` on a temporary file beside ``path``, then rename it over ``path``; return the path.

    The one-file form of :func:`write_files`.
    """
    return write_files({path: write})[0]


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def text_writer(text):
    """``write(path)``, saving ``text``: one entry of :func:`write_files`."""
    return lambda path: Path(path).write_text(text)


def write_text(path, text):
    """Write ``text`` to ``path`` whole or not at all."""
    return atomic_write(path, text_writer(text))


def json_ready(value):
    """``value`` with numpy arrays and scalars as lists and numbers, and NaN or infinities as None, recursively.

    Parameters
    ----------
    value : dict, list, tuple, numpy.ndarray, numpy scalar or any other value
        Dictionary keys become strings, tuples lists; other values are kept.

    Returns
    -------
    dict, list, int, float, None or the value itself

    Examples
    --------
    >>> json_ready({1: np.array([0.5, np.inf])})
    {'1': [0.5, None]}
    """
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
