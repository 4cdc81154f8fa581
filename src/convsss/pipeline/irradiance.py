"""The irradiance of the samples on the whole surface of a translucent object (paper Eq. 2), vectorized in Dr.Jit;
the samples' places are :mod:`.surface`'s.

Irradiance, paper Eq. 2 with the incoming Fresnel transmittance,

    E(x_i) = ∫_{H^2} F_t(eta, w) g(w) L_i(x_i, w) (n_i . w) dw,

where ``g`` is 1 as the paper has it, or, given the medium's reduced albedo, the oblique-incidence gain of Eq. O1
per channel (:mod:`convsss.profiles.incidence`: light refracted in at a slant scatters nearer the surface and more
of it comes back than the profile, a response to a normal beam, says). ``F_t g`` is :class:`Entry`.

summed over every emitter:

- delta emitters (point, spot, directional) exactly: ``E += F_t(eta, cos) cos I(w)/r^2`` (Mitsuba's
  ``sample_direction`` weight), times a shadow-ray visibility;
- area, environment and constant emitters with ``S`` samples per point and multiple importance sampling (power
  heuristic) between each emitter's own sampling and cosine-weighted hemisphere sampling, so small lights and large
  environments are both well estimated.

Indirect light, everything that reaches the point after at least one bounce (off opaque shapes, through and off
translucent objects, emitters seen after a bounce), is the same integral estimated by cosine-weighted directions:
``E_ind += F_t(eta, cos) pi L_ind(x_i, w) / P`` for ``P`` paths per point (pdf ``cos / pi``), with ``L_ind`` path
traced by the caller's ``incident`` (the path tracer, :meth:`convsss.pipeline.path_tracer.PathTracer.incident`). Fewer
paths than points (``P < 1``): a random fraction ``P`` of the points trace one path each, weighted by ``1/P``; the
transport's blur averages the noise of neighbouring points (:func:`indirect_irradiance`).

Everything is one batch of Dr.Jit arrays per chunk of points (no Python loop over points); the result is numpy.
"""

import math

import drjit as dr
import numpy as np

from ..backend import import_mitsuba, to_numpy3
from ..fresnel import same_eta
from ..hashtable import capacity, empty, grown, probe
from ..jit import njit
from ..profiles.incidence import GAIN_NODES, Orders, exit_normalization, gain_table
from .mis import power_heuristic
from .shadow import Shadows
from .surface import sample_surface

mi = import_mitsuba()

#: Lanes (points x direction samples) traced at once; bounds memory to a few hundred MB.
CHUNK_LANES = 1 << 22
#: Indirect paths traced at once (a path's wavefront state is a few hundred bytes).
CHUNK_PATHS = 1 << 19
#: Indirect directions are stratified over DIRECTION_STRATA^2 cells across neighbouring points.
DIRECTION_STRATA = 4


def _interaction(p, n):
    """A surface interaction at points ``p`` with normal ``n`` (what emitter sampling and ray spawning need)."""
    it = dr.zeros(mi.SurfaceInteraction3f, dr.width(p))
    it.p, it.n = p, n
    it.sh_frame = mi.Frame3f(n)
    it.wi = mi.Vector3f(0.0, 0.0, 1.0)
    return it


def fresnel_transmittance(eta, cos_theta):
    """``F_t = 1 - F_r`` (Mitsuba's exact unpolarized Fresnel), for directions on the outside (``cos > 0``)."""
    return 1.0 - mi.fresnel(dr.abs(cos_theta), eta)[0]


def refracted_cosine(eta, cos_theta):
    """The cosine inside a medium of relative index ``eta`` of a direction refracted in from ``cos_theta`` outside
    (Snell's law; Dr.Jit, as :func:`convsss.profiles.incidence.transmitted_cosine` for numpy)."""
    return dr.safe_sqrt(1.0 - (1.0 - cos_theta * cos_theta) / (eta * eta))


class Entry:
    """What of the light arriving at ``cos`` outside enters a medium and counts as irradiance: ``F_t(eta, cos)``, and,
    with the medium's reduced ``albedo`` (3,), times the oblique-incidence gain ``g`` per channel (Eq. O1, its tables
    read linearly in the cosine inside the medium), of the light of ``orders`` relative to what the profile carries,
    ``carried`` (:func:`~convsss.profiles.incidence.gain_table`; Eq. S1: ``multiple`` where single scattering is
    traced on its own). Not ``oblique`` (the paper's normal incidence): every direction takes the gain of the normal
    beam, which is 1 unless ``orders`` and ``carried`` differ (then the light's single scattering, spread by the
    profile as its own: ``rho(1) / (rho - rho_1)(1)``)."""

    def __init__(self, eta, albedo=None, orders=Orders.ALL, carried=None, oblique=True):
        self.eta = float(eta)
        self.gains = None
        if albedo is not None:
            tables = [gain_table(float(a), self.eta, orders, carried) for a in np.asarray(albedo, dtype=np.float64)]
            if not oblique:
                tables = [np.full_like(t, t[-1]) for t in tables]
            self.gains = mi.Float(np.concatenate(tables).astype(np.float32))

    def __call__(self, cos):
        """``Color3f``: the entering weight per channel for Dr.Jit cosines ``cos`` on the outside."""
        return self.gain(cos) * fresnel_transmittance(self.eta, cos)

    def gain(self, cos):
        """``Color3f``: the gain ``g`` per channel for Dr.Jit cosines ``cos`` on the outside (1 without an albedo)."""
        if self.gains is None:
            return dr.full(mi.Color3f, 1.0, dr.width(cos))
        inside = refracted_cosine(self.eta, cos)
        x = dr.clip(inside, 0.0, 1.0) * (GAIN_NODES - 1)
        node = mi.UInt32(dr.minimum(dr.floor(x), GAIN_NODES - 2))
        t = x - mi.Float(node)
        return mi.Color3f(*[dr.lerp(dr.gather(mi.Float, self.gains, node + c * GAIN_NODES),
                                    dr.gather(mi.Float, self.gains, node + c * GAIN_NODES + 1), t) for c in range(3)])


class Leaving:
    """The exit gain of a medium of reduced ``albedo`` (3,) behind a boundary of index ``eta``: ``g(mu_o) / k`` per
    channel (Eq. O4), what multiplies paper Eq. 7's ``(1/pi) F_t(eta, w_o)`` (the gain is
    :class:`~convsss.pipeline.irradiance.Entry`'s)."""

    def __init__(self, eta, albedo, orders=Orders.ALL):
        self.entry = Entry(eta, albedo, orders)
        self.scale = mi.Color3f(*(1.0 / exit_normalization(np.asarray(albedo, dtype=np.float64), eta,
                                                           orders)).tolist())

    def __call__(self, cos):
        """``Color3f`` for Dr.Jit cosines ``cos`` on the outside."""
        return self.entry.gain(cos) * self.scale


def keeps_irradiance(old, new, incidence, orders=Orders.ALL):
    """Whether samples lit for the material ``old`` keep their irradiance for ``new``: the same ``eta`` (``F_t``)
    and, where a gain depends on it (:class:`Entry`: ``incidence`` oblique, or a profile carrying ``orders``
    multiple, whose indirect light counts its single scattering), the same reduced albedo to the float32 rounding of
    the scene's coefficients (a preset in float64 and the same preset read back from the scene are one medium)."""
    gained = incidence == "oblique" or orders != Orders.ALL
    same_albedo = np.allclose(old.albedo_prime, new.albedo_prime, rtol=1e-6, atol=0.0)
    return same_eta(old.eta, new.eta) and (not gained or same_albedo)


def _delta_irradiance(emitters, it, entry, shadows):
    """``sum_e F_t cos I_e/r^2 T`` over the delta emitters ``emitters`` (exact: one deterministic sample each), ``T``
    what the shadow ray lets through (:meth:`.shadow.Shadows.transmittance`)."""
    total = dr.zeros(mi.Color3f, dr.width(it.p))
    for emitter in emitters:
        ds, weight = emitter.sample_direction(it, mi.Point2f(0.5, 0.5), True)
        cos = dr.dot(it.n, ds.d)
        lit = (cos > 0) & (ds.pdf > 0)
        total += dr.select(lit, weight * cos * entry(cos) * shadows.visibility(it, ds, lit), 0.0)
    return total


def _area_irradiance(scene, emitters, it, entry, rng):
    """One MIS estimate per lane of ``E`` from the non-delta ``emitters`` (area, environment, constant)."""
    total = dr.zeros(mi.Color3f, dr.width(it.p))
    # Strategy 1: each emitter samples a direction towards itself.
    for emitter in emitters:
        u = mi.Point2f(rng.next_float32(), rng.next_float32())
        ds, weight = emitter.sample_direction(it, u, True)
        cos = dr.dot(it.n, ds.d)
        ok = (cos > 0) & (ds.pdf > 0)
        ok &= ~scene.ray_test(it.spawn_ray_to(ds.p), ok)
        mis = power_heuristic(ds.pdf, cos / dr.pi)
        total += dr.select(ok, weight * cos * entry(cos) * mis, 0.0)
    # Strategy 2: a cosine-weighted direction; whatever emitter it reaches first counts (cos / pdf = pi).
    u = mi.Point2f(rng.next_float32(), rng.next_float32())
    local = mi.warp.square_to_cosine_hemisphere(u)
    cos = local.z
    si = scene.ray_intersect(it.spawn_ray(it.sh_frame.to_world(local)))
    emitter = si.emitter(scene)
    radiance = emitter.eval(si)
    pdf_emitter = emitter.pdf_direction(it, mi.DirectionSample3f(scene, si, it))
    mis = power_heuristic(cos / dr.pi, pdf_emitter)
    total += dr.select(cos > 0, radiance * dr.pi * entry(cos) * mis, 0.0)
    return total


def surface_irradiance(scene, position, normal, eta, irradiance_samples, seed, albedo=None, orders=Orders.ALL,
                       shadows=None):
    """``E_i`` (N, 3) numpy at the points ``position`` with outward ``normal`` (Dr.Jit arrays, scene units).

    Parameters
    ----------
    scene : mitsuba.Scene
    position, normal : mitsuba.Point3f, mitsuba.Vector3f
    eta : float
        Relative index of the object's boundary (1 for a null boundary).
    irradiance_samples : int
        Direction samples per point for area and environment emitters.
    seed : int
    albedo : (3,) array_like, optional
        The medium's reduced albedo: each direction weighted by its oblique-incidence gain (:class:`Entry`).
    orders : str
        The light the gain is of (:class:`Entry`).
    shadows : Shadows, optional
        The scene's shadow rays (:class:`.shadow.Shadows`, through its translucent objects); None: a scene without
        translucent objects, whose shadow rays every surface stops.
    """
    n = dr.width(position)
    shadows = shadows or Shadows(scene, [], 1.0)
    entry = Entry(eta, albedo, orders)
    delta = [e for e in scene.emitters() if mi.has_flag(e.flags(), mi.EmitterFlags.Delta)]
    other = [e for e in scene.emitters() if not mi.has_flag(e.flags(), mi.EmitterFlags.Delta)]
    out = np.zeros((n, 3))
    lanes_per_point = irradiance_samples if other else 1
    chunk = max(1, CHUNK_LANES // lanes_per_point)
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        index = dr.arange(mi.UInt32, start, stop)
        p = dr.gather(mi.Point3f, position, index)
        nrm = dr.gather(mi.Vector3f, normal, index)
        e = _delta_irradiance(delta, _interaction(p, nrm), entry, shadows)
        if other:
            lanes = (stop - start) * irradiance_samples
            owner = dr.arange(mi.UInt32, lanes) // irradiance_samples
            it = _interaction(dr.gather(mi.Point3f, p, owner), dr.gather(mi.Vector3f, nrm, owner))
            rng = mi.PCG32(lanes, dr.opaque(mi.UInt64, (int(seed) * 0x85EBCA6B + start) % 2**64),
                           dr.arange(mi.UInt64, lanes))
            estimate = _area_irradiance(scene, other, it, entry, rng)
            per_point = dr.ravel(estimate).numpy().reshape(-1, irradiance_samples, 3).mean(axis=1)
            out[start:stop] += per_point
        out[start:stop] += to_numpy3(e)
    return np.maximum(np.nan_to_num(out), 0.0)


def stratified_directions(points, owners, spacing, seed, strata=4):
    """Points of ``[0,1]^2`` for the paths of ``owners``, stratified across neighbouring points: one ``strata x
    strata`` grid per voxel of edge ``spacing``, shared by the paths that start in it.

    Within a voxel the ``k``-th path gets the grid cell ``perm[(k + shift) mod strata^2]`` (``perm`` a random
    permutation, ``shift`` random per voxel), jittered within the cell. Each path's point stays uniform, so every
    estimate stays unbiased; neighbouring points look in different directions, and the transport, which averages
    neighbouring samples, averages a stratified set.

    Parameters
    ----------
    points : (N, 3) numpy
        The points.
    owners : (K,) numpy int
        The point each path starts from.
    spacing : float
        The voxels' edge, in the points' units (a voxel should hold about ``strata^2`` paths).
    seed : int
    strata : int
        Grid cells per side.

    Returns
    -------
    numpy.ndarray
        (K, 2) float32 in ``[0, 1)``.
    """
    rng = np.random.default_rng([int(seed), 0x57A7])
    perm = rng.permutation(strata * strata)
    jitter = rng.random((len(owners), 2))
    return _stratified(np.ascontiguousarray(points, dtype=np.float64), owners.astype(np.int64), spacing, perm,
                       jitter, strata)


@njit(cache=True)
def _stratified(points, owners, spacing, perm, jitter, strata):
    """:func:`stratified_directions` from its random numbers: per path, the voxel of edge ``spacing`` its point falls
    in (a hash of its three indices; collisions merge voxels), the number of earlier paths in it (counted in a
    :mod:`~convsss.hashtable` that grows as voxels are met: they are about 16 times fewer than the paths), and the
    jittered cell ``perm[(rank + shift) mod strata^2]`` of the voxel's grid."""
    n = owners.shape[0]
    cells = strata * strata
    keys, counts = empty(capacity(n // 8 + 1))
    used = 0
    out = np.empty((n, 2), dtype=np.float32)
    below_one = np.nextafter(1.0, 0.0)
    slot, key = 0, np.int64(0)
    for k in range(n):
        p = owners[k]
        i = np.int64(np.floor(points[p, 0] / spacing))
        j = np.int64(np.floor(points[p, 1] / spacing))
        m = np.int64(np.floor(points[p, 2] / spacing))
        here = (i * 73856093) ^ (j * 19349663) ^ (m * 83492791)
        if k == 0 or here != key:  # consecutive paths mostly share a voxel (the samples follow the surface)
            key = here
            slot = probe(keys, counts, key)
            if counts[slot] < 0:
                if 2 * (used + 1) > keys.shape[0]:
                    keys, counts = grown(keys, counts, 2 * keys.shape[0])
                    slot = probe(keys, counts, key)
                keys[slot], counts[slot] = key, 0
                used += 1
        shift = np.int64((np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(40))
        cell = perm[(counts[slot] + shift) % cells]
        counts[slot] += 1
        out[k, 0] = np.float32(min((cell % strata + jitter[k, 0]) / strata, below_one))
        out[k, 1] = np.float32(min((cell // strata + jitter[k, 1]) / strata, below_one))
    return out


def indirect_irradiance(incident, position, normal, area, eta, paths, seed, stop=None, albedo=None, orders=Orders.ALL,
                        oblique=True):
    """``(E_ind, deferred)``: paper Eq. 2 over the light that reaches the points after at least one bounce, (N, 3)
    numpy, and the paths' hits on translucent objects that have no transport yet (``incident``'s).

    Cosine-weighted directions (pdf ``cos / pi``): a point with ``P`` paths gets
    ``E_ind = (1/P) sum_j F_t(eta, cos_j) g(cos_j) pi L_ind(x, w_j)`` (:class:`Entry`); with ``P < 1`` a random
    fraction ``P`` of the points
    trace one path each, with weight ``1/P`` (unbiased; the transport averages neighbouring points). The directions
    are stratified across neighbouring points (:func:`stratified_directions`, voxels holding about 16 paths).

    Parameters
    ----------
    incident : callable
        ``incident(sampler, rays, weight, tags) -> ((K, 3) numpy, deferred list)``: ``weight`` times the radiance
        arriving along ``rays`` after at least one bounce, and the hits it could not resolve yet
        (:meth:`convsss.pipeline.path_tracer.PathTracer.incident`); ``tags`` are the index of each ray's point.
    position, normal : mitsuba.Point3f, mitsuba.Vector3f
        ``N`` points and their outward normals (scene units).
    area : (N,) numpy
        The area each point stands for (scene units squared).
    eta : float
        Relative index of the object's boundary.
    paths : float
        Paths per point (> 0; below 1, the fraction of points that trace one).
    seed : int
    stop : callable, optional
        Asked between chunks; when it returns True the rest is left out (Ctrl-C).
    albedo : (3,) array_like, optional
        The medium's reduced albedo: each path weighted by its gain (:class:`Entry`).
    orders : str
        What the profile carries (:class:`Entry`); the light counts with all its orders whatever it is: the shader
        traces the single scattering of direct light only, so that of indirect light stays in the profile.
    oblique : bool
        Each path's gain at its own angle (Eq. O1), or the normal beam's (the paper's normal incidence).

    Returns
    -------
    irradiance : numpy.ndarray
        (N, 3) indirect irradiance, >= 0.
    deferred : list
        What ``incident`` returned besides the radiance, over all the paths.
    """
    n = dr.width(position)
    entry = Entry(eta, albedo, Orders.ALL, carried=orders, oblique=oblique)
    per_point = max(1, round(paths)) if paths >= 1 else 1
    if paths >= 1:
        owners = np.repeat(np.arange(n), per_point)
    else:
        pick = np.random.default_rng([int(seed), 0x1D1]).random(n) < paths
        owners = np.flatnonzero(pick)
    scale = 1.0 / (per_point if paths >= 1 else paths)
    # Voxels that hold about DIRECTION_STRATA^2 paths on a flat surface: paths per unit area = paths / area.
    spacing = DIRECTION_STRATA * math.sqrt(float(np.mean(area)) / min(paths, per_point))
    square = stratified_directions(to_numpy3(position), owners, spacing, seed,
                                   DIRECTION_STRATA)
    out, deferred = np.zeros((n, 3)), []
    for start in range(0, len(owners), CHUNK_PATHS):
        if stop is not None and stop():
            break
        owner = owners[start:start + CHUNK_PATHS]
        lanes = len(owner)
        index = mi.UInt32(owner.astype(np.uint32))
        it = _interaction(dr.gather(mi.Point3f, position, index), dr.gather(mi.Vector3f, normal, index))
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(dr.opaque(mi.UInt32, (int(seed) * 0x27D4EB2F + start) % 2**32), lanes)
        u = np.ascontiguousarray(square[start:start + CHUNK_PATHS].T)
        local = mi.warp.square_to_cosine_hemisphere(mi.Point2f(u[0], u[1]))
        rays = it.spawn_ray(it.sh_frame.to_world(local))
        # Paper Eq. 2 by cosine sampling: F_t(eta, cos) g L cos / (cos / pi) = F_t g pi L, over the paths per point.
        weight = to_numpy3(entry(local.z) * dr.pi * scale, np.float64)
        radiance, hits = incident(sampler, rays, weight, owner)
        deferred += hits
        first, last = owner[0], owner[-1] + 1  # owners ascend: the chunk's points are a range
        for c in range(3):
            out[first:last, c] += np.bincount(owner - first, radiance[:, c], minlength=last - first)
    return np.maximum(np.nan_to_num(out), 0.0), deferred


def sample_count(area_mm2, cell_mm, sample_density, profile_area_mm2=math.inf, profile_samples=0.0):
    """Surface samples for an object of ``area_mm2``: ``sample_density`` per layer cell of ``cell_mm``, and at least
    ``profile_samples`` per effective area ``profile_area_mm2`` of its profile
    (:meth:`~convsss.profiles.Profile.effective_area`, the smallest over the channels); at least 64.

    The first rule resolves the image; the second bounds the noise of Eq. 1's surface integral summed over the samples,
    which depends on how many samples the profile averages, not on the pixels (a dense medium seen at a pixel
    footprint wider than its profile gets few samples per profile from the first rule alone)."""
    by_pixel = sample_density * area_mm2 / cell_mm**2
    by_profile = profile_samples * area_mm2 / profile_area_mm2 if profile_samples > 0 else 0.0
    return max(64, math.ceil(min(max(by_pixel, by_profile), 2.0**62)))  # capped: the plan refuses what cannot fit


def object_samples(scene, obj, count, irradiance_samples, unit_mm, seed, stream=0, stage=None, oblique=False,
                   orders=Orders.ALL, shadows=None):
    """Scene -> samples, the data flow's first arrow: about ``count`` stratified points over the whole surface of the
    translucent object ``obj``, with their area, outward normal and irradiance (paper Eq. 2), in mm.

    Parameters
    ----------
    scene : mitsuba.Scene
    obj : TranslucentObject
    count : int
        Points asked for (a square number at least this large is drawn).
    irradiance_samples : int
        Direction samples per point for area and environment emitters.
    unit_mm : float
        mm per scene unit.
    seed, stream : int
        The same seed and stream give the same samples.
    stage : callable, optional
        ``stage(name)`` returns a context manager timing the stage ``samples``, then ``irradiance``.
    oblique : bool
        Weight each direction by the medium's oblique-incidence gain (:class:`Entry`) of the light of ``orders``.
    shadows : Shadows, optional
        The scene's shadow rays (:func:`surface_irradiance`).

    Returns
    -------
    IrradianceSamples
    """
    from contextlib import nullcontext

    from ..samples import IrradianceSamples

    stage = stage or (lambda name: nullcontext())
    with stage("samples"):
        position, normal, area = sample_surface(obj.shape, count, seed, obj.orientation, stream=stream,
                                                to_world=obj.to_world)
        area_mm2 = area.numpy().astype(np.float64) * unit_mm**2
        position_mm = to_numpy3(position, np.float64) * unit_mm
        normal_np = to_numpy3(normal, np.float64)
    with stage("irradiance"):
        irradiance = surface_irradiance(scene, position, normal, obj.eta, irradiance_samples, seed + 7919 * stream,
                                        albedo=obj.material.albedo_prime if oblique else None, orders=orders,
                                        shadows=shadows)
        return IrradianceSamples(position_mm, area_mm2, irradiance, normal_np)
