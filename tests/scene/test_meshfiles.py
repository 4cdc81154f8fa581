"""Mesh files checked before Mitsuba reads them (convsss.scene.meshfiles): a PLY face index beyond the vertex count
crashed Mitsuba's loader (exit 139, issue 30 defect 3); it is refused in one line, and sound files pass."""

import numpy as np
import pytest

from convsss.errors import ConvsssError
from convsss.scene.meshfiles import check_mesh_file
from convsss.scene.quick import demo_mesh

TETRA = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _ply(path, faces, form="binary_little_endian", extra_face_property=False):
    head = (f"ply\nformat {form} 1.0\nelement vertex {len(TETRA)}\nproperty float x\nproperty float y\n"
            f"property float z\nelement face {len(faces)}\n"
            + ("property uchar flags\n" if extra_face_property else "")
            + "property list uchar int vertex_indices\nend_header\n")
    if form == "ascii":
        body = "".join(" ".join(map(str, v)) + "\n" for v in TETRA)
        body += "".join(("7 " if extra_face_property else "") + "3 " + " ".join(map(str, f)) + "\n" for f in faces)
        path.write_bytes(head.encode() + body.encode())
        return path
    order = "<" if form == "binary_little_endian" else ">"
    fields = ([("flags", "u1")] if extra_face_property else []) + [("n", "u1"), ("i", order + "i4", (3,))]
    table = np.zeros(len(faces), dtype=np.dtype(fields))
    table["n"], table["i"] = 3, faces
    if extra_face_property:
        table["flags"] = 7
    path.write_bytes(head.encode() + TETRA.astype(order + "f4").tobytes() + table.tobytes())
    return path


@pytest.mark.parametrize("form", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("extra", [False, True])
def test_a_face_beyond_the_vertices_is_refused_in_one_line(tmp_path, form, extra):
    good = _ply(tmp_path / "good.ply", FACES, form, extra)
    check_mesh_file(good)
    bad = FACES.copy()
    bad[2, 1] = 40
    with pytest.raises(ConvsssError, match=r"face 2 refers to vertex 40, but the file has 4 vertices"):
        check_mesh_file(_ply(tmp_path / "bad.ply", bad, form, extra))
    bad[2, 1] = -1
    with pytest.raises(ConvsssError, match=r"face 2 refers to vertex -1"):
        check_mesh_file(_ply(tmp_path / "neg.ply", bad, form, extra))


def test_a_quick_scene_and_a_scene_file_check_their_meshes_first(mi, tmp_path):
    """The check runs before Mitsuba loads the mesh, for a scene file and for ``--mesh`` (quick scenes)."""
    from convsss.scene.loading import load_scene
    from convsss.scene.quick import mesh_bounds

    bad = FACES.copy()
    bad[0, 0] = 99
    path = _ply(tmp_path / "bad.ply", bad)
    with pytest.raises(ConvsssError, match="refers to vertex 99"):
        mesh_bounds(path)
    scene = tmp_path / "scene.xml"
    scene.write_text(f'<scene version="3.0.0"><sensor type="perspective"/><shape type="ply"><string name="filename" '
                     f'value="{path}"/></shape></scene>')
    with pytest.raises(ConvsssError, match="refers to vertex 99"):
        load_scene(scene)
    check_mesh_file(demo_mesh())  # another format: left to Mitsuba
