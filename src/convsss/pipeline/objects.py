"""Translucent objects of a loaded Mitsuba scene: shape + boundary BSDF + interior medium -> Material.

Convention (docs/architecture.md): a shape is translucent when its ``interior`` is a ``homogeneous`` medium (or a
``heterogeneous`` one: :mod:`.media` makes its classes) and its BSDF is ``null`` (``eta = 1``), ``dielectric`` or
``roughdielectric`` (``eta = int_ior / ext_ior``, must be >= 1). The medium's coefficients are per scene unit; with
``u`` mm per unit,

    sigma_t [1/mm] = scale * sigma_t / u,   sigma_s = albedo * sigma_t,   sigma_a = sigma_t - sigma_s,
    sigma_s' = sigma_s (1 - g)     (g of an ``hg`` phase function; 0 when isotropic).

Every other shape is opaque. Lengths in :class:`TranslucentObject` are in mm. A shape's boundary and interior are read
by :mod:`.interiors`, the scene's shapes walked by :mod:`.traversal`, and the objects checked by :mod:`.checks`.

Instancing: each ``instance`` of a ``shapegroup`` that holds a translucent shape is a translucent object of its own
(it sits elsewhere in the world, so it has its own samples, irradiance and transport). A ray that hits it reports the
group's shape (shared by all instances) in ``si.shape`` and the instance in ``si.instance``, so an object is known by
the pair ``(instance_index, shape_index)``, with ``instance_index = 0`` for a plain shape. Mitsuba forbids nested
instancing, so one level is all there is.
"""

from dataclasses import dataclass, replace

import numpy as np

from ..errors import ConvsssError
from ..materials import Material
from ..media.named import check_boundary, check_color_model, named_medium_of
from ..profiles.incidence import Orders
from ..profiles.models import DEFAULT_TOTAL, PROFILE_MODELS, parse_profile_spec, resolve_profile
from .checks import check_lights_outside, check_span, check_surface, warn_overlaps
from .interiors import boundary_eta, interior_material
from .traversal import instance_to_world, scene_surfaces, shape_index, world_area, world_bbox

#: Where diffusion holds (:meth:`TranslucentObject.diffusion_holds`): transport mean free paths across the object's
#: mean chord, and the least reduced albedo. Measured (docs/benchmarks.md, bench walk): the transport is within 2 %
#: of volpathmis on a 40 mm marble bunny (29-35 across, albedo 0.998) and 5-30 % off on a 40 mm skin1 bunny lit from
#: behind (10-20 across, albedo 0.68-0.96), a 4 mm milk bunny (3-5 across) and a 20 mm ketchup bunny (albedo 0.02-0.75).
DIFFUSION_SPAN = 20.0
DIFFUSION_ALBEDO = 0.95


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
        """Which lanes hit this object, from the per-lane registry indices of :func:`~.traversal.hit_indices`.

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
    def key(self):
        """``(shape_index, instance_index)``: the object, whatever list it is in."""
        return self.shape_index, self.instance_index

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


def find_translucent_objects(mi, scene, unit_mm=1.0, profile="", total=DEFAULT_TOTAL, orders=Orders.ALL,
                             lights_inside=False):
    """Every translucent shape of ``scene`` as a :class:`TranslucentObject`; a one-line error when there is none,
    and for a light inside one (:func:`~.checks.check_lights_outside`) unless ``lights_inside`` (walks to their end
    reach it).

    ``profile`` is the renderer's ``profile`` parameter (:func:`~convsss.profiles.models.parse_profile_spec`): a
    model or CSV for every object, or per object by its name (the shape's id; ``instance/shape`` for an instance,
    whose instance id alone also selects it); ``total`` the renderer's ``profile_total`` (a model's total reflectance,
    :func:`~convsss.profiles.models.model_profile`) and ``orders`` what it carries
    (:attr:`~convsss.pipeline.params.RenderParams.orders`). Each instance of a shapegroup that holds a translucent shape
    gives an object of its own. Raises :class:`~convsss.errors.ConvsssError` for a shape whose interior medium is not
    homogeneous or has varying coefficients, a translucent shape with another BSDF, a boundary with ``eta < 1``, and
    a profile entry naming no translucent object, and a ``convsss_medium`` whose boundary or ``unit_mm`` disagrees
    with it (:func:`~convsss.media.named.check_boundary`); warns when a medium given by colour renders with
    another profile model than the colour's (:class:`~convsss.media.named.ColorModelWarning`).
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
            surfaces[index] = check_surface(mi, shape, name)
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
        check_span(obj, unit_mm)
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
