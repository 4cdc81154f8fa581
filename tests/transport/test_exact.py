import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.materials import material
from convsss.profiles import TabulatedProfile, model_profile
from convsss.samples import IrradianceSamples
from convsss.transport import ExactTransport, make_transport


@pytest.fixture
def cloud():
    rng = np.random.default_rng(1)
    pos = rng.normal(scale=2.0, size=(3000, 3))
    return IrradianceSamples(pos, rng.uniform(0.01, 0.02, 3000), rng.random((3000, 3)))


@pytest.mark.parametrize("name", ["skin1", "wholemilk", "spectralon"])
def test_direct_sum_matches_numpy(cloud, name):
    profile = model_profile("dipole", material(name))
    query = cloud.position[::60] + 0.1
    distance = np.linalg.norm(query[:, None] - cloud.position[None], axis=-1)
    expected = np.einsum("kic,ic->kc", profile(distance), cloud.flux)
    np.testing.assert_allclose(ExactTransport(cloud, profile).exitance(query), expected, rtol=1e-4)


def test_any_profile_plugs_in(cloud):
    r = np.linspace(0, 5, 50)
    profile = TabulatedProfile(r, np.exp(-r)[:, None] * [1.0, 0.5, 0.25])
    query = cloud.position[:20]
    expected = np.einsum("kic,ic->kc", profile(np.linalg.norm(query[:, None] - cloud.position[None], axis=-1)),
                         cloud.flux)
    np.testing.assert_allclose(make_transport("exact", cloud, profile).exitance(query), expected, rtol=1e-4,
                               atol=1e-12)


def test_unknown_transport(cloud):
    with pytest.raises(ConvsssError, match="unknown transport 'fft'"):
        make_transport("fft", cloud, model_profile("dipole", material("skin1")))
