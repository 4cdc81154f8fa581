"""A scene around one mesh, for rendering without writing a scene: camera, key light, back light, optional floor.

Layout (scene units are mm, y is up): the mesh is scaled so that its largest side is ``size_mm``, centred on the
y axis and standing on ``y = 0``. With ``R`` the radius of its bounding sphere and ``c`` its centre:

- camera: perspective, 30° horizontal field of view, at ``c + d (0, 0.25, 1)/|.|`` looking at ``c``, with ``d`` so
  that the bounding sphere fills about 80 % of the frame;
- key light: a point light high on the camera's left, irradiance about 1 at the object;
- back light: a point light behind the object, slightly above and to the right, about 3 times stronger: the light
  that crosses thin parts (ears, edges) shows the translucency;
- floor (optional): a large grey diffuse rectangle at ``y = 0``.

The object gets the material's medium and a boundary (see :mod:`.materials`).
"""

import math
from pathlib import Path

import numpy as np

from ..backend import load_mitsuba
from ..errors import ConvsssError
from ..media.dicts import albedo_volume_dict, translucent

MESH_TYPES = {".obj": "obj", ".ply": "ply", ".serialized": "serialized"}
#: The quick scene's film and sampler (every command that renders ``--mesh`` without a size): the paper's 800 x 800.
WIDTH, HEIGHT, SPP = 800, 800, 16
FOV_DEG = 30.0
#: An albedo volume's box beyond the object's, each side, as a fraction of the object's size.
VOLUME_MARGIN = 0.01


def demo_mesh():
    """Path of the bundled Stanford bunny (watertight; credits in ``data/meshes/CREDITS.md``)."""
    from importlib import resources

    return Path(str(resources.files("convsss").joinpath("data", "meshes", "bunny.obj")))


def mesh_dict(path):
    """A Mitsuba shape dictionary for a mesh file (``.obj``, ``.ply``, ``.serialized``), checked to exist."""
    path = Path(path)
    if not path.is_file():
        raise ConvsssError(f"mesh file {str(path)!r} does not exist")
    kind = MESH_TYPES.get(path.suffix.lower())
    if kind is None:
        raise ConvsssError(f"mesh file {str(path)!r} has an unknown format: use {', '.join(MESH_TYPES)}")
    return {"type": kind, "filename": str(path.resolve())}


def load_mesh(path):
    """The Mitsuba mesh of a mesh file, checked (:func:`~.meshfiles.check_mesh_file`), or a one-line error."""
    from .meshfiles import check_mesh_file

    mi = load_mitsuba()
    check_mesh_file(path)
    try:
        return mi.load_dict(mesh_dict(path))
    except ConvsssError:
        raise
    except Exception as error:
        raise ConvsssError(f"cannot read mesh {str(path)!r}: {' '.join(str(error).split())}") from None


def mesh_bounds(path):
    """(min, max) corners of the mesh in its own units.

    Parameters
    ----------
    path : path-like
        ``.obj``, ``.ply`` or ``.serialized`` mesh.

    Returns
    -------
    lo, hi : numpy.ndarray, shape (3,), float64
        The corners of its bounding box, in the mesh's units.
    """
    return shape_bounds(load_mesh(path))


def shape_bounds(shape):
    """(min, max) corners, float64 (3,) each, of a loaded Mitsuba shape's bounding box."""
    box = shape.bbox()
    return np.array(list(box.min), dtype=np.float64), np.array(list(box.max), dtype=np.float64)


def color_texture_medium(material, color_texture, mfp_mm, color_model, unit_mm=1.0):
    """A ``convsss_medium`` dictionary whose colour is the bitmap file ``color_texture`` on the shape and whose
    reduced mean free path is ``mfp_mm`` (3,), inverted under ``color_model`` at ``material``'s eta
    (:mod:`.presets`, :mod:`.textures`)."""
    mfp = [float(x) for x in np.broadcast_to(np.asarray(mfp_mm, dtype=np.float64), (3,))]
    return {"type": "convsss_medium", "color": {"type": "bitmap", "filename": str(color_texture)},
            "mfp_mm": mfp[0] if len(set(mfp)) == 1 else ",".join(repr(x) for x in mfp),
            "eta": float(material.eta), "model": str(color_model), "unit_mm": float(unit_mm)}


def _matrix(m):
    mi = load_mitsuba()
    return mi.ScalarTransform4f(np.asarray(m, dtype=np.float64).tolist())


def _look_at(origin, target, up=(0.0, 1.0, 0.0)):
    mi = load_mitsuba()
    return mi.ScalarTransform4f().look_at(origin=[float(x) for x in origin], target=[float(x) for x in target],
                                          up=list(up))


def quick_scene(mesh, material, size_mm, width=WIDTH, height=HEIGHT, spp=SPP, floor=False, boundary="dielectric",
                unit_mm=1.0, integrator=None, albedo_volume=None, color_texture=None, color_model="exact",
                rfilter="gaussian"):
    """The scene dictionary described in the module docstring.

    Parameters
    ----------
    mesh : path-like
        ``.obj``, ``.ply`` or ``.serialized`` mesh (any units, y up).
    material : Material
        What the object is made of (e.g. ``convsss.material("wholemilk")``).
    size_mm : float
        Largest side of the object's bounding box, in mm.
    width, height, spp : int
        Film size and samples per pixel.
    floor : bool
        Add a grey floor under the object.
    boundary : str
        ``dielectric`` (default, ``int_ior`` = the material's eta), ``roughdielectric`` or ``null``.
    unit_mm : float
        mm per scene unit of the scene written (the medium's coefficients are converted).
    integrator : dict, optional
        The scene's integrator (default: ``volpathmis`` without Russian roulette, so the scene is its own
        ground truth in plain Mitsuba).
    albedo_volume : str, optional
        A ``gridvolume`` file of the albedo (1 or 3 channels): the interior is then a ``heterogeneous`` medium of
        ``material``'s extinction and this albedo, the grid stretched over the object's bounding box (grown by
        :data:`VOLUME_MARGIN` of its size each side).
    color_texture : str, optional
        A bitmap file of the surface colour (the mesh needs texture coordinates): the interior is then a
        ``convsss_medium`` of this colour map at ``material``'s mean free path and eta, inverted under
        ``color_model`` (:func:`color_texture_medium`; it renders with convsss and ``convsss reference``, not with
        plain Mitsuba, which does not know the medium).
    rfilter : str
        The film's reconstruction filter: ``gaussian`` (Mitsuba's default) or ``box`` (uncorrelated pixel noise, what
        a denoiser needs: ``convsss render --denoise`` and the editor's preview use it).
    """
    size_mm = float(size_mm)
    if not math.isfinite(size_mm) or size_mm <= 0:
        raise ConvsssError(f"size_mm={size_mm!r} is not allowed: the object's size must be a length > 0 (mm)")
    shape = load_mesh(mesh)
    to_world, half = _placement(mesh, shape, size_mm / unit_mm)
    centre = np.array([0.0, half[1], 0.0])
    radius = float(np.linalg.norm(half))
    scene = {
        "type": "scene",
        "integrator": integrator or {"type": "volpathmis", "max_depth": -1, "rr_depth": 1 << 30},
        "sensor": _sensor(centre, radius, width, height, spp, rfilter),
        "object": translucent({**mesh_dict(mesh), "to_world": _matrix(to_world)}, material, unit_mm, boundary),
        **_lights(centre, radius),
    }
    if albedo_volume is not None and color_texture is not None:
        raise ConvsssError("an albedo volume and a colour texture given: give one")
    if albedo_volume is not None:
        margin = VOLUME_MARGIN * 2 * float(np.max(half))
        box = np.diag([*(2 * half + 2 * margin), 1.0])
        box[:3, 3] = [-half[0] - margin, -margin, -half[2] - margin]
        scene["object"]["interior"] = albedo_volume_dict(material, albedo_volume, _matrix(box), unit_mm)
    if color_texture is not None:
        if not shape.has_vertex_texcoords():
            raise ConvsssError(f"mesh {str(mesh)!r} has no texture coordinates (uv): a colour texture needs them")
        scene["object"]["interior"] = color_texture_medium(material, color_texture, material.mfp_mm, color_model,
                                                           unit_mm)
    if floor:
        scene["floor"] = _floor(radius)
    return scene


def _placement(mesh, shape, size):
    """The map that scales ``shape`` (of the file ``mesh``) to ``size`` scene units on its largest side, centred on
    the y axis and standing on y = 0 (4x4), and the half extent (3,) of the placed object."""
    lo, hi = shape_bounds(shape)
    extent = float(np.max(hi - lo))
    if extent <= 0:
        raise ConvsssError(f"mesh {str(mesh)!r} is flat or empty: it has no extent")
    s = size / extent
    centre_xz = 0.5 * (lo + hi)
    to_world = np.diag([s, s, s, 1.0])
    to_world[:3, 3] = [-s * centre_xz[0], -s * lo[1], -s * centre_xz[2]]
    return to_world, 0.5 * s * (hi - lo)


def _sensor(centre, radius, width, height, spp, rfilter):
    """The camera: 30° across the larger side, looking at ``centre`` from slightly above, the bounding sphere of
    ``radius`` filling about 80 % of the frame."""
    aspect = width / height
    half_fov = math.radians(FOV_DEG) / 2 if aspect >= 1 else math.atan(math.tan(math.radians(FOV_DEG) / 2) / aspect)
    distance = radius / math.sin(half_fov) / 0.8
    view = np.array([0.0, 0.25, 1.0]) / np.linalg.norm([0.0, 0.25, 1.0])
    camera = centre + distance * view
    return {
        "type": "perspective", "fov": FOV_DEG, "fov_axis": "larger",
        "near_clip": 0.01 * distance, "far_clip": 100.0 * distance,
        "to_world": _look_at(camera, centre),
        "film": {"type": "hdrfilm", "width": int(width), "height": int(height), "rfilter": {"type": rfilter}},
        "sampler": {"type": "independent", "sample_count": int(spp)},
    }


def _lights(centre, radius):
    """The key light high on the camera's left (irradiance about 1 at the object) and the back light behind it,
    about 3 times stronger."""
    key = centre + radius * np.array([-2.5, 3.0, 2.5])
    back = centre + radius * np.array([0.8, 1.0, -3.0])

    def intensity(position, irradiance):
        value = float(irradiance * np.sum((position - centre) ** 2))
        return {"type": "rgb", "value": [value, value, value]}

    return {"key_light": {"type": "point", "position": key.tolist(), "intensity": intensity(key, 1.0)},
            "back_light": {"type": "point", "position": back.tolist(), "intensity": intensity(back, 3.0)}}


def _floor(radius):
    """A large grey diffuse floor at y = 0."""
    return {
        "type": "rectangle",
        "to_world": _matrix(np.array([[20 * radius, 0, 0, 0], [0, 0, 20 * radius, 0],
                                      [0, -20 * radius, 0, 0], [0, 0, 0, 1.0]])),
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}},
    }
