"""The exitance table on a mesh's vertices and face centroids (Eq. V2): exact where ``M`` is linear or quadratic
enough, the transport's own values on faces that do not resolve ``M``, filled only where hits outnumber its queries,
and a render that matches the transport's."""

from types import SimpleNamespace

import numpy as np
import pytest

import convsss
from convsss.media.dicts import translucent
from convsss.pipeline.mesh_exitance import TOLERANCE, MeshExitance, usable


def icosphere(subdivisions, radius=1.0):
    """Vertices (V, 3) and outward-wound faces (F, 3) of an icosahedron subdivided ``subdivisions`` times."""
    t = (1.0 + 5**0.5) / 2.0
    vertex = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
              (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    face = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
            (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
            (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    vertex = [np.array(v, dtype=np.float64) / np.linalg.norm(v) for v in vertex]
    middle = {}

    def mid(i, j):
        key = (min(i, j), max(i, j))
        if key not in middle:
            m = vertex[i] + vertex[j]
            vertex.append(m / np.linalg.norm(m))
            middle[key] = len(vertex) - 1
        return middle[key]

    for _ in range(subdivisions):
        finer = []
        for a, b, c in face:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            finer += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        face = finer
    return np.array(vertex) * radius, np.array(face, dtype=np.int64)


def _mesh_object(mi, subdivisions, to_world=None, inward=False):
    """An icosphere as a translucent object's mesh, wound outwards (or inwards, ``orientation`` -1)."""
    vertex, face = icosphere(subdivisions)
    face = face[:, ::-1].copy() if inward else face
    mesh = mi.Mesh("ico", len(vertex), len(face))
    params = mi.traverse(mesh)
    params["vertex_positions"] = vertex.astype(np.float32).ravel()
    params["faces"] = face.astype(np.uint32).ravel()
    params.update()
    return SimpleNamespace(shape=mesh, to_world=np.identity(4) if to_world is None else to_world,
                           orientation=-1.0 if inward else 1.0), vertex, face


class Counted:
    """A transport of exitance ``field(points)`` that counts its queries and checks the normals point outwards."""

    def __init__(self, field, centre=(0.0, 0.0, 0.0)):
        self.field, self.centre, self.queries = field, np.asarray(centre), 0

    def __call__(self, points, normals):
        assert np.all(np.einsum("ij,ij->i", points - self.centre, normals) > 0)
        self.queries += len(points)
        return self.field(points)


def _hits(vertex, face, count, seed=0):
    rng = np.random.default_rng(seed)
    faces = rng.integers(0, len(face), count)
    b = rng.dirichlet((1.0, 1.0, 1.0), count)
    points = np.einsum("ki,kij->kj", b, vertex[face[faces]])
    normals = points / np.linalg.norm(points, axis=1, keepdims=True)
    return faces, points, normals


def test_a_linear_exitance_is_reproduced_on_every_face(mi):
    obj, vertex, face = _mesh_object(mi, 2)
    field = Counted(lambda p: np.stack([1.0 + 0.1 * p[:, 0], 2.0 - 0.2 * p[:, 1], 3.0 + 0.05 * p[:, 2]], axis=1))
    table = MeshExitance(obj, field, unit_mm=1.0)
    faces, points, normals = _hits(vertex, face, 20 * len(face))
    got = table(faces, points, normals)
    assert table.known[np.unique(faces)].all()
    assert field.queries == table.queries <= len(vertex) + len(face)
    np.testing.assert_allclose(got, field.field(points), rtol=1e-6)  # the mesh holds float32 vertices


def test_faces_that_do_not_resolve_the_exitance_are_left_to_the_transport(mi):
    """A narrow peak (0.3 wide on a unit sphere of faces about 0.3 across): the faces near it fail the bubble's test
    and their hits get the transport's own values; far from it, ``M`` is flat and every face is interpolated."""
    obj, vertex, face = _mesh_object(mi, 3)
    peak = np.array([0.0, 0.0, 1.0])

    def field(p):
        m = 1.0 + 5.0 * np.exp(-np.sum((p - peak) ** 2, axis=1) / 0.3**2)
        return np.stack([m, m, m], axis=1)

    table = MeshExitance(obj, Counted(field), unit_mm=1.0)
    faces, points, normals = _hits(vertex, face, 20 * len(face))
    got = table(faces, points, normals)
    expected = field(points)
    centroid = vertex[face].mean(axis=1)
    near = np.linalg.norm(centroid - peak, axis=1) < 0.3
    far = np.linalg.norm(centroid - peak, axis=1) > 1.0
    assert not table.known[near].all() and table.known[far].all()
    unknown = ~table.known[faces]
    np.testing.assert_array_equal(got[unknown], expected[unknown])
    # Where Eq. V2 is used its error is of the order of the bubble it was allowed: the bubble estimates the error, it
    # does not bound it (measured: mean 0.04 %, 99th percentile 1.1 %, largest 4.8 % with TOLERANCE 2 %).
    error = np.abs(got[~unknown] / expected[~unknown] - 1)
    assert error.mean() < TOLERANCE / 10
    assert np.quantile(error, 0.99) < TOLERANCE
    assert error.max() < 3 * TOLERANCE


def test_the_table_is_filled_only_where_hits_outnumber_its_queries(mi):
    obj, vertex, face = _mesh_object(mi, 3)
    field = Counted(lambda p: np.ones((len(p), 3)))
    table = MeshExitance(obj, field, unit_mm=1.0)
    faces, points, normals = _hits(vertex, face, 50)  # 50 hits on about 50 faces: 4 queries a hit to fill
    table(faces, points, normals)
    assert table.queries == 0 and field.queries == 50
    faces = np.full(200, 7)  # 200 hits on one face: 4 queries fill it
    points = np.repeat(vertex[face[7]].mean(axis=0, keepdims=True), 200, axis=0)
    table(faces, points, points)
    assert table.queries == 4 and field.queries == 54
    assert table.filled.sum() == 1


@pytest.mark.parametrize("mirrored", [False, True])
def test_instance_maps_and_inward_winding_keep_the_queries_outward(mi, mirrored):
    """Vertices placed by the object's map, mm per unit applied, and the queries' normals outward whatever the
    winding (``orientation`` -1 for a mesh wound inwards) and a mirroring map (Counted checks them)."""
    vertex, face = icosphere(1)
    matrix = np.diag([-2.0 if mirrored else 2.0, 2.0, 2.0, 1.0])
    matrix[:3, 3] = [1.0, 2.0, 3.0]
    obj, _, _ = _mesh_object(mi, 1, to_world=matrix)
    centre = np.array([1.0, 2.0, 3.0]) * 10.0
    table = MeshExitance(obj, Counted(lambda p: np.ones((len(p), 3)), centre=centre), unit_mm=10.0)
    np.testing.assert_allclose(table.vertex, (vertex @ matrix[:3, :3].T + matrix[:3, 3]) * 10.0, atol=1e-5)
    table(np.repeat(np.arange(len(face)), 8), np.repeat(table.vertex[face].mean(axis=1), 8, axis=0), None)
    assert table.filled.all()
    inward, _, _ = _mesh_object(mi, 1, inward=True)
    table = MeshExitance(inward, Counted(lambda p: np.ones((len(p), 3))), unit_mm=1.0)
    table(np.repeat(np.arange(len(face)), 8), np.repeat(vertex[face].mean(axis=1), 8, axis=0), None)
    assert table.filled.all()


@pytest.mark.slow
def test_render_with_the_mesh_table_matches_the_transport(mi, sphere_scene, tmp_path, monkeypatch):
    """A 4 mm wholemilk icosphere (5 k faces) on a floor at 16 spp: the floor's view of it and the indirect paths
    that come back to it read the table (measured: 3.5 k transport queries against 6.3 k without); the same render
    with the transport alone agrees within 0.1 % over the object and the floor."""
    import convsss.pipeline.lookups as lookups_module

    vertex, face = icosphere(4, radius=2.0)
    path = tmp_path / "ico.obj"
    path.write_text("".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in vertex)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in face))
    scene_dict = sphere_scene(material="wholemilk", radius=2.0, res=96, spp=16, floor=True)
    scene_dict["object"] = translucent({"type": "obj", "filename": str(path), "face_normals": True},
                                       convsss.material("wholemilk"), boundary="null")
    scene = mi.load_dict(scene_dict)
    with_table = np.asarray(mi.render(scene, seed=1))
    lookups = scene.integrator().stats["exitance_lookups"]

    class Bypassed(lookups_module.MeshExitance):
        def __call__(self, faces, points, normals):
            return self.exitance(points, normals)

    monkeypatch.setattr(lookups_module, "MeshExitance", Bypassed)
    without = np.asarray(mi.render(scene, seed=1))
    assert scene.integrator().stats["exitance_lookups"] > lookups
    mask = without.sum(axis=2) > 0
    ratio = with_table[mask].sum(axis=0) / without[mask].sum(axis=0)
    np.testing.assert_allclose(ratio, 1.0, atol=1e-3)


def test_a_table_that_does_not_fit_in_memory_is_not_made(mi, monkeypatch):
    import convsss.memory

    obj, _, _ = _mesh_object(mi, 2)
    assert usable(obj)
    monkeypatch.setattr(convsss.memory, "available_memory", lambda: 10_000)
    assert not usable(obj)
    assert not usable(SimpleNamespace(shape=mi.load_dict({"type": "sphere"})))
