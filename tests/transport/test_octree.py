import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.transport.octree import Octree, morton_codes


@pytest.fixture(params=["gaussian", "clustered"])
def cloud(request):
    rng = np.random.default_rng(3)
    if request.param == "gaussian":
        pos = rng.normal(scale=2.0, size=(5000, 3))
    else:  # dense clusters, far outliers and coincident points
        pos = np.concatenate([rng.normal(scale=1e-3, size=(2000, 3)), rng.normal(loc=50.0, size=(2000, 3)),
                              np.repeat(rng.normal(size=(1, 3)), 40, axis=0), rng.uniform(-1e3, 1e3, (10, 3))])
    return pos, rng.uniform(0.01, 0.02, len(pos)), rng.random((len(pos), 3))


@pytest.mark.parametrize("leaf_size", [1, 8, 32])
def test_every_sample_in_exactly_one_leaf(cloud, leaf_size):
    pos, area, flux = cloud
    tree = Octree.build(pos, area, flux, leaf_size)
    np.testing.assert_array_equal(np.sort(tree.order), np.arange(len(pos)))
    np.testing.assert_array_equal(tree.position, pos[tree.order])
    leaves = tree.leaves
    owner = np.zeros(len(pos), int)
    for k in leaves:
        owner[tree.start[k]:tree.end[k]] += 1
    np.testing.assert_array_equal(owner, 1)
    sizes = tree.end[leaves] - tree.start[leaves]
    assert np.all(sizes >= 1)
    codes = morton_codes(pos)[tree.order]
    for k in leaves[sizes > leaf_size]:  # only samples in one finest cell (2^-21 of the extent) overfill a leaf
        assert np.all(codes[tree.start[k]:tree.end[k]] == codes[tree.start[k]])


def test_node_sums_equal_children(cloud):
    pos, area, flux = cloud
    tree = Octree.build(pos, area, flux, 4)
    assert tree.node_area[0] == pytest.approx(area.sum(), rel=1e-12)
    np.testing.assert_allclose(tree.node_flux[0], flux.sum(axis=0), rtol=1e-12)
    for k in np.flatnonzero(tree.child_count > 0):
        children = np.arange(tree.first_child[k], tree.first_child[k] + tree.child_count[k])
        assert 2 <= len(children) <= 8
        assert np.all(children > k) and np.all(tree.depth[children] == tree.depth[k] + 1)
        assert tree.start[children[0]] == tree.start[k] and tree.end[children[-1]] == tree.end[k]
        np.testing.assert_array_equal(tree.start[children[1:]], tree.end[children[:-1]])
        assert tree.node_area[k] == pytest.approx(tree.node_area[children].sum(), rel=1e-12)
        np.testing.assert_allclose(tree.node_flux[k], tree.node_flux[children].sum(axis=0), rtol=1e-12)
        np.testing.assert_array_equal(tree.box_lo[k], tree.box_lo[children].min(axis=0))
        np.testing.assert_array_equal(tree.box_hi[k], tree.box_hi[children].max(axis=0))


def test_node_aggregates_match_their_samples(cloud):
    pos, area, flux = cloud
    tree = Octree.build(pos, area, flux, 8)
    for k in range(0, len(tree), max(1, len(tree) // 200)):
        members = slice(tree.start[k], tree.end[k])
        weight = tree.flux[members].sum(axis=1)
        np.testing.assert_allclose(tree.center[k], weight @ tree.position[members] / weight.sum(), rtol=1e-9,
                                   atol=1e-9 * np.abs(pos).max())
        np.testing.assert_array_equal(tree.box_lo[k], tree.position[members].min(axis=0))
        assert np.all(tree.center[k] >= tree.box_lo[k]) and np.all(tree.center[k] <= tree.box_hi[k])


def test_flux_free_nodes_use_the_area_weighted_position():
    pos = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.0, 1, 0]])
    tree = Octree.build(pos, [1.0, 1.0, 2.0], np.zeros((3, 3)), 8)
    assert len(tree) == 1
    np.testing.assert_allclose(tree.center[0], [0.25, 0.5, 0.0])


def test_morton_order_groups_octants():
    pos = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.0, 1, 0], [0.0, 0, 1], [1.0, 1, 1]])
    codes = morton_codes(pos)
    assert codes[0] == 0 and codes[4] == 2**63 - 1
    assert codes[1] < codes[2] < codes[3]  # x is the lowest bit of each triple


def test_stats_and_bad_leaf_size(cloud):
    pos, area, flux = cloud
    stats = Octree.build(pos, area, flux, 8).stats
    assert stats["nodes"] < 2 * len(pos) and stats["leaves"] <= len(pos) and stats["depth"] >= 1
    with pytest.raises(ConvsssError, match="leaf_size=0"):
        Octree.build(pos, area, flux, 0)
