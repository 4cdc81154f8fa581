"""One contract, every registered profile model (as the transports' contract runs over theirs): declared name,
title and rank; a total reflectance that is the profile's integral and its optical total; a non-negative,
non-increasing profile; the similarity in the mean free path; the thresholds it answers."""

import numpy as np
import pytest

from convsss.profiles import PROFILE_MODELS, Profile
from convsss.profiles.models import MODEL_TITLES

KINDS = list(PROFILE_MODELS)
#: (sigma_s', sigma_a, eta) in 1/mm: skim-milk-like, marble-like, an absorbing one, index-matched.
MATERIALS = [(0.70, 0.0014, 1.3), (2.19, 0.0021, 1.5), (0.88, 0.17, 1.0)]


def test_every_model_registers_itself_with_a_name_title_and_place():
    assert KINDS[0] == "dipole" and {"better-dipole", "pbd", "burley"} <= set(KINDS)
    assert [PROFILE_MODELS[k].rank for k in KINDS] == sorted(PROFILE_MODELS[k].rank for k in KINDS)
    for name, cls in PROFILE_MODELS.items():
        assert issubclass(cls, Profile) and cls.name == name and MODEL_TITLES[name] == cls.title and cls.title


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("material", MATERIALS)
def test_total_is_the_integral_and_the_optical_total(kind, material):
    cls = PROFILE_MODELS[kind]
    profile = cls(*material)
    total = np.asarray(profile.total_reflectance)
    r = np.geomspace(1e-6, 1e4, 200_001)
    integral = np.trapezoid(2 * np.pi * r[:, None] * profile(r), r, axis=0) + np.pi * 1e-12 * profile(0.0)
    np.testing.assert_allclose(integral, total, rtol=5e-3)
    np.testing.assert_allclose(profile.energy_within(1e6), total, rtol=1e-6)
    sigma_s, sigma_a, eta = material
    albedo = sigma_s / (sigma_s + sigma_a)
    assert cls.optical_total(albedo, eta) == pytest.approx(float(total[0]), rel=1e-6)


@pytest.mark.parametrize("kind", KINDS)
def test_profile_is_non_negative_and_non_increasing(kind):
    profile = PROFILE_MODELS[kind](*MATERIALS[0])
    values = profile(np.geomspace(1e-4, 100.0, 4000))
    assert np.all(values >= 0) and np.all(np.diff(values, axis=0) <= 1e-12 * values[:-1])


@pytest.mark.parametrize("kind", KINDS)
def test_a_denser_medium_is_the_same_profile_shrunk(kind):
    """R_d depends on r only through r / mfp: k times the coefficients gives k^2 R_d(k r)."""
    cls, (s, a, eta), k = PROFILE_MODELS[kind], MATERIALS[1], 3.0
    r = np.geomspace(0.01, 20.0, 50)
    np.testing.assert_allclose(cls(k * s, k * a, eta)(r / k), k**2 * cls(s, a, eta)(r), rtol=1e-6)


@pytest.mark.parametrize("kind", KINDS)
def test_thresholds_are_where_the_profile_says(kind):
    profile = PROFILE_MODELS[kind](*MATERIALS[2])
    half = np.asarray(profile.radius_below(0.5))
    peak = np.asarray(profile(0.0))
    finite = np.isfinite(peak)
    at = np.array([profile(h)[c] for c, h in enumerate(half)])
    before = np.array([profile(h * (1 - 1e-3))[c] for c, h in enumerate(half)])
    # The smallest radius where R_d falls to half its peak (a profile may step down through it).
    assert np.all(at[finite] <= 0.5 * peak[finite] * (1 + 1e-6)) and np.all(before[finite] > 0.5 * peak[finite])
    reach = np.asarray(profile.radius_energy(1e-3))
    np.testing.assert_allclose(np.diagonal(profile.energy_within(reach)), 0.999 * np.asarray(
        profile.total_reflectance), rtol=1e-4)
