"""The render: a loaded scene in, an image out, each stage a public function passing plain data
(docs/architecture.md, the data flow; the stages in order: :data:`STAGES`, run by :mod:`.session`).

- :mod:`.params`: the integrator's parameters, checked;
- :mod:`.objects`: translucent objects found in a loaded scene; :mod:`.traversal`: the scene's shapes (plain and
  instanced) and where they lie; :mod:`.interiors`: a shape's boundary and medium read as a material;
  :mod:`.checks`: what is warned of or refused in them; :mod:`.media`: heterogeneous interiors as classes;
- :mod:`.camera`: the camera's frame, a pixel's footprint and what it sees;
- :mod:`.plan`: the sampling plan (cells, sample counts, memory and time), refused before any work;
- :mod:`.surface`: points on a shape's surface (stratified, Morton-ordered faces);
- :mod:`.irradiance`: the samples' irradiance (paper Eq. 2); :mod:`.lighting`, the stage that draws the planned
  samples and lights them (direct and indirect);
- :mod:`.passes`: the transports, and the light between translucent objects;
- :mod:`.screen`, :mod:`.mesh_exitance`: the transports' exitance at pixel centres and at mesh vertices,
  interpolated for the path tracer;
- :mod:`.path_tracer`: the path tracer the stages share (camera rays: paper Eq. 7 plus boundary reflection, path
  tracing elsewhere; the indirect light at the samples); :mod:`.mis`, :mod:`.aovs`;
- :mod:`.session`: the stages run and their results kept (what a later render reuses);
- :mod:`.integrator`: the ``convsss`` Mitsuba plugin over the session, :func:`register` and :func:`render`;
- :mod:`.reference`: the same scene with Mitsuba's ``volpathmis``, in passes.

Only :mod:`.params` and :mod:`.stages` are imported here; the others load Mitsuba when imported.
"""

from .params import RenderParams
from .stages import STAGES

__all__ = ["STAGES", "RenderParams", "register", "render"]


def register(variant=None):
    """Register ``convsss`` with Mitsuba in ``variant`` (None: the active one, or the default): the integrator and
    the ``convsss_medium``; returns the mitsuba module. See :func:`convsss.backend.load_mitsuba` for the variants."""
    from ..backend import load_mitsuba

    load_mitsuba(variant)
    from .integrator import register as _register

    return _register()


def render(scene, *args, **kwargs):
    """``mi.render`` with the integrator's own exceptions (see :func:`.integrator.render`)."""
    from .integrator import render as _render

    return _render(scene, *args, **kwargs)
