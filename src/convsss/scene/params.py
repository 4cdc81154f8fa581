"""The parameters of the ``convsss`` integrator, checked in one place (no Mitsuba needed).

The same :class:`RenderParams` backs ``<integrator type="convsss">``, :func:`mitsuba.render` and the command line, so
a bad value gets the same one-line :class:`~convsss.errors.ConvsssError` everywhere. Defaults are the paper's
(§5: 8 layers, threshold ``t = 0.1 %``, full-resolution layers).
"""

from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from ..errors import ConvsssError

SPLATS = ("linear", "half")
CORRECTIONS = ("plane", "none")
SPECULARS = ("bsdf", "phong", "none")
DOWNSAMPLES = (1.0, 0.5, 0.25)
#: Mixing costs layers^2 per frequency; the paper uses 2-16 layers, and 256 is already far past any gain.
MAX_LAYERS = 256


def available_transports():
    """Names accepted by ``transport``: whatever :mod:`convsss.transport` registers."""
    from ..transport import TRANSPORTS

    return tuple(sorted(TRANSPORTS))


@dataclass(frozen=True)
class RenderParams:
    """Every ``convsss`` integrator parameter with its default.

    Attributes
    ----------
    layers : int
        Number of layers ``n_l`` parallel to the image plane (paper §4; 4–8 is the paper's trade-off).
    threshold : float
        Skip layer pairs whose profile falls below ``t R_d(0)`` (paper §5, Eq. 8).
    downsample : float
        Layer resolution relative to the image: 1, 0.5 or 0.25 (paper §5, Fig. 3).
    splat : str
        How a sample's irradiance goes into the layers: ``linear`` (weights by depth between the two nearest layers)
        or ``half`` (half and half, as the paper says).
    correction : str
        ``plane`` (beyond the paper): correct the convolution's depth discretization with its exact response to the
        receiver's tangent plane (:mod:`convsss.transport.correction`); ``none``: the paper's method as published.
    transport : str
        ``convolution`` (the paper's method), ``hierarchical`` (Jensen & Buhler 2002) or ``exact`` (the direct sum,
        a reference for small scenes).
    irradiance_samples : int
        Direction samples per surface point for area and environment emitters (point, spot and directional lights
        are evaluated exactly).
    sample_density : float
        Surface samples per grid cell: ``N = sample_density * area / cell^2`` over the whole surface.
    specular : str
        Boundary reflection on translucent objects: ``bsdf`` (the scene's dielectric), ``phong`` (the paper's Phong
        lobe weighted by the Fresnel reflectance) or ``none``.
    phong_exponent : float
        Exponent of the Phong lobe when ``specular = phong``.
    max_depth : int
        Longest path (Mitsuba's convention: 1 shows emitters only, 2 adds direct light; -1 is unbounded with Russian
        roulette).
    rr_depth : int
        Depth from which Russian roulette may end paths.
    unit_mm : float
        How many mm one scene unit is (scene coefficients are per scene unit).
    profile : str
        CSV file ``r_mm, R, G, B`` of a user-defined radial profile that replaces the dipole ("" for the dipole).
    """

    layers: int = 8
    threshold: float = 0.001
    downsample: float = 1.0
    splat: str = "linear"
    correction: str = "plane"
    transport: str = "convolution"
    irradiance_samples: int = 16
    sample_density: float = 4.0
    specular: str = "bsdf"
    phong_exponent: float = 64.0
    max_depth: int = 6
    rr_depth: int = 5
    unit_mm: float = 1.0
    profile: str = ""

    def __post_init__(self):
        def number(name, kind, low, low_open=False, high=None):
            value = getattr(self, name)
            try:
                converted = kind(value)
            except (TypeError, ValueError):
                raise ConvsssError(f"{name}={value!r} is not allowed: it must be a number") from None
            if kind is int and converted != value:
                raise ConvsssError(f"{name}={value!r} is not allowed: it must be a whole number")
            too_low = converted <= low if low_open else converted < low
            if not np.isfinite(converted) or too_low or (high is not None and converted > high):
                bound = f"> {low}" if low_open else f">= {low}"
                bound += f" and <= {high}" if high is not None else ""
                raise ConvsssError(f"{name}={value!r} is not allowed: it must be {bound}")
            object.__setattr__(self, name, converted)

        number("layers", int, 2, high=MAX_LAYERS)
        number("threshold", float, 0.0, high=0.999)
        number("irradiance_samples", int, 1)
        number("sample_density", float, 0.0, low_open=True)
        number("phong_exponent", float, 0.0, low_open=True)
        number("rr_depth", int, 1)
        number("unit_mm", float, 0.0, low_open=True)
        number("max_depth", int, -1)
        if self.max_depth == 0:
            raise ConvsssError("max_depth=0 is not allowed: it must be -1 (unbounded) or >= 1")
        number("downsample", float, 0.0, low_open=True)
        if self.downsample not in DOWNSAMPLES:
            raise ConvsssError(f"downsample={self.downsample!r} is not allowed: choose one of 1, 0.5, 0.25")
        for name, allowed in (("splat", SPLATS), ("correction", CORRECTIONS), ("specular", SPECULARS),
                              ("transport", available_transports())):
            if getattr(self, name) not in allowed:
                raise ConvsssError(f"{name}={getattr(self, name)!r} is not allowed: choose one of {', '.join(allowed)}")
        object.__setattr__(self, "profile", str(self.profile or ""))
        if self.profile and not Path(self.profile).is_file():
            raise ConvsssError(f"profile file {self.profile!r} does not exist (a CSV with columns r_mm, R, G, B)")

    @classmethod
    def names(cls):
        return [f.name for f in fields(cls)]

    @classmethod
    def from_properties(cls, props):
        """From a Mitsuba ``Properties`` (or any mapping with ``in`` and ``[]``): only the names it holds."""
        return cls(**{name: props[name] for name in cls.names() if name in props})

    def to_dict(self):
        return asdict(self)

    def integrator_dict(self):
        """A Mitsuba dictionary ``{"type": "convsss", ...}`` with these parameters."""
        return {"type": "convsss", **self.to_dict()}
