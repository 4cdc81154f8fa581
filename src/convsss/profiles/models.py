"""The profile models by name, what the renderer's ``profile`` parameter accepts, and a material from a colour.

A profile is chosen per translucent object: ``profile`` is a model name (:data:`PROFILE_MODELS`) or a CSV file of
a tabulated profile, for every object, or per object by the shape's id: ``"pbd"``, ``"bunny=pbd,dragon=my.csv"``,
``"better-dipole,bunny=dipole"`` (an entry without ``name=`` sets the rest).
"""

from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import ConvsssError
from ..fresnel import check_eta, diffuse_transmittance
from ..materials import DEFAULT_ETA, Material
from . import beam_diffusion, better_dipole, burley, dipole  # noqa: F401  (each registers its model)
from .base import CHANNELS, PROFILE_MODELS, ScaledProfile
from .incidence import Orders, escaped
from .tabulated import TabulatedProfile

#: The renderer's default of :data:`PROFILE_MODELS` (each model registers itself, :mod:`.base`), chosen by
#: measurement (docs/history/benchmarks-notebook.md, "`convsss profile validate --all`").
DEFAULT_PROFILE = "dipole"
#: What fixes a model's total reflectance (the renderer's ``profile_total``): ``exact``, that of the half-space of the
#: medium by exact radiative transfer (:func:`exact_total`), the model keeping its shape; ``model``, the model's own.
PROFILE_TOTALS = ("exact", "model")
#: The renderer's default, chosen by measurement (docs/history/benchmarks-notebook.md, "Exit and total").
DEFAULT_TOTAL = "exact"
#: What a colour (a total reflectance) is inverted under: the exact total, which every model renders with
#: ``profile_total`` exact, or one model's own total.
COLOR_MODELS = ("exact", *PROFILE_MODELS)
DEFAULT_COLOR_MODEL = "exact"
#: What each model is, in words (help texts, plots).
MODEL_TITLES = {name: cls.title for name, cls in PROFILE_MODELS.items()}


def check_model(name):
    """``name`` if it is a model of :data:`PROFILE_MODELS`, else a one-line error listing them."""
    if name not in PROFILE_MODELS:
        raise ConvsssError(f"profile model {name!r} is not allowed: choose one of {', '.join(PROFILE_MODELS)} "
                           "(or a CSV file r_mm, R, G, B)")
    return name


def check_color_model_name(name):
    """``name`` if a colour may be inverted under it (:data:`COLOR_MODELS`), else a one-line error."""
    if name not in COLOR_MODELS:
        raise ConvsssError(f"colour model {name!r} is not allowed: choose one of {', '.join(COLOR_MODELS)}")
    return name


def is_model(spec):
    return spec in PROFILE_MODELS


def exact_total(albedo, eta, orders=Orders.ALL):
    """The total reflectance of a half-space of reduced albedo ``albedo`` (any shape, e.g. (3,) per channel) under a
    boundary of index ``eta``, in the normalization of Eq. 1: ``rho(1) / T_d(eta)``, ``rho`` the exact escaped flux
    of Eq. O3 (:mod:`.incidence`; the Monte Carlo slab agrees within its noise); ``orders`` multiple: without single
    scattering (Eq. S1)."""
    albedo = np.asarray(albedo, dtype=np.float64)
    rho = np.array([float(escaped(a, eta, 1.0, orders)) for a in albedo.ravel()]).reshape(albedo.shape)
    return rho / diffuse_transmittance(eta)


def model_profile(model, material, total="model", orders=Orders.ALL):
    """The profile of ``material`` (a :class:`~convsss.materials.Material`) by the model called ``model``; with
    ``total`` exact, scaled per channel to :func:`exact_total` of ``orders`` (a
    :class:`~convsss.profiles.ScaledProfile`)."""
    profile = PROFILE_MODELS[check_model(model)](material.sigma_s_prime, material.sigma_a, material.eta)
    if check_total(total) == "model":
        return profile
    own = np.asarray(profile.total_reflectance, dtype=np.float64)
    exact = exact_total(material.albedo_prime, material.eta, orders)
    return ScaledProfile(profile, np.divide(exact, own, out=np.ones(3), where=own > 0))


def color_of(material, model):
    """Per channel, the total reflectance of ``material`` under ``model`` (:data:`COLOR_MODELS`): its colour."""
    if check_color_model_name(model) == "exact":
        return exact_total(material.albedo_prime, material.eta)
    return np.asarray(model_profile(model, material).total_reflectance, dtype=np.float64)


def rendered_total_of(spec, total):
    """What an object's total reflectance is when it renders with ``spec`` (a model or a CSV) and ``total``
    (:data:`PROFILE_TOTALS`): the colour model (:data:`COLOR_MODELS`) a colour should be inverted under to render as
    that colour; ``None`` for a tabulated profile (its own, whatever the material)."""
    if not is_model(spec):
        return None
    return "exact" if check_total(total) == "exact" else spec


def check_total(total):
    """``total`` if it is one of :data:`PROFILE_TOTALS`, else a one-line error."""
    if total not in PROFILE_TOTALS:
        raise ConvsssError(f"profile_total={total!r} is not allowed: choose one of {', '.join(PROFILE_TOTALS)}")
    return total


def parse_profile_spec(text):
    """``(default, {object name: spec})`` from the ``profile`` parameter (module docstring); ``default`` is
    :data:`DEFAULT_PROFILE` when no entry without a name is given. Each spec is a model name or a CSV path, checked.
    """
    default, per_object = DEFAULT_PROFILE, {}
    entries = [e.strip() for e in str(text).split(",") if e.strip()]
    bare = [e for e in entries if "=" not in e]
    if len(bare) > 1:
        raise ConvsssError(f"profile={text!r} is not allowed: give one profile for every object and at most one "
                           f"per object name (name=profile), got {len(bare)} without a name")
    for entry in entries:
        name, _, spec = entry.rpartition("=")
        name, spec = name.strip(), spec.strip()
        _check_spec(spec)
        if "=" in entry:
            if not name:
                raise ConvsssError(f"profile entry {entry!r} has no object name before '='")
            per_object[name] = spec
        else:
            default = spec
    return default, per_object


def _check_spec(spec):
    if is_model(spec):
        return
    if spec.lower().endswith(".csv") or Path(spec).suffix:
        if not Path(spec).is_file():
            raise ConvsssError(f"profile file {spec!r} does not exist (a CSV with columns r_mm, R, G, B)")
        return
    check_model(spec)


def profile_files(text):
    """The CSV files named by a ``profile`` parameter (inputs a command must not overwrite)."""
    default, per_object = parse_profile_spec(text)
    return [Path(s) for s in [default, *per_object.values()] if not is_model(s)]


def resolve_profile(spec, material, total, orders=Orders.ALL):
    """The :class:`~convsss.profiles.Profile` for ``spec`` (a model name or a CSV path) and ``material``; a model's
    total per ``total`` (:data:`PROFILE_TOTALS`) and ``orders``, a tabulated profile's as given."""
    if is_model(spec):
        return model_profile(spec, material, total, orders)
    return TabulatedProfile.from_csv(spec)


# ---- Materials by colour and distance ---------------------------------------------------------------------------

def model_total(model, albedo, eta):
    """Total reflectance (normalization of Eq. 1) of ``model`` (one of :data:`COLOR_MODELS`) for reduced albedo
    ``albedo`` at index ``eta``; it does not depend on the mean free path."""
    if model == "exact":
        return float(exact_total(albedo, eta))
    return PROFILE_MODELS[check_model(model)].optical_total(float(albedo), float(eta))


#: Reduced albedos searched when inverting a colour.
ALBEDO_RANGE = (1e-6, 1.0)


def albedo_from_reflectance(model, reflectance, eta):
    """Per channel, the reduced albedo ``alpha'`` whose total reflectance under ``model`` is ``reflectance``.

    Parameters
    ----------
    model : str
        One of :data:`COLOR_MODELS`: ``exact`` (:func:`exact_total`) or a model of :data:`PROFILE_MODELS`.
    reflectance : array_like, shape (3,) or ()
        Target total reflectance (the "surface colour") per channel.
    eta : float
        Relative index of the boundary.

    Returns
    -------
    numpy.ndarray, shape (3,)
    """
    from scipy.optimize import brentq

    eta = check_eta(eta)
    target = np.broadcast_to(np.asarray(reflectance, dtype=np.float64), (3,))
    low, high = ALBEDO_RANGE
    top = min(model_total(model, high, eta), 1.0)  # a colour is a reflectance: below 1 whatever the model's total
    out = np.empty(3)
    for c, value in enumerate(target):
        if not np.isfinite(value) or value <= 0 or value >= top:
            raise ConvsssError(f"colour {float(value)!r} in channel {CHANNELS[c]} is not reachable by the {model} "
                               f"total at eta={eta:g}: it must lie in (0, {top:.4f})")
        if value <= model_total(model, low, eta):
            out[c] = low
            continue
        out[c] = brentq(lambda a, v=value: model_total(model, a, eta) - v, low, high, xtol=1e-12, rtol=1e-10)
    return out


#: The table :func:`albedos_from_reflectances` inverts through: this many nodes evenly spaced in the logit of
#: ``alpha'``, dense at both ends, up to ``1 - alpha' = INVERSE_FLOOR`` (brighter values, rare, are inverted one by
#: one: the exact total is slow to evaluate there). ``1 - alpha'`` within 3e-4 relative of brentq's root
#: (``tests/profiles/test_models.py``).
INVERSE_NODES = 81
INVERSE_FLOOR = 1e-5


@lru_cache(maxsize=16)
def _inverse_total(model, eta):
    """``logit(alpha')`` as a monotone (PCHIP) function of the total reflectance under ``model`` at ``eta``, the
    table's range of totals, and the largest colour (the total at the top of :data:`ALBEDO_RANGE`)."""
    from scipy.interpolate import PchipInterpolator

    low = ALBEDO_RANGE[0]
    logit = np.linspace(np.log(low / (1 - low)), np.log((1 - INVERSE_FLOOR) / INVERSE_FLOOR), INVERSE_NODES)
    totals = np.array([model_total(model, 1.0 / (1.0 + np.exp(-x)), eta) for x in logit])
    keep = np.concatenate([[True], np.diff(totals) > 0])  # a table strictly increasing in the total
    top = min(model_total(model, ALBEDO_RANGE[1], eta), 1.0)
    return PchipInterpolator(totals[keep], logit[keep]), totals[0], totals[keep][-1], top


def albedos_from_reflectances(model, reflectance, eta, where="colour"):
    """:func:`albedo_from_reflectance` for many values at once (a texture's texels): ``reflectance`` of any shape,
    inverted through a monotone table (:data:`INVERSE_NODES`); values at or below the total of the least albedo give
    it. A value outside ``(0, top)`` is a one-line error naming ``where``."""
    from scipy.optimize import brentq

    eta = check_eta(eta)
    values = np.asarray(reflectance, dtype=np.float64)
    inverse, bottom, brightest, top = _inverse_total(model, eta)
    bad = ~np.isfinite(values) | (values <= 0) | (values >= top)
    if bad.any():
        raise ConvsssError(f"{where}: {int(bad.sum())} of {values.size} values are not reachable by the {model} total "
                           f"at eta={eta:g} (e.g. {float(values[bad].flat[0])!r}): a colour lies in (0, {top:.4f})")
    logit = inverse(np.clip(values, bottom, brightest))
    out = np.where(values <= bottom, ALBEDO_RANGE[0], 1.0 / (1.0 + np.exp(-logit)))
    beyond = values > brightest
    for value in np.unique(values[beyond]):
        out[values == value] = brentq(lambda a, v=value: model_total(model, a, eta) - v, 1.0 - INVERSE_FLOOR,
                                      ALBEDO_RANGE[1], xtol=1e-12, rtol=1e-10)
    return out


def material_from_color(color, mfp_mm, eta=DEFAULT_ETA, model=None, name="custom", warn=True):
    """A :class:`~convsss.materials.Material` whose total reflectance under ``model`` is ``color`` and whose
    reduced mean free path ``1/sigma_t'`` is ``mfp_mm`` (pbrt's ``reflectance`` + ``mfp``, Cycles' colour + radius).

    ``sigma_s' = alpha' / mfp`` and ``sigma_a = (1 - alpha') / mfp`` with ``alpha'`` from
    :func:`albedo_from_reflectance`.

    Parameters
    ----------
    color : array_like, shape (3,) or ()
        Total reflectance per channel, in (0, the reflectance at alpha' = 1).
    mfp_mm : array_like, shape (3,) or ()
        Reduced mean free path per channel, mm (> 0).
    eta : float
        Relative index of the boundary.
    model : str, optional
        What the colour is the total of (:data:`COLOR_MODELS`; default :data:`DEFAULT_COLOR_MODEL`, the exact
        half-space's, which every model renders with the renderer's ``profile_total`` exact).
    name : str
    warn : bool
        Warn (:class:`~convsss.materials.OpticallyThinWarning`) when a channel's reduced albedo is low.

    Returns
    -------
    Material
    """
    model = check_color_model_name(model or DEFAULT_COLOR_MODEL)
    mfp = np.broadcast_to(np.asarray(mfp_mm, dtype=np.float64), (3,))
    if not np.all(np.isfinite(mfp)) or np.any(mfp <= 0):
        raise ConvsssError(f"mfp_mm={np.asarray(mfp_mm).tolist()} is not allowed: it must be finite and > 0 (mm)")
    albedo = albedo_from_reflectance(model, color, eta)
    made = Material(albedo / mfp, (1.0 - albedo) / mfp, eta, name)
    return made.warn_if_thin() if warn else made
