import numpy as np
import pytest

import convsss
from convsss.errors import ConvsssError
from convsss.media.dicts import boundary_dict, medium_dict, medium_parameters, translucent


def test_sigma_t_form_fits_rgb_mode_and_round_trips():
    milk = convsss.material("wholemilk")
    p = medium_parameters(milk, unit_mm=10.0)
    assert np.max(p["sigma_t"]) == pytest.approx(1.0) and np.all(p["sigma_t"] > 0)
    sigma_t = p["sigma_t"] * p["scale"] / 10.0  # back to 1/mm
    np.testing.assert_allclose(sigma_t * p["albedo"], milk.sigma_s_prime, rtol=1e-12)
    np.testing.assert_allclose(sigma_t * (1 - p["albedo"]), milk.sigma_a, rtol=1e-9, atol=1e-15)


def test_dicts():
    milk = convsss.material("wholemilk")
    assert medium_dict(milk)["type"] == "homogeneous"
    assert boundary_dict("dielectric", 1.3)["int_ior"] == 1.3
    assert boundary_dict("null", 1.3) == {"type": "null"}
    obj = translucent({"type": "sphere"}, milk, boundary="roughdielectric")
    assert obj["bsdf"]["type"] == "roughdielectric" and obj["interior"]["scale"] > 0
    with pytest.raises(ConvsssError, match="boundary 'glass'"):
        boundary_dict("glass", 1.3)
