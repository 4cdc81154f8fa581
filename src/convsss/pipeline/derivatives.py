"""Derivatives of a walked render with respect to the media's coefficients (issue 63): ``mi.render`` under
``dr.backward`` / ``dr.forward`` for a homogeneous medium's ``albedo`` and ``sigma_t``, and ``dr.backward`` for a
heterogeneous medium's ``albedo`` (a ``gridvolume``: textures from photographs) where its ``sigma_t`` is constant and
for a rough dielectric boundary's roughness (``alpha``, ``alpha_u``, ``alpha_v``).

The walk (:mod:`.walk`) estimates a pixel by a sum of contributions ``c = f / p``: ``f`` the path's throughput
(transmittances, scattering coefficients, phase functions, BSDFs, the light), ``p`` the density it was drawn with
(Eq. W1, W2). With ``p`` held fixed (the paths are the ones drawn; as in path replay backpropagation, Vicini,
Speierer and Jakob 2021, every density, the hero channel, the roulette and the MIS weights are detached), the
derivative of a contribution in channel ``i`` with respect to a medium's ``sigma_t`` or ``sigma_s`` in that channel is
the contribution times the sum of its events' scores, ``d log f_i``:

    d log f_i / d sigma_t,i = - (length travelled in the medium),   d log f_i / d sigma_s,i = 1 / sigma_s,i   (Eq. G1)

per free flight and shadow-ray segment (``e^{-sigma_t t}``; Eq. W4's refracted path ``e^{-sigma_t s mu/mu'}`` adds
``-s (mu/mu' - 1)``) and per scattering vertex (``sigma_s``). The walk carries each differentiated medium's two
scores per channel beside its ratios and adds ``c * scores`` to a per-sample Jacobian wherever it adds ``c`` to its
radiance:

    dL_i / d sigma_t,i = sum_c c_i D_t,i(c),   dL_i / d sigma_s,i = sum_c c_i D_s,i(c)                      (Eq. G2)

``D(c)`` the sums of Eq. G1 over the events before contribution ``c`` (its shadow ray's segments included): the same
estimator as a replay's ``sum_events score x (radiance still to come)``, in one pass. A channel's
coefficients move that channel alone, so the Jacobian is diagonal: six numbers per medium and sample. The chain to
what a user differentiates (``albedo``, ``sigma_t``: ``sigma_s = albedo sigma_t scale``) is Mitsuba's own, through
the coefficients the medium returns with gradients on (:func:`render_backward`, :func:`render_forward`).

A heterogeneous medium's albedo differs from one scattering vertex to the next, so no per-sample Jacobian holds its
parameters: its walks are walked twice on the same random numbers (path replay backpropagation), the second time
with each sample's radiance ``L`` and adjoint ``dLoss/dL`` known, each scattering vertex sending its score times the
radiance still to come to the albedo there through Mitsuba's AD (Eq. G3, :func:`replay_scattering`); a rough
boundary's roughness the same way, at each event its BSDF weighs (:func:`replay_bsdf`).

Not differentiated (refused in one line, :func:`differentiated_media`): an extinction that varies in space (a
``sigma_t`` grid: it needs differential ratio tracking, Nimier-David et al. 2022, not built), ``dr.forward`` of a
heterogeneous albedo or a roughness, the boundary's index (it bends the paths), the lights, the geometry; walks
ended in the diffusion field and the transport (``walk_depth`` other than inf or ``auto``'s walks). A medium's
``scale`` is not differentiable in Mitsuba. A channel whose ``sigma_s`` is exactly 0 reads a gradient of 0 there
(its score divides by it).
"""

import math
from contextlib import contextmanager
from dataclasses import dataclass

import drjit as dr
import numpy as np

from ..backend import import_mitsuba
from ..errors import ConvsssError
from .film import camera_samples, channels, sampled_extent, splat_adjoint
from .film import image as film_image
from .parts import pass_seed, samples_per_pixel, shares

mi = import_mitsuba()

#: What a gradient through a render that does not walk is told.
NOT_WALKED = ("derivatives through a convsss render are those of its random walk: render with walk_depth inf (or "
              "auto where it walks every object); walks ended in the diffusion field and the transport have none")
#: Camera samples per kernel of a differentiated render (as :data:`~.integrator.WALK_LANES`).
LANES = 1 << 20


# --- the scores the walk carries (Eq. G1, G2) ----------------------------------------------------------------------
def zero_scores(media, n):
    """Per lane, each of ``media``'s scores (``d log f / d sigma_t`` then ``d log f / d sigma_s``, Color3f): 0."""
    return tuple(dr.zeros(mi.Color3f, n) for _ in range(2 * len(media)))


def add_length(scores, media, medium, length, active):
    """``scores`` after a distance ``length`` travelled in ``medium`` where ``active`` (Eq. G1: ``-length``)."""
    out = list(scores)
    for k, differentiated in enumerate(media):
        out[2 * k] = dr.select(active & (medium == differentiated), out[2 * k] - length, out[2 * k])
    return tuple(out)


def add_scattering(scores, media, medium, sigma_s, active):
    """``scores`` after a scattering vertex in ``medium`` of coefficient ``sigma_s`` where ``active`` (Eq. G1:
    ``1 / sigma_s``; 0 in a channel whose ``sigma_s`` is 0: there the contribution, and its derivative here, is 0)."""
    out = list(scores)
    inverse = dr.select(sigma_s > 0.0, dr.rcp(sigma_s), 0.0)
    for k, differentiated in enumerate(media):
        here = active & (medium == differentiated)
        out[2 * k + 1] = dr.select(here, out[2 * k + 1] + inverse, out[2 * k + 1])
    return tuple(out)


def accumulate(jacobian, scores, contribution, active, more=None):
    """``jacobian`` plus ``contribution * scores`` (plus the shadow ray's own ``more``) where ``active`` (Eq. G2)."""
    more = more or tuple(0.0 for _ in scores)
    return tuple(dr.select(active, j + contribution * (s + m), j) for j, s, m in zip(jacobian, scores, more))


@dataclass
class Replay:
    """What a replayed walk needs (:attr:`~.walk.RandomWalk.replayed`): the heterogeneous ``media`` whose albedo and
    the boundaries' ``bsdfs`` whose roughness it differentiates, and per lane the ``adjoint`` radiance and the
    ``radiance`` of the first walk (None in that walk)."""

    media: list
    bsdfs: list
    adjoint: object = None
    radiance: object = None


def _among(pointer, pointers, active):
    here = dr.zeros(mi.Bool, dr.width(active))
    for other in pointers:
        here |= pointer == other
    return here & active


def _send(factor, rest, adjoint, active):
    """Eq. G3 at one event: ``factor`` (attached, per channel) times ``adjoint . rest / factor`` (detached)."""
    held = dr.detach(factor)
    dr.backward_from(factor * dr.select(active & (held > 0.0), adjoint * rest / held, 0.0))


def replay_scattering(replay, medium, mei, result, active):
    """At a scattering vertex ``mei`` in ``medium`` (where ``active``) of a replayed walk, the vertex's share of the
    albedo's gradient: its score ``d log sigma_s`` times the adjoint radiance still to come, the whole radiance less
    ``result`` (what the path found before the vertex), sent to the parameters of ``sigma_s`` there:

        dL/d theta += adjoint . (L - L_before) d log f(x) / d theta                                           (Eq. G3)

    ``f`` the event's factor (here ``sigma_s``; at a rough boundary its BSDF: :func:`replay_bsdf`)."""
    if not replay.media:
        return
    here = _among(medium, replay.media, active)
    with dr.resume_grad():
        _send(medium.get_scattering_coefficients(mei, here)[0], replay.radiance - result, replay.adjoint, here)


def replay_bsdf(replay, bsdf, si, direction, rest, active):
    """At a boundary ``si`` of a replayed walk, the share of its BSDF's roughness gradient (Eq. G3) of the light
    ``rest`` that came (or will come) along ``direction`` (world space) through it, where ``active``."""
    if not replay.bsdfs:
        return
    here = _among(bsdf, replay.bsdfs, active)
    with dr.resume_grad():
        _send(bsdf.eval(mi.BSDFContext(), si, si.to_local(direction), here), rest, replay.adjoint, here)


# --- the parameters ------------------------------------------------------------------------------------------------
def _ad_indices(value):
    """The AD variable indices of a Dr.Jit value (its components', for a vector or a colour)."""
    if dr.is_tensor_v(value):
        value = value.array
    if dr.depth_v(value) > 1:
        return {i for component in value for i in _ad_indices(component)}
    return {value.index_ad} if getattr(value, "index_ad", 0) else set()


#: A boundary BSDF's parameters whose derivatives a replayed walk gives (its roughness).
ROUGHNESS = ("alpha.value", "alpha_u.value", "alpha_v.value")


def differentiated_media(objects, params):
    """``(media, replay)``: the homogeneous interior media of ``objects`` (translucent objects) whose ``albedo`` or
    ``sigma_t`` ``params`` (Mitsuba's :class:`~mitsuba.SceneParameters`, or a dict) tracks gradients of (Eq. G1's
    scores), and a :class:`Replay` of the heterogeneous media of a constant ``sigma_t`` whose ``albedo`` (a
    ``gridvolume`` or a constant) and the boundaries whose roughness it tracks (None if none). A one-line
    :class:`ConvsssError` for any other parameter with gradients on (nothing else is differentiated: it would read 0),
    a varying extinction's."""
    supported, media, replayed, bsdfs = {}, [], [], []
    for obj in objects:
        medium, bsdf = obj.shape.interior_medium(), obj.shape.bsdf()
        if bsdf is not None and not any(bsdf == b for b in bsdfs):
            owned = mi.traverse(bsdf)
            names = [k for k in ROUGHNESS if k in owned.keys() and dr.grad_enabled(owned[k])]
            for name in names:
                supported.update(dict.fromkeys(_ad_indices(owned[name]), name))
            if names:
                bsdfs.append(bsdf)
        if medium is None or any(medium == m for m in media + replayed):
            continue
        owned = mi.traverse(medium)
        names = [k for k in owned.keys() if dr.grad_enabled(owned[k])]
        if not names:
            continue
        if not medium.is_homogeneous() and ("sigma_t.data" in owned or any(n.startswith("sigma_t") for n in names)):
            raise ConvsssError(f"the medium of {obj.name!r} varies in space: the derivatives of its {', '.join(names)} "
                               "are not built (an extinction that varies needs differential ratio tracking; convsss "
                               "differentiates a homogeneous medium's albedo and sigma_t, and a heterogeneous one's "
                               "albedo where its sigma_t is constant)")
        for name in names:
            supported.update(dict.fromkeys(_ad_indices(owned[name]), name))
        (media if medium.is_homogeneous() else replayed).append(medium)
    items = params.items() if hasattr(params, "items") else []
    others = [k for k, v in items if dr.is_array_v(v) and dr.grad_enabled(v) and not _ad_indices(v) <= supported.keys()]
    if others:
        raise ConvsssError(f"{', '.join(others)}: convsss differentiates a translucent object's medium (a homogeneous "
                           "one's albedo and sigma_t, a heterogeneous one's albedo) and its boundary's roughness, and "
                           "nothing else; disable gradients on these")
    return media, (Replay(replayed, bsdfs) if replayed or bsdfs else None)


def _coefficients(medium):
    """A homogeneous ``medium``'s ``(sigma_s, sigma_t)`` per scene unit, attached to its parameters' gradients."""
    mei = dr.zeros(mi.MediumInteraction3f, 1)
    with dr.resume_grad():
        sigma_s, _, sigma_t = medium.get_scattering_coefficients(mei)
    return sigma_s, sigma_t


# --- Mitsuba's render_backward / render_forward --------------------------------------------------------------------
def _walk_to_the_end(session):
    """The prepared walk of ``session`` (a :class:`~.session.RenderSession`), refused in one line where it does not
    walk to the end."""
    walk = session.tracer.walk if session.tracer is not None else None
    if walk is None or walk.field is not None or session.mode.walk_depth != math.inf or session.mode.transported:
        raise ConvsssError(NOT_WALKED)
    return walk


@contextmanager
def _walked(integrator, scene, sensor, seed, params):
    """``(walk, media, replay)``: ``integrator`` prepared for ``scene`` seen by ``sensor`` (refused where it does not
    walk to the end), its walk differentiating the media ``params`` tracks gradients of (:func:`differentiated_media`),
    while in the block."""
    session = integrator.session
    session.reuse(scene, sensor, seed)
    walk = None
    try:
        walk = _walk_to_the_end(session)
        media, replay = differentiated_media(walk.objects, params)
        walk.differentiate(media)
        yield walk, media, replay
    finally:
        if walk is not None:
            walk.differentiate([])
        if not session.keep:
            session.release()


def _parts(integrator, scene, sensor, seed, spp, walk, adjoint_of=None):
    """Per part of the render (at most :data:`LANES` samples, seed :func:`~.parts.pass_seed`): ``(film, positions,
    weights, radiance, jacobian, adjoint, share, part_spp)`` of its camera samples, ``part_spp`` its samples per pixel
    and ``share`` their part of all, ``adjoint`` the adjoint radiance per sample ``adjoint_of(film, positions, weights,
    part_spp)`` gives (None without), times the share. Where the walk replays (:attr:`~.walk.RandomWalk.replayed`),
    each part is walked twice on the same random numbers: first for its radiance, then with the radiance and the
    adjoint (Eq. G3)."""
    film = sensor.film()
    pixels = math.prod(sampled_extent(film)[0])
    spp = samples_per_pixel(spp, sensor)
    film.prepare(integrator.aov_names())
    for k, share in enumerate(shares(spp, most=max(1, LANES // pixels))):
        with dr.suspend_grad():
            sampler, ray, weight, position = camera_samples(sensor, pass_seed(seed, k), share)
            adjoint = None if adjoint_of is None else adjoint_of(film, position, weight, share) * (share / spp)
            if walk.replayed is not None:
                replay, walk.replayed = walk.replayed, None
                replay.radiance, _ = walk.trace(sampler.clone(), ray)
                replay.adjoint, walk.replayed = adjoint, replay
            radiance, _, jacobian = walk.trace_derivatives(sampler, ray)
        yield film, position, weight, radiance, jacobian, adjoint, share / spp, share


def _image(integrator, film, position, value, spp):
    """The film's image of per-sample ``value`` (Color3f; alpha 1, AOVs 0) at ``position`` (:func:`.film.image`)."""
    width = dr.width(value)
    zeros = [dr.zeros(mi.Float, width)] * len(integrator.aov_names())
    return film_image(film, position, channels(film, value, dr.full(mi.Bool, True, width), zeros), spp)


def render_backward(integrator, scene, params, grad_in, sensor, seed, spp):
    """``grad_in`` (the loss's gradient with respect to the image) into the gradients of the differentiated media's
    parameters: per sample its adjoint radiance (:func:`.film.splat_adjoint`), times its Jacobian (Eq. G2), summed,
    then through the homogeneous media's coefficients to their parameters. A heterogeneous medium's albedo varies from
    one scattering vertex to the next: its walks are replayed (path replay backpropagation, Vicini, Speierer and Jakob
    2021), each vertex sending its score times the adjoint radiance still to come to the albedo there (Eq. G3,
    :func:`replay_scattering`, :func:`replay_bsdf`)."""
    with _walked(integrator, scene, sensor, seed, params) as (walk, media, replay):
        totals = [dr.zeros(mi.Color3f, 1) for _ in range(2 * len(media))]
        walk.replayed = replay
        try:
            def adjoint_of(film, position, weight, part):  # the image's gradient back to each sample (Eq. G2's adjoint)
                return weight * splat_adjoint(film, position, part, grad_in)

            for _, _, _, _, jacobian, adjoint, _, _ in _parts(integrator, scene, sensor, seed, spp, walk, adjoint_of):
                for i, j in enumerate(jacobian):
                    totals[i] += mi.Color3f(*[dr.sum(adjoint[c] * j[c]) for c in range(3)])
                dr.eval(totals)
        finally:
            walk.replayed = None
    with dr.resume_grad():
        for k, medium in enumerate(media):
            sigma_s, sigma_t = _coefficients(medium)
            dr.backward_from(dr.sum(sigma_t * totals[2 * k] + sigma_s * totals[2 * k + 1], axis=None))


def render_forward(integrator, scene, params, sensor, seed, spp):
    """The image's derivative along the parameters' gradients (``dr.set_grad``): each medium's coefficients' tangents
    (Mitsuba's chain), times each sample's Jacobian (Eq. G2), splatted as the image is."""
    with _walked(integrator, scene, sensor, seed, params) as (walk, media, replay):
        if replay is not None:
            raise ConvsssError("dr.forward through a heterogeneous medium's albedo or a boundary's roughness is not "
                               "built: dr.backward gives their gradients")
        tangents = []
        for medium in media:
            with dr.resume_grad():
                sigma_s, sigma_t = _coefficients(medium)
                dr.forward_to(sigma_s, sigma_t)
                tangents += [mi.Color3f(dr.grad(sigma_t)), mi.Color3f(dr.grad(sigma_s))]
        image = 0.0
        for film, position, weight, _, jacobian, _, share, part in _parts(integrator, scene, sensor, seed, spp, walk):
            tangent = dr.zeros(mi.Color3f, dr.width(position))
            for j, t in zip(jacobian, tangents):
                tangent += j * t
            image = image + _image(integrator, film, position, tangent * weight, part) * share
            dr.eval(image)
    return image


def derivative_images(integrator, medium, spp, seed):
    """The prepared render of ``integrator`` (:meth:`~.integrator.ConvsssIntegrator.prepare`, walks to the end) and
    its derivatives with respect to ``medium``'s ``sigma_t`` and ``sigma_s`` (per scene unit, or the coefficients the
    walk weighs it by: :meth:`~.walk.RandomWalk.weigh`), per channel: three (H, W, 3) float64 arrays from the same
    samples (Eq. G2; :mod:`convsss.fitting`'s Jacobian)."""
    state, walk = integrator.prepared, _walk_to_the_end(integrator.session)
    images = [0.0, 0.0, 0.0]
    walk.differentiate([medium])
    try:
        for film, position, weight, radiance, jacobian, _, share, part in _parts(integrator, state.scene, state.sensor,
                                                                                 seed, spp, walk):
            for k, value in enumerate((radiance, *jacobian)):
                images[k] = images[k] + _image(integrator, film, position, value * weight, part) * share
    finally:
        walk.differentiate([])
    return tuple(np.array(image, dtype=np.float64)[..., :3] for image in images)
