"""What a translucent shape is made of, read from Mitsuba: its boundary BSDF -> ``(kind, eta)`` and its interior
medium -> :class:`~convsss.materials.Material` (a heterogeneous medium: its classes, :mod:`.media`), per mm; the
convention is :mod:`.objects`'.
"""

import numpy as np

from ..errors import ConvsssError
from ..materials import Material
from .media import SURVEY_POINTS, MediumField, medium_classes
from .surface import sample_surface

#: Mitsuba class names of the boundaries a translucent object may have.
BOUNDARY_CLASSES = {"Null": "null", "SmoothDielectric": "dielectric", "RoughDielectric": "roughdielectric"}


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
