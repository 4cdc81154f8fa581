"""Scene traversal: the shapes a ray can hit, plain and instanced (a shapegroup's shapes placed by each instance), as
Mitsuba's registry indices know them, and where they lie in the world (bounding box, area).
"""

import re

import numpy as np

from ..errors import ConvsssError
from .surface import area_scale, sample_surface

#: Stratified samples that estimate the world area of a shape under a map that is no similarity.
AREA_SAMPLES = 128 * 128


def _shape_name(shape, k):
    name = shape.id()
    return name if name and not name.startswith("_unnamed") else f"shape #{k} ({shape.class_name()})"


def hit_indices(mi, si):
    """Per lane of a surface interaction ``si``: the (shape, instance) registry indices (0: none), which identify a
    translucent object (:meth:`~.objects.TranslucentObject.hit`).

    Parameters
    ----------
    mi : module
        Mitsuba, with its variant set.
    si : mitsuba.SurfaceInteraction3f
        n lanes.

    Returns
    -------
    shapes, instances : mitsuba.UInt32
        n lanes each (``.numpy()`` for numpy arrays).
    """
    import drjit as dr

    return dr.reinterpret_array(mi.UInt32, si.shape), dr.reinterpret_array(mi.UInt32, si.instance)


def shape_index(mi, shape):
    """The index of ``shape`` in Mitsuba's instance registry: the value a ``ShapePtr`` lane holds for it."""
    import drjit as dr

    return int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])


def shapegroup_id(instance):
    """The id of the shapegroup that a Mitsuba ``instance`` draws.

    Mitsuba 3 has no accessor for it; the instance's description names it (``Instance[ shapegroup = ShapeGroup[
    name = "group", ...``), so it is read from there, with a one-line error if that format ever changes.
    """
    match = re.search(r'shapegroup\s*=\s*ShapeGroup\[\s*name\s*=\s*"([^"]*)"', str(instance))
    if match is None:
        raise ConvsssError(f"instance {instance.id()!r}: cannot tell which shapegroup it draws (Mitsuba's "
                           "description of an instance has no 'shapegroup = ShapeGroup[ name = ...'); instanced "
                           "translucent shapes need a Mitsuba version that describes instances that way")
    return match.group(1)


def shapegroup_shapes(mi, scene):
    """``{shapegroup id: [its shapes]}`` from Mitsuba's parameter tree, whose ``hierarchy`` maps each node to its
    parent (a shape whose parent is a shape is a member of a shapegroup)."""
    members = {}
    for node, (parent, _) in mi.traverse(scene).hierarchy.items():
        if isinstance(node, mi.Shape) and isinstance(parent, mi.Shape):
            members.setdefault(parent.id(), []).append(node)
    return members


def scene_surfaces(mi, scene):
    """Every shape a ray can hit, as ``(name, shape, instance)``: each plain shape of ``scene`` (``instance`` None)
    and, for each instance, each shape of its shapegroup."""
    shapes = scene.shapes()
    instanced = any(shape.class_name() == "Instance" for shape in shapes)
    members = shapegroup_shapes(mi, scene) if instanced else {}
    for k, shape in enumerate(shapes):
        name = _shape_name(shape, k)
        if shape.class_name() != "Instance":
            yield name, shape, None
            continue
        group = shapegroup_id(shape)
        if group not in members:
            raise ConvsssError(f"instance {name!r} draws shapegroup {group!r}, whose shapes are not in the scene's "
                               "parameters")
        for j, member in enumerate(members[group]):
            yield f"{name}/{_shape_name(member, j)}", member, shape


def instance_to_world(mi, instance):
    """The (4, 4) transform of ``instance`` (scene units); the identity for a plain shape (``instance`` None).

    Returns
    -------
    numpy.ndarray, shape (4, 4), float64
    """
    if instance is None:
        return np.identity(4)
    return np.array(mi.traverse(instance)["to_world"].matrix, dtype=np.float64).reshape(4, 4)


def world_bbox(shape, to_world):
    """(2, 3) world bounding box of ``shape`` placed by ``to_world``: the box around its bbox's 8 mapped corners.

    Parameters
    ----------
    shape : mitsuba.Shape
    to_world : numpy.ndarray, shape (4, 4), float64
        The shape's placement (scene units): its instance's transform, or the identity.

    Returns
    -------
    numpy.ndarray, shape (2, 3), float64
        The lowest and the highest corner, in scene units.
    """
    box = shape.bbox()
    low, high = np.array(list(box.min), dtype=np.float64), np.array(list(box.max), dtype=np.float64)
    corners = np.array([[x, y, z, 1.0] for x in (low[0], high[0]) for y in (low[1], high[1])
                        for z in (low[2], high[2])])
    with np.errstate(all="ignore"):  # a transform at infinity gives inf or NaN corners: refused by the caller
        mapped = corners @ to_world.T
    return np.array([mapped[:, :3].min(axis=0), mapped[:, :3].max(axis=0)])


def emitter_bounds(mi, emitter):
    """(2, 3) world box of where ``emitter`` shines from, in scene units: an area light's shape's bounding box, a
    point, spot or projector light's position (a box of no size); None for a light at infinity (an environment, a
    directional light) or one of no known place."""
    if mi.has_flag(emitter.flags(), mi.EmitterFlags.Infinite):
        return None
    if emitter.get_shape() is not None:
        return world_bbox(emitter.get_shape(), np.identity(4))
    params = mi.traverse(emitter)
    if "position" in params:
        position = np.asarray(params["position"], dtype=np.float64).reshape(-1)[:3]
    elif "to_world" in params:
        position = np.array(params["to_world"].matrix, dtype=np.float64).reshape(4, 4)[:3, 3]
    else:
        return None
    return np.array([position, position])


def world_area(shape, to_world):
    """World area of ``shape`` placed by ``to_world``: its own area times ``s^2`` for a similarity (a plain shape:
    ``s = 1``), else ``sum_i A_i`` over :data:`AREA_SAMPLES` samples of
    :func:`~convsss.pipeline.surface.sample_surface`.

    Parameters
    ----------
    shape : mitsuba.Shape
    to_world : numpy.ndarray, shape (4, 4), float64
        The shape's placement (scene units): its instance's transform, or the identity.

    Returns
    -------
    float
        The area in scene units squared.
    """
    local = float(np.asarray(shape.surface_area()).reshape(-1)[0])
    scale = area_scale(to_world[:3, :3])
    if scale is not None:
        return local * scale
    _, _, area = sample_surface(shape, AREA_SAMPLES, seed=0, to_world=to_world)
    return float(np.sum(area.numpy(), dtype=np.float64))
