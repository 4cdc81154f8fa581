"""A translucent material written as Mitsuba scene data: the ``sigma_t / scale / albedo`` form of RGB mode.

A :class:`~convsss.materials.Material` holds ``sigma_s'`` and ``sigma_a`` in 1/mm. Mitsuba's ``homogeneous`` medium
wants ``sigma_t`` (extinction), ``albedo = sigma_s / sigma_t`` and a ``scale``, per *scene unit*, and its RGB mode
refuses ``sigma_t`` values above 1. So, with an isotropic phase function (``g = 0``, hence ``sigma_s = sigma_s'``)
and ``u`` mm per scene unit:

    sigma_t = (sigma_a + sigma_s') u,    scale = max_c sigma_t,    stored sigma_t = sigma_t / scale,
    albedo = sigma_s' / (sigma_a + sigma_s').

The boundary is ``null`` (index-matched, ``eta = 1``), ``dielectric`` or ``roughdielectric`` with
``int_ior = eta`` (docs/architecture.md, physics conventions). Everything here is plain dictionaries, no Mitsuba import.
"""

import numpy as np

from ..errors import ConvsssError

BOUNDARIES = ("null", "dielectric", "roughdielectric")


def medium_parameters(material, unit_mm=1.0):
    """``{"sigma_t": (3,), "scale": float, "albedo": (3,)}`` of ``material`` in scene units of ``unit_mm`` mm.

    Parameters
    ----------
    material : Material
        ``sigma_s'`` and ``sigma_a`` in 1/mm.
    unit_mm : float
        mm per scene unit (finite, > 0).

    Returns
    -------
    dict
        ``sigma_t``: float64 (3,), the extinction over ``scale`` (at most 1, dimensionless); ``scale``: float, the
        largest extinction, per scene unit; ``albedo``: float64 (3,), ``sigma_s' / (sigma_a + sigma_s')``.

    Examples
    --------
    >>> from convsss.materials import Material
    >>> medium_parameters(Material([1.0, 2.0, 3.0], [1.0, 0.0, 1.0], 1.3), unit_mm=0.5)["sigma_t"].tolist()
    [0.5, 0.5, 1.0]
    """
    unit_mm = float(unit_mm)
    if not np.isfinite(unit_mm) or unit_mm <= 0:
        raise ConvsssError(f"unit_mm={unit_mm!r} is not allowed: it must be finite and > 0")
    sigma_t = material.sigma_t_prime * unit_mm
    scale = float(np.max(sigma_t))
    return {"sigma_t": sigma_t / scale, "scale": scale, "albedo": material.sigma_s_prime / material.sigma_t_prime}


def medium_dict(material, unit_mm=1.0):
    """A Mitsuba ``homogeneous`` medium dictionary for ``material`` (isotropic phase)."""
    p = medium_parameters(material, unit_mm)
    return {
        "type": "homogeneous",
        "sigma_t": {"type": "rgb", "value": [float(x) for x in p["sigma_t"]]},
        "albedo": {"type": "rgb", "value": [float(x) for x in p["albedo"]]},
        "scale": p["scale"],
    }


def albedo_volume_dict(material, albedo_filename, to_world, unit_mm=1.0):
    """A Mitsuba ``heterogeneous`` medium of ``material``'s extinction whose albedo is the ``gridvolume`` file
    ``albedo_filename`` (1 or 3 channels in [0, 1]), both volumes placed by ``to_world`` (the unit cube's image: it
    must hold the object). Isotropic phase."""
    p = medium_parameters(material, unit_mm)
    return {
        "type": "heterogeneous",
        "albedo": {"type": "gridvolume", "filename": str(albedo_filename), "to_world": to_world},
        "sigma_t": {"type": "constvolume", "value": {"type": "rgb", "value": [float(x) for x in p["sigma_t"]]},
                    "to_world": to_world},
        "scale": p["scale"],
    }


def boundary_dict(boundary, eta, alpha=0.1):
    """The BSDF of the object's surface: ``null``, ``dielectric`` or ``roughdielectric`` (roughness ``alpha``)."""
    if boundary == "null":
        return {"type": "null"}
    if boundary == "dielectric":
        return {"type": "dielectric", "int_ior": float(eta), "ext_ior": 1.0}
    if boundary == "roughdielectric":
        return {"type": "roughdielectric", "int_ior": float(eta), "ext_ior": 1.0, "alpha": float(alpha)}
    raise ConvsssError(f"boundary {boundary!r} is not allowed: choose one of {', '.join(BOUNDARIES)}")


def translucent(shape, material, unit_mm=1.0, boundary="dielectric"):
    """``shape`` (a Mitsuba shape dictionary) made of ``material``: a copy with the boundary BSDF and the interior
    medium set. With ``boundary = "null"`` the object is index-matched and its ``eta`` is ignored.

    Examples
    --------
    >>> from convsss import material
    >>> obj = translucent({"type": "sphere", "radius": 10.0}, material("wholemilk"))
    >>> obj["interior"]["type"], obj["bsdf"]["type"]
    ('homogeneous', 'dielectric')
    """
    out = dict(shape)
    out["bsdf"] = boundary_dict(boundary, material.eta)
    out["interior"] = medium_dict(material, unit_mm)
    return out
