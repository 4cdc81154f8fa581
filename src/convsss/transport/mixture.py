"""Light in a medium that varies in space: a transport per class of the medium, mixed at both ends.

A heterogeneous interior is split into K homogeneous classes (:mod:`convsss.pipeline.media`), each with its profile
``R_k``, and every point ``x`` of the surface between them by weights ``w_k(x)`` (per channel, summing to 1). Light
entering at ``x_i`` spreads by the profiles of its own classes, light leaving at ``x`` by those of the point's;
reciprocity asks for both alike, so Eq. 1 becomes their mean,

    M(x) = s sum_k sum_i R_k(|x - x_i|) w_k(x_i) E_i A_i + (1 - s) sum_k w_k(x) sum_i R_k(|x - x_i|) E_i A_i,  (Eq. H1)

``s`` = :data:`SOURCE_SHARE`. Each sum is an ordinary transport of one class's profile (the first over the samples
weighted by their classes, the second over all of them), of whatever kind the render asks for; ``w_k(x)`` at a query
point is read from the samples' (:class:`~convsss.samples.LocalIrradiance`, which averages the nearest on the
point's side of the surface). On a homogeneous medium (one class, ``w = 1``) both sums are Eq. 1; where the
coefficients are constant over a class's reach, so is Eq. H1. The weights are the medium each end stands for
(Eq. H2, within two diffusion lengths of it): a dark vein between two points but farther from both is seen by
neither, and light crosses it as if it were not there.
"""

import numpy as np

from ..samples import IrradianceSamples, LocalIrradiance, as_points
from ..timing import StageTimer

#: ``s`` of Eq. H1: the share of the exitance spread by the entry points' classes.
SOURCE_SHARE = 0.5
#: Transports each class builds (one weighted by the entry points' classes, one by the exit point's).
PARTS_PER_CLASS = 2 if 0.0 < SOURCE_SHARE < 1.0 else 1
#: Weights below this fraction of a class's largest leave the sample out of that class's sum.
SMALL_WEIGHT = 1e-6


class MixtureTransport:
    """Eq. H1 over ``samples`` (:class:`~convsss.samples.IrradianceSamples`) whose class weights are ``weights``
    (N, K, 3), with one of ``profiles`` and of ``materials`` (K) per class; ``make(samples, profile, material)`` builds
    one class's transport (the
    render's kind, its parameters). Answers what a transport answers: :meth:`exitance`, :meth:`relit`,
    :attr:`stats`."""

    name = "mixture"

    def __init__(self, samples, profiles, weights, make, materials=None):
        self.samples, self.profiles, self.weights, self.make = samples, tuple(profiles), weights, make
        self.materials = tuple(materials) if materials is not None else (None,) * len(self.profiles)
        self.profile = self.profiles[0]
        self.timings = StageTimer()
        self.members = [np.flatnonzero(weights[:, k, :].max(axis=1) > SMALL_WEIGHT * weights[:, k, :].max())
                        for k in range(len(self.profiles))]
        self.local = LocalIrradiance(samples)
        self._build()

    def _build(self):
        s = self.samples
        self.entering = [self.make(IrradianceSamples(s.position[i], s.area[i], s.irradiance[i] * self.weights[i, k, :],
                                                     None if s.normal is None else s.normal[i]), profile, material)
                         if SOURCE_SHARE > 0 and len(i) else None
                         for k, (i, profile, material) in enumerate(zip(self.members, self.profiles, self.materials))]
        self.leaving = [self.make(s, profile, material) if SOURCE_SHARE < 1 else None
                        for profile, material in zip(self.profiles, self.materials)]

    @property
    def query_batch(self):
        return min(t.query_batch for t in self.entering + self.leaving if t is not None)

    def exitance(self, points, normals=None):
        """``M`` (K, 3) of Eq. H1 at ``points`` (K, 3) mm (``normals``: their outward normals, optional)."""
        points = as_points(points, "query points")
        normals = None if normals is None else as_points(normals, "normals")
        out = np.zeros((len(points), 3))
        if SOURCE_SHARE < 1:
            with self.timings("class weights"):
                weight = self.local.average(self.weights, points, normals)  # (K, classes, 3)
        for k, (entering, leaving) in enumerate(zip(self.entering, self.leaving)):
            if entering is not None:  # Eq. H1, first sum: light spread by the entry points' classes
                out += SOURCE_SHARE * entering.exitance(points, normals)
            rows = np.flatnonzero(weight[:, k].max(axis=1) > 0) if leaving is not None else ()
            if len(rows):  # Eq. H1, second sum, where the exit point has the class (two per channel at most)
                out[rows] += (1.0 - SOURCE_SHARE) * weight[rows, k] * leaving.exitance(
                    points[rows], None if normals is None else normals[rows])
        return out

    def relit(self, irradiance):
        """This mixture for new ``irradiance`` (N, 3) at the same samples (each class's transport relit)."""
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        new.samples, new.timings = IrradianceSamples(self.samples.position, self.samples.area, irradiance,
                                                     self.samples.normal), StageTimer()
        new.entering = [None if t is None else t.relit(irradiance[i] * self.weights[i, k, :])
                        for k, (t, i) in enumerate(zip(self.entering, self.members))]
        new.leaving = [None if t is None else t.relit(irradiance) for t in self.leaving]
        return new

    @property
    def stats(self):
        parts = [t.stats for t in self.entering + self.leaving if t is not None]
        seconds = dict(self.timings)
        for part in parts:
            for key, value in part["seconds"].items():
                seconds[key] = seconds.get(key, 0.0) + value
        return {"transport": f"mixture of {len(self.profiles)} classes ({parts[0]['transport']})",
                "samples": len(self.samples), "classes": len(self.profiles), "parameters": parts[0]["parameters"],
                "seconds": {k: float(v) for k, v in seconds.items()}}
