"""The transport stage: each object's transport, and the light that crosses between translucent objects.

The data flow's fourth arrow (irradiance -> **transport**): a transport per object from its samples and irradiance
(paper Eq. 1; the transports are plug-ins, :mod:`convsss.transport`). Light that reached an object through or off a
translucent object (another, or itself) needs the exitance of the objects it came from, which depends on it too:
Jacobi passes. Each of ``indirect_passes`` passes looks the deferred hits of the indirect paths (:mod:`.lighting`)
up in the last transports (paper Eq. 7) and relights the objects they reach with it
(:meth:`~convsss.transport.base.Transport.relit`: the samples' places are kept). One pass leaves out light that
crossed between translucent objects twice.
"""

from contextlib import nullcontext

import numpy as np

from ..samples import IrradianceSamples
from ..transport import make_transport
from ..transport.mixture import MixtureTransport
from .plan import transport_params


def build_transports(samples, irradiance, objects, cells, frame, params, stage=None):
    """One transport per object (``params.transport`` with its parameters), from ``samples`` (their places) lit by
    ``irradiance`` (N, 3 each), each with its object's profile and material (:class:`~.objects.TranslucentObject`; a
    medium that varies in space: its classes', mixed by Eq. H1, :mod:`convsss.transport.mixture`) and its pixel
    footprint ``cells`` (mm)."""
    stage = stage or (lambda name: nullcontext())
    out = []
    for s, e, obj, cell in zip(samples, irradiance, objects, cells):
        def make(lit, profile, material, cell=cell):
            return make_transport(params.transport, lit, profile, frame, material, **transport_params(params, cell))

        lit = IrradianceSamples(s.position, s.area, e, s.normal)
        with stage("transport"):
            out.append(make(lit, obj.profile, obj.material) if obj.classes is None else
                       MixtureTransport(lit, obj.class_profiles, obj.classes.weights(s.position, s.normal), make,
                                        obj.materials))
    return out


def translucent_passes(transports, lighting, tracer, passes, stage=None, stop=None):
    """The ``transports`` (built from ``lighting.irradiance``, :func:`build_transports`) after at most ``passes``
    passes of the light between translucent objects, their deferred hits resolved by ``tracer`` (the
    :class:`~convsss.pipeline.path_tracer.PathTracer` that traced them): ``(transports, from_translucent, report)``,
    ``from_translucent[k]`` (N, 3) the irradiance that object ``k`` got from translucent objects and ``report`` one
    ``{"flux_change": ...}`` per pass (the largest change of an object's flux, relative to it)."""
    stage = stage or (lambda name: nullcontext())
    samples, irradiance, deferred = lighting.samples, lighting.irradiance, lighting.deferred
    light = [np.zeros_like(e) for e in irradiance]
    report = []
    while any(deferred) and len(report) < passes and not (stop is not None and stop()):
        change, tables = 0.0, {}  # the mesh tables of this pass's transports
        with stage("indirect"):
            for k, (s, records) in enumerate(zip(samples, deferred)):
                tags, values = tracer.lookups.resolve(transports, records, tables)
                new = np.stack([np.bincount(tags, values[:, c], minlength=len(s)) for c in range(3)], axis=1)
                new = np.maximum(new, 0.0)
                moved = np.abs(s.area @ new - s.area @ light[k])
                flux = s.area @ irradiance[k] + s.area @ new
                change = max(change, float(np.max(moved / np.maximum(flux, 1e-300))))
                light[k] = new
        report.append({"flux_change": change})
        with stage("transport"):
            transports = [t.relit(irradiance[k] + light[k]) if records else t
                          for k, (t, records) in enumerate(zip(transports, deferred))]
    return transports, light, report
