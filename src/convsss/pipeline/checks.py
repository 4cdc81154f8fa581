"""What is checked of a scene's translucent shapes, with a warning or a one-line refusal: closed, consistently wound
surfaces, sizes in mean free paths that suggest the right units, no light inside an object, no two objects
overlapping, ``convsss_medium`` boundaries that agree with their presets, a walked object's nearly smooth rough
boundary under a delta light.
"""

import hashlib
import warnings
from collections import OrderedDict

import numpy as np

from ..errors import ConvsssError
from ..media.named import any_named_media, check_boundary, named_medium_of
from .interiors import boundary_eta
from .surface import has_vertices, mesh_arrays
from .traversal import emitter_bounds, hit_indices, scene_surfaces, shape_index

#: The object may span at least / at most this many mean free paths before the units look wrong (a 2 m panel of
#: spectralon spans 4e4; a 40 mm bunny made 1000 times too large spans 1e5 in milk). It renders either way.
SPAN_LIMITS = (1e-3, 5e4)
#: Analytic shapes (Mitsuba class names) that bound a volume; disks, rectangles and cylinders are open.
CLOSED_ANALYTIC = ("Sphere",)
#: :func:`mesh_topology` of the last meshes seen, by a digest of their vertices and faces: a render checks its
#: meshes at the load and again when it surveys its objects, and a session surveys again for every render.
TOPOLOGIES = OrderedDict()
TOPOLOGIES_KEPT = 16


class MeshWarning(UserWarning):
    """The mesh of a translucent object is not a closed, consistently oriented surface."""


class UnitsWarning(UserWarning):
    """The object's size in mean free paths suggests wrong scene units."""


def mesh_topology(shape):
    """``(watertight, signed_volume, miswound)`` of a mesh in its own space (the world's, or its shapegroup's).

    Vertices closer than 1e-7 of the mesh's extent are merged first (loaders split vertices at normal or texture
    seams). Watertight: every edge joins exactly two faces. The signed volume ``sum_f v0 . (v1 x v2) / 6`` is
    positive when the faces wind around outward normals. ``miswound``: the edges that two faces traverse in the same
    direction (0 when the faces are wound consistently, each edge traversed once each way).
    """
    positions, faces = mesh_arrays(shape)
    digest = hashlib.blake2b(positions.tobytes(), digest_size=16)
    digest.update(faces.tobytes())
    key = digest.digest()
    if key not in TOPOLOGIES:
        TOPOLOGIES[key] = _topology(positions, faces)
        while len(TOPOLOGIES) > TOPOLOGIES_KEPT:
            TOPOLOGIES.popitem(last=False)
    TOPOLOGIES.move_to_end(key)
    return TOPOLOGIES[key]


def _topology(positions, faces):
    if len(faces) == 0:
        return False, 0.0, 0
    extent = max(float(np.max(np.ptp(positions, axis=0))), 1e-30)
    _, first, index = np.unique(np.round(positions / extent * 1e7), axis=0, return_index=True, return_inverse=True)
    merged = positions[first]
    faces = index.reshape(-1)[faces]
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])]
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edges = np.sort(directed, axis=1)
    _, counts = np.unique(edges[:, 0] * len(merged) + edges[:, 1], return_counts=True)  # one int64 key per edge
    watertight = bool(len(counts)) and bool(np.all(counts == 2))
    _, twice = np.unique(directed[:, 0] * len(merged) + directed[:, 1], return_counts=True)
    v0, v1, v2 = (merged[faces[:, k]] for k in range(3))
    signed_volume = float(np.sum(np.einsum("ij,ij->i", v0, np.cross(v1, v2))) / 6.0)
    return watertight, signed_volume, int(np.sum(twice > 1))


def check_surface(mi, shape, name):
    """``(orientation, closed, volume)``: +1 if the outward normal is the shape's normal, -1 if a closed mesh is wound
    inwards; whether the shape is known to bound a volume; that volume in the shape's own space (0 if not closed).
    Warns on open or unknown surfaces."""
    if not has_vertices(shape):
        closed = shape.class_name() in CLOSED_ANALYTIC
        if not closed:
            warnings.warn(f"translucent shape {name!r} is a {shape.class_name()!r}, not known to be a closed "
                          "surface: the diffusion model needs an object that bounds a volume", MeshWarning,
                          stacklevel=4)
        box = shape.bbox()  # a sphere, scaled by its transform: the ellipsoid its box holds
        with np.errstate(invalid="ignore", over="ignore"):  # an infinite one is refused once its box is known
            volume = float(np.pi / 6.0 * np.prod(np.asarray(box.max) - np.asarray(box.min))) if closed else 0.0
        return 1.0, closed, volume
    watertight, volume, miswound = mesh_topology(shape)
    if miswound:
        raise ConvsssError(f"translucent mesh {name!r} has faces wound both ways ({miswound} edges traversed twice in "
                           "the same direction): its inside and outside are ill-defined; orient its faces "
                           "consistently (e.g. Blender's Recalculate Outside)")
    if not watertight:
        warnings.warn(f"translucent mesh {name!r} is not watertight (some edges do not join exactly two faces): "
                      "light leaks through its holes and its inside is ill-defined", MeshWarning, stacklevel=4)
    if volume < 0:
        warnings.warn(f"translucent mesh {name!r} has inward-facing normals; they are flipped for shading",
                      MeshWarning, stacklevel=4)
        return -1.0, watertight, -volume if watertight else 0.0
    return 1.0, watertight, volume if watertight else 0.0


def check_surfaces(mi, scene):
    """Warn (or refuse) as :func:`~.objects.find_translucent_objects` does for every translucent surface that does
    not bound a volume: for a path tracer (``convsss reference``), which takes the scene as it is and never asks for
    objects. Returns the names of those open surfaces."""
    checked, open_ = set(), []
    for name, shape, _ in scene_surfaces(mi, scene):
        index = shape_index(mi, shape)
        if shape.interior_medium() is not None and index not in checked:
            checked.add(index)
            if not check_surface(mi, shape, name)[1]:
                open_.append(name)
    return open_


def check_span(obj, unit_mm):
    """Warn, in one line naming the span and ``unit_mm``, when the object's size in mean free paths suggests wrong
    scene units (outside :data:`SPAN_LIMITS`) or an object too thin for diffusion (under one mean free path in every
    channel: nearly transparent, which a diffusion profile cannot render)."""
    mfp = np.asarray(obj.spans()["mean_free_paths"])
    low, high = SPAN_LIMITS
    where = (f"translucent shape {obj.name!r} spans {np.min(mfp):.3g}-{np.max(mfp):.3g} mean free paths (extent "
             f"{obj.extent_mm:.4g} mm at unit_mm = {unit_mm:g} mm per scene unit)")
    if np.any(mfp < low) or np.any(mfp > high):
        warnings.warn(f"{where}: outside [{low:g}, {high:g}] the scene units are probably wrong; set the "
                      "integrator's unit_mm to the mm per scene unit", UnitsWarning, stacklevel=4)
    elif np.all(mfp < 1.0):
        warnings.warn(f"{where}: under one mean free path the object is nearly transparent and the diffusion model "
                      "does not hold (path trace it with `convsss reference`), or unit_mm is wrong", UnitsWarning,
                      stacklevel=4)


def check_lights_outside(mi, scene, objects, unit_mm):
    """A one-line error for a point, spot, projector or area light inside a closed translucent object: the diffusion
    model lights an object through its surface from outside (it would render the object black, or ignore an area
    light). Inside is decided by the parity of the object's surface crossings along a ray from the light (an area
    light's shape: from the centre of its bounding box, :func:`~.traversal.emitter_bounds`)."""
    for emitter in scene.emitters():
        bounds = emitter_bounds(mi, emitter)
        if bounds is None:
            continue
        position = bounds.mean(axis=0)
        for obj in objects:
            lo, hi = obj.bbox_mm / unit_mm  # scene units, as the light's position
            if not (obj.closed and np.all(position >= lo) and np.all(position <= hi)):
                continue
            if _inside(mi, scene, obj, position[None])[0]:
                name = emitter.get_shape().id() if emitter.get_shape() is not None else emitter.id()
                raise ConvsssError(f"light {name!r} is inside translucent shape {obj.name!r}: the diffusion "
                                   "model lights objects through their surface from outside; move the light out, or "
                                   "render the scene with --walk-depth inf (random walks) or `convsss reference`")


class OverlapWarning(UserWarning):
    """Two translucent objects overlap: each is rendered as if the other were not there."""


#: Surface points of each object tested inside the others (:func:`warn_overlaps`).
OVERLAP_POINTS = 64


def _inside(mi, scene, obj, points):
    """Which of ``points`` (K, 3; scene units) lie inside the closed object ``obj``: the parity of its surface's
    crossings along a ray from each (other shapes crossed on the way are stepped over; at most 10 000)."""
    import drjit as dr

    ray = mi.Ray3f(mi.Point3f(*np.ascontiguousarray(np.asarray(points, dtype=np.float32).T)),
                   mi.Vector3f(0.5773503, 0.5773503, 0.5773503))
    crossings = np.zeros(len(points), dtype=np.int64)
    active = dr.full(mi.Bool, True, len(points))
    for _ in range(10_000):
        si = scene.ray_intersect(ray, active)
        active &= si.is_valid()
        if not dr.any(active):
            break
        crossings += np.asarray(obj.hit(*(a.numpy() for a in hit_indices(mi, si)))) & active.numpy()
        ray = si.spawn_ray(ray.d)
    return crossings % 2 == 1


def warn_overlaps(mi, scene, objects):
    """Warn (:class:`OverlapWarning`) for each pair of closed translucent objects where surface points of one lie
    inside the other: each is rendered as its own medium in vacuum, where light crosses both (measured 0.78 of path
    tracing, issue 51)."""
    from .surface import sample_surface

    closed = [o for o in objects if o.closed]
    for k, a in enumerate(closed):
        for b in closed[k + 1:]:
            if np.any(a.bbox_mm[1] < b.bbox_mm[0]) or np.any(b.bbox_mm[1] < a.bbox_mm[0]):
                continue
            for one, other in ((a, b), (b, a)):
                position, _, _ = sample_surface(one.shape, OVERLAP_POINTS, seed=0, to_world=one.to_world)
                points = np.asarray(position, dtype=np.float64).reshape(3, -1).T
                share = float(np.mean(_inside(mi, scene, other, points)))
                if share > 0.02:
                    warnings.warn(f"translucent shapes {one.name!r} and {other.name!r} overlap ({share:.0%} of "
                                  f"{one.name!r}'s surface inside {other.name!r}): each is rendered as if the other "
                                  "were not there; make their volumes disjoint (a shared face: one shape between the "
                                  "two media)", OverlapWarning, stacklevel=3)
                    break


def check_named_media(mi, scene):
    """:func:`~convsss.media.named.check_boundary` (without units) for every shape of ``scene`` whose interior is a
    ``convsss_medium``; what ``convsss reference`` and :func:`~convsss.scene.loading.load_scene` check."""
    if not any_named_media():
        return
    for name, shape, _ in scene_surfaces(mi, scene):
        named = named_medium_of(mi, shape.interior_medium())
        if named is not None:
            boundary, eta = boundary_eta(mi, shape.bsdf(), name)
            check_boundary(named, boundary, eta, name)


#: Below this roughness a rough dielectric boundary lets a delta light in along a lobe that walks all but never find.
NEAR_DELTA_ALPHA = 0.1


class NearDeltaBoundaryWarning(UserWarning):
    """A walked object's rough dielectric boundary is nearly smooth and a delta light is in the scene."""


def warn_near_delta_boundaries(scene, objects):
    """Warn for each object of ``objects`` whose ``roughdielectric`` boundary has a roughness below
    :data:`NEAR_DELTA_ALPHA` where the scene has a point, spot or directional light: its light reaches the medium only
    through the boundary's near-delta lobe, which next-event estimation at the boundary hits by chance (Eq. W4 takes
    a smooth boundary's light straight through; a rough one's is left to its BSDF), so the object renders dark and
    noisy (issue 62: a 2 mm milk sphere at alpha 0.01 read 6e-10 against the smooth boundary's 0.037)."""
    import drjit as dr

    from ..backend import import_mitsuba

    mi = import_mitsuba()
    if not any(mi.has_flag(e.flags(), mi.EmitterFlags.Delta) for e in scene.emitters()):
        return
    for obj in objects:
        if obj.boundary != "roughdielectric":
            continue
        params = mi.traverse(obj.shape.bsdf())
        alphas = [float(dr.min(params[k])[0]) for k in params.keys() if k.startswith("alpha") and k.endswith("value")]
        if alphas and min(alphas) < NEAR_DELTA_ALPHA:
            warnings.warn(f"translucent shape {obj.name!r}: its rough dielectric boundary (alpha {min(alphas):g}) lets "
                          "a point, spot or directional light in only along a near-delta lobe, which the random walk "
                          "finds by chance: expect it dark and noisy under such a light (a smooth dielectric, an area "
                          f"light, or alpha >= {NEAR_DELTA_ALPHA:g} render it)", NearDeltaBoundaryWarning,
                          stacklevel=4)
