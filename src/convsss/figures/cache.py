"""References cached on disk by a hash of what decides them, so a second ``convsss figures`` run reuses them.

A reference (a ``volpathmis`` render or an ``exact``-transport render) is stored as ``<root>/<kind>-<key>.exr`` plus
``<root>/<kind>-<key>.json`` (how it was made and how long it took). The key is the SHA-256 of a canonical JSON
form of the scene dictionary (transforms as matrices, mesh files as the SHA-256 of their bytes, so moving the
checkout keeps the key), the renderer's parameters, spp, seed and resolution, plus :data:`CACHE_FORMAT` and the
Mitsuba version. The EXR is written first and the JSON last, both atomically: an entry without its JSON is
incomplete and is rendered again.
"""

import hashlib
import json
import time
from functools import cache
from pathlib import Path

import numpy as np

from ..files import write_text

#: Bump when a change to the code makes old references wrong.
CACHE_FORMAT = 1


@cache
def file_digest(path):
    """SHA-256 of a file's bytes (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def canonical(value):
    """A JSON-ready, deterministic form of a scene dictionary (or any nested value) for hashing.

    Parameters
    ----------
    value : dict, list, tuple, numpy.ndarray, number, str, Mitsuba transform, ...
        Dictionaries are sorted by key, an existing ``filename`` becomes the SHA-256 of its bytes and its suffix,
        a transform its 4x4 matrix (9 significant digits), a float 12 significant digits, a numpy array a list;
        anything else its ``repr``.

    Returns
    -------
    dict, list, str, int, float, bool or None
    """
    if isinstance(value, dict):
        out = {}
        for key, item in sorted(value.items()):
            if key == "filename" and isinstance(item, str) and Path(item).is_file():
                out[key] = {"sha256": file_digest(item), "suffix": Path(item).suffix.lower()}
            else:
                out[str(key)] = canonical(item)
        return out
    if isinstance(value, (list, tuple)):
        return [canonical(v) for v in value]
    if hasattr(value, "matrix"):  # mitsuba ScalarTransform4f
        return {"matrix": [float(f"{x:.9g}") for x in np.array(value.matrix, dtype=np.float64).ravel()]}
    if isinstance(value, (bool, str)) or value is None:
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(f"{float(value):.12g}")
    if isinstance(value, np.ndarray):
        return canonical(value.tolist())
    return repr(value)


def reference_key(kind, scene, **settings):
    """16 hex digits naming a reference of ``kind`` for ``scene`` (a dictionary) and ``settings`` (JSON-ready)."""
    from ..backend import load_mitsuba

    payload = {"format": CACHE_FORMAT, "kind": kind, "mitsuba": load_mitsuba().__version__,
               "scene": canonical(scene), "settings": canonical(settings)}
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


class ReferenceCache:
    """References under ``root``; :meth:`get` renders only on a miss. ``hits`` / ``misses`` count the lookups."""

    def __init__(self, root):
        self.root = Path(root)
        self.hits = 0
        self.misses = 0

    def paths(self, kind, key):
        stem = self.root / f"{kind}-{key}"
        return stem.with_suffix(".exr"), stem.with_suffix(".json")

    def load(self, kind, key):
        """``(image, meta)`` of a complete entry, or ``None``.

        Returns
        -------
        tuple of (numpy.ndarray, dict) or None
            The stored linear RGB image, shape (H, W, 3), float64 (read from float32), and its metadata; ``None``
            when the entry is missing, incomplete or unreadable.
        """
        from ..errors import ConvsssError
        from ..image import read_image

        exr, meta_path = self.paths(kind, key)
        if not (exr.is_file() and meta_path.is_file()):
            return None
        try:
            meta = json.loads(meta_path.read_text())
            image = read_image(exr)
        except (ValueError, OSError, ConvsssError):
            return None
        return image, meta

    def get(self, kind, scene, settings, render, description=""):
        """The cached reference, or ``render()`` (-> (H, W, 3) image, dict of extra metadata) stored first.

        Returns ``(image, meta, hit)``; ``meta`` holds ``seconds`` (of the original render), ``key`` and ``path``.

        Parameters
        ----------
        kind : str
            ``exact`` or ``volpathmis``: the file names' prefix.
        scene : dict
            The scene dictionary (hashed with :func:`canonical`).
        settings : dict
            The renderer's settings (JSON-ready), hashed too.
        render : callable
            ``render()`` -> ``(image, extra)``: linear RGB of shape (H, W, C >= 3), a dict or None.
        description : str

        Returns
        -------
        image : numpy.ndarray, shape (H, W, 3), float64
            Linear RGB with float32 precision, as a later run reads it back.
        meta : dict
        hit : bool
            Whether it came from the cache.
        """
        from ..image import write_exr

        key = reference_key(kind, scene, **settings)
        found = self.load(kind, key)
        exr, meta_path = self.paths(kind, key)
        if found is not None:
            self.hits += 1
            image, meta = found
            return image, {**meta, "path": str(exr)}, True
        self.misses += 1
        start = time.perf_counter()
        image, extra = render()
        seconds = time.perf_counter() - start
        image = np.asarray(image, dtype=np.float64)[..., :3]
        meta = {"kind": kind, "key": key, "description": description, "settings": canonical(settings),
                "seconds": seconds, "created": time.strftime("%Y-%m-%d %H:%M:%S"), **(extra or {})}
        write_exr(exr, image)
        write_text(meta_path, json.dumps(meta, indent=1))
        # what a later run will read back is float32: hand out the same values now
        return image.astype(np.float32).astype(np.float64), {**meta, "path": str(exr)}, False
