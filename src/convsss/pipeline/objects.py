"""Translucent objects of a loaded Mitsuba scene: shape + boundary BSDF + interior medium -> Material.

Convention (docs/architecture.md): a shape is translucent when its ``interior`` is a ``homogeneous`` medium (or a
``heterogeneous`` one: :mod:`.media` makes its classes) and its BSDF is ``null`` (``eta = 1``), ``dielectric`` or
``roughdielectric`` (``eta = int_ior / ext_ior``, must be >= 1). The medium's coefficients are per scene unit; with
``u`` mm per unit,

    sigma_t [1/mm] = scale * sigma_t / u,   sigma_s = albedo * sigma_t,   sigma_a = sigma_t - sigma_s,
    sigma_s' = sigma_s (1 - g)     (g of an ``hg`` phase function; 0 when isotropic).

Every other shape is opaque. Lengths in :class:`TranslucentObject` are in mm.

Instancing: each ``instance`` of a ``shapegroup`` that holds a translucent shape is a translucent object of its own
(it sits elsewhere in the world, so it has its own samples, irradiance and transport). A ray that hits it reports the
group's shape (shared by all instances) in ``si.shape`` and the instance in ``si.instance``, so an object is known by
the pair ``(instance_index, shape_index)``, with ``instance_index = 0`` for a plain shape. Mitsuba forbids nested
instancing, so one level is all there is.
"""

import re
import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConvsssError
from ..materials import Material
from ..profiles.incidence import Orders
from ..profiles.models import DEFAULT_TOTAL, PROFILE_MODELS, parse_profile_spec, resolve_profile
from ..scene.presets import any_named_media, check_boundary, check_color_model, named_medium_of
from .media import SURVEY_POINTS, MediumField, medium_classes
from .surface import area_scale, has_vertices, mesh_arrays, sample_surface

#: Mitsuba class names of the boundaries a translucent object may have.
BOUNDARY_CLASSES = {"Null": "null", "SmoothDielectric": "dielectric", "RoughDielectric": "roughdielectric"}
#: The object may span at least / at most this many mean free paths before the units look wrong (a 2 m panel of
#: spectralon spans 4e4; a 40 mm bunny made 1000 times too large spans 1e5 in milk). It renders either way.
SPAN_LIMITS = (1e-3, 5e4)
#: Where diffusion holds (:meth:`TranslucentObject.diffusion_holds`): transport mean free paths across the object's
#: mean chord, and the least reduced albedo. Measured (docs/benchmarks.md, bench walk): the transport is within 2 %
#: of volpathmis on a 40 mm marble bunny (29-35 across, albedo 0.998) and 5-30 % off on a 40 mm skin1 bunny lit from
#: behind (10-20 across, albedo 0.68-0.96), a 4 mm milk bunny (3-5 across) and a 20 mm ketchup bunny (albedo 0.02-0.75).
DIFFUSION_SPAN = 20.0
DIFFUSION_ALBEDO = 0.95
#: Analytic shapes (Mitsuba class names) that bound a volume; disks, rectangles and cylinders are open.
CLOSED_ANALYTIC = ("Sphere",)
#: Stratified samples that estimate the world area of a shape under a map that is no similarity.
AREA_SAMPLES = 128 * 128


class MeshWarning(UserWarning):
    """The mesh of a translucent object is not a closed, consistently oriented surface."""


class UnitsWarning(UserWarning):
    """The object's size in mean free paths suggests wrong scene units."""


@dataclass(eq=False)
class TranslucentObject:
    """One translucent shape, or one instance of a translucent shape of a shapegroup, ready for sampling and transport.

    Attributes
    ----------
    shape : mitsuba.Shape        the shape; for an instance, the shapegroup's shape (in the group's space)
    name : str                   the shape's id; ``instance/shape`` for an instanced one
    material : Material          coefficients in 1/mm, ``eta`` of the boundary
    boundary : str               ``null``, ``dielectric`` or ``roughdielectric``
    profile : Profile            the object's profile: a model of ``material`` or the user's tabulated profile
    shape_index : int            the shape's index in Mitsuba's registry (what ``si.shape`` holds per lane)
    instance_index : int         the instance's index in that registry (what ``si.instance`` holds), 0 if none
    to_world : (4, 4) array      the instance's transform (scene units), the identity for a plain shape
    orientation : float          +1 if the shape's normals point outwards, -1 if they point inwards
    closed : bool                the surface is known to bound a volume (a watertight mesh, a sphere)
    bbox_mm : (2, 3) array       world-space bounding box in mm
    area_mm2 : float             world surface area in mm^2
    volume_mm3 : float           the volume it bounds in mm^3 (0 where the surface is not closed)
    classes : MediumClasses      a heterogeneous interior's classes (:mod:`.media`), None for a homogeneous one;
                                 ``material`` is then their mean
    class_profiles : tuple       the classes' profiles, in their order
    sampling : Material          the material whose ``sigma_t'`` draws the paths' random choices (Eq. S2's distance,
                                 Eq. S3's crossing; the estimate stays that of ``material``), None: the object's
                                 own; a fit keeps the scene's so that the image moves smoothly with ``material``
    """

    shape: object
    name: str
    material: Material
    boundary: str
    profile: object
    shape_index: int
    instance_index: int
    to_world: np.ndarray
    orientation: float
    closed: bool
    bbox_mm: np.ndarray
    area_mm2: float
    volume_mm3: float = 0.0
    classes: object = None
    class_profiles: tuple = ()
    sampling: Material = None

    @property
    def profiles(self):
        """Every profile the object's light spreads with: its classes' (a heterogeneous interior), or its one."""
        return self.class_profiles or (self.profile,)

    @property
    def materials(self):
        """The material of each of :attr:`profiles`: its classes' (a heterogeneous interior), or its one."""
        return tuple(self.classes.materials) if self.class_profiles else (self.material,)

    def with_material(self, material, profile):
        """This object made of one homogeneous ``material`` spreading light by ``profile`` (what the editor and
        :func:`convsss.fit` try; a heterogeneous interior's classes are dropped)."""
        return replace(self, material=material, profile=profile, classes=None, class_profiles=())

    def hit(self, shapes, instances):
        """Which lanes hit this object, from the per-lane registry indices of :func:`hit_indices`.

        Parameters
        ----------
        shapes, instances : numpy.ndarray or mitsuba.UInt32, shape (n,)
            Per lane, the registry indices of the shape hit and of its instance (0: none).

        Returns
        -------
        numpy.ndarray or mitsuba.Bool, shape (n,)
        """
        return (shapes == self.shape_index) & (instances == self.instance_index)

    @property
    def eta(self):
        return self.material.eta

    @property
    def extent_mm(self):
        """The largest side of the bounding box (mm)."""
        return float(np.max(self.bbox_mm[1] - self.bbox_mm[0]))

    @property
    def chord_mm(self):
        """The mean chord length ``4 V / A`` (Cauchy's formula; for a body that is not convex, the mean of its chords'
        pieces inside): how thick the object is on average, its thin parts weighed in (a sphere's: 4/3 of its
        radius). Where the surface bounds no known volume, the bounding box's shortest side."""
        if self.closed and self.volume_mm3 > 0.0:
            return 4.0 * self.volume_mm3 / self.area_mm2
        return float(np.min(self.bbox_mm[1] - self.bbox_mm[0]))

    def diffusion_holds(self):
        """Whether diffusion describes this object's light in every channel of every material in it: at least
        :data:`DIFFUSION_SPAN` transport mean free paths across its mean chord (:attr:`chord_mm`) and a reduced
        albedo of at least :data:`DIFFUSION_ALBEDO`. Where it does not, walks are also short (they leave a thin
        object, or are absorbed, within a few hundred events): what ``walk_depth = auto`` walks."""
        return all(bool(np.all(m.sigma_t_prime * self.chord_mm >= DIFFUSION_SPAN)
                        and np.all(m.albedo_prime >= DIFFUSION_ALBEDO)) for m in self.materials)

    def spans(self):
        """How many reduced mean free paths and diffusion lengths the object spans, per RGB channel."""
        with np.errstate(divide="ignore"):
            return {"mean_free_paths": (self.extent_mm / self.material.mfp_mm).tolist(),
                    "diffusion_lengths": (self.extent_mm / self.material.diffusion_length_mm).tolist()}

    def summary(self):
        """JSON-ready description for the render statistics."""
        return {"name": self.name, "boundary": self.boundary, "eta": self.eta, "area_mm2": self.area_mm2,
                "classes": len(self.materials), "extent_mm": self.extent_mm, "chord_mm": self.chord_mm,
                "diffusion_holds": self.diffusion_holds(),
                "bbox_mm": self.bbox_mm.tolist(),
                "sigma_s_prime_per_mm": self.material.sigma_s_prime.tolist(),
                "sigma_a_per_mm": self.material.sigma_a.tolist(),
                "profile": repr(self.profile), **self.spans()}


def _shape_name(shape, k):
    name = shape.id()
    return name if name and not name.startswith("_unnamed") else f"shape #{k} ({shape.class_name()})"


def _rgb(params, key, what, name):
    """An RGB triple of a constant volume parameter, or a one-line error for a spatially varying one."""
    if key not in params:
        raise ConvsssError(f"translucent shape {name!r}: its homogeneous medium's {what} varies in space; give it "
                           "rgb or float values, or make the medium heterogeneous (its volumes as sigma_t, albedo)")
    value = np.asarray(params[key], dtype=np.float64).reshape(-1)
    return np.broadcast_to(value, (3,)).copy() if value.size in (1, 3) else value[:3]


def phase_g(params):
    """The mean cosine ``g`` of a medium's phase function from its traversed ``params`` (0: isotropic)."""
    return float(np.asarray(params["phase_function.g"]).reshape(-1)[0]) if "phase_function.g" in params else 0.0


def medium_material(mi, medium, eta, unit_mm, name):
    """The :class:`Material` of a Mitsuba homogeneous ``medium`` whose coefficients are per scene unit."""
    params = mi.traverse(medium)
    sigma_t = _rgb(params, "sigma_t.value.value", "sigma_t", name)
    albedo = _rgb(params, "albedo.value.value", "albedo", name)
    scale = float(params["scale"]) if "scale" in params else 1.0
    return Material.from_medium(sigma_t * scale / unit_mm, albedo, 1.0, phase_g(params), eta, name)


def interior_material(mi, medium, eta, unit_mm, name, shape, to_world, orientation, bbox_mm):
    """``(material, classes)`` of a translucent shape's interior: a homogeneous medium's :class:`Material` and None;
    a heterogeneous medium's classes over the surface (:func:`~.media.medium_classes`, checked: covering the object,
    finite, non-negative, albedo at most 1) and their mean, or its one material where it does not vary there."""
    if medium.class_name() == "HomogeneousMedium":
        return medium_material(mi, medium, eta, unit_mm, name), None
    field = MediumField(medium, unit_mm, phase_g(mi.traverse(medium)), name)

    def surface(count, seed=0):
        """About ``count`` stratified surface points (mm), their outward normals and the surface's area (mm^2)."""
        position, normal, area = sample_surface(shape, count, seed=seed, orientation=orientation, to_world=to_world)
        points, normal = (np.asarray(a, dtype=np.float64).reshape(3, -1).T for a in (position, normal))
        return points * unit_mm, normal, float(np.sum(area.numpy(), dtype=np.float64)) * unit_mm**2

    survey, normal, area = surface(SURVEY_POINTS)
    checked = field.check(survey, bbox_mm)
    classes = medium_classes(field, survey, normal, eta, checked, lambda count: surface(count, seed=1)[:2], area)
    if isinstance(classes, Material):
        return classes, None
    return classes.mean, classes


def boundary_eta(mi, bsdf, name):
    """(boundary kind, relative index) of a translucent shape's BSDF, or a one-line error."""
    cls = bsdf.class_name() if bsdf is not None else "none"
    if cls not in BOUNDARY_CLASSES:
        raise ConvsssError(f"translucent shape {name!r} has a {cls!r} BSDF: a shape with an interior medium needs a "
                           "null, dielectric or roughdielectric BSDF")
    kind = BOUNDARY_CLASSES[cls]
    if kind == "null":
        return kind, 1.0
    params = mi.traverse(bsdf)
    for key in (k for k in params.keys() if k.split(".")[0] in ("alpha", "alpha_u", "alpha_v")):
        alpha = np.asarray(params[key], dtype=np.float64)
        if not (np.all(np.isfinite(alpha)) and np.all(alpha >= 0)):
            raise ConvsssError(f"translucent shape {name!r}: the roughdielectric's {key.split('.')[0]} = "
                               f"{alpha.reshape(-1)[:3].tolist()} is not allowed: roughness is finite and >= 0")
    eta = float(np.asarray(params["eta"]).reshape(-1)[0])
    if not eta >= 1.0:
        raise ConvsssError(f"translucent shape {name!r}: boundary eta = int_ior/ext_ior = {eta:.4g} is not allowed: "
                           "it must be >= 1 (the object denser than its surroundings)")
    return kind, eta


def mesh_topology(shape):
    """``(watertight, signed_volume, miswound)`` of a mesh in its own space (the world's, or its shapegroup's).

    Vertices closer than 1e-7 of the mesh's extent are merged first (loaders split vertices at normal or texture
    seams). Watertight: every edge joins exactly two faces. The signed volume ``sum_f v0 . (v1 x v2) / 6`` is
    positive when the faces wind around outward normals. ``miswound``: the edges that two faces traverse in the same
    direction (0 when the faces are wound consistently, each edge traversed once each way).
    """
    positions, faces = mesh_arrays(shape)
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


def _surface(mi, shape, name):
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
    """Warn (or refuse) as :func:`find_translucent_objects` does for every translucent surface that does not bound a
    volume: for a path tracer (``convsss reference``), which takes the scene as it is and never asks for objects."""
    checked = set()
    for name, shape, _ in scene_surfaces(mi, scene):
        index = shape_index(mi, shape)
        if shape.interior_medium() is not None and index not in checked:
            checked.add(index)
            _surface(mi, shape, name)


def _check_span(obj, unit_mm):
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
    """A one-line error for a point, spot or area light inside a closed translucent object: the diffusion model
    lights an object through its surface from outside (it would render the object black, or ignore an area light).
    Inside is decided by the parity of the object's surface crossings along a ray from the light (an area light's
    shape: from the centre of its bounding box)."""
    for emitter in scene.emitters():
        params = mi.traverse(emitter)
        if emitter.get_shape() is not None:
            position = np.asarray(emitter.get_shape().bbox().center(), dtype=np.float64).reshape(-1)[:3]
        elif "position" in params:
            position = np.asarray(params["position"], dtype=np.float64).reshape(-1)[:3]
        elif emitter.class_name() == "SpotLight" and "to_world" in params:
            position = np.asarray(params["to_world"].matrix, dtype=np.float64).reshape(4, 4)[:3, 3]
        else:
            continue
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
    """:func:`~convsss.scene.presets.check_boundary` (without units) for every shape of ``scene`` whose interior is a
    ``convsss_medium``; what ``convsss reference`` and :func:`~convsss.scene.loading.load_scene` check."""
    if not any_named_media():
        return
    for name, shape, _ in scene_surfaces(mi, scene):
        named = named_medium_of(mi, shape.interior_medium())
        if named is not None:
            boundary, eta = boundary_eta(mi, shape.bsdf(), name)
            check_boundary(named, boundary, eta, name)


def hit_indices(mi, si):
    """Per lane of a surface interaction ``si``: the (shape, instance) registry indices (0: none), which identify a
    translucent object (:meth:`TranslucentObject.hit`).

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


def find_translucent_objects(mi, scene, unit_mm=1.0, profile="", total=DEFAULT_TOTAL, orders=Orders.ALL,
                             lights_inside=False):
    """Every translucent shape of ``scene`` as a :class:`TranslucentObject`; a one-line error when there is none,
    and for a light inside one (:func:`check_lights_outside`) unless ``lights_inside`` (walks to their end reach it).

    ``profile`` is the renderer's ``profile`` parameter (:func:`~convsss.profiles.models.parse_profile_spec`): a
    model or CSV for every object, or per object by its name (the shape's id; ``instance/shape`` for an instance,
    whose instance id alone also selects it); ``total`` the renderer's ``profile_total`` (a model's total reflectance,
    :func:`~convsss.profiles.models.model_profile`) and ``orders`` what it carries
    (:attr:`~convsss.pipeline.params.RenderParams.orders`). Each instance of a shapegroup that holds a translucent shape
    gives an object of its own. Raises :class:`~convsss.errors.ConvsssError` for a shape whose interior medium is not
    homogeneous or has varying coefficients, a translucent shape with another BSDF, a boundary with ``eta < 1``, and
    a profile entry naming no translucent object, and a ``convsss_medium`` whose boundary or ``unit_mm`` disagrees
    with it (:func:`~convsss.scene.presets.check_boundary`); warns when a medium given by colour renders with
    another profile model than the colour's (:class:`~convsss.scene.presets.ColorModelWarning`).
    """
    default_spec, per_object = parse_profile_spec(profile)
    tables = {}  # one TabulatedProfile per CSV file
    objects = []
    surfaces = {}  # per shape: its instances share its mesh, checked once
    for name, shape, instance in scene_surfaces(mi, scene):
        medium = shape.interior_medium()
        if medium is None:
            continue
        if medium.class_name() not in ("HomogeneousMedium", "HeterogeneousMedium"):
            raise ConvsssError(f"shape {name!r} has a {medium.class_name()!r} interior medium: only 'homogeneous' "
                               "and 'heterogeneous' media are supported")
        boundary, eta = boundary_eta(mi, shape.bsdf(), name)
        named = named_medium_of(mi, medium)  # a <medium type="convsss_medium">: a preset, or colour + mfp
        if named is not None:
            check_boundary(named, boundary, eta, name, unit_mm)
        index = shape_index(mi, shape)
        if index not in surfaces:
            surfaces[index] = _surface(mi, shape, name)
        to_world = instance_to_world(mi, instance)
        bbox_mm = world_bbox(shape, to_world) * unit_mm
        mat, classes = interior_material(mi, medium, eta, unit_mm, name, shape, to_world, surfaces[index][0], bbox_mm)
        spec = per_object.get(name, per_object.get(name.split("/")[0], default_spec))
        check_color_model(named, spec, name, total)
        if spec not in PROFILE_MODELS and spec not in tables:
            if classes is not None:
                raise ConvsssError(f"translucent shape {name!r}: its medium varies in space, and a tabulated profile "
                                   f"({spec}) is one material's: give it a profile model")
            tables[spec] = resolve_profile(spec, mat, total, orders)
        obj = TranslucentObject(shape=shape, name=name, material=mat, boundary=boundary,
                                profile=tables.get(spec) or resolve_profile(spec, mat, total, orders),
                                shape_index=index, instance_index=0 if instance is None else shape_index(mi, instance),
                                to_world=to_world, orientation=surfaces[index][0], closed=surfaces[index][1],
                                bbox_mm=bbox_mm, area_mm2=world_area(shape, to_world) * unit_mm**2,
                                volume_mm3=surfaces[index][2] * abs(np.linalg.det(to_world[:3, :3])) * unit_mm**3,
                                classes=classes, class_profiles=() if classes is None else tuple(
                                    resolve_profile(spec, m, total, orders) for m in classes.materials))
        if not (np.all(np.isfinite(obj.bbox_mm)) and np.isfinite(obj.area_mm2)):
            raise ConvsssError(f"translucent shape {name!r} reaches infinity (a vertex or a transform that is not "
                               "finite, or too large for float32)")
        if not obj.area_mm2 > 0:
            raise ConvsssError(f"translucent shape {name!r} has no surface area (all its faces are degenerate)")
        _check_span(obj, unit_mm)
        objects.append(obj)
    if not objects:
        raise ConvsssError("the scene has no translucent shape: give a shape an interior 'homogeneous' medium and a "
                           "null, dielectric or roughdielectric BSDF")
    if not lights_inside:
        check_lights_outside(mi, scene, objects, unit_mm)
    warn_overlaps(mi, scene, objects)
    names = {o.name for o in objects} | {o.name.split("/")[0] for o in objects}
    unknown = sorted(set(per_object) - names)
    if unknown:
        raise ConvsssError(f"profile entry {unknown[0]!r}={per_object[unknown[0]]!r} names no translucent object; the "
                           f"translucent objects are: {', '.join(o.name for o in objects)}")
    return objects
