"""The profile models beyond the classic dipole: integrals, limits, scaling, colour inversion, the profile spec."""

import numpy as np
import pytest
from scipy.integrate import quad

import convsss
from convsss.errors import ConvsssError
from convsss.fresnel import diffuse_transmittance, fresnel_moment, fresnel_reflectance
from convsss.profiles import (
    DEFAULT_PROFILE,
    PROFILE_MODELS,
    BeamDiffusionProfile,
    BetterDipoleProfile,
    BurleyProfile,
    model_profile,
)
from convsss.profiles.beam_diffusion import single_scattering
from convsss.profiles.burley import burley_values, mean_radius
from convsss.profiles.diffusion import boundary, point_source_exitance
from convsss.profiles.models import albedo_from_reflectance, albedos_from_reflectances, model_total, parse_profile_spec
from convsss.profiles.optical import CORE

pytestmark = pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")  # quad at 1e-8 on log r

NEW = [BetterDipoleProfile, BeamDiffusionProfile, BurleyProfile]
CASES = [((0.70, 0.0014, 1.3)), ((2.19, 0.0021, 1.5)), ((0.18, 0.061, 1.3)), ((0.88, 0.17, 1.0))]


def _numeric_total(p, c, core):
    # the held core in closed form, then ∫ 2 pi r^2 R d(log r) with adaptive quadrature
    head = np.pi * core**2 * p(0.0)[c]  # the constant core
    tail = quad(lambda u: 2 * np.pi * np.exp(2 * u) * p(np.exp(u))[c], np.log(core), np.log(p.support),
                limit=800, epsabs=0, epsrel=1e-8)[0]
    return head + tail


@pytest.mark.slow
@pytest.mark.parametrize("model", NEW, ids=lambda m: m.model)
@pytest.mark.parametrize("case", CASES, ids=str)
def test_integral_of_profile_equals_total_reflectance(model, case):
    s, a, eta = case
    p = model([s, 2 * s, 0.5 * s], [a, 0.5 * a, 3 * a], eta)
    for c in range(3):
        core = CORE / p.sigma_t_prime[c]
        assert _numeric_total(p, c, core) == pytest.approx(p.total_reflectance[c], rel=2e-5)
        assert p.energy_within(np.inf)[c] == pytest.approx(p.total_reflectance[c], rel=1e-12)


@pytest.mark.parametrize("albedo", [0.3, 0.9, 0.999, 1.0])
@pytest.mark.parametrize("eta", [1.0, 1.3, 1.5])
def test_better_dipole_total_matches_its_closed_form(albedo, eta):
    sampled = BetterDipoleProfile.optical_total(albedo, eta)
    assert sampled == pytest.approx(BetterDipoleProfile.closed_form_total(albedo, eta), rel=2e-4)


def test_fresnel_moments_and_diffuse_transmittance():
    assert fresnel_moment(1.0, 1) == 0.0 and diffuse_transmittance(1.0) == 1.0
    for eta in (1 / 1.5, 1 / 1.3, 1.3, 1.5):
        for n in (0, 1, 2):
            cuts = [0.0, np.sqrt(1 - eta * eta), 1.0] if eta < 1 else [0.0, 1.0]
            ref = sum(quad(lambda m, e=eta, k=n: float(fresnel_reflectance(e, m)) * m**k, a, b, epsabs=1e-15,
                           epsrel=1e-13, limit=400)[0] for a, b in zip(cuts[:-1], cuts[1:]))
            assert fresnel_moment(eta, n) == pytest.approx(ref, rel=1e-9)
    # reciprocity of the hemispherical averages: (1 - F_dr,inside) eta^2 = 1 - F_dr,outside
    for eta in (1.3, 1.5):
        assert (1 - 2 * fresnel_moment(1 / eta, 1)) * eta**2 == pytest.approx(diffuse_transmittance(eta), rel=1e-9)


def test_index_matched_boundary_has_the_classical_constants():
    c_phi, c_e, a = boundary(1.0)
    assert (c_phi, c_e, a) == (0.25, 0.5, 1.0)


@pytest.mark.parametrize("eta", [1.0, 1.3])
def test_point_source_without_absorption_sends_all_its_power_out(eta):
    # albedo 1: nothing is absorbed, so ∫ 2 pi r M dr = 1 for any depth (c_phi 2A + c_E = 1)
    for z in (0.1, 1.0, 5.0):
        total = quad(lambda u, z=z: 2 * np.pi * np.exp(2 * u) * point_source_exitance(np.exp(u), z, 1.0, eta),
                     np.log(1e-6), np.log(1e7), limit=800)[0]
        assert total == pytest.approx(1.0, abs=2e-5)


def test_single_scattering_matches_direct_integration():
    albedo, eta = 0.8, 1.3
    for r in (0.05, 0.5, 2.0):
        def f(t, r=r):
            d = np.hypot(r, t)
            return albedo * np.exp(-t - d) * (1 - fresnel_reflectance(1 / eta, t / d)) * t / (4 * np.pi * d**3)
        ref = quad(f, 0, 60, points=[r * np.sqrt(eta**2 - 1)], limit=400)[0]
        assert single_scattering(np.array([r]), albedo, eta)[0] == pytest.approx(ref, rel=1e-6)


@pytest.mark.parametrize("model", NEW, ids=lambda m: m.model)
def test_profile_scales_with_the_mean_free_path(model):
    p1 = model(0.9, 0.1, 1.3)
    p2 = model(2.7, 0.3, 1.3)  # sigma_t' three times larger: R(r) = 9 R_1(3 r)
    r = np.array([0.05, 0.3, 1.0, 4.0])
    np.testing.assert_allclose(p2(r), 9 * p1(3 * r), rtol=1e-12)
    np.testing.assert_allclose(p2.total_reflectance, p1.total_reflectance, rtol=1e-12)


def test_burley_has_the_beam_diffusion_total_and_mean_radius():
    pbd, cb = BeamDiffusionProfile(0.98, 0.02, 1.3), BurleyProfile(0.98, 0.02, 1.3)  # sigma_t' = 1
    total, d = pbd.total_reflectance[0], 0.4 * mean_radius(BeamDiffusionProfile.curve(0.98, 1.3))
    r = np.array([0.1, 1.0, 10.0])
    np.testing.assert_allclose(cb(r)[:, 0], burley_values(r, total, d), rtol=1e-6)
    # its integral is A; the constant core keeps the energy of the 1/r peak within
    assert cb.total_reflectance[0] == pytest.approx(total, rel=1e-4)
    assert mean_radius(BurleyProfile.curve(0.98, 1.3)) == pytest.approx(2.5 * d, rel=1e-3)


@pytest.mark.slow
@pytest.mark.parametrize("model", list(PROFILE_MODELS))
def test_colour_and_mfp_round_trip(model):
    color, mfp = np.array([0.8, 0.45, 0.12]), np.array([1.5, 0.8, 0.4])
    m = convsss.material_from_color(color, mfp, eta=1.3, model=model)
    np.testing.assert_allclose(m.mfp_mm, mfp, rtol=1e-12)
    np.testing.assert_allclose(model_profile(model, m).total_reflectance, color, rtol=1e-8)


@pytest.mark.parametrize("model", ["exact", "dipole"])
def test_many_colours_invert_as_one_by_one(model):
    """The table of albedos_from_reflectances: 1 - alpha' within 3e-4 relative of brentq's root, from dark colours to
    ones brighter than the table (inverted one by one), any shape; out of reach is one line."""
    values = np.concatenate([np.linspace(0.005, 0.85, 40), [0.9, 0.95]]).reshape(-1, 3, 1)
    found = albedos_from_reflectances(model, values, 1.3, where="the test's texture")
    assert found.shape == values.shape
    expected = np.array([albedo_from_reflectance(model, v.ravel(), 1.3) for v in values]).reshape(values.shape)
    np.testing.assert_allclose(1 - found, 1 - expected, rtol=3e-4)
    with pytest.raises(ConvsssError, match="the test's texture: 1 of 2 values are not reachable") as info:
        albedos_from_reflectances(model, [0.5, 0.0], 1.3, where="the test's texture")
    assert "\n" not in str(info.value)


def test_colour_out_of_reach_is_one_line_error():
    with pytest.raises(ConvsssError, match="colour 1.2 in channel R is not reachable by the pbd total"):
        albedo_from_reflectance("pbd", [1.2, 0.5, 0.5], 1.3)
    with pytest.raises(ConvsssError, match="mfp_mm"):
        convsss.material_from_color(0.5, -1.0)


def test_total_reflectance_increases_with_albedo():
    for model in PROFILE_MODELS:
        totals = [model_total(model, a, 1.3) for a in (0.2, 0.5, 0.8, 0.95, 0.99, 1.0)]
        assert np.all(np.diff(totals) > 0), model


def test_profile_spec(tmp_path):
    csv = tmp_path / "p.csv"
    csv.write_text("r_mm,R,G,B\n0,1,1,1\n1,0,0,0\n")
    assert parse_profile_spec("") == (DEFAULT_PROFILE, {}) and DEFAULT_PROFILE in PROFILE_MODELS
    assert parse_profile_spec("pbd") == ("pbd", {})
    assert parse_profile_spec(f"bunny=burley, dragon={csv}, better-dipole") == (
        "better-dipole", {"bunny": "burley", "dragon": str(csv)})
    for bad, message in [("pdb", "profile model 'pdb' is not allowed"), ("x.csv", "profile file 'x.csv' does not"),
                         ("pbd,dipole", "at most one"), ("=pbd", "no object name")]:
        with pytest.raises(ConvsssError, match=message):
            parse_profile_spec(bad)


@pytest.mark.parametrize("model", NEW, ids=lambda m: m.model)
def test_a_channel_that_does_not_scatter_returns_nothing(model):
    p = model([1.0, 1.0, 0.0], [0.1, 0.1, 0.5], 1.33)  # blue: sigma_s' = 0
    assert p.total_reflectance[2] == 0.0 and p.total_reflectance[0] > 0
    assert np.all(p([0.0, 1.0, 10.0])[:, 2] == 0.0) and p.energy_within(5.0)[2] == 0.0


def test_a_colour_is_a_reflectance_below_one_under_every_model():
    """Issue 30, defect 14: under the exact total at eta 1.3 (which reaches 1.06 at albedo 1) --color 1,1,1 was
    accepted; a surface colour is a reflectance, in (0, 1)."""
    for model in ("exact", *PROFILE_MODELS):
        with pytest.raises(ConvsssError, match=r"colour 1.0 in channel R is not reachable .* \(0, 1\.0000\)|"
                                               r"colour 1.0 in channel R is not reachable .* \(0, 0\.\d+\)"):
            albedo_from_reflectance(model, [1.0, 0.5, 0.5], 1.3)
