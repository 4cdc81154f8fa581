"""The sampling plan: what a render will draw and hold, decided and refused before anything is allocated.

The data flow's first decision (scene -> **plan** -> samples -> irradiance -> transport -> shading). For each
translucent object the camera sees, from plain facts known before a single surface point is drawn (its area, its
profile, the pixel footprint at its depth, its extent in the camera's frame, the emitters):

- the layer cell ``h``: a pixel's footprint at the object's view depth (the bounding-box centre, or the median depth
  of its visible points for a centre behind the camera), as the transport asks for it
  (:meth:`~convsss.transport.base.Transport.layer_cell`; the convolution's ``downsample`` divides it);
- the surface samples ``N = max(sample_density A / h^2, profile_samples A / A_eff)``
  (:func:`~convsss.pipeline.irradiance.sample_count`; ``A_eff`` the area the transport's sum averages over,
  :meth:`~convsss.transport.base.Transport.sample_area`: the profile's own, or in the multiscale transport's local
  limit one that grows with the pixel footprint), the second rule capped by :data:`PROFILE_RULE_MEMORY` of the
  memory guard (at most :data:`PROFILE_RULE_BYTES`) and by :data:`MAX_IRRADIANCE_SECONDS`, never below the first
  (a warning says by how much the noise grows); where every camera path walks (``0 < walk_depth < inf``) and the
  samples light the walk's diffusion field alone, the field's own rule instead
  (:func:`~convsss.pipeline.field.sample_count`: a few per face of its cells);
- the memory: ``BYTES_PER_SAMPLE`` per sample plus what the transport will build
  (:meth:`~convsss.transport.base.Transport.planned_bytes`: the multiscale far-field mesh, the convolution's layers),
  and the time of the irradiance rays: refused in one line, before any work, when either is beyond the limits.

The shading's memory (:func:`film_bytes`) is checked before the plan.
"""

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..backend import import_mitsuba
from ..errors import ConvsssError
from ..memory import USABLE_FRACTION, available_memory, check_memory
from ..transport.mixture import PARTS_PER_CLASS
from .field import planned_bytes as field_bytes
from .field import sample_count as field_sample_count
from .irradiance import sample_count
from .params import walks_alone
from .surface import has_vertices, mesh_arrays

mi = import_mitsuba()

#: Bytes per path of the shading (the symbolic loop's outputs, the recorded hits' room of 44 bytes a lane, the film's
#: samples): the peak resident memory's growth per path over the prepared state's, measured on the demo at several
#: spp, with a margin.
BYTES_PER_PATH = 120
#: More bytes per path and AOV channel (:mod:`.aovs`): the peak's further growth per path as AOV channels are added,
#: measured on the demo from none to all 12 channels, with a margin.
BYTES_PER_AOV_CHANNEL = 12
#: Bytes per surface sample held while the transport is built (measured, with a margin; irradiance runs in chunks).
BYTES_PER_SAMPLE = 400
#: Irradiance rays traced per second on the project's 2-core machine (bunny under a constant environment).
RAYS_PER_SECOND = 5e6
#: Bounces of an indirect path, for the time estimate (Russian roulette ends most of them within a few).
INDIRECT_BOUNCES = 3
#: A render whose irradiance alone would take longer than this is refused before it starts.
MAX_IRRADIANCE_SECONDS = 600.0
#: The share of the memory guard's limit that the ``profile_samples`` rule may fill with one object's samples (the
#: rest is left to the transport's and the shading's own allocations).
PROFILE_RULE_MEMORY = 0.5
#: And the bytes it may fill whatever the machine: a render's peak stays within 4 GiB (issue 50: Spectralon at 800²
#: drew 23 million samples on a 23 GB machine, 8.2 GiB and 60 s; with this cap 2.2 GiB, its sample noise about twice
#: the rule's goal, as its warning says).
PROFILE_RULE_BYTES = 2 * 2**30


class VisibilityWarning(UserWarning):
    """A translucent object is not seen by the camera and is skipped."""


class SampleNoiseWarning(UserWarning):
    """An object gets fewer surface samples than ``profile_samples`` asks (memory or time): its exitance is noisier."""


@dataclass(frozen=True)
class ObjectPlan:
    """One visible object's share of the plan (lengths in mm, areas in mm^2).

    ``index`` is the object's place in the list the plan was made for; ``samples`` the count to draw, with the two
    rules' counts beside it; ``cell_size_mm`` the layer cell the samples resolve (``pixel_footprint_mm`` divided by
    the transport's own factor); ``bounds_mm`` (2, 3) the surface's extent in the camera's view frame;
    ``transport_bytes`` what its transport will hold.
    """

    index: int
    pixel_footprint_mm: float
    cell_size_mm: float
    view_depth_mm: float
    samples: int
    samples_pixel_rule: int
    samples_profile_rule: int
    profile_area_mm2: float
    bounds_mm: np.ndarray
    transport_bytes: int

    def summary(self, area_mm2):
        """JSON-ready, for the render statistics (the object's ``area_mm2`` gives the samples per profile area)."""
        return {"samples": self.samples, "cell_size_mm": self.cell_size_mm,
                "pixel_footprint_mm": self.pixel_footprint_mm, "view_depth_mm": self.view_depth_mm,
                "samples_pixel_rule": self.samples_pixel_rule, "samples_profile_rule": self.samples_profile_rule,
                "profile_area_mm2": self.profile_area_mm2,
                "samples_per_profile_area": self.samples * self.profile_area_mm2 / area_mm2,
                "transport_bytes": self.transport_bytes}


@dataclass(frozen=True)
class SamplingPlan:
    """What a render will draw: an :class:`ObjectPlan` per object the camera sees (in the objects' order), the
    names of those it does not see (skipped, with a :class:`VisibilityWarning`), and what renders the objects (the
    :class:`~.params.RenderMode` the plan was made for)."""

    objects: tuple
    hidden: tuple
    mode: object = None

    def draws_like(self, other, rtol=1e-4):
        """Whether ``other`` draws what this plan draws: the same objects seen and hidden, their sample counts,
        cells and bounds within ``rtol``. A crop window of the same film measures the same pixel footprint up to
        the float32 rounding of its rays (about 1e-6), which can move a count by one sample."""
        def close(a, b):
            return np.allclose(a, b, rtol=rtol, atol=0.0)

        return self.hidden == other.hidden and len(self.objects) == len(other.objects) and all(
            a.index == b.index and close(a.bounds_mm, b.bounds_mm)
            and close([a.samples, a.pixel_footprint_mm, a.cell_size_mm, a.view_depth_mm],
                      [b.samples, b.pixel_footprint_mm, b.cell_size_mm, b.view_depth_mm])
            for a, b in zip(self.objects, other.objects))


def film_bytes(width, height, samples_per_pass, aov_channels=0):
    """Bytes the shading of ``width x height`` pixels at ``samples_per_pass`` holds (``BYTES_PER_PATH`` a path, and
    ``BYTES_PER_AOV_CHANNEL`` per AOV channel)."""
    return int(width) * int(height) * int(samples_per_pass) * (BYTES_PER_PATH + BYTES_PER_AOV_CHANNEL * aov_channels)


def check_film(width, height, samples_per_pass, aov_channels=0):
    """A one-line error when the shading would not fit in memory."""
    check_memory(film_bytes(width, height, samples_per_pass, aov_channels),
                 f"{width}x{height} pixels at {samples_per_pass} samples per pass",
                 "set the integrator's samples_per_pass (e.g. 4) or render fewer spp")


def view_bounds(obj, frame, unit_mm):
    """(2, 3) bounds in mm of ``obj``'s surface in the camera's view ``frame``: of its mesh's vertices (every surface
    point lies in their convex hull), or of its world bounding box's corners for an analytic shape."""
    if has_vertices(obj.shape):
        local, _ = mesh_arrays(obj.shape)
        points = (local @ obj.to_world[:3, :3].T + obj.to_world[:3, 3]) * unit_mm
    else:
        lo, hi = obj.bbox_mm
        points = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    view = frame.to_view(points)
    return np.array([view.min(axis=0), view.max(axis=0)])


def irradiance_rays(scene, count, params):
    """Rays the irradiance of ``count`` points takes: ``count`` x ``directions`` (``RenderParams``) x (one ray per
    area or environment emitter + one cosine-sampled ray), plus ``count`` x ``indirect_samples`` paths of
    ``INDIRECT_BOUNCES`` bounces, each a ray and a shadow ray per emitter."""
    sampled = sum(not mi.has_flag(e.flags(), mi.EmitterFlags.Delta) for e in scene.emitters())
    direct = count * params.directions * (sampled + 1) if sampled else 0
    return direct + count * params.indirect_samples * INDIRECT_BOUNCES * (1 + len(scene.emitters()))


def sample_cap(scene, params):
    """The ceiling of the ``profile_samples`` rule for one object: :data:`PROFILE_RULE_MEMORY` of what the memory
    guard lets through and at most :data:`PROFILE_RULE_BYTES` (``BYTES_PER_SAMPLE`` each), and what the irradiance
    time limit (``MAX_IRRADIANCE_SECONDS``) does."""
    available = available_memory()
    share = PROFILE_RULE_MEMORY * USABLE_FRACTION * available if available is not None else math.inf
    by_memory = min(share, PROFILE_RULE_BYTES) / BYTES_PER_SAMPLE
    per_point = irradiance_rays(scene, 1, params)
    by_time = MAX_IRRADIANCE_SECONDS * RAYS_PER_SECOND / per_point if per_point > 0 else math.inf
    return int(min(by_memory, by_time, 2**31))


def check_irradiance_time(scene, count, name, params):
    """Refuse irradiance longer than ``MAX_IRRADIANCE_SECONDS`` (rays counted by :func:`irradiance_rays`)."""
    sampled = sum(not mi.has_flag(e.flags(), mi.EmitterFlags.Delta) for e in scene.emitters())
    rays = irradiance_rays(scene, count, params)
    if rays / RAYS_PER_SECOND > MAX_IRRADIANCE_SECONDS:
        raise ConvsssError(f"irradiance of {name!r} needs {rays:.3g} rays ({count} points x "
                           f"{params.directions} directions x {sampled + 1} + {count} x "
                           f"{params.indirect_samples:g} indirect paths), about {rays / RAYS_PER_SECOND / 60:.0f} min "
                           f"at {RAYS_PER_SECOND:.0e} rays/s: lower irradiance_samples (auto: 1-16), "
                           "indirect_samples or sample_density")


def _check_outside(obj, visible):
    """A one-line error when the camera is inside the closed object (most of its visible points seen from inside)."""
    seen_from_inside = visible.from_behind == (obj.orientation > 0)  # against the outward normal
    if obj.closed and len(visible.depth) and seen_from_inside.mean() > 0.5:
        raise ConvsssError(f"the camera is inside translucent shape {obj.name!r}: the diffusion model renders "
                           "objects seen from outside; move the camera out of it")


def plan_object(scene, sensor, frame, obj, visible, index, params, mode):
    """The :class:`ObjectPlan` of one visible object, or a one-line error when its samples or its transport would
    not fit in memory, or its irradiance would take too long."""
    from .camera import pixel_footprint

    p = params
    depth = float(frame.to_view((0.5 * (obj.bbox_mm[0] + obj.bbox_mm[1]))[None])[0, 2])
    depth = depth if depth > 0 else float(np.median(visible.depth))
    footprint = pixel_footprint(sensor, frame, depth, p.unit_mm)
    if walks_alone(p, mode):  # the walks reach the interior themselves: no samples, no transport to hold
        return ObjectPlan(index, footprint, footprint, depth, 0, 0, 0, 0.0, view_bounds(obj, frame, p.unit_mm), 0)
    transport = p.transport_class()
    cell = transport.layer_cell(footprint, p.transport_params())
    count_pixel = sample_count(obj.area_mm2, cell, p.sample_density)
    held_params = transport_params(p, footprint)
    if obj.classes is None:
        profile_area = transport.sample_area(obj.profile, held_params)
    else:  # a medium of classes: the density each class's profile asks for, averaged over the surface it covers
        profile_area = 1.0 / sum(f / transport.sample_area(profile, held_params)
                                 for f, profile in zip(obj.classes.shares, obj.class_profiles))
    count = wanted = sample_count(obj.area_mm2, cell, p.sample_density, profile_area, p.profile_samples)
    for_field = field_sample_count(obj, p, mode)
    if for_field is not None:  # every camera path walks: the samples light the random walk's field alone
        count = wanted = for_field
    elif count > count_pixel:
        count = max(count_pixel, min(count, sample_cap(scene, p)))
        if count < wanted:
            warnings.warn(f"translucent shape {obj.name!r}: {wanted} surface samples would keep its sample noise near "
                          f"the goal ({p.profile_samples:g} per profile area of {profile_area:.3g} mm^2), more than "
                          f"the memory and time limits allow; {count} used: expect about "
                          f"{(wanted / count) ** 0.7:.1f}x that noise (passes average it down: each draws its own "
                          "samples)", SampleNoiseWarning, stacklevel=4)
    bounds = view_bounds(obj, frame, p.unit_mm)
    held = sum(transport.planned_bytes(bounds, profile, count, held_params, material)
               for profile, material in zip(obj.profiles, obj.materials))
    held *= PARTS_PER_CLASS if obj.classes is not None else 1  # Eq. H1: each class's transports
    field = field_bytes(obj, mode)  # the random walk's diffusion field
    check_memory(count * BYTES_PER_SAMPLE + held + field,
                 f"{count} surface samples of {obj.name!r} ({_span(obj, p.unit_mm)}) and its {p.transport} transport"
                 + (f" and walk_depth {mode}'s field" if field else ""),
                 transport.memory_advice + (", or a larger walk_depth (a coarser field)" if field else ""))
    held += field
    check_irradiance_time(scene, count, obj.name, p)
    return ObjectPlan(index, footprint, cell, depth, count, count_pixel, wanted, profile_area, bounds, held)


def _span(obj, unit_mm):
    """The object's extent in mean free paths and the scene's unit, for a message: a unit mistake shows there."""
    mfp = np.asarray(obj.spans()["mean_free_paths"])
    return f"{obj.extent_mm:.4g} mm, {np.min(mfp):.3g}-{np.max(mfp):.3g} mean free paths across, unit_mm = {unit_mm:g}"


def transport_params(params, footprint):
    """The chosen transport's parameters, and the pixel footprint as its ``cell_size`` if it declares one."""
    out = params.transport_params()
    if params.transport_class().accepts("cell_size"):
        out["cell_size"] = footprint
    return out


def plan_samples(scene, sensor, frame, objects, seen, params, mode):
    """The :class:`SamplingPlan` for ``objects`` (:class:`~convsss.pipeline.objects.TranslucentObject`) whose visible
    points are ``seen`` (:func:`~convsss.pipeline.camera.first_hits`), under the render parameters ``params`` and
    their :class:`~.params.RenderMode` ``mode``; one-line errors (camera inside an object, memory, time) before
    anything is drawn."""
    plans, hidden = [], []
    for k, (obj, visible) in enumerate(zip(objects, seen)):
        _check_outside(obj, visible)
        if len(visible.depth) == 0:
            warnings.warn(f"translucent shape {obj.name!r} is not visible from the camera: skipped (its light on "
                          "other surfaces is not rendered)", VisibilityWarning, stacklevel=3)
            hidden.append(obj.name)
            continue
        plans.append(plan_object(scene, sensor, frame, obj, visible, k, params, mode))
    total = sum(q.samples * BYTES_PER_SAMPLE + q.transport_bytes for q in plans)
    if len(plans) > 1:
        check_memory(total, f"the {len(plans)} visible translucent objects' samples and transports",
                     params.transport_class().memory_advice)
    return SamplingPlan(tuple(plans), tuple(hidden), mode)
