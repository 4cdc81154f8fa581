"""The diffusion equation on the object's volume (Eq. D1 of :mod:`convsss.transport.volume`): the domain on a grid,
each resolved channel's system and multigrid solver, and the fields solved for the samples' flux. The volume
transport reads their slope at the surface (Eq. D2); the random walk ends in their fluence
(:mod:`convsss.pipeline.field`)."""

import math

import numpy as np

from ...memory import check_memory
from ...timing import StageTimer
from .grid import BYTES_PER_NODE, Surface, assemble, deposit, gather, grid_shape, multigrid
from .medium import RESOLVED_LENGTH


class DiffusionSolve:
    """Eq. D1 for surface samples at ``view`` (N, 3) with outward ``normal`` (N, 3), both in the view frame (mm), of
    a medium of :class:`~.medium.Coefficients` ``coefficients`` on a grid of spacing ``h`` (mm).

    A channel is solved (:attr:`corrected`) where its diffusion length is at least :data:`RESOLVED_LENGTH` cells.
    Where the samples bound nothing (an open sheet, the grid's border inside) the medium goes on: the grid grows by
    ``grow`` (mm) on those sides. ``memory_limit`` bounds the grid (:func:`~convsss.memory.check_memory`, naming it
    ``what``, with ``advice``); ``timings`` (a :class:`~convsss.timing.StageTimer`) takes ``domain``, ``matrix``,
    ``multigrid``, ``sources`` and ``solve``."""

    def __init__(self, view, normal, coefficients, h, grow, memory_limit=None, timings=None, advice="",
                 what="the volume transport's grid"):
        self.coefficients, self.spacing = coefficients, h
        self.timings = StageTimer() if timings is None else timings
        with np.errstate(divide="ignore"):
            self.corrected = 1.0 / coefficients.sigma_tr >= RESOLVED_LENGTH * h
        self.origin, self.sd = None, np.zeros((0, 0, 0))
        self.channels = [(None, None, None)] * 3
        if not self.corrected.any():
            return
        with self.timings("domain"):
            self.surface = Surface(view, normal, h)
            self.origin, self.sd = self._domain(view.min(axis=0), view.max(axis=0), grow, memory_limit, advice, what)
        self.channels = []
        k = coefficients
        for c in range(3):
            if not self.corrected[c]:
                self.channels.append((None, None, None))
                continue
            with self.timings("matrix"):
                matrix, index = assemble(self.sd, k.z_b[c], k.diffusion[c], k.absorption[c], h)
            with self.timings("multigrid"):
                solver = multigrid(matrix) if matrix.shape[0] else None
            self.channels.append((index, k.z_b[c] - self.sd, solver))

    def _domain(self, lo, hi, grow, memory_limit, advice, what):
        """The grid's origin and the signed distance at its nodes, grown by ``grow`` on the sides an open sheet of
        samples leaves open."""
        h = self.spacing
        pad = float(np.max(self.coefficients.z_b)) + 2 * h
        low, high = lo - pad, hi + pad
        for grown in (False, True):
            origin, shape = grid_shape(low, high, h, 0.0)
            check_memory(BYTES_PER_NODE * math.prod(shape), what, advice, memory_limit)
            sd = self.surface.signed_distance_on(origin, h, shape, pad + h)
            inside = sd < pad - 2 * h
            open_low = np.array([inside.take(0, axis=d).any() for d in range(3)])
            open_high = np.array([inside.take(-1, axis=d).any() for d in range(3)])
            if grown or not (open_low.any() or open_high.any()):
                return origin, sd
            low, high = low - grow * open_low, high + grow * open_high

    def solve(self, view, normal, flux, tol=1e-8):
        """The fields (one per channel, over its unknowns; empty where not solved) of sources of ``flux`` (N, 3) at
        the samples ``view`` with ``normal`` (each :attr:`~.medium.Coefficients.source_depth` inside the
        extrapolated boundary, Eq. D5), and the flux each channel's grid holds (N, 3): 0 where a sample has no
        inside node around it."""
        held = np.zeros_like(flux)
        fields = []
        k = self.coefficients
        for c, (_, _, solver) in enumerate(self.channels):
            if solver is None:
                fields.append(np.zeros(0))
                continue
            with self.timings("sources"):
                rhs, has = self.place(c, view, normal, k.source_depth[c], flux[:, c])
                held[:, c] = np.where(has, flux[:, c], 0.0)
            with self.timings("solve"):
                fields.append(solver.solve(rhs / self.spacing**3, x0=np.zeros_like(rhs), tol=tol, accel="cg",
                                           maxiter=200))
        return fields, held

    def place(self, c, points, normal, distance, flux=None, field=None):
        """Channel ``c``'s sources (``flux`` given: returns the right-hand side and which samples are held) or reads
        (``field`` given: returns the values and which points are held) at ``distance`` inside the extrapolated
        boundary under surface ``points`` (sources where Eq. D5 puts them, reads at Eq. D4's depths), with
        :func:`~.grid.moment_weights`."""
        index, depth, solver = self.channels[c]
        at = points - (distance - self.coefficients.z_b[c]) * normal
        if flux is not None:
            return deposit(at, flux, self.origin, self.spacing, index, depth, solver.levels[0].A.shape[0])
        return gather(at, field, self.origin, self.spacing, index, depth)

    def fluence(self, fields):
        """``fields`` as the fluence they stand for on the whole grid (nx, ny, nz, 3): sources of the dipole's
        strength ``s alpha' Phi_i`` (Eq. D4's ``beta / D``, with Eq. D5's gain), in the irradiance's unit; 0 off the
        domain and in the channels not solved."""
        k = self.coefficients
        phi = np.zeros((*self.sd.shape, 3))
        for c, (index, _, solver) in enumerate(self.channels):
            if solver is not None:
                inside = index >= 0
                phi[inside, c] = fields[c][index[inside]] * k.beta[c] / k.diffusion[c] * k.source_gain[c]
        return phi
