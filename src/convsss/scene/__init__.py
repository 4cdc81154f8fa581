"""Scene authoring: what a user writes or loads before a render (docs/architecture.md). The render itself is
:mod:`convsss.pipeline`.

- :mod:`.materials`: a material written as a Mitsuba medium (``sigma_t / scale / albedo``) and boundary;
- :mod:`.presets`: the ``convsss_medium`` plugin, a medium named by a preset or by a colour and a mean free path;
- :mod:`.textures`: a ``convsss_medium`` painted on the surface, made at the load as its heterogeneous medium;
- :mod:`.source`: what a command renders (a scene file, or a mesh, a material and a size), one value;
- :mod:`.loading`: scene files with the integrator replaced and the film resized;
- :mod:`.quick`: a scene around a mesh (camera, key light, back light, floor); :mod:`.meshfiles`: mesh files checked;
- :mod:`.variations`: every light scaled, the camera orbited;
- :mod:`.xmlwriter`: scene dictionaries written as Mitsuba XML.

Only :mod:`.materials` is imported here; the others load Mitsuba when used.
"""

from ..media.dicts import boundary_dict, medium_dict, medium_parameters, translucent

__all__ = ["boundary_dict", "medium_dict", "medium_parameters", "translucent"]
