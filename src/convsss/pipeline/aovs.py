"""The integrator's AOVs: what each camera ray meets first, as extra film channels (Mitsuba's AOV mechanism).

Mitsuba's ``SamplingIntegrator.render`` gives the film one channel per name of the integrator's ``aov_names()`` and
accumulates the values ``sample()`` returns for them as it does the radiance: weighted by the reconstruction filter,
so a pixel holds the filter-weighted mean over its camera samples. The ``aovs`` parameter chooses them
(:data:`.params.AOVS`; channels named ``<aov>.<channel>`` as in Mitsuba's ``aov`` integrator):

- ``exitance`` (``exitance.R/G/B``): the transport's exitance ``M`` at the first hit when that is on a translucent
  object, read as the shading reads it (the screen table where it knows ``M``, else the object's transport); 0
  elsewhere. Paper Eq. 7: that hit's subsurface radiance is ``(1/pi) F_t(eta, w_o) M``, so an index-matched object
  (``F_t = 1``, no reflection) shows exactly ``M / pi``;
- ``irradiance`` (``irradiance.R/G/B``): the irradiance ``E`` (paper Eq. 2, times ``F_t``) that the object's samples
  carry around the hit, i.e. the light the transport spreads from there: the area-weighted mean of the nearest
  samples facing the same way (:class:`~convsss.samples.LocalIrradiance`), so it is as smooth and as noisy as the
  samples; 0 elsewhere;
- ``object`` (``object.I``): 1 + the index of the translucent object hit (the order of the stats' ``objects``),
  0 for any other shape or none; a pixel on an edge averages its samples' values;
- ``mask`` (``mask.Y``): 1 where a translucent object is hit, else 0: per pixel, the fraction the translucent
  objects cover (exactly so with a ``box`` filter; a wider filter spreads it over its radius);
- ``depth`` (``depth.T``) and ``normal`` (``normal.X/Y/Z``): the hit's distance along the ray (scene units) and its
  shading normal (world space), 0 where nothing is hit, as Mitsuba's ``aov`` integrator's ``depth`` and
  ``sh_normal`` (without the perturbation of a ``normalmap`` or ``bumpmap`` BSDF);
- ``albedo`` (``albedo.R/G/B``): on a translucent object its total diffuse reflectance (the profile's
  ``total_reflectance``, ``∫ 2 pi r R_d(r) dr``: the colour the object shows under even light), on another surface
  its BSDF's diffuse reflectance (``eval_diffuse_reflectance``, as Mitsuba's ``albedo`` AOV), 0 where nothing is hit:
  the guide a denoiser reads (:mod:`convsss.denoise`).

The first hit comes from its own ray cast: the path loop's first segment is the same ray, so it meets the same
point, and the radiance (and the sampler's numbers) are the same whatever AOVs are asked.
"""

import drjit as dr
import numpy as np

from ..backend import import_mitsuba, to_numpy3
from ..samples import LocalIrradiance
from .params import aov_channels

mi = import_mitsuba()


def film_channels(film, names):
    """A rendered film (H, W, C: R, G, B, an alpha where the film has one, then the channels of the AOVs, ``names``
    as :meth:`~.integrator.ConvsssIntegrator.aov_names` gives them) as float64 (H, W, 3 + len(names)) without its
    alpha, and its channels' names: ``["R", "G", "B", *names]``."""
    film = np.asarray(film, dtype=np.float64)
    return np.concatenate([film[..., :3], film[..., film.shape[2] - len(names):]], axis=2), ["R", "G", "B", *names]


def _channels(color):
    return [mi.Float(color[0]), mi.Float(color[1]), mi.Float(color[2])]


def _scatter(target, values, lanes):
    """``target`` (mi.Color3f) with ``values`` ((K, 3) numpy) written at ``lanes`` ((K,) numpy)."""
    if len(lanes) == 0:
        return target
    a = np.ascontiguousarray(np.asarray(values, dtype=np.float32).T)
    dr.scatter(target, mi.Color3f(*(mi.Float(a[c].copy()) for c in range(3))), mi.UInt32(lanes.astype(np.uint32)))
    return target


class FirstHitAOVs:
    """The AOVs ``names`` (:func:`~convsss.pipeline.params.parse_aovs`) of camera rays, from the path tracer's objects,
    transports and screen table (module docstring).

    Parameters
    ----------
    tracer : PathTracer
        Of the prepared scene (:class:`~.path_tracer.PathTracer`, its transports attached).
    names : tuple of str
        The AOVs, in the order of their channels.
    """

    def __init__(self, tracer, names):
        self.tracer, self.names = tracer, tuple(names)
        self.channels = aov_channels(self.names)
        self._irradiance = {}  # object index -> LocalIrradiance, built when first asked

    def __call__(self, ray):
        """The AOV channels for a batch of camera rays: a list of ``mi.Float``, one per name of :attr:`channels`.

        Called right after the tracer shaded the same ``ray`` object, ``exitance`` reuses what its transports gave."""
        if not self.names:
            return []
        tracer = self.tracer
        si = tracer.scene.ray_intersect(ray)
        valid = si.is_valid()
        which, _ = tracer.classify(si)
        values = {}
        if "exitance" in self.names or "irradiance" in self.names:
            values["exitance"], values["irradiance"] = self._surface(ray, si, which)
        values["object"] = [mi.Float(which + 1)]
        values["mask"] = [dr.select(which >= 0, mi.Float(1.0), mi.Float(0.0))]
        values["depth"] = [dr.select(valid, si.t, 0.0)]
        values["normal"] = _channels(dr.select(valid, si.sh_frame.n, 0.0))
        if "albedo" in self.names:
            values["albedo"] = _channels(self._albedo(si, valid, which))
        return [channel for name in self.names for channel in values[name]]

    def _albedo(self, si, valid, which):
        albedo = dr.select(valid, si.bsdf().eval_diffuse_reflectance(si, valid), 0.0)
        for k, obj in enumerate(self.tracer.objects):
            albedo = dr.select(which == k, mi.Color3f(*[float(x) for x in obj.profile.total_reflectance]), albedo)
        return albedo

    def _surface(self, ray, si, which):
        """``(exitance, irradiance)`` channel lists at the hits ``si`` of ``ray`` on translucent objects.

        ``M`` as the shading of the same rays had it (:meth:`~.path_tracer.PathTracer.trace`: the screen table's,
        else what its transports gave, :attr:`~.lookups.ExitanceLookups.first_recorded`); what neither knows (paths
        that end at the first hit, ``max_depth`` 1) and ``E`` are asked in numpy of each object's transport and
        samples, at the hit in mm with the outward normal."""
        tracer = self.tracer
        n = dr.width(si.p)
        exitance = dr.zeros(mi.Color3f, n)
        known = dr.zeros(mi.Bool, n)
        if "exitance" in self.names:
            if tracer.lookups.screen is not None:
                exitance, known = tracer.lookups.screen.lookup(si, which)
            rays, recorded, values = tracer.lookups.first_recorded
            if rays is ray and len(recorded):
                exitance = _scatter(exitance, values, recorded)
                dr.scatter(known, True, mi.UInt32(recorded.astype(np.uint32)))
        irradiance = dr.zeros(mi.Color3f, n)
        asked = (which >= 0) if "irradiance" in self.names else (which >= 0) & ~known
        lanes = dr.compress(asked)
        if dr.width(lanes) > 0:
            owner = dr.gather(mi.Int32, which, lanes).numpy()
            known_np = dr.gather(mi.Bool, known, lanes).numpy()
            points = to_numpy3(dr.gather(mi.Point3f, si.p, lanes), np.float64)
            normals = to_numpy3(dr.gather(mi.Vector3f, mi.Vector3f(si.n), lanes))
            points *= tracer.params.unit_mm
            lanes = lanes.numpy()
            for k, obj in enumerate(tracer.objects):
                mine = owner == k
                outward = normals[mine].astype(np.float64) * obj.orientation
                if "exitance" in self.names:
                    ask = mine & ~known_np
                    exitance = _scatter(exitance, tracer.lookups.exitance(k, points[ask], outward[~known_np[mine]]),
                                        lanes[ask])
                if "irradiance" in self.names and np.any(mine):
                    irradiance = _scatter(irradiance, self._local(k)(points[mine], outward), lanes[mine])
        return _channels(exitance), _channels(irradiance)

    def _local(self, k):
        if k not in self._irradiance:
            self._irradiance[k] = LocalIrradiance(self.tracer.lookups.transports[k].samples)
        return self._irradiance[k]
