"""Wavefront OBJ read in chunks of lines, for files larger than memory (``hsr partition``
streams them): the grammar and the faces of :mod:`hsr.scene.obj`, whose normalisation,
careful scanner and number and corner conversions run on each chunk, and geometry only
(texture coordinates, normals and materials are checked for their indices and dropped).

The file is cut at line ends, never inside a line continued by a backslash, so every
statement is whole in one chunk. What crosses chunks is counted: the vertices,
texture coordinates and normals defined so far (negative indices count back from them)
and the highest index each face used (OBJ lets a face name a vertex defined later, so
the check against the totals waits for the end of the file). Vertex positions are kept
(24 bytes each); the triangles go to a scratch file as they are read.
"""

from __future__ import annotations

import os

import numpy as np

from ..errors import MeshError
from .files import MAX_STREAM_BYTES, check_regular
from .obj import MAX_LINE_BYTES, face_refs, fan_corners, normalise_obj, obj_numbers, scan_careful

__all__ = ["ObjStream", "CHUNK_BYTES"]

CHUNK_BYTES = 1 << 26
_KINDS = ("vertex", "texture", "normal")  # the three indices of a face corner, in order


class ObjStream:
    """An OBJ file converted once, chunk by chunk: ``positions`` (V, 3) float64 and
    ``n_faces`` triangles (fan-triangulated in file order) in a scratch file of int64
    corner indices, read back by :meth:`face_chunks`. Raises
    :class:`~hsr.errors.MeshError` as :func:`hsr.load` does for the geometry."""

    def __init__(self, path: str | os.PathLike, scratch: str,
                 chunk_bytes: int = CHUNK_BYTES) -> None:
        self.path = os.fspath(path)
        check_regular(self.path, "mesh file", MAX_STREAM_BYTES)
        self.name = os.path.basename(self.path)
        self.faces_file = os.path.join(scratch, "obj.faces")
        positions: list = []
        seen = np.zeros(3, dtype=np.int64)  # v, vt, vn defined before the chunk
        highest = np.full(3, -1, dtype=np.int64)  # highest 0-based index any face used
        self.n_faces = 0
        with open(self.faces_file, "wb") as out:
            for scanned in _scanned_chunks(self.path, chunk_bytes, self.name):
                positions.append(obj_numbers(scanned.v, 3, 3, self.name, "vertex"))
                triangles = _triangles(scanned, seen, highest, self.name)
                triangles.tofile(out)
                self.n_faces += len(triangles)
                seen += (len(scanned.v), len(scanned.vt), len(scanned.vn))
        if not self.n_faces:
            raise MeshError(f"{self.name}: mesh is empty (no faces)")
        if np.any(highest >= seen):  # a face names an element the file never defines
            _refuse_first_bad_face(self.path, chunk_bytes, self.name, seen)
        self.positions = np.concatenate(positions)
        self.n_vertices = len(self.positions)

    def face_chunks(self, chunk: int = 1 << 20):
        """Yield ``(first face index, (n, 3) int64 corners)`` in file order."""
        with open(self.faces_file, "rb") as f:
            for start in range(0, self.n_faces, chunk):
                count = min(chunk, self.n_faces - start)
                yield start, np.fromfile(f, dtype=np.int64, count=3 * count).reshape(-1, 3)


def _line_chunks(path: str, chunk_bytes: int, name: str):
    """The file's bytes in pieces of about ``chunk_bytes`` that end at a line end which
    does not continue the line (not after a backslash)."""
    carry = b""
    with open(path, "rb") as f:
        while True:
            data = f.read(chunk_bytes)
            if not data:
                if carry:
                    yield carry
                return
            data = carry + data
            cut = len(data)
            while True:
                cut = max(data.rfind(b"\n", 0, cut), data.rfind(b"\r", 0, cut))
                before = data[max(0, cut - 2):cut]
                if cut < 0 or not (before.endswith(b"\\") or before == b"\\\r"):
                    break
            if cut < 0:
                if len(data) > 2 * MAX_LINE_BYTES:
                    raise MeshError(f"{name}: a line longer than {MAX_LINE_BYTES:,} bytes: "
                                    f"not OBJ text")
                carry = data
                continue
            if data[cut:cut + 1] == b"\r" and cut + 1 == len(data):
                # A CR that may start a CR LF pair whose LF is in the next read.
                carry = data
                continue
            yield data[:cut + 1]
            carry = data[cut + 1:]


def _scanned_chunks(path: str, chunk_bytes: int, name: str):
    """The file's chunks (:func:`_line_chunks`) normalised and scanned as
    :mod:`hsr.scene.obj` scans a whole file (a byte-order mark only at its start, line
    numbers counted on)."""
    line = 1
    for k, data in enumerate(_line_chunks(path, chunk_bytes, name)):
        text = normalise_obj(data, name, file_start=k == 0)
        yield scan_careful(text, name, first_line=line)
        line += text.count("\n")


def _refuse_first_bad_face(path: str, chunk_bytes: int, name: str, totals) -> None:
    """Raise the :class:`MeshError` :func:`hsr.load` raises for the first face (in file
    order, vertices before texture coordinates before normals) whose index passes the
    file's ``totals``: the file is read again, only on this error path, since the totals
    are known only at its end."""
    for c in range(3):
        for scanned in _scanned_chunks(path, chunk_bytes, name):
            if not scanned.f:
                continue
            _, corner_face, refs = _corner_refs(scanned, name)
            bad = refs[:, c] > totals[c]
            if bad.any():
                j = int(np.argmax(bad))
                raise MeshError(f"{name}:{scanned.f_lines[corner_face[j]]}: {_KINDS[c]} "
                                f"index {int(refs[j, c])} outside 1..{int(totals[c])}")
    raise MeshError(f"{name}: a face names an element the file does not define")


def _corner_refs(scanned, name: str) -> tuple:
    """``(corners per face, face of each corner, (C, 3) raw v / vt / vn references)`` of
    a chunk's faces (0 = absent); a face of fewer than 3 corners is a
    :class:`MeshError` naming its line."""
    counts = np.fromiter((row.count(" ") + 1 if row else 0 for row in scanned.f),
                         dtype=np.int64, count=len(scanned.f))
    if counts.min() < 3:
        bad = int(np.argmax(counts < 3))
        raise MeshError(f"{name}:{scanned.f_lines[bad]}: a face needs at least 3 vertices")
    corner_face = np.repeat(np.arange(len(counts)), counts)
    return counts, corner_face, face_refs(" ".join(scanned.f), name, scanned.f_lines,
                                          corner_face)


def _triangles(scanned, seen: np.ndarray, highest: np.ndarray, name: str) -> np.ndarray:
    """(T, 3) int64 vertex indices of the chunk's faces, fan-triangulated as
    :mod:`hsr.scene.obj` does; negative indices resolved against what was defined before
    each face (``seen`` before the chunk plus the chunk's own counts); ``highest``
    updated with the largest index of each kind."""
    if not scanned.f:
        return np.zeros((0, 3), dtype=np.int64)
    counts, corner_face, refs = _corner_refs(scanned, name)
    limits = np.stack([np.asarray(scanned.f_nv), np.asarray(scanned.f_nt),
                       np.asarray(scanned.f_nn)], axis=1)[corner_face] + seen
    resolved = np.where(refs < 0, limits + refs, refs - 1)
    for c in range(3):
        present = refs[:, c] != 0
        bad = present & (resolved[:, c] < 0)
        if c == 0:
            bad |= ~present
        if bad.any():
            k = int(np.argmax(bad))
            raise MeshError(f"{name}:{scanned.f_lines[corner_face[k]]}: {_KINDS[c]} index "
                            f"{int(refs[k, c])} outside 1..{int(limits[k, c])}")
        if present.any():
            highest[c] = max(highest[c], int(resolved[present, c].max()))
    corner, _ = fan_corners(counts)
    return np.ascontiguousarray(resolved[corner, 0], dtype=np.int64)
