"""Loading scenes for rendering: an XML file or a dictionary, with the ``convsss`` integrator registered first and the
film optionally resized (the camera keeps its field of view; the crop window becomes the whole film).

Scenes load without Mitsuba's optimizations (``optimize=False``): by default Mitsuba merges meshes that share a BSDF
and a medium into one shape, which would make two separate translucent objects of one material a single object,
with light diffusing across the air between them.
"""

from pathlib import Path

from ..backend import load_mitsuba
from ..errors import ConvsssError
from .integrator import register


def _one_line(error):
    return " ".join(str(error).split())


def load_scene(source, width=None, height=None):
    """A loaded ``mitsuba.Scene`` from an XML path or a scene dictionary; ``width``/``height`` resize every film.

    Raises :class:`~convsss.errors.ConvsssError` (one line) when the file is missing or Mitsuba cannot load it.
    """
    mi = load_mitsuba()
    register()
    if isinstance(source, dict):
        try:
            scene = mi.load_dict(source, optimize=False)
        except Exception as error:
            raise ConvsssError(f"cannot build the scene: {_one_line(error)}") from None
    else:
        path = Path(source)
        if not path.is_file():
            raise ConvsssError(f"scene file {str(path)!r} does not exist")
        try:
            scene = mi.load_file(str(path), optimize=False)
        except Exception as error:
            raise ConvsssError(f"cannot load scene {str(path)!r}: {_one_line(error)}") from None
    if not scene.sensors():
        raise ConvsssError("the scene has no sensor (camera) to render from")
    for name, value in (("width", width), ("height", height)):
        if value is not None and (int(value) != value or value < 1 or value > 32768):
            raise ConvsssError(f"{name}={value!r} is not allowed: it must be a whole number of pixels in [1, 32768]")
    if width is not None or height is not None:
        for sensor in scene.sensors():
            resize_film(mi, sensor, width, height)
    return scene


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
