"""Options shared by the commands, in one vocabulary: what to render (a scene file, or ``--mesh``, a material by
``--material`` or ``--color/--mfp-mm``, and ``--size-mm``, with ``--width/--height``), ``--seed``, the tone mapping of
PNGs, and one option per integrator parameter, generated from the parameters' declarations (:mod:`convsss.parameters`)
so that help, defaults and checks are stated once.
"""

import functools

import click

from ..errors import ConvsssError
from ..image import TONEMAPS, check_tonemap
from ..materials import DEFAULT_ETA
from ..media.dicts import BOUNDARIES
from ..scene.quick import SPP, WIDTH
from ..scene.source import FIELDS, SceneSource

#: ``--progress/--no-progress``: every command that takes more than a moment shows a bar on stderr.
PROGRESS = click.option("--progress/--no-progress", default=True, show_default=True,
                        help="Show a progress bar on stderr.")

#: Random seeds: Mitsuba's are unsigned 32-bit integers.
SEED = click.IntRange(0, 2**32 - 1)


def _decorate(func, options):
    """``func`` with the click ``options`` applied, the first listed shown first in ``--help``."""
    for option in reversed(options):
        func = option(func)
    return func


MODEL_NAMES = ("dipole", "better-dipole", "pbd", "burley")
#: What --color may be the total reflectance of (convsss.profiles.models.COLOR_MODELS).
COLOR_MODEL_NAMES = ("exact", *MODEL_NAMES)


#: ``--color-model``: what a colour is the total reflectance of (every command that takes ``--color``).
COLOR_MODEL = click.option(
    "--color-model", type=click.Choice(COLOR_MODEL_NAMES),
    help="With --color: what --color is the total reflectance of: exact, the half-space of the medium by exact "
         "radiative transfer, which every profile model renders with --profile-total exact (the default); or one "
         "model's own total (give the model you render with --profile-total model). Render and reference must use "
         "the same. [default: exact]")


def dask_options(runs, default_workers):
    """``--workers`` and ``--scheduler``: where ``runs`` (the work past this process) runs, a local Dask cluster of
    ``--workers`` processes or a running scheduler's workers (``default_workers``: the help's word on no option)."""
    options = [
        click.option("--workers", type=click.IntRange(1), default=None,
                     help=f"Worker processes of a local Dask cluster for {runs}, one job at a time each, the "
                          f"machine's memory shared out among them. [default: {default_workers}]"),
        click.option("--scheduler", metavar="tcp://HOST:PORT",
                     help=f"A running Dask scheduler whose workers take {runs} instead (they need convsss, and "
                          "the scenes' and outputs' files at the same paths)."),
    ]
    return lambda func: _decorate(func, options)


def color_options(func):
    """``--color``, ``--mfp-mm``, ``--eta`` and ``--color-model``: a material by colour and distance, the alternative
    to ``--material`` (shared by the commands that take ``--material``;
    :func:`~convsss.scene.source.source_material`)."""
    options = [
        click.option("--color", metavar="R,G,B",
                     help="Instead of --material: the surface colour, the total diffuse reflectance per channel in "
                          "(0, 1) (linear), e.g. 0.8,0.5,0.3; with --mfp-mm."),
        click.option("--mfp-mm", metavar="D|R,G,B",
                     help="With --color: the reduced mean free path 1/sigma_t' in mm, one number or one per channel."),
        click.option("--eta", type=float,
                     help="With --color: the relative index of refraction of a dielectric boundary (a null boundary "
                          f"is eta 1). [default: {DEFAULT_ETA}]"),
        COLOR_MODEL,
    ]
    return _decorate(func, options)


def scene_source_options(func=None, *, preview=False):
    """The options that say what to render: a scene file, or ``--mesh``, ``--material`` (or ``--color/--mfp-mm``,
    :func:`color_options`) and ``--size-mm``, the film size, lights and camera (collected into one ``source``
    argument, a :class:`~convsss.scene.source.SceneSource`), and spp, seed and sensor (shared by commands);
    ``preview``: the editor's defaults (a 256² preview at 1 spp, whatever the scene's film)."""
    if func is None:
        return lambda f: scene_source_options(f, preview=preview)
    size = "default 256 (the scene's film is resized)" if preview else f"default: the scene's; {WIDTH} with --mesh"
    spp = "default 1" if preview else f"default: the scene's sampler; {SPP} with --mesh"
    options = [
        click.argument("scene_file", required=False, type=click.Path(dir_okay=False)),
        click.option("--mesh", type=click.Path(dir_okay=False),
                     help="Without a scene file: a mesh (.obj, .ply, .serialized, y up) framed with a camera, a key "
                          "light and a back light. 'bunny' is the bundled Stanford bunny."),
        click.option("--material", help="With --mesh: a preset name (see `convsss materials`), e.g. wholemilk; or "
                                        "--color and --mfp-mm."),
        color_options,
        click.option("--size-mm", type=float, help="With --mesh: the object's largest side in mm."),
        click.option("--floor", is_flag=True, help="With --mesh: add a grey floor under the object."),
        click.option("--boundary", type=click.Choice(BOUNDARIES), default="dielectric",
                     show_default=True,
                     help="With --mesh: the object's surface: a smooth or rough dielectric with the material's index "
                          "of refraction, or index-matched (null)."),
        click.option("--width", type=int, help=f"Film width in pixels ({size})."),
        click.option("--height", type=int, help=f"Film height in pixels ({size})."),
        click.option("--spp", type=click.IntRange(1), help=f"Samples per pixel ({spp})."),
        click.option("--sensor", type=click.IntRange(0), default=None,
                     help="Which of the scene's sensors to render, from 0 (default: the first; a note names the "
                          "others)."),
        click.option("--light-scale", type=click.FloatRange(0), default=1.0, show_default=True,
                     help="Multiply every light's power by this (the scene's emitters, or --mesh's key and back "
                          "light): the image scales by it."),
        click.option("--orbit-deg", type=float, default=0.0, show_default=True,
                     help="Turn the camera by this many degrees about the vertical (+y) axis through the translucent "
                          "objects' centre: a turntable's frame."),
        click.option("--seed", type=SEED, default=0, show_default=True,
                     help="Random seed, 0 to 2^32 - 1: the same seed gives the same image (render: bit for bit, "
                          "whatever the thread count; reference: up to Mitsuba's float rounding, about 1e-7 "
                          "relative)."),
    ]

    @functools.wraps(func)
    def collected(**kwargs):
        return func(source=SceneSource(**{name: kwargs.pop(name) for name in FIELDS}), **kwargs)

    return _decorate(collected, options)


def _check_tonemap_option(ctx, param, value):
    check_tonemap(**{param.name: value})
    return value


def tonemap_options(func):
    """``--tonemap``, ``--key``, ``--exposure`` and ``--exposure-from`` for the PNG (shared by commands); bad values
    fail at once (``--exposure-from`` with :func:`~convsss.outputs.exposure_anchor`)."""
    options = [
        click.option("--tonemap", type=click.Choice(TONEMAPS), default="reinhard", show_default=True,
                     help="PNG tone mapping: Reinhard's photographic operator, exposure only, or none (clipped)."),
        click.option("--key", type=float, default=0.18, show_default=True, callback=_check_tonemap_option,
                     help="Key value of the Reinhard operator (> 0)."),
        click.option("--exposure", type=float, default=0.0, show_default=True, callback=_check_tonemap_option,
                     help="Exposure in stops, applied before tone mapping."),
        click.option("--exposure-from", type=click.Path(dir_okay=False), metavar="IMAGE",
                     help="Key the Reinhard operator (scale and white point) on IMAGE, a linear EXR, instead of this "
                          "image: a render and its reference exposed alike."),
    ]
    return _decorate(func, options)


class DeclaredType(click.ParamType):
    """A click type that converts and checks a value by its :class:`~convsss.parameters.Parameter` declaration."""

    def __init__(self, parameter):
        self.parameter = parameter
        self.name = "|".join([parameter.kind.__name__, *parameter.words])  # the metavar: FLOAT|AUTO

    def convert(self, value, param, ctx):
        try:
            return self.parameter.check(value if self.parameter.kind is str else _number(value))
        except ConvsssError as error:
            self.fail(str(error), param, ctx)


def _number(text):
    """``text`` as an int when it is one, else a float (the declaration decides what is allowed)."""
    try:
        return int(text)
    except (TypeError, ValueError):
        try:
            return float(text)
        except (TypeError, ValueError):
            return text


def integrator_options(func):
    """One option per integrator parameter, from its declaration; unset ones keep the scene's (or the default)."""
    from ..pipeline.params import integrator_parameters

    for p, owner in reversed(integrator_parameters()):
        where = f" ({owner} transport)" if owner else ""
        shown = "none" if p.default in ("", None) else p.default
        allowed = "" if p.kind is str else f" Allowed: {p.allowed()}."
        help_text = f"{p.help}{where}{allowed} [default: {shown}]"
        kind = click.Choice(p.choices) if p.kind is str and p.choices else DeclaredType(p)
        func = click.option(f"--{p.name.replace('_', '-')}", p.name, type=kind, help=help_text)(func)
    return func
