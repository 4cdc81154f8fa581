"""Loading scenes for rendering: an XML file or a dictionary, with the ``convsss`` integrator and medium
(:mod:`.presets`) registered first and the film optionally resized (the camera keeps its field of view; the crop
window becomes the whole film); and the files an XML scene reads (:func:`scene_inputs`), which no output may
overwrite.

Scenes load without Mitsuba's optimizations (``optimize=False``): by default Mitsuba merges meshes that share a BSDF
and a medium into one shape, which would make two separate translucent objects of one material a single object,
with light diffusing across the air between them.
"""

import re
import warnings
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..backend import load_mitsuba, ordered_kernels
from ..errors import ConvsssError
from ..media.named import any_textured_media, equivalents
from ..pipeline import register
from ..pipeline.checks import MeshWarning, check_named_media, mesh_topology
from .meshfiles import check_mesh_file
from .textures import equivalent_media

#: ``<string name=...>`` properties that name a file: every plugin's ``filename``, the convsss integrator's ``profile``.
FILE_PROPERTIES = ("filename", "profile")

#: The deepest element nesting a scene file may have (scenes need about 6; Mitsuba's recursive loader crashed at
#: 20 000).
MAX_XML_DEPTH = 256
#: Largest difference (per component) between a loaded vertex normal and its recomputation for which both are taken
#: for the normal Mitsuba computed: rounding of a few float32 sums is about 2e-7, normals that came with a mesh
#: differ far more.
NORMAL_TOLERANCE = 1e-4



def _load_error(error, context):
    """A one-line ConvsssError for Mitsuba's ``error``: a plugin's own ConvsssError message (Mitsuba wraps it in its
    text with the flattened traceback) as it is, anything else after ``context``."""
    wrapped = re.findall(r"ConvsssError: (.+)", str(error))
    if wrapped:
        return ConvsssError(wrapped[-1].strip())
    return ConvsssError(f"{context}: {' '.join(str(error).split())}")


def load_scene(source, width=None, height=None):
    """A loaded ``mitsuba.Scene`` from an XML path or a scene dictionary; ``width``/``height`` resize every film.

    Vertex normals that Mitsuba computed are recomputed in a fixed order (:func:`order_vertex_normals`), and a mesh
    around a medium that is wound inward is turned outward (:func:`wind_outward`). Raises
    :class:`~convsss.errors.ConvsssError` (one line) when the file is missing, Mitsuba cannot load it, or a
    ``<medium type="convsss_medium">`` disagrees with its shape's boundary
    (:func:`~convsss.media.named.check_boundary`).
    """
    mi = load_mitsuba()
    register()
    if isinstance(source, dict):
        for name in _dict_files(source):
            check_mesh_file(name)
    else:
        path = Path(source)
        if not path.is_file():
            raise ConvsssError(f"scene file {str(path)!r} does not exist")
        for name in scene_inputs(path)[1:]:  # what would crash Mitsuba's loader is refused first
            check_mesh_file(name)
    with equivalents({}):  # a textured convsss_medium is first its placeholder
        scene = _load(mi, source)
    if not scene.sensors():
        raise ConvsssError("the scene has no sensor (camera) to render from")
    check_emitters(mi, scene)
    check_named_media(mi, scene)
    if any_textured_media():
        media = equivalent_media(mi, scene)
        if media:  # loaded again, each textured medium made as the heterogeneous medium it stands for
            with equivalents(media):
                scene = _load(mi, source)
    wind_outward(mi, scene)
    order_vertex_normals(mi, scene)
    for name, value in (("width", width), ("height", height)):
        if value is not None and (int(value) != value or value < 1 or value > 32768):
            raise ConvsssError(f"{name}={value!r} is not allowed: it must be a whole number of pixels in [1, 32768]")
    if width is not None or height is not None:
        for sensor in scene.sensors():
            resize_film(mi, sensor, width, height)
    return scene


def _load(mi, source):
    """Mitsuba's scene of ``source`` (a dictionary or a checked path), or a one-line error."""
    try:
        if isinstance(source, dict):
            return mi.load_dict(source, optimize=False)
        return mi.load_file(str(source), optimize=False)
    except Exception as error:
        raise _load_error(error, "cannot build the scene" if isinstance(source, dict) else
                          f"cannot load scene {str(source)!r}") from None


def _dict_files(value):
    """Every ``filename`` in a scene dictionary, at any depth."""
    if isinstance(value, dict):
        for key, item in value.items():
            if key == "filename" and isinstance(item, (str, Path)):
                yield item
            else:
                yield from _dict_files(item)


def check_emitters(mi, scene):
    """A one-line error for an emitter whose intensity, radiance, irradiance, scale or image holds a negative or
    non-finite value (it would render negative or NaN pixels, or black, without a word)."""
    for k, emitter in enumerate(scene.emitters()):
        params = mi.traverse(emitter)
        for key in params.keys():
            if key.split(".")[-1] not in ("value", "data", "scale"):
                continue
            values = np.asarray(params[key], dtype=np.float64)
            if values.size and not (np.all(np.isfinite(values)) and np.all(values >= 0)):
                name = emitter.id() if emitter.id() and not emitter.id().startswith("_unnamed") else f"#{k}"
                bad = values[~(np.isfinite(values) & (values >= 0))].reshape(-1)[0]
                raise ConvsssError(f"emitter {name!r} ({emitter.class_name()}) has {key} = {bad:g}: emitted light "
                                   "must be finite and >= 0")


def scene_inputs(path):
    """The files a Mitsuba 3 XML scene reads, without loading it.

    The scene file, its ``<include>``s (recursively), and every file named in them: ``<string name="filename">``
    (meshes, textures, environment maps, ...), the ``convsss`` integrator's ``<string name="profile">`` and any
    ``filename`` attribute. ``$name`` is replaced by the scene's ``<default>`` values; relative paths are resolved as
    Mitsuba does: against the file's folder, the scene's folder, ``<path>`` entries and Mitsuba's search path.

    Parameters
    ----------
    path : str or Path
        The scene file.

    Returns
    -------
    list of Path
        The scene file first; a file that exists nowhere is given relative to the scene's folder.

    Raises
    ------
    ConvsssError
        When the scene file or an included file does not exist or is not XML.
    """
    path = Path(path)
    if not path.is_file():
        raise ConvsssError(f"scene file {str(path)!r} does not exist")
    search = [path.parent, *(Path(str(p)) for p in load_mitsuba().file_resolver())]
    found = [path]
    _collect_inputs(path, search, {}, found, ())
    return found


def _depth(root):
    """The nesting depth of an XML tree (iteratively: a tree may be deeper than Python's recursion limit)."""
    deepest, stack = 0, [(root, 1)]
    while stack:
        element, depth = stack.pop()
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in element)
    return deepest


def _collect_inputs(path, search, defaults, found, including):
    if path.resolve() in including:
        chain = " -> ".join(repr(str(p)) for p in (*including, path.resolve()))
        raise ConvsssError(f"scene {str(including[0])!r} includes itself: {chain}")
    try:
        root = ElementTree.parse(path).getroot()
    except (ElementTree.ParseError, OSError, RecursionError) as error:
        raise ConvsssError(f"cannot read scene {str(path)!r}: {error}") from None
    depth = _depth(root)
    if depth > MAX_XML_DEPTH:
        raise ConvsssError(f"scene {str(path)!r} nests its elements {depth} levels deep, more than the "
                           f"{MAX_XML_DEPTH} a scene needs (Mitsuba's loader would overflow its stack)")

    def value(element, attribute):
        return re.sub(r"\$(\w+)", lambda m: defaults.get(m[1], m[0]), element.get(attribute, ""))

    for element in root.iter():
        if element.tag == "default":
            defaults.setdefault(element.get("name"), element.get("value", ""))
        elif element.tag == "path":
            search.insert(0, _resolve(value(element, "value"), path.parent, search))
        elif element.tag == "string" and element.get("name") == "profile":
            from ..profiles.models import PROFILE_MODELS

            for entry in value(element, "value").split(","):  # model names and CSV files, per object or for all
                spec = entry.rpartition("=")[2].strip()
                if spec and spec not in PROFILE_MODELS:
                    found.append(_resolve(spec, path.parent, search))
        elif element.tag == "string" and element.get("name") in FILE_PROPERTIES:
            found.append(_resolve(value(element, "value"), path.parent, search))
        elif element.get("filename"):
            found.append(_resolve(value(element, "filename"), path.parent, search))
            if element.tag == "include":
                if not found[-1].is_file():
                    raise ConvsssError(f"scene {str(path)!r} includes {str(found[-1])!r}, which does not exist")
                _collect_inputs(found[-1], search, defaults, found, (*including, path.resolve()))


def _resolve(name, folder, search):
    """``name`` as Mitsuba's file resolver finds it: absolute, or the first existing of ``folder / name`` and
    ``s / name`` for the search path ``s`` (``folder / name`` when none exists)."""
    name = Path(name).expanduser()
    if name.is_absolute():
        return name
    candidates = [folder / name, *(base / name for base in search)]
    return next((c for c in candidates if c.exists()), candidates[0])

def order_vertex_normals(mi, scene):
    """Replace the vertex normals Mitsuba computed while loading ``scene`` by the same computation on one thread.

    Mitsuba computes the normals of a mesh loaded without them by scatter-adding face normals from all threads at
    once, so their float sums, and the image, change from run to run. Its ``recompute_vertex_normals`` run on one
    thread adds in a fixed order: bit-identical normals for any thread count. (Loading the whole scene on one thread
    would hang Mitsuba's OpenEXR reader.) Normals further than :data:`NORMAL_TOLERANCE` from the recomputation came
    with the mesh and are kept.
    """
    for shape in scene.shapes():
        if not isinstance(shape, mi.Mesh) or not shape.has_vertex_normals():
            continue
        loaded = np.array(shape.vertex_normals_buffer(), dtype=np.float32).reshape(-1, 3)
        with ordered_kernels():
            shape.recompute_vertex_normals()
        normals = np.array(shape.vertex_normals_buffer(), dtype=np.float32).reshape(-1, 3)
        kept = np.abs(normals - loaded).max(axis=1) > NORMAL_TOLERANCE
        if kept.any():
            normals[kept] = loaded[kept]
            params = mi.traverse(shape)
            params["vertex_normals"] = mi.Float(normals.ravel())
            params.update()


def wind_outward(mi, scene):
    """Turn outward, with a warning, each mesh around a medium whose faces wind around inward normals (a negative
    signed volume, :func:`~convsss.pipeline.checks.mesh_topology`), as Mitsuba's ``flip_normals`` would have at
    load: Mitsuba puts a shape's interior medium, and a dielectric's inside, on the side its normals point away
    from, so an inward mesh is rendered inside out, by the path tracer too (a 10 mm sphere of albedo 0.9-0.99 behind
    a dielectric under an area light: 1.11-1.13 of the outward mesh in ``convsss render``, 0.68-0.81 in
    ``convsss reference``). Faces wound both ways are left to the object check's error. Vertex normals are turned
    with the faces (those Mitsuba computed are then recomputed in order, :func:`order_vertex_normals`)."""
    for shape in scene.shapes():
        if not isinstance(shape, mi.Mesh) or shape.interior_medium() is None:
            continue
        _, volume, miswound = mesh_topology(shape)
        if volume >= 0 or miswound:
            continue
        params = mi.traverse(shape)
        params["faces"] = mi.UInt32(np.array(params["faces"]).reshape(-1, 3)[:, [0, 2, 1]].ravel())
        params["vertex_positions"] = mi.Float(np.array(params["vertex_positions"]))  # the scene's BVH rebuilt
        if shape.has_vertex_normals():
            params["vertex_normals"] = mi.Float(-np.array(params["vertex_normals"]))
        params.update()
        scene.parameters_changed()
        warnings.warn(f"mesh {shape.id() or shape.class_name()!r} around a medium winds its faces inward (its "
                      "normals point in): turned outward, as flip_normals would", MeshWarning, stacklevel=3)


def resize_film(mi, sensor, width=None, height=None):
    """Give ``sensor``'s film a new size (``None`` keeps that side); the crop window becomes the whole film."""
    film = sensor.film()
    old = film.size()
    size = mi.ScalarVector2u(int(width or old[0]), int(height or old[1]))
    params = mi.traverse(sensor)
    params["film.size"] = size
    params["film.crop_offset"] = mi.ScalarPoint2u(0, 0)
    params["film.crop_size"] = size
    params.update()
