"""Points on a shape's surface, each standing for an equal share of its area: the places of the irradiance samples
(paper §4.1: "light is sampled from the front and the back").

``N = k^2`` points of ``[0,1]^2`` are mapped through Mitsuba's ``shape.sample_position`` (area-proportional), so each
sample stands for the same area ``A_i = A / N``; the points are a jittered ``k x k`` grid for an analytic shape, and
for a mesh stratified along a space-filling curve over its faces (:func:`mesh_square`: a mesh file's face order is not
spatial, and a grid would leave the points as clumped as independent ones, whose noise the sum of Eq. 1 inherits); an
instanced shape is sampled in its shapegroup's space and mapped by the instance's transform, which scales ``A_i`` by
the map's area element (:func:`sample_surface`). Also the mesh's own arrays (:func:`mesh_arrays`), which the plan,
the mesh exitance table and the painted media read.
"""

import math

import drjit as dr
import numpy as np

from ..backend import import_mitsuba
from ..morton import MORTON_BITS, interleave

mi = import_mitsuba()

#: The golden ratio's fractional part: the rank-1 lattice of the points within a face.
GOLDEN = 0.5 * (math.sqrt(5.0) - 1.0)
#: Whether meshes are sampled by :func:`mesh_square` (False: the plain grid; kept for measuring the difference).
MESH_STRATIFICATION = True


def stratified_square(count, seed, stream=0):
    """A jittered ``k x k`` grid in ``[0,1]^2`` with ``k = ceil(sqrt(count))`` (so ``k^2 >= count`` points)."""
    k = max(1, math.ceil(math.sqrt(count)))
    n = k * k
    index = dr.arange(mi.UInt32, n)
    rng = mi.PCG32(n, dr.opaque(mi.UInt64, (int(seed) * 0x9E3779B9 + stream) % 2**64), dr.arange(mi.UInt64, n))
    u = (mi.Float(index % k) + rng.next_float32()) / k
    v = (mi.Float(index // k) + rng.next_float32()) / k
    return mi.Point2f(u, v)


def morton_order(points):
    """The order of ``points`` (N, 3) along a Morton (Z-order) curve over their bounding box (21 bits per axis): any
    run of consecutive points in it lies in a few octree cells, so a run is a compact region."""
    lo = points.min(axis=0)
    extent = max(float(np.max(points.max(axis=0) - lo)), 1e-300)
    cells = np.minimum((points - lo) / extent * (1 << MORTON_BITS), (1 << MORTON_BITS) - 1).astype(np.uint64)
    return np.argsort(interleave(cells), kind="stable")


def has_vertices(shape):
    """Whether ``shape`` is a triangle mesh with vertex arrays (Mitsuba's rectangle says it is a mesh, and has
    none: it maps the unit square continuously, as analytic shapes do)."""
    return bool(shape.is_mesh()) and "vertex_positions" in mi.traverse(shape)


def mesh_arrays(shape):
    """A Mitsuba mesh's vertices (V, 3) float64, in its own space, and faces (F, 3) int64."""
    params = mi.traverse(shape)
    return (np.asarray(params["vertex_positions"], dtype=np.float64).reshape(-1, 3),
            np.asarray(params["faces"], dtype=np.int64).reshape(-1, 3))


def mesh_square(shape, count, seed, stream=0):
    """Points of ``[0,1]^2`` (``k^2 >= count`` of them, as :func:`stratified_square`) that Mitsuba's
    ``mesh.sample_position`` maps to points stratified over the mesh's surface at the scale of its faces or finer.

    ``sample_position`` picks the face by the second coordinate through the faces' area CDF in the file's order and
    reuses what is left of it inside the face; a file's face order is not spatial (on the bunny, 10 % of consecutive
    faces are more than half the mesh apart), so a grid over the square leaves the points as clumped as independent
    ones at the scale of a few faces. Here the faces are ordered along a Morton curve of their centroids
    (:func:`morton_order`), and ``t_i = (i + xi_i) / N`` is stratified along the area CDF in that order: every run of
    consecutive faces, hence every compact patch, gets its share of the ``N`` points to within one. ``t_i``'s place in
    its face's interval, ``r``, is carried over to the face's interval of the file's CDF (the second coordinate); the
    first, which sets the distance from the face's first vertex, is ``frac(s_f + j phi)`` for the ``j``-th point of
    face ``f`` (``s_f`` uniform per face, ``phi`` the golden ratio), a rank-1 lattice with ``r``, so the points within a
    large face are spread in both directions. Each point is uniform over the surface, so every estimate stays
    unbiased.
    """
    vertex, face = mesh_arrays(shape)
    a, b, c = vertex[face[:, 0]], vertex[face[:, 1]], vertex[face[:, 2]]
    pmf = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    pmf /= pmf.sum()
    file_cdf = np.concatenate([[0.0], np.cumsum(pmf)])
    order = morton_order((a + b + c) / 3.0)
    curve_cdf = np.concatenate([[0.0], np.cumsum(pmf[order])])
    k = max(1, math.ceil(math.sqrt(count)))
    n = k * k
    rng = np.random.default_rng([int(seed), int(stream), 0x5A3F])
    t = (np.arange(n) + rng.random(n)) / n
    # searchsorted(side="right") never lands in a zero-area face (an empty interval).
    slot = np.clip(np.searchsorted(curve_cdf, t, side="right") - 1, 0, len(face) - 1)
    picked = order[slot]
    r = np.clip((t - curve_cdf[slot]) / pmf[picked], 0.0, 1.0)
    index = np.arange(n)
    run_start = np.maximum.accumulate(np.where(np.r_[True, slot[1:] != slot[:-1]], index, 0))
    rank = index - run_start  # slot is sorted: the point's rank within its face
    x = (rng.random(len(face))[picked] + rank * GOLDEN) % 1.0
    y = file_cdf[picked] + r * pmf[picked]
    return mi.Point2f(np.minimum(x, np.nextafter(1.0, 0.0)).astype(np.float32),
                      np.minimum(y, np.nextafter(1.0, 0.0)).astype(np.float32))


def surface_square(shape, count, seed, stream=0):
    """The points of ``[0,1]^2`` that ``shape.sample_position`` maps to stratified surface points: :func:`mesh_square`
    for a mesh, else the jittered grid of :func:`stratified_square` (analytic shapes map the square continuously,
    :func:`has_vertices`)."""
    if MESH_STRATIFICATION and has_vertices(shape):
        return mesh_square(shape, count, seed, stream)
    return stratified_square(count, seed, stream)


def sample_surface(shape, count, seed, orientation=1.0, stream=0, to_world=None):
    """About ``count`` stratified uniform points on ``shape`` placed by the affine map ``to_world``:
    ``(position, outward normal, area)`` in scene units, ``area`` the world area each sample stands for.

    ``to_world`` (4x4, identity when None) is an instance's transform: a plain shape's points are already in world
    space, an instanced shape is sampled in its shapegroup's space. With ``M`` its linear part, points map by
    ``to_world``, normals by ``M^{-T}`` (renormalized), and an area element with unit geometric normal ``g`` scales
    by ``|det M| |M^{-T} g|``, so each of the ``N`` samples of a shape of area ``A`` covers

        A_i = (A / N) |det M| |M^{-T} g_i|,

    and ``sum_i A_i`` estimates the world area (exact for a similarity, e.g. the identity). ``orientation`` (+1/-1)
    flips the shape's normals to point outwards; ``M^{-T}`` keeps them outward, also for a mirroring map
    (``det M < 0``).
    """
    matrix = np.identity(4) if to_world is None else np.asarray(to_world, dtype=np.float64)
    transform = mi.Transform4f(matrix)
    u = surface_square(shape, count, seed, stream)
    ps = shape.sample_position(0.0, u)
    position = transform @ mi.Point3f(ps.p)
    normal = mi.Vector3f(dr.normalize(transform @ mi.Normal3f(ps.n * orientation)))
    local_area = float(np.asarray(shape.surface_area()).reshape(-1)[0]) / dr.width(u)
    stretch = dr.norm(transform @ mi.Normal3f(_geometric_normal(shape, u, ps.n, matrix[:3, :3])))
    area = local_area * abs(float(np.linalg.det(matrix[:3, :3]))) * stretch
    # A flat shape (disk, rectangle) has one normal for all its points: give every sample its own entry.
    n = dr.width(u)
    normal, area = normal + dr.zeros(mi.Vector3f, n), area + dr.zeros(mi.Float, n)
    dr.eval(position, normal, area)
    return position, normal, area


def area_scale(linear):
    """``s^2`` when the linear map is a similarity (``M^T M = s^2 I``: every area element scales by ``s^2``), else
    None (the scale depends on the surface's orientation)."""
    gram = linear.T @ linear
    scale = np.trace(gram) / 3
    return float(scale) if np.allclose(gram, scale * np.identity(3), rtol=0, atol=1e-6 * np.trace(gram)) else None


def _geometric_normal(shape, u, normal, linear):
    """The unit geometric normal at the points ``shape.sample_position(0, u)``, whose normals are ``normal``, as far
    as the area element of ``linear`` depends on it.

    A similarity (``M^T M = s^2 I``) scales every area element by ``s^2``: ``normal`` will do. So does the normal of
    an analytic shape or of a mesh without vertex normals; a mesh with vertex normals interpolates them, so the same
    points are drawn again from a copy of the mesh without them (same vertices and faces, same area PMF).
    """
    if area_scale(linear) is not None or not (shape.is_mesh() and shape.has_vertex_normals()):
        return normal
    faceted = mi.Mesh("faceted", shape.vertex_count(), shape.face_count())
    source, params = mi.traverse(shape), mi.traverse(faceted)
    params["vertex_positions"] = source["vertex_positions"]
    params["faces"] = source["faces"]
    params.update()
    return faceted.sample_position(0.0, u).n
