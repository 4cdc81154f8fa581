"""convsss: convolution-based subsurface scattering (Munoz et al., Computer Graphics Forum 30(8), 2011).

Layers parallel to the image plane, surface irradiance deposited in them, and convolutions with a diffusion
profile through FFTs. See ``docs/architecture.md`` for the data flow: scene -> samples -> transport -> shading -> image.
"""

__version__ = "0.1.0"

from .errors import ConvsssError

#: Where each lazily imported name lives (imported on first use: ``convsss --version`` needs none of numpy or scipy).
_LAZY = {"Material": "materials", "catalog": "materials", "material": "materials", "DipoleProfile": "profiles",
         "Profile": "profiles", "TabulatedProfile": "profiles", "material_from_color": "profiles",
         "model_profile": "profiles"}


def __getattr__(name):
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = ["ConvsssError", "DipoleProfile", "Material", "Profile", "TabulatedProfile", "catalog", "fit", "material",
           "load_scene", "material_from_color", "model_profile", "register", "render", "__version__"]


def register(variant=None):
    """Register the ``convsss`` integrator with Mitsuba (imports Mitsuba only now); returns the mitsuba module.

    ``variant`` None keeps the active Mitsuba variant, or sets ``llvm_ad_rgb`` when none is set; convsss renders in
    ``llvm_ad_rgb`` or ``cuda_ad_rgb``, any other variant (requested or active) is a :class:`ConvsssError`. Call it
    before loading a scene that names ``<integrator type="convsss">``::

        mi = convsss.register()
        image = convsss.render(mi.load_file("scene.xml"))   # mi.render, with the integrator's own errors
    """
    from .pipeline import register as _register

    return _register(variant)


def load_scene(source, width=None, height=None):
    """A ``mitsuba.Scene`` from an XML path or a scene dictionary, checked, with the convsss plugins registered and
    every film resized to ``width`` x ``height`` where given (:func:`convsss.scene.loading.load_scene`): what every
    ``convsss`` command loads. A ``convsss_medium`` of textured colour is made here as the heterogeneous medium it
    stands for (``mi.load_file`` gives its mean colour)::

        image = convsss.render(convsss.load_scene("painted.xml"))
    """
    from .scene.loading import load_scene as _load_scene

    return _load_scene(source, width, height)


def render(scene, *args, **kwargs):
    """``mi.render(scene, ...)``, raising the integrator's own exception (e.g. a :class:`ConvsssError` with its
    one-line message) where ``mi.render`` raises ``drjit.custom(...) ... (see above)``."""
    from .pipeline import render as _render

    return _render(scene, *args, **kwargs)


def fit(scene, target, **options):
    """A translucent object's material fitted so that ``scene`` renders like ``target`` ((H, W, 3) linear RGB):
    :func:`convsss.fitting.fit`, returning a :class:`~convsss.fitting.FitResult` (``reduced_albedo``, ``mfp_mm``,
    their uncertainties, the fitted ``render``)."""
    from .fitting import fit as _fit

    return _fit(scene, target, **options)
