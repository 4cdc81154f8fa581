"""The irradiance stage: the planned surface samples of each object and the light that reaches them (paper Eq. 2).

The data flow's second and third arrows (scene -> plan -> **samples -> irradiance** -> transport -> shading): for
each :class:`~convsss.pipeline.plan.ObjectPlan`, the stratified samples over the object's whole surface with their
direct irradiance from every emitter (:func:`~convsss.pipeline.irradiance.object_samples`), then the indirect
irradiance, path traced into the scene from the samples by the render's path tracer (:mod:`.path_tracer`)
(:func:`~convsss.pipeline.irradiance.indirect_irradiance`, ``indirect_samples`` paths a sample). Before any transport
exists, a path that reaches a translucent object cannot know its exitance: such hits come back as ``deferred``, for
the transport passes (:mod:`.passes`) to resolve.
"""

from contextlib import nullcontext
from dataclasses import dataclass

import numpy as np

from ..backend import import_mitsuba
from .irradiance import indirect_irradiance, object_samples

mi = import_mitsuba()


@dataclass(eq=False)
class Lighting:
    """Per planned object (in the plan's order): ``samples`` (:class:`~convsss.samples.IrradianceSamples`, with the
    direct irradiance), ``irradiance`` (N, 3) direct + indirect without the light of translucent objects, and
    ``deferred``, the indirect paths' hits on translucent objects (resolved by the path tracer once the transports
    exist, :meth:`~convsss.pipeline.lookups.ExitanceLookups.resolve`)."""

    samples: list
    irradiance: list
    deferred: list


def light_samples(scene, objects, plan, params, seed, tracer, stage=None, stop=None):
    """The :class:`Lighting` of the objects the :class:`~convsss.pipeline.plan.SamplingPlan` ``plan`` draws.

    ``objects`` is the list the plan was made for; ``tracer`` the render's
    :class:`~convsss.pipeline.path_tracer.PathTracer` of the planned objects, which traces the indirect light before
    any transport exists; ``stage(name)`` a context manager timing ``samples``, ``irradiance`` and ``indirect``;
    ``stop()`` ends the indirect paths early (Ctrl-C). The same ``seed`` gives the same samples and light.
    """
    stage = stage or (lambda name: nullcontext())
    p = params
    shown = [objects[q.index] for q in plan.objects]
    direct = [object_samples(scene, objects[q.index], q.samples, p.directions, p.unit_mm, seed,
                             stream=q.index, stage=stage, oblique=p.incidence == "oblique", orders=p.orders,
                             shadows=tracer.shadows)
              for q in plan.objects]
    # Indirect light needs a path of at least 3 segments (camera, the object, a bounce, an emitter).
    if p.indirect_samples == 0 or 0 < p.max_depth < 3 or not shown:
        return Lighting(direct, [s.irradiance for s in direct], [[] for _ in shown])
    irradiance, deferred = [], []
    with stage("indirect"):
        for k, (obj, s) in enumerate(zip(shown, direct)):
            position = mi.Point3f(*np.ascontiguousarray((s.position / p.unit_mm).T, dtype=np.float32))
            normal = mi.Vector3f(*np.ascontiguousarray(s.normal.T, dtype=np.float32))
            e, hits = indirect_irradiance(tracer.incident, position, normal, s.area / p.unit_mm**2, obj.eta,
                                          p.indirect_samples, seed + 104729 * (k + 1), stop=stop,
                                          albedo=obj.material.albedo_prime, orders=p.orders,
                                          oblique=p.incidence == "oblique")
            irradiance.append(s.irradiance + e)
            deferred.append(hits)
    return Lighting(direct, irradiance, deferred)
