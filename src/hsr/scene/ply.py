"""Binary PLY read in chunks, for inputs larger than memory (``hsr partition`` streams
them; :func:`hsr.load` reads PLY through trimesh).

A binary PLY (Turk 1994) is a text header naming its elements and their properties,
then the elements' records back to back. Triangle meshes write ``element vertex V`` with
fixed-size properties (x, y, z first or anywhere among them) and ``element face F`` with
one list property (a count and that many indices) and possibly fixed-size ones. When
every face has 3 corners the face records have a fixed size too, so both elements read
as NumPy structured arrays, a chunk at a time, without holding the file.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import MeshError
from .files import MAX_STREAM_BYTES, check_regular

__all__ = ["PlyLayout", "read_layout", "read_positions", "face_chunks", "is_binary_ply"]

_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
          "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
          "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
          "float64": "f8"}
MAX_HEADER_BYTES = 1 << 16
COUNT_FIELD = "count of the list"
INDEX_FIELD = "corners of the list"


@dataclass(frozen=True)
class PlyLayout:
    """Where a binary PLY's vertices and faces are: byte offsets, counts and the NumPy
    dtypes of one record (the face record assumes 3 corners)."""

    path: str
    n_vertices: int
    n_faces: int
    vertex_offset: int
    vertex_dtype: np.dtype
    face_offset: int
    face_dtype: np.dtype
    index_field: str

    @property
    def geometry_only(self) -> bool:
        """True when the file holds nothing :func:`hsr.load` would use besides positions
        and faces (vertex normals are not used), so streaming it loses nothing."""
        vertex = set(self.vertex_dtype.names or ()) - {"x", "y", "z", "nx", "ny", "nz"}
        face = set(self.face_dtype.names or ()) - {COUNT_FIELD, self.index_field}
        return not vertex and not face


def is_binary_ply(path: str) -> bool:
    """True when ``path`` is a regular file that starts like a binary PLY (never opens a
    FIFO or device, which could block)."""
    if not os.path.isfile(path):
        return False
    try:
        with open(path, "rb") as f:
            head = f.read(64)
    except OSError:
        return False
    return head.startswith(b"ply") and b"format binary_" in head


def read_layout(path: str | os.PathLike) -> PlyLayout:
    """The layout of a binary PLY holding ``vertex`` then ``face`` elements. Raises
    :class:`~hsr.errors.MeshError` for a file that is not one, or not one this reader
    takes (ASCII, other elements before the faces, more than one list per face)."""
    path = os.fspath(path)
    check_regular(path, "mesh file", MAX_STREAM_BYTES)
    with open(path, "rb") as f:
        header = f.read(MAX_HEADER_BYTES)
    end = header.find(b"end_header\n")
    if not header.startswith(b"ply") or end < 0:
        raise MeshError(f"{path}: not a PLY file with a header under 64 KiB")
    lines = header[:end].decode("ascii", "replace").splitlines()
    fmt, elements = _parse_header(lines, path)
    if fmt not in ("binary_little_endian", "binary_big_endian"):
        raise MeshError(f"{path}: streaming reads binary PLY, this one is {fmt or 'unknown'}")
    order = "<" if fmt == "binary_little_endian" else ">"
    names = [e[0] for e in elements]
    if names[:2] != ["vertex", "face"]:
        raise MeshError(f"{path}: streaming needs the vertex then the face element first, "
                        f"got {names}")
    (_, n_vertices, vertex_props), (_, n_faces, face_props) = elements[:2]
    if any(p[0] == "list" for p in vertex_props) or not {"x", "y", "z"} <= {
            p[-1] for p in vertex_props}:
        raise MeshError(f"{path}: vertices need fixed-size x, y and z properties")
    vertex_dtype = np.dtype([(p[-1], order + _type(p[0], path)) for p in vertex_props])
    lists = [p for p in face_props if p[0] == "list"]
    if len(lists) != 1:
        raise MeshError(f"{path}: faces need exactly one list of vertex indices")
    # The list's count and corners under names no PLY property can have (names have no
    # spaces), so a property called "count" cannot collide with them.
    fields = []
    for p in face_props:
        if p[0] == "list":
            fields += [(COUNT_FIELD, order + _type(p[1], path)),
                       (INDEX_FIELD, order + _type(p[2], path), (3,))]
        else:
            fields.append((p[-1], order + _type(p[0], path)))
    face_dtype = np.dtype(fields)
    vertex_offset = end + len(b"end_header\n")
    face_offset = vertex_offset + n_vertices * vertex_dtype.itemsize
    needed = face_offset + n_faces * face_dtype.itemsize
    for name, count, props in elements[2:]:
        if any(p[0] == "list" for p in props):
            raise MeshError(f"{path}: element {name!r} after the faces has a list; "
                            f"streaming reads files whose later elements have fixed-size "
                            f"records (load it without --stream)")
        needed += count * sum(np.dtype(_type(p[0], path)).itemsize for p in props)
    size = os.path.getsize(path)
    if size < needed:
        raise MeshError(f"{path}: the file is shorter than its header says (truncated, or "
                        f"faces that are not all triangles)")
    if size > needed:
        raise MeshError(f"{path}: {size - needed:,} bytes after the elements its header "
                        f"declares (faces past the declared count, or not all "
                        f"triangles); hsr does not guess which")
    return PlyLayout(path, n_vertices, n_faces, vertex_offset, vertex_dtype, face_offset,
                     face_dtype, INDEX_FIELD)


def _parse_header(lines: list, path: str) -> tuple:
    """``(format, [(element name, count, [property words]), ...])`` of a PLY header's
    lines (Turk 1994): ``format F V``, ``element NAME COUNT``, ``property TYPE NAME`` or
    ``property list COUNT_TYPE INDEX_TYPE NAME``; any other line, a property before any
    element or named twice in one, is a :class:`MeshError` naming the line."""
    fmt: str | None = None
    elements: list[tuple] = []
    for line in lines[1:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) == 3 and fmt is None:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and (
                len(words) == 3 or (len(words) == 5 and words[1] == "list")):
            props = elements[-1][2]
            if words[-1] in {p[-1] for p in props}:
                raise MeshError(f"{path}: PLY property {words[-1]!r} appears twice in "
                                f"element {elements[-1][0]!r}")
            props.append(words[1:])
        else:
            raise MeshError(f"{path}: PLY header line not understood: {line[:80]!r}")
    return fmt or "", elements


def _type(name: str, path: str) -> str:
    if name not in _TYPES:
        raise MeshError(f"{path}: PLY property type {name!r} not understood")
    return _TYPES[name]


def read_positions(layout: PlyLayout, chunk: int = 1 << 20) -> np.ndarray:
    """(V, 3) float64 vertex positions, read a chunk of records at a time (only x, y, z
    are kept; not checked: unused vertices may hold anything)."""
    out = np.empty((layout.n_vertices, 3))
    with open(layout.path, "rb") as f:
        f.seek(layout.vertex_offset)
        for start in range(0, layout.n_vertices, chunk):
            count = min(chunk, layout.n_vertices - start)
            records = np.fromfile(f, dtype=layout.vertex_dtype, count=count)
            for axis, name in enumerate("xyz"):
                out[start:start + count, axis] = records[name]
    return out  # checked where the faces say which vertices are used


def face_chunks(layout: PlyLayout, chunk: int = 1 << 20):
    """Yield ``(first face index, (n, 3) int64 corner indices)`` for every chunk of faces,
    in file order. Raises :class:`~hsr.errors.MeshError` for a face that is not a
    triangle or an index outside the vertices."""
    with open(layout.path, "rb") as f:
        f.seek(layout.face_offset)
        for start in range(0, layout.n_faces, chunk):
            count = min(chunk, layout.n_faces - start)
            records = np.fromfile(f, dtype=layout.face_dtype, count=count)
            if len(records) != count:
                raise MeshError(f"{layout.path}: truncated face data")
            counts = records[COUNT_FIELD]
            if np.any(counts != 3):
                k = start + int(np.argmax(counts != 3))
                raise MeshError(f"{layout.path}: face {k} has {counts[k - start]} "
                                f"corners; streaming takes triangles only")
            corners = records[layout.index_field].astype(np.int64)
            if corners.size and (corners.min() < 0 or corners.max() >= layout.n_vertices):
                raise MeshError(f"{layout.path}: a face in {start}..{start + count - 1} "
                                f"indexes outside the {layout.n_vertices:,} vertices")
            yield start, corners
