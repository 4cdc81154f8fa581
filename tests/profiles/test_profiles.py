import numpy as np
import pytest
from scipy.integrate import quad

from convsss.errors import ConvsssError
from convsss.materials import catalog
from convsss.profiles import DipoleProfile, TabulatedProfile, model_profile

# shared/data/materials/README.md: check values of the classic dipole, "4 significant digits".
CHECK = {
    "Skimmilk R": ((0.70, 0.0014, 1.3), [0.040823, 0.034572, 0.023144, 0.0091904, 0.0016623], 0.81495),
    "Marble R": ((2.19, 0.0021, 1.5), [0.39075, 0.12545, 0.034847, 0.0090938, 0.0012667], 0.83019),
    "Ketchup R": ((0.18, 0.061, 1.3), [0.0027199, 0.0026543, 0.0024714, 0.0019036, 0.00055703], 0.16384),
    "Skin1 G": ((0.88, 0.17, 1.3), [0.062824, 0.042161, 0.018234, 0.0034159, 0.00010255], 0.22733),
}
RADII = np.array([0.0, 0.5, 1.0, 2.0, 5.0])


@pytest.mark.parametrize("case", CHECK)
def test_dipole_check_values(case):
    (s, a, eta), values, total = CHECK[case]
    p = DipoleProfile(s, a, eta)
    np.testing.assert_allclose(p(RADII)[:, 0], values, rtol=5e-4)
    assert p.total_reflectance[0] == pytest.approx(total, rel=5e-4)


def _numeric_total(p, c):
    # ∫ 2 pi r R_d(r) dr in log r (r = e^u, dr = r du), which resolves both the peak and the long tail.
    def integrand(u):
        r = np.exp(u)
        return 2 * np.pi * r * r * p(r)[c]

    head = quad(lambda r: 2 * np.pi * r * p(r)[c], 0, 1e-6)[0]
    tail = quad(integrand, np.log(1e-6), np.log(1e6), limit=500, epsabs=0, epsrel=1e-10)[0]
    return head + tail


@pytest.mark.parametrize("m", [m for m in catalog() if np.all(m.sigma_a > 0) and np.all(m.sigma_s_prime > 0)],
                         ids=lambda m: m.name)
def test_integral_of_profile_equals_closed_form(m):
    p = model_profile("dipole", m)
    for c in range(3):
        assert _numeric_total(p, c) == pytest.approx(p.total_reflectance[c], rel=1e-4)


def test_energy_within_is_the_integral():
    p = DipoleProfile([2.55, 3.21, 3.77], [0.0011, 0.0024, 0.014], 1.3)
    for radius in (0.1, 1.0, 10.0):
        numeric = quad(lambda r: 2 * np.pi * r * p(r)[1], 0, radius, limit=200)[0]
        assert p.energy_within(radius)[1] == pytest.approx(numeric, rel=1e-8)
    np.testing.assert_allclose(p.energy_within(np.inf), p.total_reflectance, rtol=1e-12)


def test_no_absorption_spectralon():
    p = DipoleProfile([11.6, 20.4, 14.9], 0.0, 1.3)
    assert np.all(np.isfinite(p(np.array([0.0, 1.0, 1e3]))))
    np.testing.assert_allclose(p.total_reflectance, 1.0)
    r_e = p.radius_energy(0.01)
    assert np.all(np.isfinite(r_e)) and np.all(r_e > 0)
    np.testing.assert_allclose(np.diagonal(p.energy_within(r_e)), 0.99, rtol=1e-6)


def test_threshold_and_energy_radii():
    p = DipoleProfile([0.74, 0.88, 1.01], [0.032, 0.17, 0.48], 1.3)
    d_t = p.radius_below(1e-3)
    np.testing.assert_allclose(np.diagonal(p(d_t)), 1e-3 * p(0.0), rtol=1e-6)
    r_f = p.radius_energy(1e-3)
    np.testing.assert_allclose(np.diagonal(p.energy_within(r_f)), 0.999 * p.total_reflectance, rtol=1e-6)
    assert np.all(p.radius_below(0.05) < d_t)  # a larger threshold reaches less far (paper Eq. 8)
    with pytest.raises(ConvsssError, match="threshold"):
        p.radius_below(-0.1)


def _dipole_table(p, n=300, r_max=200.0):
    r = np.concatenate([[0.0], np.geomspace(1e-3, r_max, n)])
    return r, p(r)


def test_tabulated_dipole_reproduces_dipole():
    p = DipoleProfile([2.55, 3.21, 3.77], [0.0011, 0.0024, 0.014], 1.3)
    t = TabulatedProfile(*_dipole_table(p))
    r = np.linspace(0, 30, 2001)
    np.testing.assert_allclose(t(r), p(r), rtol=1e-4)
    np.testing.assert_allclose(t.total_reflectance, p.energy_within(200.0), rtol=1e-4)
    np.testing.assert_allclose(t.radius_below(1e-3), p.radius_below(1e-3), rtol=1e-3)
    np.testing.assert_allclose(t.radius_energy(1e-2), p.radius_energy(1e-2), rtol=1e-3)
    assert np.all(t(np.array([250.0])) == 0)  # zero past the table


def test_tabulated_zero_tail_and_csv(tmp_path):
    r = np.array([0.0, 1.0, 2.0, 3.0])
    v = np.array([[1.0, 1.0, 1.0], [0.5, 0.5, 0.2], [0.1, 0.0, 0.05], [0.0, 0.0, 0.0]])
    t = TabulatedProfile(r, v)
    out = t(np.array([0.0, 1.0, 1.5, 2.5, 3.0]))
    assert np.all(np.diff(out, axis=0) <= 1e-15) and np.all(out >= 0)
    np.testing.assert_allclose(out[:2], v[:2])
    path = tmp_path / "profile.csv"
    path.write_text("r_mm,R,G,B\n" + "\n".join(",".join(map(str, [ri, *vi])) for ri, vi in zip(r, v)))
    np.testing.assert_allclose(TabulatedProfile.from_csv(path)(r), t(r))


@pytest.mark.parametrize("r, v, message", [
    ([0, 1, 2], [1.0, 2.0, 0.5], "increases in channel R"),
    ([0, 1, 2], [1.0, -0.5, -1.0], "value -0.5"),
    ([0, 1, 2], [1.0, np.nan, 0.5], "value nan"),
    ([0, 2, 1], [1.0, 0.5, 0.2], "strictly increase"),
    ([-1, 1, 2], [1.0, 0.5, 0.2], "r=-1.0"),
    ([0, 1, 2], [0.0, 0.0, 0.0], "zero at its first radius"),
])
def test_tabulated_bad_input(r, v, message):
    with pytest.raises(ConvsssError, match=message):
        TabulatedProfile(r, v)


def test_profile_csv_bad_header(tmp_path):
    path = tmp_path / "p.csv"
    path.write_text("radius,a,b,c\n0,1,1,1\n1,0.5,0.5,0.5\n")
    with pytest.raises(ConvsssError, match="header"):
        TabulatedProfile.from_csv(path)
    with pytest.raises(ConvsssError, match="does not exist"):
        TabulatedProfile.from_csv(tmp_path / "missing.csv")


@pytest.mark.parametrize("text", ["r_mm,R,G\n0,1,1\n1,0.5,0.5\n", "r_mm,R,G,B\n0,1,1\n1,0.5,0.5\n"])
def test_profile_csv_with_three_columns(tmp_path, text):
    path = tmp_path / "p.csv"
    path.write_text(text)
    with pytest.raises(ConvsssError, match="has 3 columns: a profile needs 4 columns r_mm, R, G, B"):
        TabulatedProfile.from_csv(path)


def test_profile_csv_that_is_not_text(tmp_path):
    path = tmp_path / "p.exr"
    path.write_bytes(b"v/1\x01\x02\x00\x00\x00channels\x00chlist\x00\x80\xff\xfe" * 8)
    with pytest.raises(ConvsssError, match="is not a CSV") as info:
        TabulatedProfile.from_csv(path)
    assert "\n" not in str(info.value)


def test_effective_area_of_a_gaussian_profile():
    """``(∫R dA)^2 / ∫R^2 dA = 4 pi s^2`` for ``R = exp(-r^2 / 2 s^2)``; cutting the peak at the radius holding 2 %
    of the energy (where R is 98 % of its peak) changes it by 0.08 %."""
    s = 0.3
    r = np.linspace(0.0, 8 * s, 4001)
    values = np.exp(-0.5 * (r / s) ** 2)[:, None] * [1.0, 2.0, 0.5]
    area = TabulatedProfile(r, values).effective_area()
    np.testing.assert_allclose(area, 4 * np.pi * s**2 / (0.98**2 * (1 - 2 * np.log(0.98))), rtol=2e-3)


def test_effective_area_of_the_dipole_shrinks_with_the_mean_free_path_squared():
    base = DipoleProfile(0.5, 0.01, 1.3)
    scaled = DipoleProfile(5.0, 0.1, 1.3)  # every length 10 times shorter
    np.testing.assert_allclose(scaled.effective_area(), base.effective_area() / 100, rtol=1e-3)


def test_a_profile_file_with_too_many_rows_is_refused_before_it_is_read_whole(tmp_path, monkeypatch):
    """Issue 30, defect 14: `convsss profile plot` of a million rows ran past 150 s; the rows are counted as read."""
    import convsss.profiles.tabulated as tabulated

    monkeypatch.setattr(tabulated, "MAX_PROFILE_ROWS", 50)
    path = tmp_path / "long.csv"
    path.write_text("r_mm,R,G,B\n" + "".join(f"{0.01 * (k + 1)},{1.0 / (k + 1)},{1.0 / (k + 1)},{1.0 / (k + 1)}\n"
                                             for k in range(51)))
    with pytest.raises(ConvsssError, match="has more than 50 rows"):
        TabulatedProfile.from_csv(path)
    path.write_text("".join(path.read_text().splitlines(keepends=True)[:51]))
    assert TabulatedProfile.from_csv(path) is not None


def test_a_radius_beyond_a_kilometre_is_refused():
    """Issue 30, defect 10: a profile CSV with a radius of 1e300 mm ended `convsss profile plot` in a matplotlib
    traceback."""
    with pytest.raises(ConvsssError, match=r"radius r=1e\+300 is not allowed: radii are in mm, finite, from 0"):
        TabulatedProfile([0.1, 1e300], [[1.0] * 3, [1e-3] * 3])
