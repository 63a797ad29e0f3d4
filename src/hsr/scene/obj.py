"""The Wavefront OBJ reader: keeps file order exactly, fan-triangulates n-gons
``(v0, v1, v2), (v0, v2, v3), ...``, reads ``mtllib`` materials (``Kd``, ``map_Kd``).

The grammar (Wavefront's OBJ specification, as exporters write it): a statement is a tag and
its arguments separated by spaces or tabs, ``#`` starts a comment that runs to the end of
the line, a backslash at the end of a line continues it, leading white space and a UTF-8
byte-order mark are ignored. Statements: ``v x y z [w]``, ``vt u [v [w]]``,
``vn x y z``, ``f c1 c2 c3 ...`` with corners ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn``
(1-based, or negative: counted back from the elements defined so far), ``mtllib``,
``usemtl``. Other known statements (groups, smoothing, lines, free-form geometry) are
skipped; an unknown statement whose tag starts with ``v`` or ``f`` is refused, because
skipping a vertex-like line would shift every index after it.

Two readers implement it and must agree (a test runs both on every case): a regular-
expression reader for the common files (C speed) and a careful line-by-line reader that
handles everything and names the line of an error. Both see the same normalised text and
share the conversion of numbers and corners.
"""

from __future__ import annotations

import functools
import os
import re
import warnings

import numpy as np

from ..errors import HsrWarning, MeshError
from .files import MAX_MESH_BYTES, MAX_MTL_BYTES, read_regular
from .mesh import Mesh

__all__ = ["read_obj", "MAX_LINE_BYTES"]

# A longer line is not OBJ text (a binary file, or a generator gone wrong).
MAX_LINE_BYTES = 1 << 20
# Largest index magnitude accepted before it is compared with the element counts.
_MAX_INDEX = 1 << 62

_SKIPPED = frozenset((
    "vp", "l", "p", "o", "g", "s", "mg", "cstype", "deg", "bmat", "step", "curv", "curv2",
    "surf", "parm", "trim", "hole", "scrv", "sp", "end", "con", "bevel", "c_interp",
    "d_interp", "lod", "maplib", "usemap", "shadow_obj", "trace_obj", "ctech", "stech",
    "call", "csh"))
# A line the regular-expression reader does not take: not empty, and its tag is neither
# one it reads nor one both readers skip.
_OTHER_TAG = re.compile(r"^(?!(?:(?:v|vt|vn|f|%s)(?: |$)|$))" % "|".join(sorted(_SKIPPED)),
                        re.M)
_INT = r"-?\d+"
# One corner: v, v/vt, v//vn or v/vt/vn, nothing else.
_CORNER = re.compile(rf"({_INT})(?:/({_INT})(?:/({_INT}))?|//({_INT}))?")
# Whole face blocks of one corner form (tokens joined by single spaces).
_UNIFORM = {form: re.compile(rf"{pat}(?: {pat})*") for form, pat in (
    ("v", _INT), ("v/vt", rf"{_INT}/{_INT}"), ("v//vn", rf"{_INT}//{_INT}"),
    ("v/vt/vn", rf"{_INT}/{_INT}/{_INT}"))}


def read_obj(path, method: str = "auto", max_bytes: int = MAX_MESH_BYTES) -> Mesh:
    """Read a Wavefront OBJ file. ``method``: ``auto`` (the regular-expression reader where
    it applies, else the careful one), ``regex`` (the same: files it cannot take go to the
    careful reader) or ``careful`` (always line by line). Raises :class:`MeshError` naming
    the line on anything malformed, for a file that is not a regular file or is larger
    than ``max_bytes``, and for a broken material file."""
    if method not in ("auto", "regex", "careful"):
        raise MeshError(f"OBJ read method must be auto, regex or careful, got {method!r}")
    path = os.fspath(path)
    name = os.path.basename(path)
    text = normalise_obj(read_regular(path, "mesh file", max_bytes), name)
    scanned = None if method == "careful" else scan_regex(text, name)
    if scanned is not None:
        try:
            return _build(path, name, scanned)
        except MeshError:
            pass  # read it again carefully, to report the line
    return _build(path, name, scan_careful(text, name))


def normalise_obj(data: bytes, name: str, file_start: bool = True) -> str:
    """OBJ text with the grammar's noise removed, identically for both readers: no
    byte-order mark at the start of the file (``file_start``: ``data`` begins the file;
    a mark anywhere else is text, for the streamed reader's chunks as for the whole
    file), ``\\n`` line ends, continuation lines joined, comments dropped, runs of
    spaces and tabs folded to one space, no space at either end of a line."""
    if file_start and data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    _check_line_lengths(data, name)
    text = data.decode("utf-8", errors="replace")
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    if "\\\n" in text:
        text = text.replace("\\\n", " ")
    if "#" in text:
        text = re.sub(r"#[^\n]*", "", text)
    if "\t" in text or "  " in text or "\f" in text or "\v" in text:
        text = re.sub(r"[ \t\f\v]+", " ", text)
    if "\n " in text or " \n" in text or text[:1] == " " or text[-1:] == " ":
        text = re.sub(r"^ +| +$", "", text, flags=re.M)
    return text


def _check_line_lengths(data: bytes, name: str) -> None:
    if len(data) <= MAX_LINE_BYTES:
        return
    ends = np.flatnonzero(np.frombuffer(data, dtype=np.uint8) == 10)
    starts = np.concatenate([[0], ends + 1])
    lengths = np.concatenate([ends, [len(data)]]) - starts
    longest = int(np.argmax(lengths))
    if lengths[longest] > MAX_LINE_BYTES:
        raise MeshError(f"{name}:{longest + 1}: line of {int(lengths[longest]):,} bytes, "
                        f"longer than {MAX_LINE_BYTES:,}: not OBJ text")


class _Scanned:
    """What a reader found: rows of v / vt / vn as (line number, argument text), face rows
    (argument text) with their line numbers and the counts of v / vt / vn defined before
    each (for negative indices), material events (face number, name) and mtllib names.
    Line numbers are 0 where the regular-expression reader does not know them."""

    def __init__(self, v, vt, vn, f, f_lines, f_nv, f_nt, f_nn, mat_events, mtllibs):
        self.v, self.vt, self.vn, self.f = v, vt, vn, f
        self.f_lines, self.f_nv, self.f_nt, self.f_nn = f_lines, f_nv, f_nt, f_nn
        self.mat_events, self.mtllibs = mat_events, mtllibs


def scan_careful(text: str, name: str, first_line: int = 1) -> _Scanned:
    """Line by line: sort the statements by tag, keeping line numbers (``first_line``:
    the number of the text's first line, for a chunk of a longer file)."""
    v_rows: list = []
    vt_rows: list = []
    vn_rows: list = []
    f_rows, f_lines, f_nv, f_nt, f_nn = [], [], [], [], []
    mat_events: list[tuple[int, str]] = []
    mtllibs: list[str] = []
    for lineno, line in enumerate(text.split("\n"), first_line):
        if not line:
            continue
        tag, _, rest = line.partition(" ")
        if tag == "v":
            v_rows.append((lineno, rest))
        elif tag == "f":
            f_rows.append(rest)
            f_lines.append(lineno)
            f_nv.append(len(v_rows))
            f_nt.append(len(vt_rows))
            f_nn.append(len(vn_rows))
        elif tag == "vt":
            vt_rows.append((lineno, rest))
        elif tag == "vn":
            vn_rows.append((lineno, rest))
        elif tag == "usemtl":
            mat_events.append((len(f_rows), rest))
        elif tag == "mtllib":
            mtllibs.extend(rest.split())
        elif tag not in _SKIPPED and tag[0] in "vf":
            raise MeshError(f"{name}:{lineno}: unknown statement {line[:60]!r}")
    return _Scanned(v_rows, vt_rows, vn_rows, f_rows, f_lines, f_nv, f_nt, f_nn, mat_events,
                    mtllibs)


def scan_regex(text: str, name: str) -> _Scanned | None:
    """The same as :func:`scan_careful` with regular expressions, for the common files: no
    materials and no negative indices. None when it does not apply (the careful reader
    takes the file)."""
    if _OTHER_TAG.search(text):
        return None  # materials, or an unknown statement to report with its line
    f_rows = re.findall(r"^f(?: (.*))?$", text, re.M)
    if any("-" in row for row in f_rows):
        return None
    v_rows = [(0, r) for r in re.findall(r"^v(?: (.*))?$", text, re.M)]
    vt_rows = [(0, r) for r in re.findall(r"^vt(?: (.*))?$", text, re.M)]
    vn_rows = [(0, r) for r in re.findall(r"^vn(?: (.*))?$", text, re.M)]
    zeros = [0] * len(f_rows)
    return _Scanned(v_rows, vt_rows, vn_rows, f_rows, zeros, zeros, zeros, zeros, [], [])


def _build(path, name, s: _Scanned) -> Mesh:
    if not s.f:
        raise MeshError(f"{name}: mesh is empty (no faces)")
    positions = obj_numbers(s.v, 3, 3, name, "vertex")
    uvs = obj_numbers(s.vt, 1, 2, name, "texture coordinate")
    normals = obj_numbers(s.vn, 3, 3, name, "normal")

    # Normalised text: one space between tokens, none at the ends.
    counts = np.fromiter((row.count(" ") + 1 if row else 0 for row in s.f), dtype=np.int64,
                         count=len(s.f))
    if counts.min() < 3:
        bad = int(np.argmax(counts < 3))
        raise MeshError(f"{name}:{s.f_lines[bad]}: a face needs at least 3 vertices")
    corner_face = np.repeat(np.arange(len(counts)), counts)
    refs = face_refs(" ".join(s.f), name, s.f_lines, corner_face)  # v, vt, vn; 0 = absent
    limits = (np.array(s.f_nv)[corner_face], np.array(s.f_nt)[corner_face],
              np.array(s.f_nn)[corner_face])
    totals = (len(positions), len(uvs), len(normals))
    what = ("vertex", "texture", "normal")
    resolved = np.empty_like(refs)
    for c in range(3):
        ref = refs[:, c]
        # Negative indices count back from the elements defined so far (OBJ spec).
        idx = np.where(ref < 0, limits[c] + ref, ref - 1)
        present = ref != 0
        bad = present & ((idx < 0) | (idx >= totals[c]))
        if c == 0:
            bad |= ref == 0
        if bad.any():
            k = int(np.argmax(bad))
            raise MeshError(f"{name}:{s.f_lines[corner_face[k]]}: {what[c]} index "
                            f"{int(ref[k])} outside 1..{totals[c]}")
        resolved[:, c] = np.where(present, idx, -1)

    corner, tri_poly = fan_corners(counts)
    faces = resolved[corner, 0]
    corner_uv = uvs[resolved[corner, 1]] if len(uvs) and (resolved[:, 1] >= 0).all() else None
    corner_normals = (normals[resolved[corner, 2]]
                      if len(normals) and (resolved[:, 2] >= 0).all() else None)
    materials: list[str] = []
    poly_mat = np.full(len(counts), -1, dtype=np.int64)
    for first_face, mat in s.mat_events:
        if mat not in materials:
            materials.append(mat)
        poly_mat[first_face:] = materials.index(mat)
    face_colors, texture, named, uv_map = _read_materials(path, s.mtllibs, materials,
                                                          poly_mat[tri_poly])
    corner_uv = _uv_transform(corner_uv, poly_mat[tri_poly], materials, uv_map)
    return Mesh(positions, faces, corner_uv=corner_uv, corner_normals=corner_normals,
                face_colors=face_colors, texture=texture, name=name,
                sources=(os.path.abspath(path), *named))


def fan_corners(counts: np.ndarray) -> tuple:
    """Fan triangulation in file order, polygon (c0, c1, ..., cn-1) -> (c0, ck, ck+1), of
    polygons with ``counts`` corners stored one after another: ``(corner (T, 3) indices
    into the corners, the polygon of each triangle (T,))``."""
    n_tris = counts - 2
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    tri_poly = np.repeat(np.arange(len(counts)), n_tris)
    step = np.arange(int(n_tris.sum())) - np.repeat(np.cumsum(n_tris) - n_tris, n_tris) + 1
    corner = np.stack([start[tri_poly], start[tri_poly] + step, start[tri_poly] + step + 1],
                      axis=1)
    return corner, tri_poly


def obj_numbers(rows, min_count, keep, name, what) -> np.ndarray:
    """(N, keep) float64 from OBJ rows ``a b c ...``; extra values (w, colours) are
    dropped, missing optional ones are zero."""
    if not rows:
        return np.zeros((0, keep))
    block = "\n".join(text for _, text in rows)
    for width in (keep, keep + 1):  # rows of one width (e.g. vt u v w): in bulk
        if _fields(width).fullmatch(block):
            try:
                return np.array(block.split(), dtype=np.float64).reshape(-1, width)[:, :keep]
            except ValueError:
                break  # a bad number: named below
    fields = [text.split() for _, text in rows]
    widths = {len(f) for f in fields}
    try:
        if len(widths) == 1 and min(widths) >= keep:
            return np.array(fields, dtype=np.float64)[:, :keep]
        out = np.zeros((len(fields), keep))
        for i, f in enumerate(fields):
            if len(f) < min_count:
                raise ValueError
            values = [float(x) for x in f[:keep]]
            out[i, : len(values)] = values
        return out
    except ValueError:
        for (lineno, text), f in zip(rows, fields):
            try:
                if len(f) < min_count:
                    raise ValueError
                [float(x) for x in f[:keep]]
            except ValueError:
                raise MeshError(f"{name}:{lineno}: bad {what} {text[:60]!r}") from None
        raise MeshError(f"{name}: bad {what} data") from None


def face_refs(joined, name, f_lines, corner_face) -> np.ndarray:
    """(corners, 3) int64 (v, vt, vn) from the face tokens joined by single spaces; absent
    fields are 0. Every token must be a corner of the grammar; a block of one form is
    converted in bulk."""
    flat = joined.split(" ")
    try:
        if _UNIFORM["v"].fullmatch(joined):
            out = np.zeros((len(flat), 3), dtype=np.int64)
            out[:, 0] = np.array(flat, dtype=np.int64)
            return _check_magnitude(out)
        if _UNIFORM["v/vt/vn"].fullmatch(joined):
            return _check_magnitude(np.array(joined.replace("/", " ").split(),
                                             dtype=np.int64).reshape(-1, 3))
        if _UNIFORM["v//vn"].fullmatch(joined):
            return _check_magnitude(np.array(joined.replace("//", "/0/").replace("/", " ")
                                             .split(), dtype=np.int64).reshape(-1, 3))
        if _UNIFORM["v/vt"].fullmatch(joined):
            out = np.zeros((len(flat), 3), dtype=np.int64)
            out[:, :2] = np.array(joined.replace("/", " ").split(),
                                  dtype=np.int64).reshape(-1, 2)
            return _check_magnitude(out)
    except (OverflowError, ValueError):
        pass  # an index too large for int64: the loop below names it
    out = np.zeros((len(flat), 3), dtype=np.int64)
    for i, tok in enumerate(flat):  # mixed forms, or a bad token to report
        m = _CORNER.fullmatch(tok)
        where = f"{name}:{f_lines[corner_face[i]]}" if f_lines[corner_face[i]] else name
        if m is None:
            raise MeshError(f"{where}: bad face vertex {tok!r} (a corner is v, v/vt, v//vn "
                            f"or v/vt/vn)")
        v, vt, vn, vn_only = m.groups()
        for c, part in enumerate((v, vt, vn or vn_only)):
            if part is not None:
                value = int(part)
                if abs(value) >= _MAX_INDEX:
                    raise MeshError(f"{where}: index {part[:30]} is out of range")
                out[i, c] = value
    return out


@functools.lru_cache(maxsize=8)
def _fields(width: int) -> re.Pattern:
    """Lines of exactly ``width`` space-separated fields."""
    one = r"[^ \n]+" + r" [^ \n]+" * (width - 1)
    return re.compile(rf"{one}(?:\n{one})*")


def _check_magnitude(refs: np.ndarray) -> np.ndarray:
    if refs.size and np.abs(refs).max() >= _MAX_INDEX:
        raise OverflowError  # the token loop reports it
    return refs


def _read_materials(obj_path, mtllibs, materials, face_mat):
    """Kd colours per face, the first map_Kd texture path from the OBJ's .mtl files and
    the files they name that exist (the .mtl files, every map_ texture: inputs that no
    output may replace).
    A missing .mtl is not an error (many OBJ files name one they do not ship); one that
    exists but cannot be read, or a ``Kd`` that is not three finite numbers, is. Finite
    ``Kd`` values outside [0, 1] are clamped to it (OpenGL clamps colours the same way)."""
    base = os.path.dirname(obj_path)
    named = [os.path.abspath(os.path.join(base, lib)) for lib in mtllibs
             if os.path.lexists(os.path.join(base, lib))]
    if not mtllibs or not materials:
        return None, None, named, None
    kd: dict[str, tuple] = {}
    texture, uv_map = None, None
    for lib in mtllibs:
        mtl_path = os.path.join(base, lib)
        if not os.path.lexists(mtl_path):
            continue
        text = read_regular(mtl_path, "material file", MAX_MTL_BYTES).decode(
            "utf-8", errors="replace")
        current = None
        for lineno, line in enumerate(text.splitlines(), 1):
            parts = line.split("#", 1)[0].split()
            if not parts:
                continue
            if parts[0] == "newmtl" and len(parts) > 1:
                current = parts[1]
            elif parts[0] == "Kd" and current is not None and len(parts) >= 4:
                try:
                    rgb = tuple(float(x) for x in parts[1:4])
                except ValueError:
                    rgb = (float("nan"),)
                if not all(np.isfinite(rgb)):
                    raise MeshError(f"{lib}:{lineno}: Kd must be three finite numbers, "
                                    f"got {' '.join(parts[1:4])!r}")
                kd[current] = rgb
            elif parts[0].startswith("map_") and len(parts) > 1:
                name, options = map_statement(line.split("#", 1)[0].split(None, 1)[1])
                candidate = os.path.join(base, name)
                if name and os.path.isfile(candidate):
                    named.append(os.path.abspath(candidate))
                    if parts[0] == "map_Kd" and texture is None:
                        texture, uv_map = candidate, (current, options)
                elif parts[0] == "map_Kd":
                    warnings.warn(HsrWarning(f"{lib}:{lineno}: map_Kd names {name!r}, "
                                             f"which is not a file beside the model; "
                                             f"drawn without it"), stacklevel=2)
    if not kd:
        return None, texture, named, uv_map
    table = np.array([kd.get(m, (0.8, 0.8, 0.8)) for m in materials] + [(0.8, 0.8, 0.8)])
    colors = np.round(np.clip(table[face_mat], 0, 1) * 255).astype(np.uint8)
    return colors, texture, named, uv_map


# Options of an MTL texture map statement and how many values each takes (Wavefront's
# MTL format, "Texture map statements"): -o, -s and -t take one to three numbers.
_MAP_OPTIONS = {"-blendu": (1, 1), "-blendv": (1, 1), "-boost": (1, 1), "-mm": (2, 2),
                "-o": (1, 3), "-s": (1, 3), "-t": (1, 3), "-texres": (1, 1),
                "-clamp": (1, 1), "-bm": (1, 1), "-imfchan": (1, 1), "-type": (1, 1),
                "-cc": (1, 1)}


def map_statement(rest: str) -> tuple:
    """``(file name, {option: [values]})`` of a ``map_*`` statement's arguments: its
    options first, then the file name, which is the rest of the line and may hold
    spaces (``map_Kd -s 2 2 1 fuze uv.jpg`` names ``fuze uv.jpg``)."""
    tokens = [(m.group(), m.start()) for m in re.finditer(r"\S+", rest)]
    options: dict = {}
    k = 0
    while k < len(tokens) and tokens[k][0] in _MAP_OPTIONS:
        flag, (low, high) = tokens[k][0], _MAP_OPTIONS[tokens[k][0]]
        values: list = []
        k += 1
        while k < len(tokens) and len(values) < high and (len(values) < low
                                                          or _is_number(tokens[k][0])):
            values.append(tokens[k][0])
            k += 1
        options[flag] = values
    name = rest[tokens[k][1]:].strip() if k < len(tokens) else ""
    return name, options


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _uv_transform(corner_uv, face_material, materials, uv_map):
    """Texture coordinates with the texture's ``-s`` scale and ``-o`` offset applied to
    the faces of its material (u' = u s + o, as MTL defines them), or as they are."""
    if corner_uv is None or uv_map is None:
        return corner_uv
    material, options = uv_map
    try:
        scale = [float(v) for v in options.get("-s", [])] + [1.0, 1.0]
        offset = [float(v) for v in options.get("-o", [])] + [0.0, 0.0]
    except ValueError:
        return corner_uv
    if scale[:2] == [1.0, 1.0] and offset[:2] == [0.0, 0.0] or material not in materials:
        return corner_uv
    mine = face_material == materials.index(material)
    out = corner_uv.copy()
    out[mine] = out[mine] * np.array(scale[:2]) + np.array(offset[:2])
    return out
