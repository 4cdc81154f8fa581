"""Each profile model's total reflectance against the exact one of the same half-space (docs/benchmarks.md,
"Oblique incidence"): ``rho(1) / T_d(eta)`` of :mod:`convsss.profiles.incidence`, the normalization of Eq. 1.

    PYTHONPATH=src python docs/history/scripts/incidence-totals.py
"""

import dataclasses
import warnings

import numpy as np

from convsss.fresnel import diffuse_transmittance
from convsss.materials import OpticallyThinWarning, material
from convsss.profiles import model_profile
from convsss.profiles.incidence import escaped

warnings.simplefilter("ignore", OpticallyThinWarning)
print("preset     eta   alpha'             exact total           model total / exact (R G B)")
for name in ["wholemilk", "marble", "skin1", "ketchup"]:
    preset = material(name)
    for eta in sorted({1.0, preset.eta}):
        m = dataclasses.replace(preset, eta=eta)
        exact = np.array([float(escaped(a, eta, 1.0)) for a in m.albedo_prime]) / diffuse_transmittance(eta)
        ratios = "  ".join(f"{model} {np.round(np.asarray(model_profile(model, m).total_reflectance) / exact, 3)}"
                           for model in ["dipole", "better-dipole", "pbd", "burley"])
        print(f"{name:10s} {eta:.2f}  {np.round(m.albedo_prime, 3)}  {np.round(exact, 4)}  {ratios}")
