"""Materials named in scene files: the ``convsss_medium``, a preset or a colour + mean free path that becomes
Mitsuba's own ``homogeneous`` medium, so that ``volpathmis`` renders the very same file as ground truth.

``<medium type="convsss_medium">`` (registered with the integrator, :func:`convsss.register`) takes

- ``preset`` (string): a name of ``convsss materials`` (case, spaces and punctuation ignored), e.g. ``skin1``; or
- ``color`` (rgb, float or ``"R,G,B"``) and ``mfp_mm`` (float or rgb): the total diffuse reflectance per channel,
  in (0, 1), and the reduced mean free path ``1/sigma_t'`` in mm (pbrt's ``reflectance`` + ``mfp``, Cycles' colour
  + radius), inverted by :func:`~convsss.profiles.models.material_from_color` under

  - ``model`` (string, default ``exact``): what ``color`` is the total reflectance of: ``exact``, the half-space of
    the medium by exact radiative transfer, which every profile model renders with the integrator's ``profile_total``
    exact (its default), or a profile model's own total (for ``profile_total`` model). The file says it, not the
    integrator: the medium, and so the ground truth, must not change with the integrator's ``profile`` (or
    ``--profile``);
  - ``eta`` (float, default 1.3): the boundary's relative index the colour is meant for;

- ``unit_mm`` (float, default 1): mm per scene unit, the convsss integrator's ``unit_mm`` (use one
  ``<default name="unit_mm" .../>`` for both).

It is built as :func:`~convsss.media.dicts.medium_dict` writes a material, the very medium ``convsss scene``
writes for a preset (isotropic phase, ``sigma_t / scale / albedo`` per scene unit)::

    sigma_t = (sigma_a + sigma_s') unit_mm,   scale = max_c sigma_t,   albedo = sigma_s' / (sigma_a + sigma_s'),

so a preset by name gives exactly the :class:`~convsss.materials.Material` of ``--material``. A colour gives
``sigma_s' = alpha' / mfp``, ``sigma_a = (1 - alpha') / mfp`` with ``alpha'`` the reduced albedo whose ``model``
total reflectance at ``eta`` is the colour.

Mitsuba cannot show a medium its shape's BSDF, so convsss checks the boundary when it loads or renders the scene
(:func:`check_boundary`; plain Mitsuba does not): a ``dielectric`` or ``roughdielectric`` needs
``int_ior / ext_ior`` = the preset's eta (``convsss materials`` lists it) or the colour's ``eta``; a ``null``
boundary (index-matched, eta 1) takes a preset's coefficients as they are, as ``convsss scene --boundary null``
does, and a colour only with ``eta = 1``. The integrator's ``unit_mm`` must be the medium's. An object that
renders at another total than its colour's ``model`` warns (:class:`ColorModelWarning`): its total reflectance is
then not quite the colour.

``color`` may be a texture on the shape (a ``bitmap``, or any 2D texture) and ``mfp_mm`` a constant or a texture:
a medium whose coefficients vary along the surface and are constant with depth (:mod:`.textures`). Such a medium
stands for a ``heterogeneous`` one of ``gridvolume`` coefficients built from the texture over its shape
(:func:`~.textures.equivalent_media`), which :func:`~convsss.scene.loading.load_scene` makes when it loads the scene,
so that convsss and ``volpathmis`` (``convsss reference``) render one medium. Loaded any other way it is the
homogeneous medium of the texture's mean colour (:class:`TextureWarning`).

The constructor returns Mitsuba's native medium; which medium came from which ``convsss`` properties is kept here
(:func:`named_medium_of`), keyed by the medium's address and its coefficients, so an edited medium (the editor
writes new ones, :func:`forget`) is an ordinary ``homogeneous`` one again.
"""

import hashlib
import threading
import warnings
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ..errors import ConvsssError
from ..materials import DEFAULT_ETA, Material
from ..materials import material as preset_material
from ..profiles.models import (
    DEFAULT_COLOR_MODEL,
    check_color_model_name,
    color_of,
    material_from_color,
    rendered_total_of,
)
from .dicts import medium_dict

#: Mitsuba plugin name of the medium: ``<medium type="convsss_medium">``.
PLUGIN = "convsss_medium"
#: What the medium takes, besides ``preset`` or ``color`` + ``mfp_mm``.
OPTIONS = ("eta", "model", "unit_mm")
#: The homogeneous medium's own coefficients: not with a preset or a colour.
COEFFICIENTS = ("sigma_t", "albedo", "scale", "sigma_s", "sigma_a", "sigma_s_prime", "phase", "phase_function")
#: Relative difference up to which the boundary's eta (float32 in Mitsuba) is the medium's.
ETA_TOLERANCE = 1e-5


#: The (u, v) lattice per side a texture is read on for its mean and its fingerprint.
TEXTURE_LATTICE = 64


class TextureWarning(UserWarning):
    """A ``convsss_medium`` of textured colour was loaded without its heterogeneous equivalent (outside
    :func:`~convsss.scene.loading.load_scene`): it is the homogeneous medium of the texture's mean colour."""


class ColorModelWarning(UserWarning):
    """An object whose medium is given by colour renders with another profile model than the colour's."""


@dataclass(frozen=True, eq=False)
class NamedMedium:
    """What a ``convsss_medium`` was given, and the material it stands for.

    Attributes
    ----------
    material : Material      coefficients in 1/mm; ``eta`` the preset's or the colour's
    unit_mm : float          mm per scene unit the medium was written in
    preset : str or None     the preset's name as the catalogue spells it
    color : tuple or None    total reflectance per channel (a colour medium)
    mfp_mm : tuple or None   reduced mean free path per channel, mm (a colour medium)
    model : str or None      the profile model the colour is inverted under (a colour medium)
    color_texture : object   the Mitsuba texture of the colour (``color`` is then its mean), or None
    mfp_texture : object     the Mitsuba texture of the mean free path (``mfp_mm`` its mean), or None
    key : tuple              what tells two textured media apart (their values on a lattice), or None
    """

    material: Material
    unit_mm: float = 1.0
    preset: str = None
    color: tuple = None
    mfp_mm: tuple = None
    model: str = None
    color_texture: object = None
    mfp_texture: object = None
    key: tuple = None

    @property
    def eta(self):
        return self.material.eta

    @property
    def textured(self):
        """Whether the colour or the mean free path is a texture on the shape."""
        return self.color_texture is not None or self.mfp_texture is not None

    def describe(self):
        """``preset 'Skin1'`` or ``color 0.8,0.5,0.3, mfp_mm 2 (dipole, eta 1.3)``, for messages and the stats."""
        if self.preset is not None:
            return f"preset {self.preset!r}"

        def listed(values, texture):
            if texture is not None:
                return f"a {texture.class_name()} texture"
            return ",".join(f"{x:g}" for x in (values if len(set(values)) > 1 else values[:1]))

        return (f"color {listed(self.color, self.color_texture)}, mfp_mm {listed(self.mfp_mm, self.mfp_texture)} "
                f"({self.model}, eta {self.eta:g})")

    def medium_dict(self):
        """The Mitsuba ``homogeneous`` medium this stands for (:func:`~convsss.media.dicts.medium_dict`)."""
        return medium_dict(self.material, self.unit_mm)


def texture_values(texture, uv):
    """A 2D Mitsuba ``texture``'s RGB values (N, 3) at the texture coordinates ``uv`` (N, 2)."""
    import drjit as dr
    import mitsuba as mi

    si = dr.zeros(mi.SurfaceInteraction3f, len(uv))
    si.uv = mi.Point2f(*np.asarray(uv, dtype=np.float32).T)
    return np.asarray(texture.eval(si), dtype=np.float64).reshape(3, -1).T


def _texture(value, key):
    """``value`` if it is a 2D Mitsuba texture; a one-line error for a volume or any other Mitsuba object."""
    import mitsuba as mi

    if not isinstance(value, mi.Texture):
        hint = (": a convsss_medium's colour is a texture on the surface; for a volume write the interior as a "
                "heterogeneous medium (convsss scene --volume, docs/guide/scene-files.md)"
                if isinstance(value, mi.Volume) else ": give a constant (rgb or float) or a 2D texture (bitmap)")
        raise ConvsssError(f"convsss_medium: {key} as a {value.class_name()} is not supported{hint}")
    return value


def _lattice_values(texture):
    """``texture``'s values (TEXTURE_LATTICE^2, 3) at the centres of a lattice over (u, v) in [0, 1]^2."""
    t = (np.arange(TEXTURE_LATTICE) + 0.5) / TEXTURE_LATTICE
    return texture_values(texture, np.stack(np.meshgrid(t, t, indexing="ij"), axis=-1).reshape(-1, 2))


def _triple(value, key):
    """An RGB triple of floats from a Mitsuba property value: a number, a colour, a sequence or ``"R,G,B"``."""
    if hasattr(value, "class_name"):  # a Mitsuba object: only color and mfp_mm take textures, read before this
        raise ConvsssError(f"convsss_medium: {key} as a {value.class_name()} is not supported: give a constant "
                           "(rgb or float)")
    if isinstance(value, str):
        parts = value.split(",")
    elif isinstance(value, bool):
        parts = None
    else:
        try:
            parts = list(np.asarray(value, dtype=np.float64).reshape(-1))
        except (TypeError, ValueError):
            parts = None
    try:
        values = [float(x) for x in parts] if parts is not None else []
    except ValueError:
        values = []
    if len(values) not in (1, 3):
        raise ConvsssError(f"convsss_medium: {key}={value!r} is not allowed: give one number or three (R, G, B), "
                           "as a float, an rgb or a string 'R,G,B'")
    return tuple(values * 3 if len(values) == 1 else values)


def _number(value, key):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ConvsssError(f"convsss_medium: {key}={value!r} is not allowed: give a number")
    return float(value)


def named_medium(values):
    """The :class:`NamedMedium` for a ``convsss_medium``'s properties ``values`` (a dict), checked.

    Parameters
    ----------
    values : dict
        ``preset``, or ``color`` + ``mfp_mm`` (+ ``eta``, ``model``); ``unit_mm`` (module docstring).

    Returns
    -------
    NamedMedium

    Raises
    ------
    ConvsssError
        One line: an unknown preset (with the closest names), a colour outside what the model reaches, an
        ``mfp_mm`` <= 0, a preset and a colour or coefficients together, an unknown property.

    Examples
    --------
    >>> named_medium({"preset": "skin1"}).describe()
    "preset 'Skin1'"
    >>> m = named_medium({"color": [0.8, 0.5, 0.3], "mfp_mm": 2.0})
    >>> m.model, m.eta, m.material.mfp_mm.tolist()
    ('exact', 1.3, [2.0, 2.0, 2.0])
    """
    values = dict(values)
    _check_properties(values)
    unit_mm = _number(values.get("unit_mm", 1.0), "unit_mm")
    if not np.isfinite(unit_mm) or unit_mm <= 0:
        raise ConvsssError(f"convsss_medium: unit_mm={unit_mm!r} is not allowed: it must be finite and > 0 (mm per "
                           "scene unit)")
    return _preset_medium(values, unit_mm) if "preset" in values else _colour_medium(values, unit_mm)


def _check_properties(values):
    """One-line errors for properties the medium does not take: an unknown one, coefficients."""
    coefficients = [k for k in values if k in COEFFICIENTS]
    unknown = [k for k in values if k not in ("preset", "color", "mfp_mm", *OPTIONS, *COEFFICIENTS)]
    if unknown:
        raise ConvsssError(f"convsss_medium: unknown property {unknown[0]!r}: it takes preset, or color and mfp_mm "
                           f"(with eta, model), and unit_mm")
    by_color = "color" in values or "mfp_mm" in values
    if coefficients:
        given = "a preset" if "preset" in values else "color + mfp_mm" if by_color else "no preset nor colour"
        raise ConvsssError(f"convsss_medium: {given} and coefficients ({', '.join(coefficients)}) given: the "
                           "medium takes a preset or color + mfp_mm; for coefficients use a 'homogeneous' medium")


def _preset_medium(values, unit_mm):
    """The medium of a ``preset`` (alone: a preset has its own coefficients and eta)."""
    if "color" in values or "mfp_mm" in values:
        raise ConvsssError("convsss_medium: both a preset and color/mfp_mm given: give a preset, or color and "
                           "mfp_mm")
    extra = [k for k in ("eta", "model") if k in values]
    if extra:
        raise ConvsssError(f"convsss_medium: {extra[0]} goes with color and mfp_mm; a preset has its own "
                           "coefficients and eta (`convsss materials` lists them)")
    if not isinstance(values["preset"], str):
        raise ConvsssError(f"convsss_medium: preset={values['preset']!r} is not allowed: give a name")
    try:
        found = preset_material(values["preset"], warn=False)
    except ConvsssError as error:
        raise ConvsssError(f"convsss_medium: {error}") from None
    return NamedMedium(found, unit_mm, preset=found.name)


def _colour_medium(values, unit_mm):
    """The medium of a ``color`` and ``mfp_mm`` (each a value or a texture on the shape; with ``eta`` and
    ``model``), inverted into a material; a texture's mean stands for it here, its values per point at the load."""
    if "color" not in values and "mfp_mm" not in values:
        raise ConvsssError("convsss_medium: nothing given: it needs a preset, or color and mfp_mm")
    if "color" not in values or "mfp_mm" not in values:
        raise ConvsssError(f"convsss_medium: {'color' if 'color' in values else 'mfp_mm'} without "
                           f"{'mfp_mm' if 'color' in values else 'color'}: a colour needs both")
    model = values.get("model", DEFAULT_COLOR_MODEL)
    if not isinstance(model, str):
        raise ConvsssError(f"convsss_medium: model={model!r} is not allowed: give a model's name")
    eta = _number(values.get("eta", DEFAULT_ETA), "eta")
    textures, given, lattices = {}, {}, []
    for key in ("color", "mfp_mm"):
        if hasattr(values[key], "class_name"):
            textures[key] = _texture(values[key], key)
            lattice = _lattice_values(textures[key])
            if not (np.all(np.isfinite(lattice)) and np.all(lattice > 0)):
                raise ConvsssError(f"convsss_medium: the {key} texture has values that are not finite or <= 0 (e.g. "
                                   f"{lattice[~(np.isfinite(lattice) & (lattice > 0))][0]!r}): it must be > 0 "
                                   "everywhere")
            given[key] = tuple(float(x) for x in lattice.mean(axis=0))
            lattices.append(lattice.astype(np.float32).tobytes())
        else:
            given[key] = _triple(values[key], key)
    color, mfp = given["color"], given["mfp_mm"]
    try:
        model = check_color_model_name(model)
        found = material_from_color(color, mfp, eta, model, name="color", warn=False)
    except ConvsssError as error:
        raise ConvsssError(f"convsss_medium: {error}{' (the texture mean)' if textures else ''}") from None
    key = (unit_mm, eta, model, color, mfp, *lattices) if textures else None
    return NamedMedium(found, unit_mm, color=color, mfp_mm=mfp, model=model, color_texture=textures.get("color"),
                       mfp_texture=textures.get("mfp_mm"), key=key)


# ---- The Mitsuba plugin ----------------------------------------------------------------------------------------

#: Per medium made: its address -> (NamedMedium, its coefficients as made). Guarded by :data:`_LOCK` (Mitsuba
#: builds a scene's objects on several threads), which is never held while Dr.Jit evaluates anything.
_MADE = {}
_LOCK = threading.Lock()
#: While :func:`equivalents` holds: per textured medium's key, the heterogeneous medium's dictionary the constructor
#: makes instead (None: the placeholder, without a warning).
_EQUIVALENTS = None


def _fingerprint(mi, medium):
    """A digest of the medium's parameters as Mitsuba holds them (coefficients, volumes' data, scale)."""
    params = mi.traverse(medium)
    digest = hashlib.blake2b(digest_size=16)
    for key in sorted(params.keys()):
        digest.update(key.encode())
        digest.update(np.ascontiguousarray(np.asarray(params[key], dtype=np.float64)).tobytes())
    return digest.hexdigest()


def construct(props):
    """The ``convsss_medium``'s constructor: Mitsuba's ``homogeneous`` medium of :func:`named_medium`."""
    from ..backend import load_mitsuba

    mi = load_mitsuba()
    named = named_medium({key: props[key] for key in props.keys()})  # reading a property marks it as used
    with _LOCK:
        equivalent = None if _EQUIVALENTS is None or not named.textured else _EQUIVALENTS.get(named.key)
    if named.textured and _EQUIVALENTS is None:
        warnings.warn(f"convsss_medium ({named.describe()}): loaded outside convsss.load_scene, it is the "
                      "homogeneous medium of the texture's mean colour, not its heterogeneous equivalent",
                      TextureWarning, stacklevel=2)
    medium = mi.load_dict(equivalent or named.medium_dict())
    if props.id():
        medium.set_id(props.id())
    # The fingerprint reads the medium's arrays outside the lock: waiting for Dr.Jit, this thread may run another
    # pending constructor of the same scene (Mitsuba builds its objects in parallel), which takes the lock too
    # (the suite hung there once, in test_named's example scene)
    made = (named, _fingerprint(mi, medium))
    with _LOCK:
        _MADE[medium.ptr] = made
    return medium


@contextmanager
def equivalents(media):
    """While held, a textured ``convsss_medium`` whose key is in ``media`` (key -> a Mitsuba medium dictionary) is
    made as that medium; any other textured one is its placeholder, without a :class:`TextureWarning`."""
    global _EQUIVALENTS
    with _LOCK:
        _EQUIVALENTS = dict(media)
    try:
        yield
    finally:
        with _LOCK:
            _EQUIVALENTS = None


def register_medium(mi):
    """Register ``<medium type="convsss_medium">`` with Mitsuba (in the active variant)."""
    mi.register_medium(PLUGIN, construct)


def named_medium_of(mi, medium):
    """The :class:`NamedMedium` a ``convsss_medium`` made ``medium`` from, or None (another medium, or one whose
    coefficients changed since)."""
    if medium is None:
        return None
    with _LOCK:
        made = _MADE.get(medium.ptr)
    if made is None or _fingerprint(mi, medium) != made[1]:
        return None
    return made[0]


def forget(medium):
    """``medium`` is no longer what its ``convsss`` properties said (its coefficients were edited)."""
    with _LOCK:
        _MADE.pop(medium.ptr, None)


# ---- Checks against the object ---------------------------------------------------------------------------------

def check_boundary(named, boundary, eta, name, unit_mm=None):
    """A one-line error unless translucent shape ``name``'s ``boundary`` (kind, relative index ``eta``) and the
    renderer's ``unit_mm`` (None: not checked) agree with its ``convsss_medium`` ``named``."""
    what = f"translucent shape {name!r}: its convsss_medium ({named.describe()})"
    if boundary == "null":
        if named.color is not None and abs(named.eta - 1.0) > ETA_TOLERANCE:
            raise ConvsssError(f"{what} is inverted at eta {named.eta:g}, but its boundary is null (index-matched, "
                               "eta 1): give the medium eta 1, or the shape a dielectric boundary with int_ior "
                               f"{named.eta:g}")
    elif abs(eta - named.eta) > ETA_TOLERANCE * named.eta:
        hint = f"give the {boundary} int_ior {named.eta:g} and ext_ior 1 (Mitsuba's default ext_ior is air, 1.000277)"
        if named.color is not None:
            hint += f", or the medium eta {eta:.6g}"
        raise ConvsssError(f"{what} has eta {named.eta:g}, but its {boundary} boundary has int_ior/ext_ior "
                           f"{eta:.6g}: {hint}")
    if unit_mm is not None and abs(float(unit_mm) - named.unit_mm) > 1e-9 * named.unit_mm:
        raise ConvsssError(f"{what} is written for unit_mm {named.unit_mm:g} (mm per scene unit), but the render "
                           f"uses unit_mm {float(unit_mm):g}: give both the same value (one <default "
                           "name=\"unit_mm\"> for the integrator and the medium)")


def check_color_model(named, spec, name, total):
    """Warn (:class:`ColorModelWarning`) when translucent shape ``name``, whose medium ``named`` is given by colour,
    renders with the profile ``spec`` and ``profile_total`` ``total`` at another total reflectance than the colour's
    (:func:`~convsss.profiles.models.rendered_total_of`; a tabulated profile: no warning)."""
    rendered = rendered_total_of(spec, total)
    if named is None or named.color is None or rendered is None or rendered == named.model:
        return
    warnings.warn(f"translucent shape {name!r}: its colour {np.round(named.color, 4).tolist()} is the "
                  f"{named.model} total but it renders with the {rendered} total, "
                  f"{np.round(color_of(named.material, rendered), 4).tolist()}; give the medium model {rendered!r} "
                  "to match the colour", ColorModelWarning, stacklevel=3)


def any_textured_media():
    """Whether this process has made any ``convsss_medium`` of textured colour or mean free path."""
    with _LOCK:
        return any(named.textured for named, _ in _MADE.values())


def any_named_media():
    """Whether this process has made any ``convsss_medium`` (else no scene holds one)."""
    with _LOCK:
        return bool(_MADE)
