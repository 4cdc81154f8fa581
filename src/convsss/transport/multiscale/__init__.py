"""The multi-scale transport: the exact sum's accuracy at any object size, by splitting the profile by distance.

The package: :mod:`.scales` the split and its lengths, :mod:`.far_field` the mesh, :mod:`.clusters` and
:mod:`.cells` the direct sums, :mod:`.transport` the class.

As particle–particle/particle–mesh N-body codes and multilevel summation split a force, the profile is split at
radii ``r_0 < r_1 < ... < r_L = r_c``, each twice the last, into a core, ``L`` middle bands and a far field,
``R_d = R_core + R_1 + ... + R_L + R_far``, each piece smooth at the scale of its inner split radius. A split at
``r`` replaces ``f`` inside ``r`` by a cap,

    cap_r[f](x) = a + b x^2,   a, b per channel matching the value and slope of f at r,                 (Eq. M1)

so that ``f - cap_r[f]`` is zero from ``r`` on and ``cap_r[f]`` is C^1:

    R_far  = R_d beyond r_c, cap_{r_c}[R_d] inside;                                                      (Eq. M2)
    R_k    = f_k beyond r_{k-1}, cap_{r_{k-1}}[f_k] inside (zero from r_k on), f_k = R_d - R_far - R_L - ... - R_{k+1};
    R_core = f_0 (zero from r_0 on; >= 0 for a profile convex inside r_0, such as the dipole).

One middle band (``L = 1``) unless the far mesh would hold more than :data:`FAR_CELLS` cells (an object many
profile widths across): each further band doubles ``r_c`` and the mesh spacing.

- **Far field** ``sum_i R_far(|x - x_i|) Phi_i``: smooth at the scale ``r_c``, so it needs neither image resolution
  nor thin layers. The flux is deposited on a voxel mesh of spacing ``h`` aligned with the camera (the
  paper's layers with spacing ``h`` in x, y *and* depth: its §7 "layers with variable resolution"), convolved with
  ``R_far`` on the mesh by 3-D FFTs (the layer mixing of Eq. 6 is itself a convolution along depth; zero-padded, so
  nothing wraps around) and read back, with the weights of a quadratic B-spline (each point spread over the 3^3
  nodes around it, the triangular-shaped cloud of particle-mesh codes). The kernel's spectrum is divided by the
  transfer function of the deposit and the read-back (``sinc^6`` per axis), which removes their blur to second order.
- **Middle bands**: band ``k`` summed directly (through a cell list) at the corners of the voxels of side
  ``2^(k-1) g`` that hold clusters and that queries fall in, each corner once, when first needed, and read back
  trilinearly: it is smooth at the scale ``r_{k-1} > 2^(k-1) g``. (At a query in any other voxel, or among queries
  sparser than the voxels, it is summed where the query is.)
- **Core**: summed directly at each query point over the samples within ``r_0``.

Both direct sums run over *clusters*: the samples merged in cubes of side ``s`` for the core, those clusters merged
again in cubes of side ``2^k s`` for the smoother band ``k`` (flux summed, placed at its centroid; the two sides of a
thin sheet are kept apart by the normals' directions). The render's samples are many
times denser than the profile's core is wide, so the sums lose almost nothing (the error is second order in ``s``
and cancels where the irradiance is smooth) for a small fraction of the cost.

One knob, ``accuracy`` (the relative error aimed at), sets every length from the profile's core width ``w`` (the
radius where ``R_d`` falls to half its peak, smallest over the channels: about 0.8 mean free paths for the dipole);
see :func:`scales`. The lengths are common to the channels, sized by the narrowest.

**The local limit.** What the image cannot show need not be resolved. Given the pixel footprint ``f`` where the
object is seen (``cell_size``), the lengths are set by ``w' = max(w, f / 3)``; where ``w' > w`` (a dense medium, a
small image, a sharp-peaked model such as photon beam diffusion's) the core is narrower than the samples are apart,
and its sum is replaced by its local limit, its energy times the irradiance averaged over the samples around
the query with a smooth kernel of radius ``r_0``:

    M_core(x) = E_core sum_i K_i Phi_i / sum_i K_i A_i,   K_i = (1 - |x - x_i|^2 / r_0^2)^2,
    E_core = ∫ R_core dA,                                                                                (Eq. M3)

``M = E_core E(x) + O(r_0^2 ∇^2 E)`` at the scale of the pixel (``K``'s rms radius is ``r_0 / 2 = f / 2``). As a
ratio it keeps the energy wherever the samples lie (a concave or thin part gathers more surface within ``r_0``
than a plane: a sum of ``E_core K`` would be too bright there) and it has little noise. The far
mesh and the samples follow the image (:meth:`MultiscaleTransport.sample_area`), not the mean free path. A far
field holding less than ``accuracy / 10`` of every channel's energy is dropped (:func:`far_energy`).
"""

from .cells import BandCorners, CellList
from .clusters import cube_cells, group, merge, sheet_side
from .far_field import SPECTRA, far_bytes
from .scales import BAND_TABLE, Scales, core_width, scales, split
from .transport import MultiscaleTransport

__all__ = ["BAND_TABLE", "SPECTRA", "BandCorners", "CellList", "MultiscaleTransport", "Scales", "core_width",
           "cube_cells", "far_bytes", "group", "merge", "scales", "sheet_side", "split"]
