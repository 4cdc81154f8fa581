"""The profiles against the path-traced slab (convsss.profiles.validate): the exact half-space total that renders
use by default (profile_total exact) agrees with the slab's total, and the models' own totals do not all."""

import numpy as np

from convsss.materials import material
from convsss.profiles.validate import EXACT, summary, validate_material


def test_exact_total_agrees_with_the_slab_and_the_dipole_does_not():
    skin = material("skin1")  # alpha' 0.96 / 0.84 / 0.68 under eta 1.3
    result = validate_material(skin, ["dipole"], photons=1 << 16, seed=2)
    slab = result["slab"]
    error = np.abs(result["exact"]["total"] - slab["total"])
    assert np.all(error < 4.0 * slab["total_stderr"]), (result["exact"]["total"], slab["total"])
    assert abs(result["models"]["dipole"]["total_error"][0]) > 0.03  # the dipole's own total: -7 % in R
    stats = summary([result], ["dipole"])
    assert list(stats) == [EXACT, "dipole"]
    assert stats[EXACT]["thick_within_2pct"] == 3 and stats[EXACT]["thick_max"] < 0.02
