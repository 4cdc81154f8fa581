"""The Mitsuba side of convsss: scenes in, images out (docs/architecture.md: scene -> plan -> samples -> transport ->
shading).

- :mod:`.params`: the integrator's parameters, checked;
- :mod:`.materials`: a material written as a Mitsuba medium (``sigma_t / scale / albedo``) and boundary;
- :mod:`.objects`: translucent objects found in a loaded scene;
- :mod:`.camera`: the camera's frame, a pixel's footprint and what it sees;
- :mod:`.plan`: the sampling plan (cells, sample counts, memory and time), refused before any work;
- :mod:`.irradiance`: surface samples and their irradiance (paper Eq. 2); :mod:`.lighting`, the stage that draws
  the planned samples and lights them (direct and indirect);
- :mod:`.passes`: the transports, and the light between translucent objects;
- :mod:`.shading`: camera rays (paper Eq. 7 plus boundary reflection, path tracing elsewhere);
- :mod:`.screen`, :mod:`.mesh_exitance`: the transports' exitance at pixel centres and at mesh vertices, interpolated
  for the shading;
- :mod:`.integrator`: the ``convsss`` integrator and :func:`register`;
- :mod:`.quick`: a scene around a mesh (camera, key light, back light, floor);
- :mod:`.loading`: scene files with the integrator replaced and the film resized;
- :mod:`.reference`: the same scene with Mitsuba's ``volpathmis``, in passes;
- :mod:`.xmlwriter`: scene dictionaries written as Mitsuba XML.

Only :mod:`.params` and :mod:`.materials` are imported here; the others load Mitsuba when imported.
"""

from .materials import boundary_dict, medium_dict, medium_parameters, translucent
from .params import RenderParams

__all__ = ["RenderParams", "boundary_dict", "medium_dict", "medium_parameters", "register", "render", "translucent"]


def register(variant=None):
    """Register the ``convsss`` integrator with Mitsuba in ``variant`` (None: the active one, or the default);
    returns the mitsuba module. See :func:`convsss.backend.load_mitsuba` for the variants."""
    from ..backend import load_mitsuba

    load_mitsuba(variant)
    from .integrator import register as _register

    return _register()


def render(scene, *args, **kwargs):
    """``mi.render`` with the integrator's own exceptions (see :func:`.integrator.render`)."""
    from .integrator import render as _render

    return _render(scene, *args, **kwargs)
