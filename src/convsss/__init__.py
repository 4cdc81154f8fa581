"""convsss: convolution-based subsurface scattering (Munoz et al., Computer Graphics Forum 30(8), 2011).

Layers parallel to the image plane, surface irradiance deposited in them, and convolutions with a diffusion
profile through FFTs. See ``DESIGN.md`` for the data flow: scene -> samples -> transport -> shading -> image.
"""

__version__ = "0.1.0"

from .errors import ConvsssError
from .materials import Material, catalog, material
from .profiles import DipoleProfile, Profile, TabulatedProfile

__all__ = ["ConvsssError", "DipoleProfile", "Material", "Profile", "TabulatedProfile", "catalog", "material",
           "__version__"]
