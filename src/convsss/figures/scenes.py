"""The figures' scenes: a bundled mesh of a preset material, framed by :func:`convsss.scene.quick.quick_scene`.

A :class:`SceneSpec` names everything that decides the image apart from the renderer: mesh, material, size, boundary
and a turn about the vertical axis (the bust faces away from the camera as stored). Scenes have no floor and a black
background, so the object's pixels are exactly the non-black pixels of a reference (what :mod:`convsss.compare`
uses as the object mask).

Meshes (``data/meshes``, credits in ``CREDITS.md`` there): ``bunny`` (Stanford bunny, 69.6k triangles), ``bust``
(Max Planck bust, 10.5k triangles), ``dragon`` (Stanford dragon, 100k triangles).
"""

import math
from dataclasses import asdict, dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from ..errors import ConvsssError

MESHES = {"bunny": "bunny.obj", "bust": "decimated-max.obj", "dragon": "dragon.ply"}


def mesh_path(name):
    """Path of a bundled mesh by its short name (see :data:`MESHES`)."""
    if name not in MESHES:
        raise ConvsssError(f"unknown figure mesh {name!r}: choose one of {', '.join(MESHES)}")
    return Path(str(resources.files("convsss").joinpath("data", "meshes", MESHES[name])))


@dataclass(frozen=True)
class SceneSpec:
    """One figure scene: ``material`` (a preset name) on ``mesh`` (a :data:`MESHES` name), ``size_mm`` across."""

    mesh: str
    material: str
    size_mm: float
    boundary: str = "null"
    turn_deg: float = 0.0

    def describe(self):
        """A short human description, e.g. ``wholemilk bunny 40 mm (null boundary)``."""
        turn = f", turned {self.turn_deg:g}°" if self.turn_deg else ""
        return f"{self.material} {self.mesh} {self.size_mm:g} mm ({self.boundary} boundary{turn})"

    def to_dict(self):
        return asdict(self)


def scene_dict(spec, width, height, spp=4):
    """The Mitsuba scene dictionary of ``spec`` (volpathmis named as its integrator, as ``quick_scene`` writes)."""
    from ..backend import load_mitsuba
    from ..materials import material
    from ..scene.quick import quick_scene

    scene = quick_scene(mesh_path(spec.mesh), material(spec.material), spec.size_mm, width, height, spp=spp,
                        floor=False, boundary=spec.boundary)
    if spec.turn_deg:
        mi = load_mitsuba()
        obj = dict(scene["object"])
        matrix = np.array(obj["to_world"].matrix, dtype=np.float64).reshape(4, 4)
        a = math.radians(spec.turn_deg)
        turn = np.array([[math.cos(a), 0, math.sin(a), 0], [0, 1, 0, 0], [-math.sin(a), 0, math.cos(a), 0],
                         [0, 0, 0, 1.0]])
        # quick_scene centres the object on the y axis, so a turn about it keeps the framing.
        obj["to_world"] = mi.ScalarTransform4f((turn @ matrix).tolist())
        scene["object"] = obj
    return scene


def load(spec, width, height, spp=4):
    """The loaded ``mitsuba.Scene`` of ``spec`` (the convsss integrator registered; Mitsuba's PLY warnings muted)."""
    from ..backend import load_mitsuba
    from ..scene.loading import load_scene

    mi = load_mitsuba()
    level = mi.log_level()
    mi.set_log_level(mi.LogLevel.Error)  # dragon.ply carries per-vertex "flags" that Mitsuba warns about
    try:
        return load_scene(scene_dict(spec, width, height, spp))
    finally:
        mi.set_log_level(level)
