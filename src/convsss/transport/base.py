"""The interface every transport implements, so that transports are interchangeable and comparable.

A transport is built from :class:`~convsss.samples.IrradianceSamples` and a :class:`~convsss.profiles.Profile` and
answers ``exitance(points) -> (K, 3)``: the radiant exitance due to multiple scattering,

    M(x) = ∫_A R_d(|x - x_i|) E(x_i) dA(x_i) ≈ sum_i R_d(|x - x_i|) E_i A_i      (paper Eq. 1, 4),

in the units of ``E``. The outgoing radiance is ``L = (1/pi) F_t(eta, w_o) M`` (paper Eq. 7), applied by shading,
never here. A transport knows nothing of Mitsuba.
"""

import copy
import dataclasses

import numpy as np

from ..parameters import check_parameters
from ..samples import IrradianceSamples, ViewFrame, as_points
from ..timing import StageTimer

#: Every transport, by name: each module registers its class on its last line (:func:`register_transport`).
TRANSPORTS = {}


def register_transport(cls):
    """Make ``cls`` (a :class:`Transport` subclass with a ``name`` and ``parameters``) available by its name."""
    TRANSPORTS[cls.name] = cls
    return cls


class Transport:
    """Base class of every transport: ``Transport(samples, profile, frame, material, **params)``.

    Keeps the samples, the profile, the camera's :class:`~convsss.samples.ViewFrame` (``None`` where a transport
    needs none), the parameters checked against the class's declared :attr:`parameters` (defaults filled in) as
    :attr:`params`, per-stage timings; answers :meth:`exitance`.
    """

    name = "transport"
    #: Whether the transport sums Eq. 1 (the profile at the straight distance); a transport that follows the
    #: object's shape instead (``volume``) agrees with Eq. 1 on a half-space only.
    sums_eq1 = True
    #: The :class:`~convsss.parameters.Parameter` declarations of this transport's keyword parameters.
    parameters = ()

    def __init__(self, samples, profile, frame=None, material=None, **params):
        if not isinstance(samples, IrradianceSamples):
            raise TypeError("samples must be an IrradianceSamples")
        if frame is not None and not isinstance(frame, ViewFrame):
            raise TypeError("frame must be a ViewFrame or None")
        self.samples = samples
        self.profile = profile
        self.frame = frame
        #: The object's :class:`~convsss.materials.Material` beside its profile (None where a caller gives none; a
        #: transport that needs the medium's coefficients, the volume's diffusion, refuses that).
        self.material = material
        self.params = check_parameters(self.parameters, params, f"the {self.name} transport")
        self.timings = StageTimer()

    @classmethod
    def accepts(cls, name):
        """Whether this transport declares a parameter called ``name``."""
        return any(p.name == name for p in cls.parameters)

    #: What to do when :meth:`planned_bytes` is refused (the end of the memory guard's one-line message).
    memory_advice = "lower sample_density"

    @classmethod
    def layer_cell(cls, footprint, params):
        """The cell (mm) the surface samples must resolve for a pixel ``footprint`` (mm) under ``params``: the
        footprint itself unless the transport works at another resolution."""
        return footprint

    @classmethod
    def planned_bytes(cls, bounds, profile, count, params, material=None):
        """Bytes this transport will hold, beyond the samples, for ``count`` samples within ``bounds`` (2, 3) mm of
        the camera's view frame, under ``params``: known before any sample is drawn, so that a render is refused
        before any work (:mod:`convsss.pipeline.plan`). None by default."""
        return 0

    @classmethod
    def sample_area(cls, profile, params):
        """The area (mm^2) over which this transport's sum of Eq. 1 averages its samples under ``params``: the
        renderer draws ``profile_samples`` samples per such area (:func:`~convsss.pipeline.irradiance.sample_count`).
        The profile's smallest :meth:`~convsss.profiles.Profile.effective_area` by default."""
        return float(np.min(profile.effective_area()))

    @property
    def query_batch(self):
        """Query points per :meth:`exitance` call that keep a call short (a caller checks for Ctrl-C between calls)."""
        return 1 << 16

    def exitance(self, points, normals=None):
        """Radiant exitance ``M`` at ``points`` (K, 3) in mm; returns (K, 3) float64.

        ``normals`` (K, 3), the outward surface normals at the points, are optional; transports that can use the
        local surface orientation (the convolution's plane correction) do, the others ignore them.
        """
        points = as_points(points, "query points")
        if normals is not None:
            normals = as_points(normals, "query normals")
            if len(normals) != len(points):
                raise ValueError(f"{len(points)} query points need {len(points)} normals, got {len(normals)}")
        self._prepare(points)
        with self.timings("lookup"):
            out = self._exitance(points)
        if normals is not None:
            self._correct(points, normals, out)
        return out

    def relit(self, irradiance):
        """This transport for new irradiance (N, 3) at the same samples: Eq. 1 is linear in ``E`` and nothing of the
        samples' places changes, so a transport may keep what it built from them (:meth:`_relit`)."""
        return self._relit(dataclasses.replace(self.samples, irradiance=irradiance))

    def _relit(self, samples):
        """A transport of ``samples`` (this one's but for their irradiance); by default built again."""
        return type(self)(samples, self.profile, self.frame, self.material, **self.params)

    def _rebuilt(self, samples):
        """For a :meth:`_relit` that keeps what depends on the samples' places: a shallow copy with ``samples`` and
        fresh timings whose ``_build`` (what depends on their flux) runs again."""
        new = copy.copy(self)
        new.samples, new.timings = samples, StageTimer()
        new._build()
        return new

    def _to_view(self, points, vectors=False):
        """World points (``vectors``: directions) in the camera's view frame; as they are without a frame."""
        f = self.frame
        if f is None:
            return points
        return f.rotate(points) if vectors else f.to_view(points)

    def _prepare(self, points):
        """Work a query needs before the lookup itself (timed by the transport under its own stage names)."""

    def _exitance(self, points):
        raise NotImplementedError

    def _correct(self, points, normals, exitance):
        """Adjust ``exitance`` in place using the query normals (timed by the transport); nothing by default."""

    @property
    def stats(self):
        """A JSON-ready dict describing the run: transport name, sample count, per-stage seconds."""
        return {"transport": self.name, "samples": len(self.samples), "parameters": dict(self.params),
                "seconds": {k: float(v) for k, v in self.timings.items()}}

