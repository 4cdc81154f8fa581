"""Light that crosses an object (docs/benchmarks.md, "What is left on skin1"): a slab of thickness d lit from
behind, in diffusion theory, against what paper Eq. 1 gives it with the half-space's dipole profile.

    PYTHONPATH=src python docs/history/scripts/incidence-transmission.py [MATERIAL [D_MM ...]]

Both in the dipole's diffusion theory (eta 1): one source of strength alpha' at depth z_r, extrapolated boundaries
z_b = 2 A D. The slab's exact 1-D solution transmits, per unit of normal incident flux,

    T(d) = alpha' sinh(sigma_tr u_0) cosh(sigma_tr z_b) / sinh(sigma_tr (d + 2 z_b)),   u_0 = z_r + z_b,

(Fick's flux at the far face). Eq. 1 sums the half-space profile at the straight distance r >= d between a point
of the lit face and one of the far face: int_d^inf R_d(r) 2 pi r dr, the profile's energy beyond d.
"""

import dataclasses
import sys

import numpy as np

from convsss.materials import material
from convsss.profiles.models import model_profile

name = sys.argv[1] if len(sys.argv) > 1 else "skin1"
thicknesses = [float(d) for d in sys.argv[2:]] or [2.0, 5.0, 10.0, 20.0]
medium = dataclasses.replace(material(name), eta=1.0)
dipole = model_profile("dipole", medium, total="model")
sigma, z_r = np.asarray(dipole.sigma_tr), np.asarray(dipole.z_r)
z_b = 0.5 * (np.asarray(dipole.z_v) - z_r)
print(f"{name}, eta 1, dipole; per channel R/G/B")
print("d mm   sigma_tr d           slab T                  Eq. 1 beyond d          T / Eq. 1")
for d in thicknesses:
    slab = dipole.alpha_prime * np.sinh(sigma * (z_r + z_b)) * np.cosh(sigma * z_b) / np.sinh(sigma * (d + 2 * z_b))
    beyond = np.asarray(dipole.total_reflectance) - np.asarray(dipole.energy_within(d))
    fmt = lambda v: " ".join(f"{x:.2e}" for x in v)  # noqa: E731
    print(f"{d:5.1f}  {' '.join(f'{x:5.1f}' for x in sigma * d)}   {fmt(slab)}   {fmt(beyond)}   "
          f"{' '.join(f'{x:6.1f}' for x in slab / beyond)}")
