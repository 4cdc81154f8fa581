"""Points on a shape's surface (convsss.pipeline.surface): uniform, stratified, Morton-ordered faces on a mesh."""

import drjit as dr
import numpy as np
import pytest


@pytest.fixture(scope="module")
def surface(mi):
    from convsss.pipeline import surface

    return surface


def _points(surface, scene, count=2000, seed=1):
    p, n, area = surface.sample_surface(scene.shapes()[0], count, seed)
    return p, n, dr.width(area), dr.ravel(p).numpy().reshape(-1, 3).astype(np.float64)


def test_stratified_points_cover_the_sphere_uniformly(mi, surface):
    scene = mi.load_dict({"type": "scene", "s": {"type": "sphere", "radius": 1.0}})
    _, n, size, p = _points(surface, scene, 1000)
    assert size == 32 * 32
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 1.0, atol=1e-5)
    normals = dr.ravel(n).numpy().reshape(-1, 3)
    np.testing.assert_allclose(normals, p, atol=1e-4)
    # Uniform on a sphere: z is uniform in [-1, 1] (Archimedes); stratification keeps every bin close to its share.
    counts = np.histogram(p[:, 2], bins=8, range=(-1, 1))[0]
    assert np.all(np.abs(counts - size / 8) < 0.1 * size / 8)


def _voxel_count_spread(surface, shape, seeds, side):
    """``var(c_0 - c_1) / (2 mean c)`` over voxels of ``side`` of the point counts of two seeds: 1 for independent
    uniform points (Poisson counts), less for stratified ones."""
    points = [dr.ravel(surface.sample_surface(shape, 20_000, s)[0]).numpy().reshape(-1, 3) for s in seeds]
    keys = [np.floor(p / side).astype(np.int64) for p in points]
    cells, inverse = np.unique(np.concatenate(keys), axis=0, return_inverse=True)
    inverse = inverse.ravel()
    counts = [np.bincount(inverse[:len(keys[0])], minlength=len(cells)),
              np.bincount(inverse[len(keys[0]):], minlength=len(cells))]
    return float(np.var(counts[0] - counts[1]) / (2 * np.mean(counts[0])))


def test_mesh_points_are_stratified_in_space(mi, surface, monkeypatch):
    """The bunny's faces are not in spatial order in its file: the grid over the square leaves Poisson-like counts
    per voxel (measured 0.95-1.03 over four pairs of seeds); ordering the faces along a Morton curve stratifies them
    (measured 0.22-0.24), and every point stays uniform over the area (octant shares)."""
    from convsss.scene.quick import demo_mesh

    shape = mi.load_dict({"type": "obj", "filename": str(demo_mesh())})
    side = 0.2  # the bunny is 3 units wide: about 28 of 20 000 points per voxel
    assert _voxel_count_spread(surface, shape, (1, 2), side) < 0.5
    monkeypatch.setattr(surface, "MESH_STRATIFICATION", False)
    assert _voxel_count_spread(surface, shape, (1, 2), side) > 0.8
    monkeypatch.setattr(surface, "MESH_STRATIFICATION", True)
    # Unbiased: the share of the points in each octant of the bounding box is that of the area (the faces' own,
    # split by their centroids, to well within the points' spread).
    params = mi.traverse(shape)
    vertex = np.asarray(params["vertex_positions"], dtype=np.float64).reshape(-1, 3)
    face = np.asarray(params["faces"], dtype=np.int64).reshape(-1, 3)
    a, b, c = vertex[face[:, 0]], vertex[face[:, 1]], vertex[face[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    centre = 0.5 * (vertex.min(axis=0) + vertex.max(axis=0))

    def octant(p):
        return ((p > centre) * [1, 2, 4]).sum(axis=1)

    expected = np.bincount(octant((a + b + c) / 3), area, 8) / area.sum()
    points = np.concatenate([dr.ravel(surface.sample_surface(shape, 20_000, s)[0]).numpy().reshape(-1, 3)
                             for s in range(4)])
    share = np.bincount(octant(points), minlength=8) / len(points)
    np.testing.assert_allclose(share, expected, atol=0.004)
