"""Translucent objects of a loaded Mitsuba scene: shape + boundary BSDF + interior homogeneous medium -> Material.

Convention (DESIGN.md): a shape is translucent when its ``interior`` is a ``homogeneous`` medium and its BSDF is
``null`` (``eta = 1``), ``dielectric`` or ``roughdielectric`` (``eta = int_ior / ext_ior``, must be >= 1). The medium's
coefficients are per scene unit; with ``u`` mm per unit,

    sigma_t [1/mm] = scale * sigma_t / u,   sigma_s = albedo * sigma_t,   sigma_a = sigma_t - sigma_s,
    sigma_s' = sigma_s (1 - g)     (g of an ``hg`` phase function; 0 when isotropic).

Every other shape is opaque. Lengths in :class:`TranslucentObject` are in mm.
"""

import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import ConvsssError
from ..materials import Material
from ..profiles import TabulatedProfile

#: Mitsuba class names of the boundaries a translucent object may have.
BOUNDARY_CLASSES = {"Null": "null", "SmoothDielectric": "dielectric", "RoughDielectric": "roughdielectric"}
#: The object may span at most / at least this many mean free paths before the units look wrong.
SPAN_LIMITS = (1e-3, 1e6)


class MeshWarning(UserWarning):
    """The mesh of a translucent object is not a closed, consistently oriented surface."""


class UnitsWarning(UserWarning):
    """The object's size in mean free paths suggests wrong scene units."""


@dataclass(eq=False)
class TranslucentObject:
    """One translucent shape, ready for sampling and transport.

    Attributes
    ----------
    shape : mitsuba.Shape
    name : str
    material : Material          coefficients in 1/mm, ``eta`` of the boundary
    boundary : str               ``null``, ``dielectric`` or ``roughdielectric``
    profile : Profile            the dipole of ``material``, or the user's tabulated profile
    shape_index : int            the shape's index in Mitsuba's registry (what ``si.shape`` holds per lane)
    orientation : float          +1 if the shape's normals point outwards, -1 if they point inwards
    bbox_mm : (2, 3) array       world-space bounding box in mm
    area_mm2 : float             surface area in mm^2
    """

    shape: object
    name: str
    material: Material
    boundary: str
    profile: object
    shape_index: int
    orientation: float
    bbox_mm: np.ndarray
    area_mm2: float

    @property
    def eta(self):
        return self.material.eta

    @property
    def extent_mm(self):
        """The largest side of the bounding box (mm)."""
        return float(np.max(self.bbox_mm[1] - self.bbox_mm[0]))

    def spans(self):
        """How many reduced mean free paths and diffusion lengths the object spans, per RGB channel."""
        with np.errstate(divide="ignore"):
            return {"mean_free_paths": (self.extent_mm / self.material.mfp_mm).tolist(),
                    "diffusion_lengths": (self.extent_mm / self.material.diffusion_length_mm).tolist()}

    def summary(self):
        """JSON-ready description for the render statistics."""
        return {"name": self.name, "boundary": self.boundary, "eta": self.eta, "area_mm2": self.area_mm2,
                "extent_mm": self.extent_mm, "bbox_mm": self.bbox_mm.tolist(),
                "sigma_s_prime_per_mm": self.material.sigma_s_prime.tolist(),
                "sigma_a_per_mm": self.material.sigma_a.tolist(),
                "profile": repr(self.profile), **self.spans()}


def _shape_name(shape, k):
    name = shape.id()
    return name if name and not name.startswith("_unnamed") else f"shape #{k} ({shape.class_name()})"


def _rgb(params, key, what, name):
    """An RGB triple of a constant volume parameter, or a one-line error for a spatially varying one."""
    if key not in params:
        raise ConvsssError(f"translucent shape {name!r}: the medium's {what} varies in space; "
                           "only constant values are supported (a homogeneous medium with rgb or float values)")
    value = np.asarray(params[key], dtype=np.float64).reshape(-1)
    return np.broadcast_to(value, (3,)).copy() if value.size in (1, 3) else value[:3]


def medium_material(mi, medium, eta, unit_mm, name):
    """The :class:`Material` of a Mitsuba homogeneous ``medium`` whose coefficients are per scene unit."""
    params = mi.traverse(medium)
    sigma_t = _rgb(params, "sigma_t.value.value", "sigma_t", name)
    albedo = _rgb(params, "albedo.value.value", "albedo", name)
    scale = float(params["scale"]) if "scale" in params else 1.0
    g = float(np.asarray(params["phase_function.g"]).reshape(-1)[0]) if "phase_function.g" in params else 0.0
    return Material.from_medium(sigma_t * scale / unit_mm, albedo, 1.0, g, eta, name)


def boundary_eta(mi, bsdf, name):
    """(boundary kind, relative index) of a translucent shape's BSDF, or a one-line error."""
    cls = bsdf.class_name() if bsdf is not None else "none"
    if cls not in BOUNDARY_CLASSES:
        raise ConvsssError(f"translucent shape {name!r} has a {cls!r} BSDF: a shape with an interior medium needs a "
                           "null, dielectric or roughdielectric BSDF")
    kind = BOUNDARY_CLASSES[cls]
    if kind == "null":
        return kind, 1.0
    eta = float(np.asarray(mi.traverse(bsdf)["eta"]).reshape(-1)[0])
    if not eta >= 1.0:
        raise ConvsssError(f"translucent shape {name!r}: boundary eta = int_ior/ext_ior = {eta:.4g} is not allowed: "
                           "it must be >= 1 (the object denser than its surroundings)")
    return kind, eta


def mesh_topology(mi, shape):
    """``(watertight, signed_volume)`` of a mesh in its world space.

    Vertices closer than 1e-7 of the mesh's extent are merged first (loaders split vertices at normal or texture
    seams). Watertight: every edge joins exactly two faces. The signed volume ``sum_f v0 . (v1 x v2) / 6`` is
    positive when the faces wind around outward normals.
    """
    params = mi.traverse(shape)
    positions = np.asarray(params["vertex_positions"], dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(params["faces"], dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        return False, 0.0
    extent = max(float(np.max(np.ptp(positions, axis=0))), 1e-30)
    _, first, index = np.unique(np.round(positions / extent * 1e7), axis=0, return_index=True, return_inverse=True)
    merged = positions[first]
    faces = index.reshape(-1)[faces]
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])]
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    watertight = bool(len(counts)) and bool(np.all(counts == 2))
    v0, v1, v2 = (merged[faces[:, k]] for k in range(3))
    signed_volume = float(np.sum(np.einsum("ij,ij->i", v0, np.cross(v1, v2))) / 6.0)
    return watertight, signed_volume


def _orientation(mi, shape, name):
    """+1 if the outward normal is the shape's normal, -1 if a closed mesh is wound inwards; warns on open meshes."""
    if not shape.is_mesh():
        return 1.0
    watertight, volume = mesh_topology(mi, shape)
    if not watertight:
        warnings.warn(f"translucent mesh {name!r} is not watertight (some edges do not join exactly two faces): "
                      "irradiance leaks through its holes and its inside is ill-defined", MeshWarning, stacklevel=4)
    if volume < 0:
        warnings.warn(f"translucent mesh {name!r} has inward-facing normals; they are flipped for shading",
                      MeshWarning, stacklevel=4)
        return -1.0
    return 1.0


def _check_span(obj):
    mfp = np.asarray(obj.spans()["mean_free_paths"])
    low, high = SPAN_LIMITS
    if np.any(mfp < low) or np.any(mfp > high):
        warnings.warn(f"translucent shape {obj.name!r} spans {np.round(mfp, 6).tolist()} mean free paths "
                      f"(extent {obj.extent_mm:.4g} mm): outside [{low:g}, {high:g}] the scene units are probably "
                      "wrong; set the integrator's unit_mm to the mm per scene unit", UnitsWarning, stacklevel=4)


def shape_index(mi, shape):
    """The index of ``shape`` in Mitsuba's instance registry: the value a ``ShapePtr`` lane holds for it."""
    import drjit as dr

    return int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape))[0])


def find_translucent_objects(mi, scene, unit_mm=1.0, profile_csv=""):
    """Every translucent shape of ``scene`` as a :class:`TranslucentObject`; a one-line error when there is none.

    Raises :class:`~convsss.errors.ConvsssError` for a shape whose interior medium is not homogeneous or has varying
    coefficients, a translucent shape with another BSDF, and a boundary with ``eta < 1``.
    """
    user_profile = TabulatedProfile.from_csv(profile_csv) if profile_csv else None
    objects = []
    for k, shape in enumerate(scene.shapes()):
        medium = shape.interior_medium()
        if medium is None:
            continue
        name = _shape_name(shape, k)
        if medium.class_name() != "HomogeneousMedium":
            raise ConvsssError(f"shape {name!r} has a {medium.class_name()!r} interior medium: only 'homogeneous' "
                               "media are supported")
        boundary, eta = boundary_eta(mi, shape.bsdf(), name)
        mat = medium_material(mi, medium, eta, unit_mm, name)
        box = shape.bbox()
        area_mm2 = float(np.asarray(shape.surface_area()).reshape(-1)[0]) * unit_mm**2
        bbox = np.array([list(box.min), list(box.max)], dtype=np.float64) * unit_mm
        obj = TranslucentObject(shape=shape, name=name, material=mat, boundary=boundary,
                                profile=user_profile if user_profile is not None else mat.profile(),
                                shape_index=shape_index(mi, shape), orientation=_orientation(mi, shape, name),
                                bbox_mm=bbox, area_mm2=area_mm2)
        _check_span(obj)
        objects.append(obj)
    if not objects:
        raise ConvsssError("the scene has no translucent shape: give a shape an interior 'homogeneous' medium and a "
                           "null, dielectric or roughdielectric BSDF")
    return objects
