"""Loading scenes for rendering: an XML file or a dictionary, with the ``convsss`` integrator registered first and the
film optionally resized (the camera keeps its field of view; the crop window becomes the whole film)."""

from pathlib import Path

import numpy as np

from ..backend import load_mitsuba, ordered_kernels
from ..errors import ConvsssError
from .integrator import register

#: Largest difference (per component) between a loaded vertex normal and its recomputation for which both are taken
#: for the normal Mitsuba computed: rounding of a few float32 sums is about 2e-7, normals that came with a mesh
#: differ far more.
NORMAL_TOLERANCE = 1e-4


def _one_line(error):
    return " ".join(str(error).split())


def load_scene(source, width=None, height=None):
    """A loaded ``mitsuba.Scene`` from an XML path or a scene dictionary; ``width``/``height`` resize every film.

    Vertex normals that Mitsuba computed are recomputed in a fixed order (:func:`order_vertex_normals`). Raises
    :class:`~convsss.errors.ConvsssError` (one line) when the file is missing or Mitsuba cannot load it.
    """
    mi = load_mitsuba()
    register()
    if isinstance(source, dict):
        try:
            scene = mi.load_dict(source)
        except Exception as error:
            raise ConvsssError(f"cannot build the scene: {_one_line(error)}") from None
    else:
        path = Path(source)
        if not path.is_file():
            raise ConvsssError(f"scene file {str(path)!r} does not exist")
        try:
            scene = mi.load_file(str(path))
        except Exception as error:
            raise ConvsssError(f"cannot load scene {str(path)!r}: {_one_line(error)}") from None
    if not scene.sensors():
        raise ConvsssError("the scene has no sensor (camera) to render from")
    order_vertex_normals(mi, scene)
    for name, value in (("width", width), ("height", height)):
        if value is not None and (int(value) != value or value < 1 or value > 32768):
            raise ConvsssError(f"{name}={value!r} is not allowed: it must be a whole number of pixels in [1, 32768]")
    if width is not None or height is not None:
        for sensor in scene.sensors():
            resize_film(mi, sensor, width, height)
    return scene


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
