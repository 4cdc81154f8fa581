import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.fresnel import diffuse_fresnel_reflectance, fresnel_reflectance, fresnel_transmittance


@pytest.mark.parametrize("eta", [1.3, 1.5, 0.8])
def test_normal_incidence(eta):
    assert fresnel_reflectance(eta, 1.0) == pytest.approx(((eta - 1) / (eta + 1)) ** 2, rel=1e-12)


@pytest.mark.parametrize("eta", [1.3, 1.5, 0.75])
def test_grazing_reflects_everything(eta):
    assert fresnel_reflectance(eta, 0.0) == pytest.approx(1.0)
    assert fresnel_reflectance(eta, 1e-9) == pytest.approx(1.0, abs=1e-6)


def test_total_internal_reflection():
    eta = 1 / 1.5  # from inside glass to air
    critical = np.sqrt(1 - eta**2)  # cosine of the critical angle
    cos = np.array([critical * 0.99, critical * 0.5])
    np.testing.assert_array_equal(fresnel_reflectance(eta, cos), 1.0)
    assert fresnel_reflectance(eta, min(1.0, critical * 1.01)) < 1.0


def test_index_matched_boundary_transmits_all():
    cos = np.linspace(0, 1, 11)
    np.testing.assert_allclose(fresnel_reflectance(1.0, cos)[1:], 0.0, atol=1e-15)
    np.testing.assert_allclose(fresnel_transmittance(1.0, cos[1:]), 1.0)


def test_reflectance_increases_towards_grazing_and_sign_ignored():
    cos = np.linspace(0.01, 1, 50)
    fr = fresnel_reflectance(1.3, cos)
    assert np.all(np.diff(fr) <= 0)
    np.testing.assert_array_equal(fresnel_reflectance(1.3, -cos), fr)


def test_diffuse_fresnel_fit_matches_hemispherical_average():
    # F_dr = ∫ F_r(cos) 2 cos d(cos) for light arriving from inside (relative index 1/eta): the fit is within ~1 %.
    eta = 1.3
    cos = np.linspace(0, 1, 200001)
    exact = np.trapezoid(fresnel_reflectance(1 / eta, cos) * 2 * cos, cos)
    assert diffuse_fresnel_reflectance(eta) == pytest.approx(exact, rel=0.02)


@pytest.mark.parametrize("eta", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_eta(eta):
    with pytest.raises(ConvsssError, match="eta"):
        fresnel_reflectance(eta, 0.5)
