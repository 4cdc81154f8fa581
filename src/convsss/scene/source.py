"""What to render, as every command takes it: a scene file, or a mesh with a material (a preset, or a colour and a
mean free path) and a size framed by the quick scene (:mod:`.quick`); the film's size, every light scaled and the
camera orbited (:mod:`.variations`). A value: checked before anything is loaded, loaded when asked.
"""

import warnings
from dataclasses import asdict, dataclass
from pathlib import Path

from ..errors import ConvsssError
from ..materials import DEFAULT_ETA


def parse_triple(text, name):
    """Three floats from ``"R,G,B"`` or one number (repeated), or a one-line error naming option ``name``."""
    try:
        values = [float(x) for x in str(text).split(",")]
    except ValueError:
        raise ConvsssError(f"{name} {text!r} is not allowed: give one number or three, R,G,B") from None
    if len(values) not in (1, 3):
        raise ConvsssError(f"{name} {text!r} is not allowed: give one number or three, R,G,B")
    return values * 3 if len(values) == 1 else values


def source_material(material, color, mfp_mm, eta, color_model, boundary):
    """The :class:`~convsss.materials.Material` of ``--material NAME`` or of ``--color/--mfp-mm`` (None when neither
    is given), for an object with ``boundary``; one-line errors for bad combinations and values.

    A colour is inverted by :func:`~convsss.profiles.models.material_from_color` under ``color_model`` (default: the
    exact total) at ``eta`` (default :data:`~convsss.materials.DEFAULT_ETA`; 1 on a ``null`` boundary, which is
    index-matched). No :class:`~convsss.materials.OpticallyThinWarning` here: the scene's object says it once, by
    its own name.
    """
    from ..materials import material as lookup_material
    from ..profiles.models import DEFAULT_COLOR_MODEL, material_from_color

    by_color = color is not None or mfp_mm is not None
    if material and by_color:
        raise ConvsssError("give --material or --color/--mfp-mm, not both")
    if not by_color:
        extra = "--eta" if eta is not None else "--color-model" if color_model is not None else None
        if extra:
            raise ConvsssError(f"{extra} goes with --color/--mfp-mm (a preset has its own coefficients and eta)")
        return lookup_material(material, warn=False) if material else None
    if color is None or mfp_mm is None:
        raise ConvsssError(f"{'--color' if color is not None else '--mfp-mm'} needs "
                           f"{'--mfp-mm' if color is not None else '--color'}: a material by colour needs both")
    if boundary == "null" and eta is not None and eta != 1.0:
        raise ConvsssError(f"--eta {eta:g} is not allowed with --boundary null: an index-matched boundary has eta 1")
    eta = 1.0 if boundary == "null" else (DEFAULT_ETA if eta is None else eta)
    return material_from_color(parse_triple(color, "--color"), parse_triple(mfp_mm, "--mfp-mm"), eta,
                               color_model or DEFAULT_COLOR_MODEL, name="color", warn=False)


@dataclass(frozen=True)
class SceneSource:
    """The scene a command renders (module doc). ``scene_file``, or ``mesh`` (a path, or ``bunny``) with
    ``material`` (a preset name) or ``color``/``mfp_mm`` (``"R,G,B"`` or one number; ``eta`` and ``color_model``
    with them), ``size_mm``, ``floor`` and ``boundary``; ``width``/``height`` (None: the scene's film, or the quick
    scene's); ``light_scale`` and ``orbit_deg``; ``rfilter`` the quick scene's film filter (a scene file keeps its
    own)."""

    scene_file: str = None
    mesh: str = None
    material: str = None
    color: str = None
    mfp_mm: str = None
    eta: float = None
    color_model: str = None
    size_mm: float = None
    floor: bool = False
    boundary: str = "dielectric"
    width: int = None
    height: int = None
    light_scale: float = 1.0
    orbit_deg: float = 0.0
    rfilter: str = "gaussian"

    @property
    def quick(self):
        """Whether the scene is the quick scene around a mesh (no scene file)."""
        return self.scene_file is None

    @property
    def colored(self):
        """Whether the material is given by its colour (``color``, ``mfp_mm``, ``eta`` or ``color_model``)."""
        return any(x is not None for x in (self.color, self.mfp_mm, self.eta, self.color_model))

    def check(self):
        """One-line errors for a source that names nothing to render or two things at once; the quick scene's
        :class:`~convsss.materials.Material` (None with a scene file). Nothing is loaded."""
        if self.scene_file and (self.mesh or self.material or self.colored or self.size_mm is not None):
            raise ConvsssError("give a scene file or --mesh/--material (or --color/--mfp-mm)/--size-mm, not both")
        if self.scene_file:
            return None
        made = source_material(self.material, self.color, self.mfp_mm, self.eta, self.color_model, self.boundary)
        if not (self.mesh and made is not None and self.size_mm is not None):
            raise ConvsssError("nothing to render: give a scene file, or all of --mesh, --material (or --color and "
                               "--mfp-mm) and --size-mm")
        return made

    def inputs(self):
        """The files the source reads: the scene file and every file it names, or the mesh."""
        from .loading import scene_inputs
        from .quick import demo_mesh

        inputs = scene_inputs(self.scene_file) if self.scene_file else []
        if self.mesh:
            inputs.append(demo_mesh() if self.mesh == "bunny" else Path(self.mesh))
        return inputs

    def load(self):
        """The loaded Mitsuba scene, its lights scaled by ``light_scale`` and its cameras orbited by ``orbit_deg``;
        one-line errors for bad combinations (:meth:`check`)."""
        from .loading import load_scene
        from .quick import HEIGHT, WIDTH, demo_mesh, quick_scene
        from .variations import orbit_camera, scale_lights

        made = self.check()
        if self.scene_file:
            scene = load_scene(self.scene_file, self.width, self.height)
        else:
            mesh = demo_mesh() if self.mesh == "bunny" else Path(self.mesh)
            scene = load_scene(quick_scene(mesh, made, self.size_mm, self.width or WIDTH, self.height or HEIGHT,
                                           floor=self.floor, boundary=self.boundary, rfilter=self.rfilter))
        return orbit_camera(scale_lights(scene, self.light_scale), self.orbit_deg)

    def warn_color_model(self, profile, total):
        """Warn (:class:`~convsss.media.named.ColorModelWarning`) when the quick scene's object, made from
        ``color`` under ``color_model``, renders with another total (the integrator's ``profile`` and
        ``profile_total``, :func:`~convsss.profiles.models.rendered_total_of`); nothing without a colour."""
        if self.color is None:
            return
        from ..media.named import ColorModelWarning
        from ..profiles.models import DEFAULT_COLOR_MODEL, parse_profile_spec, rendered_total_of

        default, per_object = parse_profile_spec(profile)
        spec, model = per_object.get("object", default), self.color_model or DEFAULT_COLOR_MODEL
        rendered = rendered_total_of(spec, total)
        if rendered is not None and rendered != model:
            warnings.warn(f"--color is the {model} total reflectance but the object renders with the {rendered} "
                          f"total: give --color-model {rendered} to match the colour", ColorModelWarning,
                          stacklevel=2)

    def summary(self):
        """The quick scene's options (for the stats), None with a scene file."""
        if not self.quick:
            return None
        keys = ("mesh", "material", "color", "mfp_mm", "eta", "color_model", "size_mm", "floor", "boundary")
        quick = {k: v for k, v in asdict(self).items() if k in keys}
        return {**quick, "mesh": str(self.mesh)}


#: The command-line options (click's parameter names) that make a :class:`SceneSource` (``rfilter`` is set by the
#: commands that denoise, not by an option).
FIELDS = tuple(name for name in SceneSource.__dataclass_fields__ if name != "rfilter")
