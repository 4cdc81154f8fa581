"""convsss: convolution-based subsurface scattering (Munoz et al., Computer Graphics Forum 30(8), 2011).

Layers parallel to the image plane, surface irradiance deposited in them, and convolutions with a diffusion
profile through FFTs. See ``DESIGN.md`` for the data flow: scene -> samples -> transport -> shading -> image.
"""

__version__ = "0.1.0"

from .errors import ConvsssError
from .materials import Material, catalog, material
from .profiles import DipoleProfile, Profile, TabulatedProfile

__all__ = ["ConvsssError", "DipoleProfile", "Material", "Profile", "TabulatedProfile", "catalog", "material",
           "register", "__version__"]


def register():
    """Register the ``convsss`` integrator with Mitsuba (imports Mitsuba only now); returns the mitsuba module.

    Call it before loading a scene that names ``<integrator type="convsss">``::

        mi = convsss.register()
        image = mi.render(mi.load_file("scene.xml"))
    """
    from .scene import register as _register

    return _register()
