"""Variations of a loaded scene that a sweep asks for: every light scaled, the camera orbited about the objects.

Both work on any loaded Mitsuba scene through ``mi.traverse`` (so a scene file needs no edit): ``--light-scale``
and ``--orbit-deg`` of ``convsss render`` and ``convsss reference`` (:mod:`convsss.cli.options`), and the axes
``light_scale`` and ``orbit_deg`` of ``convsss batch``.
"""

import math
import re

import numpy as np

from ..backend import import_mitsuba
from ..errors import ConvsssError

mi = import_mitsuba()

#: The parameters of an emitter that carry its power: Mitsuba's point and spot ``intensity``, area and constant
#: ``radiance``, directional ``irradiance`` (a value or a texture's data), and the environment map's ``scale``.
POWER = re.compile(r"(^|\.)((intensity|radiance|irradiance)\.(value|data)|scale)$")


def scale_lights(scene, factor):
    """Multiply every emitter's power by ``factor`` (>= 0), in place: the image scales by ``factor``."""
    if not (math.isfinite(factor) and factor >= 0):
        raise ConvsssError(f"light scale {factor!r} is not allowed: give a finite number >= 0")
    if factor == 1.0:
        return scene
    for emitter in scene.emitters():
        params = mi.traverse(emitter)
        keys = [k for k in params.keys() if POWER.search(k)]
        for key in keys:
            params[key] = params[key] * factor
        params.update()
    return scene


def _translucent_centre(scene):
    """The centre of the bounding box of the shapes with an interior medium, else of the whole scene (scene units)."""
    boxes = [s.bbox() for s in scene.shapes() if s.interior_medium() is not None]
    if not boxes:
        boxes = [scene.bbox()]
    lo = np.min([np.array(b.min) for b in boxes], axis=0)
    hi = np.max([np.array(b.max) for b in boxes], axis=0)
    return 0.5 * (lo + hi)


def orbit_camera(scene, degrees, sensor=None):
    """Turn ``sensor`` (default: every sensor) by ``degrees`` about the vertical (+y) axis through the centre of the
    translucent objects (of the whole scene when it has none), in place: a turntable's frame."""
    if not math.isfinite(degrees):
        raise ConvsssError(f"orbit angle {degrees!r} is not allowed: give a finite number of degrees")
    if degrees % 360.0 == 0.0:
        return scene
    centre = [float(c) for c in _translucent_centre(scene)]
    turn = (mi.ScalarTransform4f().translate(centre).rotate([0.0, 1.0, 0.0], float(degrees))
            .translate([-c for c in centre]))
    for camera in scene.sensors() if sensor is None else [sensor]:
        params = mi.traverse(camera)
        if "to_world" not in params.keys():
            raise ConvsssError(f"the sensor {camera.id()!r} has no to_world to orbit")
        params["to_world"] = mi.Transform4f(turn) @ params["to_world"]
        params.update()
    return scene
