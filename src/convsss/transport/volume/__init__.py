"""The volume transport: the half-space sum of Eq. 1, corrected by the diffusion equation solved on the object itself.

Paper Eq. 1 reads a half-space's profile at the straight distance between two surface points, so light that crosses
the body, leaves through a thin part or would cross an air gap is counted as if the object were the half-space under
each entry point. The classic dipole is the Green's function of the diffusion equation on a half-space with the
extrapolated boundary; the same equation solved on the object's own volume makes it geometric. Per channel,

    -D ∇²u + sigma_a u = sum_i Phi_i delta(x - x_i + z_r n_i)   in the object grown by z_b,  u = 0 beyond,  (Eq. D1)

with ``D = 1/(3 sigma_t')``, ``z_r = 1/sigma_t'`` (the dipole's real source under the entry point ``x_i``, normal
``n_i``) and ``z_b = 2 A D`` (the extrapolated boundary). It is solved on a voxel grid of spacing ``h`` aligned with
the camera: the domain is where the signed distance to the surface (from the nearest sample's tangent plane) is
below ``z_b``; a link from an inside node to an outside one ends on that boundary at the fraction ``theta`` of the
link where the distance crosses ``z_b``, and adds ``D / (theta h^2)`` to the inside node's diagonal (the symmetric
second-order treatment of Gibou et al. 2002), so the matrix is symmetric positive definite and the boundary sits
where it is, not on the nearest node. Conjugate gradients with smoothed-aggregation multigrid (pyamg) solve it.

The grid cannot resolve the profile's core, so the solve is used as a *difference*: the exitance is

    M(x) = sum_i R_d(|x - x_i|) Phi_i + beta [du/dd(x) - sum_i T(|x - x_i|) Phi_i],                      (Eq. D2)

where ``du/dd`` is the solve's slope along the inward normal at the real surface (read from two depths, Eq. D4),
``beta`` turns it into Fick's flux (Eq. D4), and ``T(r)`` is the same solver's slope on a flat half-space, placed
and read the same way (sources where Eq. D5 puts them, :func:`moment_weights`), averaged over where the boundary
and the source fall within a cell (:func:`half_space_response`, solved exactly in lateral Fourier modes). On a
half-space ``du/dd = sum_i T Phi_i`` and Eq. D2 is Eq. 1: any profile model keeps
its near field. Where the object is not a half-space at the scale of the diffusion length, the bracket adds what
crosses the body and removes what would cross the air. Both sums run on the multiscale transport
(:mod:`.multiscale`), so the cost is theirs plus the solve.

What diffusion cannot do, this cannot either: parts thinner than a few mean free paths, low albedo (single
scattering is traced by shading, as for every transport). A part thinner than a cell keeps Eq. 1 where no node of
the domain is near: sources and queries with no inside node around them add no correction; a channel whose
diffusion length is under :data:`RESOLVED_LENGTH` cells keeps Eq. 1 entirely. Checked against closed forms
(tests/transport/test_volume.py): a single point source on a half-space differs from Eq. 1 near the source (the
grid's response to one source against the average over where it falls in a cell); a slab 2 or 5 mm thick transmits
the 1-D closed form within 2 % and converges to it as the spacing falls; a 5 mm sphere's exitance is the
eigenfunction series' within 2.5 % from 60 degrees off the source on, 5 % nearer. A part only a few cells thick is
not resolved: the 2 mm slab at a 0.5 mm spacing (7 cells across) transmits too little.

The package: :mod:`.medium` the coefficients on the grid, :mod:`.response` the half-space's response that calibrates
it, :mod:`.grid` the interior, its system and its deposit and gather, :mod:`.solve` Eq. D1 solved on it (also the
field the random walk ends in, :mod:`convsss.pipeline.field`), :mod:`.transport` the class.
"""

from .medium import auto_spacing, coefficients, medium_of
from .response import half_space_response
from .solve import DiffusionSolve
from .transport import OPEN_DEPTH, RESPONSES, VolumeTransport

__all__ = ["OPEN_DEPTH", "RESPONSES", "DiffusionSolve", "VolumeTransport", "auto_spacing", "coefficients",
           "half_space_response", "medium_of"]
