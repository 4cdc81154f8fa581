"""Hierarchical (Jensen & Buhler 2002) against the exact sum on the same samples.

The test cloud: 20 000 Fibonacci-sphere samples on a sphere of radius 4 mm, lit by a directional light plus a
banded ambient term; 500 query points on the surface. Measured (relative L2 error of the RGB exitance against the
exact sum; per query the nodes visited, nodes used whole and samples summed exactly; the skin1 lookup time of the
500 queries on 2 cores, median of 3, on a shared machine: the exact sum took 128 ms; default octree, leaf size 4:
15 538 nodes, 11 975 leaves, depth 6):

=======  ===========  ===============  =======  =====  ======  =========
epsilon  skin1 error  wholemilk error  visited  whole  summed  skin1 ms
=======  ===========  ===============  =======  =====  ======  =========
0        4e-15        4e-15             15 538      0  20 000  212
0.01     1.7e-4       1.2e-4             3 937  1 290   3 527   58
0.02     5.7e-4       4.2e-4             2 424    974   1 882   34
0.05     1.9e-3       1.6e-3             1 167    547     777   16
0.1      4.1e-3       4.0e-3               655    330     398    9.1
0.2      8.1e-3       9.5e-3               360    194     198    5.0
0.5      2.0e-2       2.7e-2               177    106      79    2.4
1        3.8e-2       5.4e-2                93     57      40    1.3
=======  ===========  ===============  =======  =====  ======  =========
"""

import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.materials import material
from convsss.profiles import model_profile
from convsss.samples import IrradianceSamples
from convsss.transport import HierarchicalTransport, make_transport
from convsss.transport.exact import ExactTransport

EPSILONS = (0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)


def lit_sphere(n=20000, radius=4.0):
    """Fibonacci points on a sphere, each with an equal share of its area, and a non-uniform irradiance."""
    i = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / n)
    azimuth = np.pi * (1.0 + 5.0**0.5) * i
    normal = np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1)
    light = np.array([0.6, 0.3, 0.74]) / np.linalg.norm([0.6, 0.3, 0.74])
    banded = 0.05 * (1.0 + np.sin(5 * normal[:, :1]))
    irradiance = np.clip(normal @ light, 0.0, None)[:, None] * [1.0, 0.8, 0.6] + banded
    return IrradianceSamples(radius * normal, np.full(n, 4.0 * np.pi * radius**2 / n), irradiance, normal)


@pytest.fixture(scope="module")
def sphere():
    return lit_sphere()


def relative_error(samples, name, epsilons, query):
    profile = model_profile("dipole", material(name))
    exact = ExactTransport(samples, profile).exitance(query)
    errors, visits = [], []
    for eps in epsilons:
        transport = HierarchicalTransport(samples, profile, epsilon=eps)
        errors.append(np.linalg.norm(transport.exitance(query) - exact) / np.linalg.norm(exact))
        visits.append(transport.stats["nodes_visited_per_query"])
    return np.array(errors), np.array(visits)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["skin1", "wholemilk"])
def test_matches_exact_and_error_rises_with_epsilon(sphere, name):
    errors, visits = relative_error(sphere, name, EPSILONS, sphere.position[::40])
    assert errors[0] < 1e-12  # epsilon 0: every leaf summed exactly
    assert np.all(errors[1:5] < 0.01)  # within 1 % for epsilon <= 0.1
    assert errors[-1] < 0.1
    assert np.all(np.diff(errors) > 0)  # smooth, monotone trade-off
    assert np.all(np.diff(visits) < 0)  # and it buys speed: fewer nodes per query
    ratios = errors[2:] / errors[1:-1]
    assert np.all((ratios > 1.2) & (ratios < 10.0))  # no jumps


def test_query_points_off_the_surface(sphere):
    direction = sphere.normal[::97]
    query = np.concatenate([3.0 * direction, 4.5 * direction, 20.0 * direction])
    errors, _ = relative_error(sphere, "marble", (0.0, 0.05), query)
    assert errors[0] < 1e-12 and errors[1] < 0.01


def test_single_sample_is_the_profile():
    profile = model_profile("dipole", material("apple"))
    samples = IrradianceSamples([[1.0, 2.0, 3.0]], [0.5], [[2.0, 1.0, 4.0]])
    query = np.array([[1.0, 2.0, 3.0], [1.5, 2.0, 3.0], [1.0, 4.0, 3.0]])
    m = HierarchicalTransport(samples, profile, epsilon=0.2).exitance(query)
    r = np.linalg.norm(query - [1.0, 2.0, 3.0], axis=1)
    np.testing.assert_allclose(m, profile(r) * [1.0, 0.5, 2.0], rtol=1e-4)


def test_registered_with_stats(sphere):
    profile = model_profile("dipole", material("skin1"))
    transport = make_transport("hierarchical", sphere, profile, frame=None, epsilon=0.1, leaf_size=4)
    assert isinstance(transport, HierarchicalTransport)
    transport.exitance(sphere.position[:300])
    stats = transport.stats
    assert stats["transport"] == "hierarchical" and stats["epsilon"] == 0.1 and stats["leaf_size"] == 4
    assert stats["queries"] == 300
    assert stats["octree"]["nodes"] == len(transport.octree) and stats["octree"]["depth"] >= 1
    assert 1 <= stats["nodes_visited_per_query"] < stats["octree"]["nodes"]
    assert {"octree", "lookup"} <= set(stats["seconds"])


@pytest.mark.parametrize("eps", [-0.1, float("nan")])
def test_bad_epsilon(sphere, eps):
    with pytest.raises(ConvsssError, match="epsilon"):
        HierarchicalTransport(sphere, model_profile("dipole", material("skin1")), epsilon=eps)
