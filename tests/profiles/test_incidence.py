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


@pytest.mark.parametrize("eta", [1.0, 1.3])
def test_exit_normalization_keeps_the_exitance_of_eq_7(eta):
    """Eq. O4: ``2 ∫ F_t g mu dmu / k`` over the outside cosine is ``T_d``, what Lambertian Eq. 7 sends out; no
    scattering (g = 1) gives k = 1."""
    from convsss.fresnel import diffuse_transmittance, fresnel_reflectance

    albedo = np.array([0.99, 0.7, 0.2])
    k = incidence.exit_normalization(albedo, eta)
    mu = np.linspace(0.0, 1.0, 20001)
    sent = 2.0 * np.trapezoid((1.0 - fresnel_reflectance(eta, mu))[:, None] * incidence.gain(albedo, eta, mu)
                              * mu[:, None], mu, axis=0) / k
    np.testing.assert_allclose(sent, diffuse_transmittance(eta), rtol=1e-6)
    assert np.all(k > 1.0) and k[2] > k[1] > k[0]
    np.testing.assert_allclose(incidence.exit_normalization(np.zeros(3), eta), 1.0, rtol=1e-6)


@pytest.mark.parametrize("albedo", [0.96, 0.68])
def test_reciprocal_exit_matches_the_half_space_radiance_on_a_sphere(albedo):
    """A sphere (each point a half-space, index-matched) lit at 47° to the view: per band of the view cosine, the
    radiance ``E g(mu_0) rho(1) g(mu) / (pi k)`` of Eq. O1 + O4 is within 2 % of the exact Eq. O2
    ``E alpha'/(4 pi) H(mu_0) H(mu) / (mu + mu_0)``, where the Lambertian ``E rho(mu_0) / pi`` is 13 % (albedo 0.96) and
    27 % (0.68) too dark at grazing view."""
    y, x = np.mgrid[-1:1:300j, -1:1:300j]
    inside = x * x + y * y < 0.999
    normal = np.stack([x[inside], y[inside], np.sqrt(1.0 - x[inside] ** 2 - y[inside] ** 2)], axis=-1)
    light = np.array([np.sin(np.radians(47.0)), 0.0, np.cos(np.radians(47.0))])
    mu0, mu = normal @ light, normal[:, 2]
    lit = mu0 > 1e-3
    mu0, mu = mu0[lit], mu[lit]
    exact = mu0 * albedo / (4 * np.pi) * incidence.h_function(albedo, mu0) * incidence.h_function(albedo, mu) / (
        mu + mu0)
    rho1 = incidence.escaped(albedo, 1.0, 1.0)
    g = incidence.gain([albedo], 1.0, np.stack([mu0, mu]))[..., 0]
    reciprocal = mu0 * g[0] * rho1 * g[1] / (np.pi * incidence.exit_normalization([albedo], 1.0)[0])
    lambertian = mu0 * g[0] * rho1 / np.pi
    bands = [(0.0, 0.3), (0.3, 0.6), (0.6, 0.85), (0.85, 1.0)]
    ratio = np.array([[model[(mu >= lo) & (mu < hi)].sum() / exact[(mu >= lo) & (mu < hi)].sum()
                       for lo, hi in bands] for model in (reciprocal, lambertian)])
    np.testing.assert_allclose(ratio[0], 1.0, atol=0.02)
    assert ratio[1][0] < 0.9


@pytest.mark.parametrize("albedo", [0.05, 0.7, 0.999])
def test_single_scattering_is_the_first_order_of_eq_o2(albedo):
    """Index-matched, the once-scattered flux (Eq. S1) is ``(alpha'/2) (1 - mu0 ln(1 + 1/mu0))``; under a dielectric
    less of it leaves (total internal reflection), and the rest is left to the multiple scattering."""
    mu0 = np.array([0.1, 0.5, 1.0])
    escaped = incidence.escaped
    single = escaped(albedo, 1.0, mu0) - escaped(albedo, 1.0, mu0, "multiple")
    np.testing.assert_allclose(single, 0.5 * albedo * (1.0 - mu0 * np.log(1.0 + 1.0 / mu0)), rtol=1e-6)
    under_glass = escaped(albedo, 1.3, mu0) - escaped(albedo, 1.3, mu0, "multiple")
    assert np.all(under_glass < single) and np.all(escaped(albedo, 1.3, mu0, "multiple") > 0)
    with pytest.raises(ConvsssError, match="orders='first' is not allowed"):
        escaped(albedo, 1.0, mu0, "first")
