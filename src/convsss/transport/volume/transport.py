"""The volume transport itself: Eq. 1 by two multiscale sums, corrected by the diffusion equation solved on the
object's interior (:mod:`convsss.transport.volume`)."""

import math
import warnings

import numpy as np

from ...errors import ConvsssError
from ...parameters import Parameter
from ...profiles.base import ScaledProfile
from ...profiles.tabulated import TabulatedProfile
from ...samples import IrradianceSamples
from ..base import Transport, register_transport
from ..kernels import KernelCache
from ..multiscale import MultiscaleTransport
from .grid import BYTES_PER_NODE, grid_shape
from .medium import RESOLVED_LENGTH, auto_spacing, coefficients
from .response import half_space_response
from .solve import DiffusionSolve

#: Grid nodes beyond which a spacing is refused outright (long before, the memory guard refuses what does not fit).
MAX_NODES = 1e12
#: The half-space response's reach: the radius holding all but this fraction of the profile's energy.
RESPONSE_TAIL = 1e-4


#: The half-space response's largest reach, in cells (its cost grows as the cube).
MAX_REACH = 128


#: How many diffusion lengths the medium under an open sheet of samples is grown (:meth:`VolumeTransport._domain`).
OPEN_DEPTH = 3.0


#: The half-space responses, keyed by (coefficients, spacing).
RESPONSES = KernelCache()


#: Below this many transport mean free paths across (the clearest channel's), diffusion on the object is poor: the
#: volume transport was measured 1.22-1.34 times path tracing on objects of a few (issue 51), with a warning.
FEW_MEAN_FREE_PATHS = 10.0


class VolumeWarning(UserWarning):
    """The volume transport renders what it cannot correct: no channel resolved, or an object too few mean free paths
    across for diffusion."""


def _model_of(profile):
    """A one-line error for a profile that is no model of the material (a tabulated CSV): the correction of Eq. D2
    is the diffusion of the object's material, which a measured profile need not be."""
    base = profile.base if isinstance(profile, ScaledProfile) else profile
    if isinstance(base, TabulatedProfile):
        raise ConvsssError("the volume transport needs a profile model with coefficients (sigma_s', sigma_a, eta), "
                           f"not {type(base).__name__}: use a model, or another transport")


class VolumeTransport(Transport):
    """Eq. 1 summed by the multiscale transport, corrected by the diffusion equation solved on the object's volume
    (Eq. D2); see the module docstring. Needs the samples' normals."""

    name = "volume"
    sums_eq1 = False
    parameters = (
        Parameter("accuracy", float, 0.01, "Relative error aimed at by the sums of Eq. 1 (as the multiscale "
                  "transport's accuracy).", low=1e-6, high=0.5),
        Parameter("spacing", float, 0.0, "Grid spacing of the diffusion solve in mm; 0 sets it from the material "
                  "and the object (half the shortest diffusion length, 1/64 to 1/24 of the object's extent).",
                  low=0.0),
        Parameter("memory_limit", float, None, "Bytes the grid and the sums may use (default: what the machine has "
                  "available).", low=0.0, low_open=True, exposed=False),
    )

    memory_advice = "set a coarser spacing for the volume transport, or use the multiscale transport"

    @classmethod
    def spacing_for(cls, bounds, material, params):
        """The grid spacing (mm) for samples within ``bounds`` (2, 3) of a medium of ``material``."""
        lo, hi = np.asarray(bounds, dtype=np.float64)
        return params.get("spacing") or auto_spacing(material, float(np.max(hi - lo)))

    @classmethod
    def planned_bytes(cls, bounds, profile, count, params, material=None):
        """The grid (:data:`BYTES_PER_NODE` per node) and the two multiscale sums (their far meshes)."""
        _model_of(profile)
        lo, hi = np.asarray(bounds, dtype=np.float64)
        h = cls.spacing_for(bounds, material, params)
        with np.errstate(over="ignore"):  # the unpadded grid's nodes, a float: no integer overflows, inf is refused
            nodes = float(np.prod(np.floor((hi - lo) / h) + 2))
        if not nodes <= MAX_NODES:
            raise ConvsssError(f"the volume transport's grid at spacing {h:.3g} mm would hold {nodes:.3g} nodes, "
                               f"more than {MAX_NODES:.0e}: give a coarser spacing (0: set from the material)")
        _, shape = grid_shape(lo, hi, h, float(np.max(coefficients(profile, material, h).z_b)) + 2 * h)
        sums = MultiscaleTransport.planned_bytes(bounds, profile, count, {"accuracy": params.get("accuracy", 0.01)})
        return int(BYTES_PER_NODE * math.prod(shape) + 2 * sums)

    def __init__(self, samples, profile, frame=None, material=None, **params):
        super().__init__(samples, profile, frame, material, **params)
        _model_of(profile)
        if len(samples) and samples.normal is None:
            raise ConvsssError("the volume transport needs the samples' normals")
        self.spacing, self.solve = 0.0, None
        self.coefficients = coefficients(profile, material, 1.0)
        self._half = self._flat = None  # the two sums of Eq. D2, built by the first _build, relit by the others
        if len(samples):  # without samples there is nothing to solve for: Eq. 1 (of nothing)
            self._set_up()
        self._build()

    @property
    def corrected(self):
        """Per channel, whether the grid resolves its diffusion length (the channels Eq. D2 corrects)."""
        return np.zeros(3, dtype=bool) if self.solve is None else self.solve.corrected

    def _set_up(self):
        """The grid, its matrices and multigrid hierarchies (:class:`~.solve.DiffusionSolve`) and the half-space
        responses, for the channels whose diffusion length the grid resolves (none: Eq. 1, and no grid is built)."""
        view = self._to_view(self.samples.position)
        normal = self._to_view(self.samples.normal, vectors=True)
        lo, hi = view.min(axis=0), view.max(axis=0)
        self.spacing = h = self.spacing_for((lo, hi), self.material, self.params)
        self.coefficients = coefficients(self.profile, self.material, h)
        reach = self._reach(h, float(np.linalg.norm(hi - lo)))
        self._view, self._normal = view, normal
        self.solve = DiffusionSolve(view, normal, self.coefficients, h, self._depth_of_medium(reach),
                                    self.params["memory_limit"], self.timings, self.memory_advice)
        across = float(np.max(hi - lo) * np.min(self.material.sigma_t_prime)) if self.material is not None else np.inf
        if across < FEW_MEAN_FREE_PATHS:
            warnings.warn(f"the volume transport on an object {across:.3g} transport mean free paths across: "
                          "diffusion is poor there (measured 1.2-1.3 times path tracing on objects of a few); "
                          "walk_depth inf (--walk-depth inf) follows the light instead", VolumeWarning, stacklevel=2)
        if not self.corrected.any():
            warnings.warn(f"the volume transport's grid at spacing {h:.3g} mm resolves no channel's diffusion length "
                          f"(at least {RESOLVED_LENGTH:g} cells): it renders Eq. 1 alone, as the multiscale transport; "
                          "give a finer spacing (0: set from the material)", VolumeWarning, stacklevel=2)
            return
        with self.timings("response"):
            self._response = self._half_space(h, reach)

    def _reach(self, h, diagonal):
        """How far the half-space response reaches (mm): the profile's reach (:data:`RESPONSE_TAIL`) or the samples'
        diagonal, whichever is shorter (no two samples are farther apart), and at most :data:`MAX_REACH` cells."""
        return min(float(np.max(self.profile.radius_energy(RESPONSE_TAIL))), diagonal + h, MAX_REACH * h)

    def _depth_of_medium(self, reach):
        """How far an open sheet's medium is grown (mm): :data:`OPEN_DEPTH` diffusion lengths (the field falls by
        ``e^-6`` there and back), at most the reach."""
        with np.errstate(divide="ignore"):
            length = float(np.max(1.0 / self.coefficients.sigma_tr))
        return min(reach, OPEN_DEPTH * length)

    def _half_space(self, h, reach):
        """``beta T`` of Eq. D2 as a tabulated profile (``T`` with the source gain of Eq. D5). A channel not corrected
        holds no flux in the second sum, but its response is solved all the same: it sets the sum's scales (with
        the corrected channels' alone, coarser, the slab's far face comes out too dark)."""
        k = self.coefficients
        key = (k.key(), h, reach)
        cached = RESPONSES.get(key)
        if cached is None:
            tables = [half_space_response(k.diffusion[c], k.absorption[c], k.source_depth[c], k.read_depths[:, c],
                                          k.read_weights[:, c], h, reach) for c in range(3)]
            cached = (tables[0][0], np.stack([t[1] for t in tables], axis=1))
            RESPONSES.put(key, cached)
        r, response = cached
        return TabulatedProfile(r, response * (k.beta * k.source_gain), name="half-space response")

    def _build(self):
        """What depends on the flux: the solves of Eq. D1 and the two sums of Eq. D2."""
        if self.solve is not None:
            self._fields, held = self.solve.solve(self._view, self._normal, self.samples.flux)
        else:
            self._fields, held = [np.zeros(0)] * 3, np.zeros_like(self.samples.flux)
        with self.timings("sums"):  # relit: the sums keep their clusters (the samples' places are the same)
            if self._half is not None:
                self._half = self._half.relit(self.samples.irradiance)
                self._flat = None if self._flat is None else self._flat.relit(held / self.samples.area[:, None])
                return
            ms = {"accuracy": self.params["accuracy"], "memory_limit": self.params["memory_limit"]}
            self._half = MultiscaleTransport(self.samples, self.profile, self.frame, **ms)
            held_samples = IrradianceSamples(self.samples.position, self.samples.area,
                                             held / self.samples.area[:, None], self.samples.normal)
            self._flat = MultiscaleTransport(held_samples, self._response, self.frame, **ms) \
                if self.corrected.any() else None

    def _relit(self, samples):
        """The same grid, matrices, multigrid hierarchies and responses; the solves and sums again."""
        return self._rebuilt(samples)

    def _exitance(self, points):
        out = self._half.exitance(points)
        view = self._to_view(points)
        if self._flat is None:
            return out
        correction = -self._flat.exitance(points)
        k = self.coefficients
        with self.timings("read_back"):
            normal = self.solve.surface.normal_near(view)
            for c in np.flatnonzero([solver is not None for _, _, solver in self.solve.channels]):
                slope, held = 0.0, np.ones(len(view), dtype=bool)
                for depth, weight in zip(k.read_depths[:, c], k.read_weights[:, c]):  # Eq. D4
                    value, has = self.solve.place(c, view, normal, depth, field=self._fields[c])
                    slope, held = slope + weight * value, held & has
                correction[:, c] += k.beta[c] * k.source_gain[c] * slope
                correction[~held, c] = 0.0
        return np.maximum(out + correction, 0.0)

    @property
    def stats(self):
        """The base stats plus the grid's spacing, shape and unknowns per channel, Eq. D4's ``beta``, the corrected
        channels and the two sums' stats."""
        channels = [(None, None, None)] * 3 if self.solve is None else self.solve.channels
        return {**super().stats, "spacing_mm": self.spacing,
                "grid": [0, 0, 0] if self.solve is None else list(self.solve.sd.shape),
                "unknowns": [0 if index is None else int((index >= 0).sum()) for index, _, _ in channels],
                "beta": self.coefficients.beta.tolist(), "corrected": self.corrected.tolist(),
                "sums": [t.stats for t in (self._half, self._flat) if t is not None]}


register_transport(VolumeTransport)
