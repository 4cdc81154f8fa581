"""Mesh files checked before Mitsuba reads them: what its loaders do not check crashes the process.

Mitsuba 3.9's PLY loader follows face indices without bounds checks, so a face that names a vertex beyond the
file's count ends the process with a segmentation fault (exit 139) instead of an error. :func:`check_mesh_file`
reads a PLY file's header and faces (ASCII or binary, either byte order) with numpy and refuses such a file in one
line. Other formats are left to Mitsuba.
"""

import re
from pathlib import Path

import numpy as np

from ..errors import ConvsssError

#: The names a PLY face element gives its list of vertex indices.
INDEX_LISTS = ("vertex_indices", "vertex_index")
#: PLY scalar types and their numpy codes.
PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2", "ushort": "u2",
             "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4", "float": "f4",
             "float32": "f4", "double": "f8", "float64": "f8"}


def check_mesh_file(path):
    """A one-line :class:`ConvsssError` when the mesh file ``path`` would crash Mitsuba's loader (a PLY face index
    outside ``[0, vertices)``, or a header that does not parse); nothing for other formats or sound files."""
    path = Path(path)
    if path.suffix.lower() != ".ply" or not path.is_file():
        return
    with open(path, "rb") as f:
        data = f.read()
    header, body = _ply_header(path, data)
    layout = _ply_layout(path, header)
    if layout is None:
        return
    form, vertices, before, face = layout
    if form == "ascii":
        faces = _ascii_faces(body, before, face)
    else:
        faces = _binary_faces(body, "<" if form == "binary_little_endian" else ">", before, face)
    if faces is None:
        return
    counts, indices = faces
    bad = np.flatnonzero((indices < 0) | (indices >= vertices))
    if len(bad):
        owner = int(np.searchsorted(np.cumsum(counts), bad[0], side="right"))
        raise ConvsssError(f"mesh {str(path)!r}: face {owner} refers to vertex {int(indices[bad[0]])}, but the file "
                           f"has {vertices} vertices (its faces must index 0 to {vertices - 1})")


def _ply_header(path, data):
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise ConvsssError(f"mesh {str(path)!r} is not a PLY file (no 'ply' ... 'end_header' header)")
    newline = data.find(b"\n", end)
    text = data[:end].decode("ascii", errors="replace")
    return [line.split() for line in text.splitlines() if line.strip()], data[newline + 1:]


def _ply_layout(path, header):
    """``(format, vertices, elements before the faces, face properties)`` or None when the layout is not one this
    check reads (then Mitsuba's loader decides)."""
    form, elements = None, []
    for words in header:
        if words[0] == "format" and len(words) > 1:
            form = words[1]
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements:
            elements[-1][2].append(words[1:])
    if form not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ConvsssError(f"mesh {str(path)!r}: PLY format {form!r} is not ascii or binary")
    names = [e[0] for e in elements]
    if "vertex" not in names or "face" not in names:
        return None
    vertices = elements[names.index("vertex")][1]
    face = elements[names.index("face")]
    before = elements[:names.index("face")]
    if any(p[0] == "list" for e in before for p in e[2]):
        return None  # an element before the faces with variable-length records: not read here
    if not any(p[0] == "list" and p[-1] in INDEX_LISTS for p in face[2]):
        return None
    return form, vertices, before, face


def _ascii_faces(body, before, face):
    """Counts and indices of the faces of an ASCII PLY body, the face properties read in order; None when a line
    does not parse."""
    lines = body.decode("ascii", errors="replace").splitlines()
    skip = sum(count for _, count, _ in before)
    _, faces, props = face
    counts, indices = [], []
    for line in lines[skip:skip + faces]:
        words, at = line.split(), 0
        for p in props:
            if p[0] != "list":
                at += 1
                continue
            if at >= len(words) or not re.fullmatch(r"\d+", words[at]):
                return None
            n = int(words[at])
            if p[-1] in INDEX_LISTS:
                try:
                    indices.extend(int(float(w)) for w in words[at + 1:at + 1 + n])
                except ValueError:
                    return None
                counts.append(n)
            at += 1 + n
    return np.asarray(counts, dtype=np.int64), np.asarray(indices, dtype=np.int64)


def _binary_faces(body, order, before, face):
    """Counts and indices of the faces, for faces whose lists all have the first face's length (triangles, or
    quads); None otherwise."""
    offset = 0
    for _, count, props in before:
        offset += count * sum(np.dtype(PLY_TYPES.get(p[0], "f4")).itemsize for p in props)
    _, faces, props = face
    if faces == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    fields = []
    for k, p in enumerate(props):
        if p[0] == "list":
            count_type, item_type = PLY_TYPES.get(p[1]), PLY_TYPES.get(p[2])
            at = offset + (np.dtype(fields).itemsize if fields else 0)  # this list's count in the first face
            if count_type is None or item_type is None or at >= len(body):
                return None
            n = int(np.frombuffer(body, dtype=order + count_type, count=1, offset=at)[0])
            fields += [(f"{p[-1]} count", order + count_type), (p[-1], order + item_type, (n,))]
        else:
            fields.append((f"p{k}", order + PLY_TYPES.get(p[0], "f4")))
    record = np.dtype(fields)
    if offset + faces * record.itemsize > len(body):
        return None
    table = np.frombuffer(body, dtype=record, count=faces, offset=offset)
    name = next(p[-1] for p in props if p[0] == "list" and p[-1] in INDEX_LISTS)
    counts = table[f"{name} count"].astype(np.int64)
    if np.any(counts != counts[0]):
        return None
    return counts, table[name].astype(np.int64).reshape(-1)
