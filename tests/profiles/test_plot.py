"""Profile plots (convsss.profiles.plot): a PNG for any material, a medium that does not scatter included."""

import warnings

import numpy as np
import pytest

from convsss.materials import Material
from convsss.profiles.plot import plot_profiles


@pytest.mark.parametrize("sigma_s_prime", [[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]])
def test_a_plot_is_written_without_a_warning(tmp_path, sigma_s_prime):
    """Zero scattering (the editor's sigma_s' = 0) reflects nothing: the panel says so, and matplotlib is not asked
    for log axes of zeros (it warned, on the editor's stderr)."""
    from convsss.profiles import model_profile

    material = Material(np.array(sigma_s_prime), np.array([0.1, 0.1, 0.1]), 1.3, "test")
    profile = model_profile("dipole", material)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plot_profiles([("test", [("dipole", profile)])], tmp_path / "p.png")
    assert (tmp_path / "p.png").read_bytes().startswith(b"\x89PNG")
