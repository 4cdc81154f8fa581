"""The parameters of the ``convsss`` integrator, checked in one place (no Mitsuba needed).

The same :class:`RenderParams` backs ``<integrator type="convsss">``, :func:`mitsuba.render` and the command line, so
a bad value gets the same one-line :class:`~convsss.errors.ConvsssError` everywhere. They are the renderer's own
(:func:`render_parameters`) and the transports' (each transport's declared ``parameters``, e.g. ``layers`` of the
convolution, ``epsilon`` of the hierarchical method): every declaration has one default, stated once.
"""

import math
from dataclasses import dataclass

from ..errors import ConvsssError
from ..parameters import Parameter, check_parameters
from ..profiles.incidence import Orders
from ..profiles.models import DEFAULT_PROFILE, DEFAULT_TOTAL, PROFILE_TOTALS, parse_profile_spec

SPECULARS = ("bsdf", "phong", "none")
#: Direction samples per effective area of the profile that ``irradiance_samples`` auto draws for area and
#: environment emitters (:attr:`RenderParams.directions`). The exitance averages the directions of every point
#: under its profile: its sample noise (median, p95 over the object's pixels, 128^2, exitance AOV of two seeds) from
#: 16 directions a point to 1, at the default 1500 points a profile area: 0.51/3.58 -> 0.55/3.60 % on the 40 mm marble
#: bunny under an area light, 0.60/3.70 -> 0.65/3.72 % on the armadillo, 0.39/1.20 -> 0.46/1.74 % on the potato under
#: an environment, 0.24/0.94 -> 0.29/1.12 % on the dragon under a sun and a sky; the irradiance stage 9.8-18x faster.
PROFILE_DIRECTIONS = 16
#: Default ``profile_samples``: chosen to hold the exitance's sample noise near the goal of 1 % (docs/benchmarks.md
#: has the measurements).
PROFILE_SAMPLES = 1500.0

#: The integrator's AOVs (``aovs``) and their film channels, ``<name>.<channel>`` (Mitsuba's ``aov`` convention), all
#: taken at the camera ray's first hit: the transport's exitance ``M`` (paper Eq. 7) and the irradiance ``E`` (Eq. 2)
#: there on a translucent object (0 elsewhere), the translucent object's index + 1 (0: none), a mask (1 on a
#: translucent object, 0 elsewhere; its pixel average is the coverage), Mitsuba's ``depth`` and ``sh_normal``, and an
#: ``albedo`` (a translucent object's total diffuse reflectance, another surface's diffuse reflectance as Mitsuba's
#: ``albedo`` AOV: the denoiser's guide).
AOVS = {"exitance": ("R", "G", "B"), "irradiance": ("R", "G", "B"), "object": ("I",), "mask": ("Y",),
        "depth": ("T",), "normal": ("X", "Y", "Z"), "albedo": ("R", "G", "B")}


def parse_aovs(text):
    """The AOV names of the ``aovs`` parameter (comma-separated, in their order), each checked; one-line errors.

    Examples
    --------
    >>> parse_aovs("exitance, object")
    ('exitance', 'object')
    >>> parse_aovs("position")
    Traceback (most recent call last):
    ...
    convsss.errors.ConvsssError: aovs='position' is not allowed: 'position' is not an AOV of convsss; choose from \
exitance, irradiance, object, mask, depth, normal, albedo
    """
    names = tuple(n.strip() for n in str(text).split(",") if n.strip())
    for k, name in enumerate(names):
        if name not in AOVS:
            raise ConvsssError(f"aovs={text!r} is not allowed: {name!r} is not an AOV of convsss; choose from "
                               f"{', '.join(AOVS)}")
        if name in names[:k]:
            raise ConvsssError(f"aovs={text!r} is not allowed: {name!r} is named twice")
    return names


def with_aovs(aovs, extra):
    """The ``aovs`` parameter with the names ``extra`` added where it does not name them already.

    >>> with_aovs("mask", ("albedo", "mask"))
    'mask,albedo'
    """
    names = parse_aovs(aovs)
    return ",".join((*names, *(name for name in extra if name not in names)))


def reads_transports(aovs):
    """Whether the ``aovs`` parameter asks for what only the transports give: their exitance, or the samples'
    irradiance (a render whose every camera path walks needs them for nothing else)."""
    return bool({"exitance", "irradiance"} & set(parse_aovs(aovs)))


def walks_alone(params, mode):
    """Whether a render with ``params`` in ``mode`` (a :class:`RenderMode`) needs none of stages 2-5 (samples,
    irradiance, transports, screen): every walk goes to its end and no AOV asks for the transports' exitance or the
    samples' irradiance."""
    return mode.walk_depth == math.inf and not mode.transported and not reads_transports(params.aovs)


def aov_channels(names):
    """The film channels of the AOVs ``names`` (from :func:`parse_aovs`), e.g. ``exitance.R``, in order."""
    return [f"{name}.{channel}" for name in names for channel in AOVS[name]]


def available_transports():
    """Names accepted by ``transport``: whatever :mod:`convsss.transport` registers."""
    from ..transport import TRANSPORTS

    return tuple(sorted(TRANSPORTS))


def render_parameters():
    """The renderer's own parameters (the transports declare theirs)."""
    return (
        Parameter("transport", str, "multiscale", "multiscale: near field summed directly, far field by 3-D FFTs "
                  "(the exact sum's accuracy at any size); convolution: the paper's layered FFTs; exact: the direct "
                  "sum (slow, a reference); hierarchical: Jensen & Buhler 2002; volume: multiscale corrected by the "
                  "diffusion equation solved on the object's interior (light through the body and thin parts, "
                  "none across air gaps; slower: a diffusion solve on top of the multiscale sums).",
                  choices=available_transports()),
        Parameter("irradiance_samples", int, "auto", "Direction samples per surface point for area and "
                  "environment emitters (point, spot and directional lights are evaluated exactly). auto: enough "
                  f"for {PROFILE_DIRECTIONS} per effective area of the profile, where the profile_samples rule draws "
                  f"the samples (1 at its default: the exitance averages the directions of the many points under "
                  f"its profile), else {PROFILE_DIRECTIONS} a point.", low=1, words=("auto",)),
        Parameter("indirect_samples", float, 1.0, "Paths per surface sample for indirect light (light that reaches a "
                  "translucent object after bouncing off the rest of the scene, other translucent objects included); "
                  "below 1, that fraction of the samples traces one path each; 0: direct light only.", low=0.0),
        Parameter("indirect_passes", int, 1, "Passes of light between translucent objects (another's or an object's "
                  "own light coming back): each builds the transports of the objects it lights once more; the stats "
                  "say how much the last pass changed.", low=1),
        Parameter("incidence", str, "oblique", "How light entering and leaving a translucent object at a slant "
                  "counts: oblique: each direction's irradiance weighted per channel by how much more a half-space of "
                  "the medium sends back for light refracted in at that angle than for a normal beam (exact radiative "
                  "transfer; large at low albedo, small near albedo 1), and by reciprocity the exitance leaving "
                  "towards each direction likewise; normal: every direction as the profile's normal beam, the "
                  "exitance leaving as Lambert's law (the paper's).", choices=("oblique", "normal")),
        Parameter("single_scattering", str, "traced", "Light scattered once inside a translucent object: traced: "
                  "traced through the object's own shape at every path vertex on it (one distance along the "
                  "refracted view ray, one light sample per emitter from there: Jensen et al. 2001's "
                  "single-scattering term), the profile carrying the rest and the single scattering of indirect "
                  "light (needs profile_total exact; a CSV profile should hold multiple scattering only); profile: "
                  "all of it in the diffusion profile, as a half-space sends it back (the paper's, and what "
                  "profile_total model implies when this is not given). Traced is what makes low-albedo media "
                  "(ketchup, skin) and objects a few mean free paths across right.",
                  choices=("profile", "traced")),
        Parameter("profile_total", str, DEFAULT_TOTAL, "Each profile model's total reflectance: exact: scaled per "
                  "channel to that of a half-space of the medium by exact radiative transfer (the Monte Carlo slab's "
                  "within its noise), the model keeping its shape; model: the model's own (the paper's dipole is "
                  "low under a dielectric, beam diffusion high at eta 1; docs/benchmarks.md has by how much). A CSV "
                  "profile is used as given.", choices=PROFILE_TOTALS),
        Parameter("sample_density", float, 4.0, "Surface samples per layer cell: N = sample_density * area / cell^2 "
                  "over the whole surface.", low=0.0, low_open=True),
        Parameter("profile_samples", float, PROFILE_SAMPLES, "Surface samples per effective area of the object's "
                  "diffusion profile, at least (A_eff = (∫R_d dA)^2 / ∫R_d^2 dA, smallest over the channels; for a "
                  "profile narrower than the pixel footprint f, the multiscale transport's local limit, about "
                  "1.75 f^2): N >= profile_samples * area / A_eff, so that the noise the discrete samples leave in "
                  "the exitance (more camera samples do not remove it) stays near the goal of 1 % (mean over the "
                  "object's pixels) at the default; it falls faster than N^-1/2, the samples being stratified. 0: the "
                  "pixel rule alone. Capped, with a warning, by the memory and time limits.", low=0.0),
        Parameter("passes", int, 1, "Render in this many passes, each with its own surface samples (fresh, from its "
                  "own seed stream, 1/passes of sample_density and profile_samples) and its share of the camera "
                  "samples (spp); the image is their mean, so the exitance's sample noise averages out with passes "
                  "as camera noise does, and each pass is a whole image (at most spp passes).", low=1),
        Parameter("time_limit", float, 0.0, "With passes > 1: seconds after which no further pass is started (one "
                  "that the mean pass so far says would end past the limit is not); at least one pass is rendered, "
                  "and the image is the mean of those done. 0: no limit.", low=0.0),
        Parameter("specular", str, "bsdf", "Boundary reflection on translucent objects: the scene's BSDF, the paper's "
                  "Phong lobe weighted by the Fresnel reflectance, or none.", choices=SPECULARS),
        Parameter("phong_exponent", float, 64.0, "Exponent of the Phong lobe with specular = phong.", low=0.0,
                  low_open=True),
        Parameter("walk_depth", float, "auto", "Light under a translucent object's surface by a random walk through "
                  "its medium (volumetric path tracing: the scene's medium, phase function and boundary BSDF), ended "
                  "in the diffusion field solved on the object's volume where it scatters at least this many "
                  "transport mean free paths (1/sigma_t') below the surface, in the channels where diffusion holds. "
                  "0 renders with the transport alone (paper Eq. 7); inf follows every walk to its end, which is "
                  "Mitsuba's volpathmis for those objects. auto: each object its own way: the transport where "
                  "diffusion holds (at least 20 transport mean free paths across its mean chord 4V/A, reduced albedo "
                  "at least 0.95), walks to their end elsewhere, with every light but an environment without a sun "
                  "sampled through smooth boundaries along the path that refracts to it (Eq. W5): where diffusion "
                  "fails walks are short; a walk that meets an object its transport renders reads its exitance there. "
                  "Where a transport is named and walk_depth is not, 0.", low=0.0, infinite=True, words=("auto",)),
        Parameter("refraction", str, "manifold", "How a walk's scattering vertex reaches a light behind a smooth "
                  "dielectric boundary (a delta light always; every light but the environment in auto's walks and "
                  "where walks end in the field): manifold: along the path that refracts to it by Snell's law "
                  "(Eq. W5, manifold next-event estimation, weighed against the paths that refract out and hit "
                  "it; an environment map with a sun too, as a directional light, one without left to those hits: "
                  "unbiased for area lights and environments, noisier on detailed meshes, whose many refracted "
                  "paths the solver misses and the hits carry); straight: along the straight shadow ray, corrected "
                  "as if the boundary were a plane (Eq. W4: less noise, biased on curved boundaries, 0.84-0.90 of "
                  "volpathmis on a 1 mm sphere, 0.95-0.99 on a 30 mm armadillo).", choices=("manifold", "straight")),
        Parameter("jumps", str, "on", "Whether auto's walks cross the deep interior of an object of isotropic "
                  "scattering in one step (shell tracing, Eq. J1): from a scattering vertex a ball's radius below "
                  "every surface, to a point of that ball's sphere drawn from a homogeneous sphere's tabulated exit "
                  "distribution, with its throughput: the same light with fewer events. The ball keeps 6 mean free "
                  "paths from the surface where light is sampled inside the object (what it leaves out there is "
                  "below 1e-2 of a surface vertex's light), none behind a rough dielectric or under environments "
                  "left to the paths that hit them. off: every event walked. Not at an explicit walk_depth (inf is "
                  "volpathmis's estimator).", choices=("on", "off")),
        Parameter("max_depth", int, 6, "Longest path (Mitsuba's convention: 1 shows emitters only, 2 adds direct "
                  "light; -1 is unbounded with Russian roulette; 0 is not allowed). Light under a translucent "
                  "object's surface is one bounce, whether the transport or a walk renders it (a walk's scattering "
                  "events inside are not counted).", low=-1),
        Parameter("rr_depth", int, 5, "Depth from which Russian roulette may end paths.", low=1),
        Parameter("unit_mm", float, 1.0, "How many mm one scene unit is (scene coefficients are per scene unit).",
                  low=0.0, low_open=True),
        Parameter("profile", str, "", "Diffusion profile per translucent object: a model (dipole: Jensen et al. "
                  "2001, the paper's; better-dipole: d'Eon 2012; pbd: photon beam diffusion with single scattering, "
                  "Habel et al. 2013; burley: Christensen & Burley 2015) or a CSV file r_mm, R, G, B, for every "
                  "object, or per object by shape id: 'bunny=pbd,dragon=skin.csv' (an entry without 'name=' sets "
                  f"the others). Empty: {DEFAULT_PROFILE}."),
        Parameter("aovs", str, "", "Extra film channels (AOVs) at each camera ray's first hit, comma-separated: "
                  "exitance (the transport's M, RGB, on translucent objects), irradiance (the E its samples carry "
                  "there, RGB), object (the translucent object's index + 1, 0: none), mask (1 on a translucent "
                  "object; per pixel: its coverage), depth (hit distance, as Mitsuba's aov), normal (shading "
                  "normal), albedo (a translucent object's total diffuse reflectance R_d, another surface's diffuse "
                  "reflectance). Empty: none."),
    )


def integrator_parameters():
    """Every parameter a scene or the command line may set, with the transport that declares it (``None``: the
    renderer's own): the renderer's first, then each transport's exposed ones. A name declared by several transports
    keeps its first declaration (transports in name order)."""
    from ..transport import TRANSPORTS

    rows = [(p, None) for p in render_parameters()]
    seen = {p.name for p, _ in rows}
    for kind in sorted(TRANSPORTS):
        for p in TRANSPORTS[kind].parameters:
            if p.exposed and p.name not in seen:
                seen.add(p.name)
                rows.append((p, kind))
    return rows


def transport_parameters():
    """The exposed (user-settable) parameters of every registered transport, by name (:func:`integrator_parameters`)."""
    return {p.name: p for p, owner in integrator_parameters() if owner is not None}


def plugin_parameters():
    """The integrator's parameters as Mitsuba documents a plugin's (a ``.. pluginparameters::`` table): name, type,
    and the help with the allowed values and default, for every parameter a scene may set."""
    lines = [".. pluginparameters::", ""]
    for p, owner in integrator_parameters():
        where = f" ({owner} transport)" if owner else ""
        default = "none" if p.default in ("", None) else p.default
        kind = {int: "integer", float: "float", str: "string"}[p.kind]
        allowed = f" Allowed: {p.allowed()}." if p.kind is not str or p.choices else ""
        lines += [f" * - {p.name}", f"   - |{kind}|", f"   - {p.help}{where}{allowed}",
                  f"     (Default: {default})", ""]
    return "\n".join(lines)


@dataclass(frozen=True)
class RenderMode:
    """What renders the camera's paths through the translucent objects: the parameters' ``walk_depth`` resolved once,
    by the survey, for the scene's objects (:func:`render_mode`); every stage downstream reads this value.

    Attributes
    ----------
    walk_depth : float
        0: the transport's exitance (paper Eq. 7); inf: walks to their end (volumetric path tracing of the objects'
        media, ``volpathmis``'s estimator); between: walks ended in the diffusion field at that depth (Eq. W3).
    straight : bool
        Whether walks sample every light but an environment without a sun through smooth boundaries (Eq. W5, the path
        that refracts to it, weighed against the paths that hit it): walks ended in the field, and ``auto``'s walks;
        at an explicit inf only a delta light, which no path reaches, so that the walk stays ``volpathmis``.
    transported : frozenset
        The objects (their :attr:`~.objects.TranslucentObject.key`) that their transport renders while the others
        walk (``auto`` on a scene where diffusion holds on some objects only): a path that meets one reads its
        exitance (paper Eq. 7) instead of walking into it.
    """

    walk_depth: float
    straight: bool = False
    transported: frozenset = frozenset()

    @property
    def walks(self):
        """Whether the camera's paths walk through the objects' media."""
        return self.walk_depth > 0.0

    @property
    def field(self):
        """Whether walks end in a diffusion field (``0 < walk_depth < inf``)."""
        return 0.0 < self.walk_depth < math.inf

    @property
    def plain(self):
        """Whether walks are ``volpathmis``'s estimator and nothing else: to their end, no light straight through
        smooth boundaries but a delta light's, one emitter chosen per vertex (an explicit inf)."""
        return self.walk_depth == math.inf and not self.straight

    def transports(self, obj):
        """Whether the translucent object ``obj`` is rendered by its transport's exitance: every object where nothing
        walks, the :attr:`transported` ones where the others walk."""
        return not self.walks or obj.key in self.transported

    def __str__(self):
        return f"{self.walk_depth:g}"


def render_mode(params, objects):
    """The :class:`RenderMode` of ``params`` for the translucent ``objects``: ``walk_depth`` as given, or for
    ``auto`` each object its own way (issue 60): 0 (the transport) where diffusion holds on every object
    (:meth:`~.objects.TranslucentObject.diffusion_holds`), else inf with every light but an environment without a sun
    straight through smooth boundaries, the objects where diffusion holds still rendered by their transport."""
    if params.walk_depth != "auto":
        depth = float(params.walk_depth)
        return RenderMode(depth, straight=0.0 < depth < math.inf)
    holds = [obj.diffusion_holds() for obj in objects]
    if all(holds):
        return RenderMode(0.0)
    return RenderMode(math.inf, straight=True,
                      transported=frozenset(obj.key for obj, held in zip(objects, holds) if held))


class IgnoredParameterWarning(UserWarning):
    """An integrator parameter belongs to another transport than the one rendering, or to the transports where every
    object walks to its end: it has no effect."""


#: The parameters of the transports, which a render whose every translucent object walks to its end never reads
#: (the walk renders the media themselves). ``specular`` and ``phong_exponent`` are not read either (the walk shades
#: the boundary by its BSDF), but a scene made by ``--mesh`` sets them without being asked: not warned about.
TRANSPORT_ONLY = ("transport", "irradiance_samples", "indirect_samples", "indirect_passes", "incidence",
                  "single_scattering", "profile_total", "sample_density", "profile_samples", "profile")


def walk_ignored(params):
    """The parameters of ``params`` set away from their defaults that a render walking every object to its end
    never reads (:data:`TRANSPORT_ONLY`, and every transport option given); the passes' shares of the samples
    aside."""
    defaults = {p.name: p.default for p in render_parameters()}
    defaults.update({name: p.default for name, p in transport_parameters().items()})
    defaults.update({p.name: p.default for p in params.transport_class().parameters if p.exposed})
    shared = ("sample_density", "profile_samples") if params.passes > 1 else ()
    values = params.to_dict()
    options = sorted(name for name in values if name in transport_parameters() and values[name] != defaults[name])
    return [name for name in TRANSPORT_ONLY if name not in shared and values[name] != defaults[name]] + options


class RenderParams:
    """Every ``convsss`` integrator parameter: the renderer's and the transports', each checked, defaults filled in.

    ``RenderParams(transport="hierarchical", epsilon=0.1)``: attributes read the value given or the default
    (``params.layers``, ``params.epsilon``). A transport's parameter is checked against its own declaration.
    """

    def __init__(self, **values):
        renderer = {p.name for p in render_parameters()}
        declared = transport_parameters()
        unknown = sorted(set(values) - renderer - set(declared))
        if unknown:
            raise ConvsssError(f"the convsss integrator has no parameter {unknown[0]!r}")
        self._renderer = check_parameters(render_parameters(), {k: v for k, v in values.items() if k in renderer},
                                          "the convsss integrator")
        if "transport" in values and "walk_depth" not in values:  # a transport named is the one that renders
            self._renderer["walk_depth"] = 0.0
        if self._renderer["max_depth"] == 0:
            raise ConvsssError("max_depth=0 is not allowed: it must be -1 (unbounded) or >= 1")
        if self._renderer["profile_total"] == "model":
            if values.get("single_scattering") == "traced":
                raise ConvsssError("single_scattering=traced needs profile_total=exact: a model's own total holds "
                                   "single scattering, which would then count twice")
            self._renderer["single_scattering"] = "profile"
        parse_profile_spec(self._renderer["profile"])
        parse_aovs(self._renderer["aovs"])
        own = {p.name: p for p in self.transport_class().parameters if p.exposed}
        self._options = {k: (own.get(k) or declared[k]).check(v) for k, v in values.items() if k in declared}

    @property
    def directions(self):
        """Direction samples per point for area and environment emitters: ``irradiance_samples``, or for auto
        :data:`PROFILE_DIRECTIONS` per profile area (``profile_samples`` points), at least 1 a point; without the
        profile rule (``profile_samples`` 0, the paper's samples by cells) :data:`PROFILE_DIRECTIONS` a point."""
        given = self._renderer["irradiance_samples"]
        if given != "auto":
            return given
        per_area = self._renderer["profile_samples"]
        return PROFILE_DIRECTIONS if per_area <= 0 else max(1, math.ceil(PROFILE_DIRECTIONS / per_area))

    @property
    def orders(self):
        """What the profiles and their gains carry (:class:`~convsss.profiles.incidence.Orders`): multiple where the
        path tracer traces single scattering, else all."""
        return Orders.MULTIPLE if self._renderer["single_scattering"] == "traced" else Orders.ALL

    def ignored(self):
        """The options given that belong to another transport than the chosen one (kept, and ignored by it)."""
        own = {p.name for p in self.transport_class().parameters if p.exposed}
        return sorted(set(self._options) - own)

    def transport_class(self):
        from ..transport import TRANSPORTS

        return TRANSPORTS[self._renderer["transport"]]

    def transport_params(self):
        """The chosen transport's exposed parameters: given values over its defaults."""
        return {p.name: self._options.get(p.name, p.default) for p in self.transport_class().parameters if p.exposed}

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        if name in self._renderer:
            return self._renderer[name]
        if name in self._options:
            return self._options[name]
        declared = {p.name: p for p in self.transport_class().parameters if p.exposed}
        declared = declared if name in declared else transport_parameters()
        if name in declared:
            return declared[name].default
        raise AttributeError(name)

    def __repr__(self):
        return f"RenderParams({', '.join(f'{k}={v!r}' for k, v in self.to_dict().items())})"

    @classmethod
    def names(cls):
        """Every parameter name: the renderer's and every transport's exposed ones."""
        return [p.name for p, _ in integrator_parameters()]

    @classmethod
    def from_properties(cls, props):
        """From a Mitsuba ``Properties`` (or any mapping with ``in`` and ``[]``): only the names it holds."""
        return cls(**{name: props[name] for name in cls.names() if name in props})

    def replace(self, **changes):
        """These parameters with ``changes`` (checked as at construction; a ``transport`` changed keeps the
        ``walk_depth`` these have, unlike a transport named at construction)."""
        return RenderParams(**{**self.to_dict(), **changes})

    def to_dict(self):
        """The renderer's values, the chosen transport's parameters, and any other transport option given."""
        return {**self._renderer, **self.transport_params(), **self._options}

    def integrator_dict(self):
        """A Mitsuba dictionary ``{"type": "convsss", ...}`` with these parameters."""
        return {"type": "convsss", **self.to_dict()}


def render_params(options, base=None):
    """:class:`RenderParams` from the command's options (only those given) over ``base`` (a dict); a transport given
    without a walk_depth renders with that transport (``base``'s walk_depth dropped)."""
    values = dict(base or {})
    given = {name: value for name, value in options.items() if value is not None}
    if "transport" in given and "walk_depth" not in given:
        values.pop("walk_depth", None)
    values.update(given)
    return RenderParams(**values)
