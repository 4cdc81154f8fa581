"""Homogeneous translucent materials: reduced coefficients per RGB channel, and the published presets.

A :class:`Material` holds ``sigma_s'`` (reduced scattering) and ``sigma_a`` (absorption) in 1/mm and the relative
index ``eta``. It derives what the diffusion approximation needs: ``sigma_t' = sigma_a + sigma_s'``, the reduced
albedo ``alpha' = sigma_s'/sigma_t'``, the effective transport coefficient ``sigma_tr = sqrt(3 sigma_a sigma_t')``,
the mean free path ``1/sigma_t'`` and the diffusion length ``1/sigma_tr`` (infinite without absorption).

Presets: the 12 media of Jensen et al. 2001 and the 35 of Narasimhan et al. 2006 (``data/materials``; credits in
``data/materials/CREDITS.md``). :func:`material` looks a name up ignoring case, spaces and punctuation.
"""

import csv
import difflib
import re
import warnings
from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np

from .errors import ConvsssError
from .fresnel import check_eta

#: The colour channels of every per-channel quantity.
CHANNELS = "RGB"

#: Reduced albedo below which a channel is not optically thick enough for the diffusion approximation.
THIN_ALBEDO = 0.5


class OpticallyThinWarning(UserWarning):
    """A channel scatters too little for the diffusion approximation to be accurate."""


#: The largest coefficient a material may have, in 1/mm (a mean free path of 1e-30 mm; larger ones overflow the
#: profiles' float arithmetic, which then printed numpy warnings before the refusal).
MAX_COEFFICIENT = 1e30


def _coefficients(name, value):
    """A finite, non-negative RGB triple (a scalar is broadcast), or a one-line error naming the bad value."""
    try:
        arr = np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)).copy()
    except (TypeError, ValueError):
        raise ConvsssError(f"{name}={value!r} is not allowed: give one number or three (R, G, B)") from None
    for c, x in enumerate(arr):
        if not np.isfinite(x) or x < 0 or x > MAX_COEFFICIENT:
            raise ConvsssError(f"{name} = {float(x)!r} in channel {CHANNELS[c]} is not allowed: "
                               f"coefficients must be finite, >= 0 and at most {MAX_COEFFICIENT:g} (1/mm)")
    return arr


#: The relative index of refraction of a material that names none (a dielectric boundary of skin, milk, wax).
DEFAULT_ETA = 1.3


@dataclass(frozen=True, eq=False)
class Material:
    """A homogeneous medium in the reduced form the dipole needs. Coefficients in 1/mm, RGB."""

    sigma_s_prime: np.ndarray
    sigma_a: np.ndarray
    eta: float = DEFAULT_ETA
    name: str = "custom"

    def __post_init__(self):
        object.__setattr__(self, "sigma_s_prime", _coefficients("sigma_s'", self.sigma_s_prime))
        object.__setattr__(self, "sigma_a", _coefficients("sigma_a", self.sigma_a))
        object.__setattr__(self, "eta", check_eta(self.eta))
        empty = self.sigma_t_prime <= 0
        if empty.any():
            c = int(np.argmax(empty))
            raise ConvsssError(f"material {self.name!r} has sigma_a = sigma_s' = 0 in channel {CHANNELS[c]}: "
                               "an object that neither scatters nor absorbs is not translucent")

    # --- constructors -------------------------------------------------------------------------------------------
    @classmethod
    def from_reduced(cls, sigma_s_prime, sigma_a, eta=DEFAULT_ETA, name="custom"):
        """From reduced scattering ``sigma_s'`` and absorption ``sigma_a`` (1/mm)."""
        return cls(sigma_s_prime, sigma_a, eta, name).warn_if_thin()

    @classmethod
    def from_scattering(cls, sigma_s, sigma_a, g=0.0, eta=DEFAULT_ETA, name="custom"):
        """From scattering ``sigma_s``, absorption and the phase function's mean cosine ``g``.

        ``sigma_s' = sigma_s (1 - g)`` (the similarity relation).
        """
        g = np.broadcast_to(np.asarray(g, dtype=np.float64), (3,))
        if not np.all(np.abs(g) < 1):
            raise ConvsssError(f"phase function g={g.tolist()} is not allowed: it must lie in (-1, 1)")
        return cls.from_reduced(_coefficients("sigma_s", sigma_s) * (1.0 - g), sigma_a, eta, name)

    @classmethod
    def from_medium(cls, sigma_t, albedo, scale=1.0, g=0.0, eta=1.0, name="custom"):
        """From a Mitsuba ``homogeneous`` medium: ``sigma_t = scale sigma_t``, ``sigma_s = albedo sigma_t``,
        ``sigma_a = sigma_t - sigma_s`` (in the scene's units: convert to 1/mm before if they differ)."""
        scale = float(scale)
        if not np.isfinite(scale) or scale <= 0:
            raise ConvsssError(f"medium scale={scale!r} is not allowed: it must be finite and > 0")
        sigma_t = _coefficients("sigma_t", sigma_t) * scale
        albedo = _coefficients("albedo", albedo)
        if np.any(albedo > 1):
            raise ConvsssError(f"medium albedo={albedo.tolist()} is not allowed: it must lie in [0, 1]")
        sigma_s = albedo * sigma_t
        return cls.from_scattering(sigma_s, sigma_t - sigma_s, g, eta, name)

    # --- derived quantities -------------------------------------------------------------------------------------
    @property
    def sigma_t_prime(self):
        return self.sigma_a + self.sigma_s_prime

    @property
    def albedo_prime(self):
        return self.sigma_s_prime / self.sigma_t_prime

    @property
    def sigma_tr(self):
        return np.sqrt(3.0 * self.sigma_a * self.sigma_t_prime)

    @property
    def mfp_mm(self):
        """Reduced mean free path ``1/sigma_t'`` (mm)."""
        return 1.0 / self.sigma_t_prime

    @property
    def diffusion_length_mm(self):
        """``1/sigma_tr`` (mm); infinite where nothing is absorbed."""
        with np.errstate(divide="ignore"):
            return 1.0 / self.sigma_tr

    def thin_channels(self):
        """Channels whose reduced albedo is below :data:`THIN_ALBEDO` (the diffusion approximation is poor there)."""
        return [CHANNELS[c] for c in range(3) if self.albedo_prime[c] < THIN_ALBEDO]

    def warn_if_thin(self):
        thin = self.thin_channels()
        if thin:
            warnings.warn(f"material {self.name!r} is not optically thick in channel(s) {', '.join(thin)} "
                          f"(reduced albedo {np.round(self.albedo_prime, 3).tolist()} < {THIN_ALBEDO}): "
                          "the diffusion approximation is poor there", OpticallyThinWarning, stacklevel=3)
        return self

    def summary(self):
        """A JSON-ready dict: coefficients, eta, mfp and diffusion length (mm)."""
        def listed(a):
            return [None if not np.isfinite(x) else float(x) for x in a]

        return {
            "name": self.name,
            "sigma_s_prime": listed(self.sigma_s_prime),
            "sigma_a": listed(self.sigma_a),
            "eta": self.eta,
            "mfp_mm": listed(self.mfp_mm),
            "diffusion_length_mm": listed(self.diffusion_length_mm),
        }


def normalize_name(name):
    """``'Whole Milk'``, ``'wholemilk'`` and ``'WHOLE-milk'`` all become ``'wholemilk'``."""
    return re.sub(r"[^0-9a-z]", "", str(name).lower())


@cache
def _catalog():
    """Every preset by normalized name, read from the package's CSV tables (Jensen 2001 first)."""
    presets = {}
    for table in ("jensen2001.csv", "narasimhan2006.csv"):
        text = resources.files("convsss").joinpath("data", "materials", table).read_text()
        for row in csv.DictReader(text.splitlines()):
            m = Material(
                [float(row[f"sigma_s_prime_{c}"]) for c in "rgb"],
                [float(row[f"sigma_a_{c}"]) for c in "rgb"],
                float(row["eta"]),
                row["name"],
            )
            presets[normalize_name(m.name)] = m
    return presets


def catalog():
    """All presets, in table order (Jensen et al. 2001, then Narasimhan et al. 2006)."""
    return list(_catalog().values())


def material(name, warn=True):
    """The preset called ``name`` (case, spaces and punctuation ignored); the closest names on a miss. ``warn``:
    an :class:`OpticallyThinWarning` for a preset with thin channels (off where the object warns by its own name)."""
    presets = _catalog()
    key = normalize_name(name)
    if key in presets:
        return presets[key].warn_if_thin() if warn else presets[key]
    close = difflib.get_close_matches(key, presets.keys(), n=3, cutoff=0.5)
    hint = f"; did you mean {', '.join(repr(presets[k].name) for k in close)}?" if close else ""
    raise ConvsssError(f"unknown material {name!r}{hint} (`convsss materials` lists all {len(presets)})")
