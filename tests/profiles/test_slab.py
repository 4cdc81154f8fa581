"""The path-traced slab that validates the profiles: the tally against Mitsuba's volpathmis, exact limits, and the
normalization of Eq. 1 checked on the better dipole where diffusion is exact (albedo near 1)."""

import numpy as np
import pytest

import convsss
from convsss.pipeline.reference import volpath_slab_albedo
from convsss.profiles import BetterDipoleProfile
from convsss.profiles.slab import slab_tally, tally_albedo


def test_same_seed_same_tally_whatever_the_thread_count():
    import numba

    first = slab_tally(0.9, 1.3, photons=20000, seed=3)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        again = slab_tally(0.9, 1.3, photons=20000, seed=3)
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_array_equal(first["profile"], again["profile"])
    assert slab_tally(0.9, 1.3, photons=20000, seed=4)["total"] != first["total"]


def test_single_scattering_of_an_index_matched_slab_is_exact():
    # eta = 1: a photon leaves after exactly one scattering with probability alpha (1 - ln 2) / 2
    t = slab_tally(0.5, 1.0, photons=1 << 18)
    single = np.sum(t["single"] * np.pi * np.diff(t["edges"] ** 2))
    assert single == pytest.approx(0.5 * (1 - np.log(2)) / 2, rel=0.01)


@pytest.mark.slow
def test_tally_equals_volpathmis_on_the_same_slab():
    """By reciprocity a radiance meter looking down at the slab under a uniform sky reads its normal-incidence
    albedo; a black disk of 1 mm over the meter keeps only the light leaving beyond 1 mm."""
    skin = convsss.material("skin1")
    for occluder, tolerance in ((0.0, 0.015), (1.0, 0.04)):
        path_traced = volpath_slab_albedo(skin, occluder, spp=1 << 16)
        tallied = tally_albedo(skin, occluder, photons=1 << 18)
        np.testing.assert_allclose(path_traced[:2], tallied[:2], rtol=tolerance)


@pytest.mark.slow
@pytest.mark.parametrize("eta", [1.0, 1.3, 1.5])
def test_normalization_of_eq1_on_the_better_dipole_at_high_albedo(eta):
    """At albedo 0.999 diffusion is exact away from the entry point: the better dipole's total, divided by T_d as
    every model is, must equal the slab's (within 1 %), which checks the normalization of Eq. 1 for all models."""
    t = slab_tally(0.999, eta, photons=1 << 17)
    assert BetterDipoleProfile.optical_total(0.999, eta) == pytest.approx(t["total"], rel=0.01)
