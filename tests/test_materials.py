import warnings

import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.materials import Material, OpticallyThinWarning, catalog, material
from convsss.profiles import model_profile

# shared/data/materials/README.md: total diffuse reflectance, 3 significant digits.
TOTALS = {
    "Apple": (0.85, 0.84, 0.53), "Cream": (0.98, 0.90, 0.72), "Ketchup": (0.16, 0.01, 0.00),
    "Marble": (0.83, 0.79, 0.75), "Potato": (0.76, 0.61, 0.21), "Skimmilk": (0.81, 0.81, 0.68),
    "Skin1": (0.44, 0.23, 0.13), "Skin2": (0.62, 0.43, 0.34), "Wholemilk": (0.91, 0.88, 0.76),
    "Chicken1": (0.31, 0.16, 0.13),
}


def test_catalog_has_all_presets():
    names = [m.name for m in catalog()]
    assert len(names) == 12 + 35 and len(set(names)) == len(names)
    assert names[0] == "Apple" and "Pacific Ocean Surface Water" in names


@pytest.mark.parametrize("name", TOTALS)
def test_published_total_reflectance(name):
    np.testing.assert_allclose(model_profile("dipole", material(name)).total_reflectance, TOTALS[name], atol=0.0051)


@pytest.mark.parametrize("query", ["wholemilk", "Whole Milk", "WHOLE-milk", " whole_milk "])
def test_lookup_ignores_case_spaces_punctuation(query):
    assert material(query).name == "Wholemilk"


def test_unknown_material_suggests_closest():
    with pytest.raises(ConvsssError, match=r"unknown material 'wholemilkk'.*'Wholemilk'"):
        material("wholemilkk")
    with pytest.raises(ConvsssError, match="unknown material"):
        material("zzzzzz")


@pytest.mark.filterwarnings("ignore::convsss.materials.OpticallyThinWarning")
def test_narasimhan_reduced_matches_unreduced():
    # The table's sigma_s' equals sigma_s (1 - g) within rounding; from_scattering must agree.
    import csv
    from importlib import resources

    text = resources.files("convsss").joinpath("data/materials/narasimhan2006.csv").read_text()
    for row in csv.DictReader(text.splitlines()):
        sigma_s = [float(row[f"sigma_s_{c}"]) for c in "rgb"]
        g = [float(row[f"g_{c}"]) for c in "rgb"]
        m = Material.from_scattering(sigma_s, material(row["name"]).sigma_a, g, 1.33, row["name"])
        np.testing.assert_allclose(m.sigma_s_prime, material(row["name"]).sigma_s_prime, rtol=0.02, atol=1e-4)


def test_from_medium_roundtrip():
    wm = material("wholemilk")
    sigma_t = wm.sigma_a + wm.sigma_s_prime
    scale = sigma_t.max()
    m = Material.from_medium(sigma_t / scale, wm.sigma_s_prime / sigma_t, scale=scale, g=0.0, eta=1.3)
    np.testing.assert_allclose(m.sigma_s_prime, wm.sigma_s_prime)
    np.testing.assert_allclose(m.sigma_a, wm.sigma_a, atol=1e-12)
    m2 = Material.from_medium(1.0, 0.9, scale=10.0, g=0.5)
    np.testing.assert_allclose(m2.sigma_s_prime, 4.5)
    np.testing.assert_allclose(m2.sigma_a, 1.0)


def test_derived_lengths():
    m = material("skin1")
    np.testing.assert_allclose(m.mfp_mm, 1 / (m.sigma_a + m.sigma_s_prime))
    np.testing.assert_allclose(m.diffusion_length_mm, 1 / np.sqrt(3 * m.sigma_a * (m.sigma_a + m.sigma_s_prime)))
    spectralon = material("spectralon")
    assert np.all(np.isinf(spectralon.diffusion_length_mm))
    assert spectralon.summary()["diffusion_length_mm"] == [None, None, None]


def test_thin_material_warns():
    with pytest.warns(OpticallyThinWarning, match="channel"):
        material("ketchup")
    with pytest.warns(OpticallyThinWarning):
        Material.from_reduced(0.1, 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        material("marble")


@pytest.mark.parametrize("kwargs, message", [
    (dict(sigma_s_prime=-1.0, sigma_a=0.1), "sigma_s' = -1.0 in channel R"),
    (dict(sigma_s_prime=[1.0, np.nan, 1.0], sigma_a=0.1), "sigma_s' = nan in channel G"),
    (dict(sigma_s_prime=1.0, sigma_a=[0.1, 0.1, np.inf]), "sigma_a = inf in channel B"),
    (dict(sigma_s_prime=1.0, sigma_a=0.1, eta=0.0), "eta"),
    (dict(sigma_s_prime=1.0, sigma_a=0.1, eta=-1.3), "eta"),
    (dict(sigma_s_prime=0.0, sigma_a=0.0), "neither scatters nor absorbs"),
])
def test_bad_coefficients(kwargs, message):
    with pytest.raises(ConvsssError, match=message):
        Material.from_reduced(**kwargs)


def test_bad_medium():
    with pytest.raises(ConvsssError, match="albedo"):
        Material.from_medium(1.0, 1.5)
    with pytest.raises(ConvsssError, match="scale"):
        Material.from_medium(1.0, 0.5, scale=0)
    with pytest.raises(ConvsssError, match="g="):
        Material.from_scattering(1.0, 0.1, g=1.0)
