"""Exitance once per vertex: a mesh's ``M`` at its vertices and face centroids, interpolated over each face.

A render asks an object's transport for the exitance ``M`` of paper Eq. 7 wherever a path meets the object and the
screen table (:mod:`.screen`) does not know it: silhouettes, sides the camera does not see, the object seen from the
floor, indirect paths that come back to it. On the demo's bunny such hits far outnumber the faces they land on, in
the shading and more so in the indirect paths. Where the hits on faces outnumber their vertices and centroids, the
transport is asked instead once at each of those vertices ``v_i`` (outward normal: the area-weighted mean of its
faces') and centroids ``c``, and a hit at barycentric coordinates ``b`` in a face is given

    M(x) = sum_i b_i M(v_i) + 27 b_0 b_1 b_2 (M(c) - (1/3) sum_i M(v_i)),                             (Eq. V2)

linear interpolation plus the cubic bubble that makes it exact at the centroid. The bubble's size measures how far
``M`` is from linear over the face, so it is the face's error estimate: a face is used only where
``|M(c) - (1/3) sum_i M(v_i)| <= TOLERANCE M(c)`` in every channel (the mesh resolves ``M`` there). Hits on the other
faces, on shapes that are not meshes and on meshes whose table would not fit in memory, go to the transport.
"""

import numpy as np

from ..errors import ConvsssError
from ..jit import njit, prange
from ..memory import check_memory
from .surface import has_vertices, mesh_arrays

#: A face is interpolated (Eq. V2) when its centroid's ``M`` is within this fraction of its vertices' mean.
TOLERANCE = 0.02
#: Bytes the table holds per vertex (position, normal, ``M``, a flag) and per face (corners, bubble, two flags).
BYTES_PER_VERTEX, BYTES_PER_FACE = 73, 50
#: Faces whose normals are summed at once into their vertices' (bounds the temporaries).
CHUNK_FACES = 1 << 20


def usable(obj):
    """Whether ``obj`` can have a :class:`MeshExitance`: its shape is a mesh whose table fits in memory (else its
    hits are asked of the transport, as without a table)."""
    if not has_vertices(obj.shape):
        return False
    size = BYTES_PER_VERTEX * int(obj.shape.vertex_count()) + BYTES_PER_FACE * int(obj.shape.face_count())
    try:
        check_memory(size, "the mesh exitance table", "")
    except ConvsssError:
        return False
    return True


class MeshExitance:
    """Object ``obj``'s ``M`` at hits on its mesh: Eq. V2 on the faces that resolve ``M``, its transport elsewhere.

    The table is filled lazily: a batch of hits asks the transport at the vertices and centroids of the faces it
    lands on that are not filled yet, when those are fewer than its hits on them (else the transport is asked at the
    hits themselves).

    Parameters
    ----------
    obj : TranslucentObject
        :func:`usable`.
    exitance : callable
        ``exitance(points_mm (K, 3), outward normals (K, 3)) -> M (K, 3)``: the object's transport.
    unit_mm : float

    Attributes
    ----------
    filled, known : (F,) bool
        The faces whose vertices and centroid are asked, and of those the ones Eq. V2 is used on.
    queries : int
        Transport queries made to fill the table.
    """

    def __init__(self, obj, exitance, unit_mm):
        self.exitance = exitance
        vertex, self.face = mesh_arrays(obj.shape)
        matrix = np.asarray(obj.to_world, dtype=np.float64)
        self.vertex = (vertex @ matrix[:3, :3].T + matrix[:3, 3]) * unit_mm
        # The winding's normal mapped to the world (a mirroring map reverses the winding), turned outwards.
        self.outward = np.sign(np.linalg.det(matrix[:3, :3])) * obj.orientation
        self.vertex_normal = np.zeros_like(self.vertex)
        for start in range(0, len(self.face), CHUNK_FACES):
            face = self.face[start:start + CHUNK_FACES]
            cross = self._cross(face)
            for i in range(3):
                np.add.at(self.vertex_normal, face[:, i], cross)
        self.vertex_normal /= np.maximum(np.linalg.norm(self.vertex_normal, axis=1), 1e-300)[:, None]
        self.at_vertex = np.zeros((len(self.vertex), 3))
        self.bubble = np.zeros((len(self.face), 3))
        self.vertex_filled = np.zeros(len(self.vertex), dtype=bool)
        self.filled = np.zeros(len(self.face), dtype=bool)
        self.known = np.zeros(len(self.face), dtype=bool)
        self.queries = 0

    def _cross(self, face):
        """(K, 3) outward normals of the faces ``face`` (K, 3), twice their area long."""
        a, b, c = (self.vertex[face[:, i]] for i in range(3))
        return np.cross(b - a, c - a) * self.outward

    def __call__(self, faces, points, normals):
        """``M`` (K, 3) at the hits ``points`` (mm) with outward ``normals`` on the faces ``faces`` (K,)."""
        faces = np.asarray(faces, dtype=np.int64)
        self._fill(faces)
        out = np.zeros((len(faces), 3))
        known = _interpolate(self.face, self.vertex, self.at_vertex, self.bubble, self.known, faces,
                             np.ascontiguousarray(points, dtype=np.float64), out)
        if not np.all(known):
            out[~known] = self.exitance(points[~known], normals[~known])
        return out

    def _fill(self, faces):
        """Asks the transport at the vertices and centroids of the unfilled ``faces`` when they are fewer than the
        hits on those faces, and marks each face known where its bubble is within :data:`TOLERANCE`."""
        new_hits = faces[~self.filled[faces]]
        new = np.flatnonzero(np.bincount(new_hits, minlength=len(self.face)))
        vertices = np.flatnonzero(np.bincount(self.face[new].ravel(), minlength=len(self.vertex)))
        vertices = vertices[~self.vertex_filled[vertices]]
        if len(new) == 0 or len(new) + len(vertices) > len(new_hits):
            return
        self.at_vertex[vertices] = self.exitance(self.vertex[vertices], self.vertex_normal[vertices])
        self.vertex_filled[vertices] = True
        cross = self._cross(self.face[new])
        twice_area = np.linalg.norm(cross, axis=1)
        centroid = self.vertex[self.face[new]].mean(axis=1)
        at_centroid = self.exitance(centroid, cross / np.maximum(twice_area, 1e-300)[:, None])
        self.bubble[new] = at_centroid - self.at_vertex[self.face[new]].mean(axis=1)
        self.known[new] = (twice_area > 0) & np.all(np.abs(self.bubble[new]) <= TOLERANCE * at_centroid, axis=1)
        self.filled[new] = True
        self.queries += len(new) + len(vertices)


@njit(cache=True, parallel=True)
def _interpolate(face, vertex, at_vertex, bubble, known_face, faces, points, out):
    """Eq. V2 at each hit ``points[k]`` on face ``faces[k]`` into ``out[k]`` where the face is known; returns which
    hits were (K,) bool. The barycentric coordinates are those of the point projected onto the face's plane,
    clamped to the face (float rounding may put a hit a little outside it)."""
    known = np.zeros(len(faces), dtype=np.bool_)
    for k in prange(len(faces)):
        f = faces[k]
        if not known_face[f]:
            continue
        known[k] = True
        i, j, m = face[f, 0], face[f, 1], face[f, 2]
        d11 = d12 = d22 = d1 = d2 = 0.0
        for c in range(3):
            e1, e2, d = vertex[j, c] - vertex[i, c], vertex[m, c] - vertex[i, c], points[k, c] - vertex[i, c]
            d11 += e1 * e1
            d12 += e1 * e2
            d22 += e2 * e2
            d1 += d * e1
            d2 += d * e2
        det = d11 * d22 - d12 * d12
        u = max((d22 * d1 - d12 * d2) / det, 0.0)
        v = max((d11 * d2 - d12 * d1) / det, 0.0)
        w = max(1.0 - u - v, 0.0)
        total = u + v + w
        u, v, w = u / total, v / total, w / total
        for c in range(3):
            value = w * at_vertex[i, c] + u * at_vertex[j, c] + v * at_vertex[m, c] + 27.0 * u * v * w * bubble[f, c]
            out[k, c] = max(value, 0.0)
    return known
