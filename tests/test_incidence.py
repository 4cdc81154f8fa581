"""Oblique incidence (convsss.profiles.incidence): Chandrasekhar's H-function and the adding method against analytic
identities and the Monte Carlo slab (convsss.profiles.slab) at a slant."""

import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.profiles import incidence
from convsss.profiles.slab import slab_tally


@pytest.mark.parametrize("albedo", [0.1, 0.5, 0.9, 0.999])
def test_h_function_zeroth_moment(albedo):
    """Chandrasekhar (1960) eq. 5.IX: (albedo / 2) ∫_0^1 H(mu) dmu = 1 - sqrt(1 - albedo)."""
    x, w = np.polynomial.legendre.leggauss(200)
    mu, w = 0.5 * (x + 1.0), 0.5 * w
    moment = 0.5 * albedo * np.sum(w * incidence.h_function(albedo, mu))
    assert moment == pytest.approx(1.0 - np.sqrt(1.0 - albedo), rel=1e-6)


def test_h_function_of_a_conservative_medium():
    """H(1) = 2.9078 for albedo 1 (Chandrasekhar's table)."""
    assert float(incidence.h_function(1.0, 1.0)) == pytest.approx(2.9078, rel=1e-3)


@pytest.mark.parametrize("albedo, eta, mu", [(0.68, 1.0, 0.3), (0.68, 1.3, 1.0), (0.68, 1.3, 0.3), (0.96, 1.4, 0.5),
                                             (0.1, 1.5, 0.2)])
def test_escaped_flux_matches_the_monte_carlo_slab(albedo, eta, mu):
    tally = slab_tally(albedo, eta, photons=1 << 18, seed=4, incidence=mu)
    sigma = tally["total_stderr"] / tally["total"] * tally["escaped"]
    assert abs(float(incidence.escaped(albedo, eta, mu)) - tally["escaped"]) < 4.0 * sigma


@pytest.mark.parametrize("eta", [1.0, 1.3])
def test_gain_is_one_at_normal_incidence_and_grows_at_a_slant(eta):
    g = incidence.gain([0.99, 0.8, 0.3], eta, [1.0, 0.7, 0.4, 0.1])
    assert g.shape == (4, 3)
    np.testing.assert_allclose(g[0], 1.0, atol=1e-12)
    assert np.all(np.diff(g, axis=0) > 0)
    assert np.all(np.diff(g[-1]) > 0)  # lower albedo, more of the light scatters near the surface


def test_gain_without_scattering_is_one():
    np.testing.assert_array_equal(incidence.gain_table(0.0, 1.3), 1.0)


def test_bad_albedo_is_refused():
    with pytest.raises(ConvsssError, match="albedo"):
        incidence.escaped(1.5, 1.3, 1.0)
    with pytest.raises(ConvsssError, match="incidence"):
        slab_tally(0.5, 1.3, photons=16, incidence=0.0)
