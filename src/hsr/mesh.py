"""Triangle meshes: validation, loading (OBJ by hsr's own reader, other formats through
trimesh), and the ``Scene`` of mesh instances that every renderer consumes.

Face order is part of hsr's contract (``face_id`` is the index in the loaded face list and
ties are decided by submission order), so loading must never reorder faces. trimesh keeps
file order for single-material OBJ files but regroups faces by material when an OBJ has
several ``usemtl`` blocks, so OBJ files are read by :func:`read_obj` below, which keeps
file order exactly and fan-triangulates n-gons ``(v0, v1, v2), (v0, v2, v3), ...``.
PLY, STL, OFF, glTF/GLB and anything else trimesh understands go through trimesh with
``process=False`` (no merging, no reordering).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import numpy as np

from .errors import MeshError

__all__ = ["Mesh", "Scene", "Instance", "load", "read_obj", "as_scene", "instance_of"]


@dataclass(eq=False)
class Mesh:
    """A triangle mesh in model space.

    Attributes
    ----------
    positions : (V, 3) float64 array, model-space vertex positions.
    faces : (F, 3) int64 array of vertex indices; counter-clockwise = front by default.
    corner_uv : (F, 3, 2) float64 or None, texture coordinates per face corner
        (OBJ convention: v = 0 is the bottom row of the image).
    corner_normals : (F, 3, 3) float64 or None, normals per face corner.
    face_colors : (F, 3) uint8 or None, a base colour per face.
    texture : path or (H, W, 3|4) uint8 array or None, the diffuse texture.
    name : a label used in messages.
    """

    positions: np.ndarray
    faces: np.ndarray
    corner_uv: np.ndarray | None = None
    corner_normals: np.ndarray | None = None
    face_colors: np.ndarray | None = None
    texture: object = None
    name: str = "mesh"

    def __post_init__(self):
        self.positions, self.faces = _validate_arrays(self.positions, self.faces, self.name)
        n_faces = len(self.faces)
        self.corner_uv = _validate_corner(self.corner_uv, (n_faces, 3, 2), "corner_uv", self.name)
        self.corner_normals = _validate_corner(
            self.corner_normals, (n_faces, 3, 3), "corner_normals", self.name
        )
        if self.face_colors is not None:
            colors = np.asarray(self.face_colors)
            if colors.shape != (n_faces, 3):
                raise MeshError(
                    f"{self.name}: face_colors must have shape ({n_faces}, 3), got {colors.shape}"
                )
            self.face_colors = np.clip(colors, 0, 255).astype(np.uint8)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    def face_normals(self) -> np.ndarray:
        """(F, 3) unit normals from the counter-clockwise winding (zero for degenerate faces)."""
        tri = self.positions[self.faces]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        return np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)

    def degenerate_mask(self) -> np.ndarray:
        """(F,) bool: faces with a repeated vertex index or zero area (collinear corners).

        Such faces cover no pixel in OpenGL either; renderers skip and count them.
        """
        from .pipeline import degenerate_faces

        return degenerate_faces(self.positions, self.faces)

    def bounds(self) -> np.ndarray:
        """(2, 3) array: min and max corner of the vertices that faces use."""
        used = np.zeros(len(self.positions), dtype=bool)
        used[self.faces.ravel()] = True
        pos = self.positions if used.all() else self.positions[used]
        return np.stack([pos.min(axis=0), pos.max(axis=0)])


def _validate_arrays(positions, faces, name):
    try:
        positions = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise MeshError(f"{name}: vertex positions are not numeric ({exc})") from None
    try:
        faces_in = np.asarray(faces)
    except (TypeError, ValueError) as exc:
        raise MeshError(f"{name}: faces are not an integer array ({exc})") from None
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise MeshError(f"{name}: vertex positions must have shape (V, 3), got {positions.shape}")
    if faces_in.size == 0:
        raise MeshError(f"{name}: mesh is empty (no faces)")
    if faces_in.ndim != 2 or faces_in.shape[1] != 3:
        raise MeshError(f"{name}: faces must have shape (F, 3), got {faces_in.shape}")
    if not np.issubdtype(faces_in.dtype, np.integer):
        if not np.issubdtype(faces_in.dtype, np.floating) or np.any(faces_in != np.round(faces_in)):
            raise MeshError(f"{name}: face indices must be integers")
    faces = faces_in.astype(np.int64)
    if len(positions) == 0:
        raise MeshError(f"{name}: mesh is empty (no vertices)")
    bad = (faces < 0) | (faces >= len(positions))
    if bad.any():
        f = int(np.argwhere(bad)[0][0])
        raise MeshError(
            f"{name}: face {f} has vertex index {int(faces[bad][0])} outside 0..{len(positions) - 1}"
        )
    finite = np.isfinite(positions).all(axis=1)
    used = np.zeros(len(positions), dtype=bool)
    used[faces.ravel()] = True
    if not finite[used].all():
        v = int(np.argwhere(~finite & used)[0][0])
        raise MeshError(f"{name}: vertex {v} has a NaN or infinite coordinate")
    return np.ascontiguousarray(positions), np.ascontiguousarray(faces)


def _validate_corner(values, shape, what, name):
    if values is None:
        return None
    values = np.asarray(values, dtype=np.float64)
    if values.shape != shape:
        raise MeshError(f"{name}: {what} must have shape {shape}, got {values.shape}")
    if not np.isfinite(values).all():
        raise MeshError(f"{name}: {what} has a NaN or infinite value")
    return values


@dataclass(eq=False)
class Instance:
    """A mesh placed in the world by a 4x4 model matrix (column vectors: p_world = M @ p).
    ``opacity`` < 1 makes the instance transparent (alpha blended, see hsr.transparency)."""

    mesh: Mesh
    model: np.ndarray = field(default_factory=lambda: np.eye(4))
    opacity: float = 1.0

    def __post_init__(self):
        model = np.asarray(self.model, dtype=np.float64)
        if model.shape != (4, 4) or not np.isfinite(model).all():
            raise MeshError(f"{self.mesh.name}: model matrix must be a finite 4x4 array")
        self.model = model
        try:
            opacity = float(self.opacity)
        except (TypeError, ValueError):
            raise MeshError(f"{self.mesh.name}: opacity must be a number, "
                            f"got {self.opacity!r}") from None
        if not 0.0 <= opacity <= 1.0:
            raise MeshError(f"{self.mesh.name}: opacity must be in [0, 1], got {self.opacity!r}")
        self.opacity = opacity


class Scene:
    """Mesh instances drawn in order. ``face_id`` is global: the faces of the first
    instance come first, then the second's, and so on (submission order)."""

    def __init__(self, instances=()):
        self.instances: list[Instance] = []
        for item in instances:
            if isinstance(item, Instance):
                self.instances.append(item)
            elif isinstance(item, Mesh):
                self.add(item)
            else:
                self.add(*item)

    def add(self, mesh: Mesh, model=None, opacity: float = 1.0) -> "Scene":
        if not isinstance(mesh, Mesh):
            mesh = as_mesh(mesh)
        self.instances.append(Instance(mesh, np.eye(4) if model is None else model, opacity))
        return self

    def __len__(self):
        return len(self.instances)

    @property
    def n_faces(self) -> int:
        return sum(inst.mesh.n_faces for inst in self.instances)

    def face_offsets(self) -> np.ndarray:
        """(n_instances + 1,) start of each instance's faces in the global face list."""
        return np.concatenate([[0], np.cumsum([i.mesh.n_faces for i in self.instances])]).astype(
            np.int64
        )

    def instance_of(self, face_id) -> np.ndarray:
        """Instance index of each global face id (see :func:`instance_of`)."""
        return instance_of(self.face_offsets(), face_id)

    def world_triangles(self) -> np.ndarray:
        """(F, 3, 3) world-space corners of every face, in submission order."""
        parts = []
        for inst in self.instances:
            tri = inst.mesh.positions[inst.mesh.faces]
            parts.append(tri @ inst.model[:3, :3].T + inst.model[:3, 3])
        return np.concatenate(parts) if parts else np.zeros((0, 3, 3))

    def bounds(self) -> np.ndarray:
        """(2, 3) world-space bounding box of all instances."""
        tri = self.world_triangles().reshape(-1, 3)
        return np.stack([tri.min(axis=0), tri.max(axis=0)])


def instance_of(face_offsets: np.ndarray, face_id) -> np.ndarray:
    """Index of the instance owning each global face id, given the scene's face offsets
    (:meth:`Scene.face_offsets`); -1 for face id -1."""
    return np.searchsorted(face_offsets, face_id, side="right") - 1


def as_mesh(source) -> Mesh:
    """A Mesh from a Mesh, a trimesh.Trimesh or a ``(vertices, faces)`` pair."""
    if isinstance(source, Mesh):
        return source
    if isinstance(source, tuple) and len(source) == 2:
        return Mesh(source[0], source[1], name="arrays")
    if type(source).__name__ == "Trimesh":
        return _from_trimesh(source, "trimesh")
    raise MeshError(f"cannot make a mesh from {type(source).__name__}")


def as_scene(source) -> Scene:
    """A Scene from a Scene, a Mesh, a trimesh.Trimesh, a (vertices, faces) pair or a list."""
    if isinstance(source, Scene):
        if len(source) == 0:
            raise MeshError("scene is empty")
        return source
    if isinstance(source, list):
        return Scene([as_mesh(s) for s in source])
    return Scene([as_mesh(source)])


def load(source) -> Mesh:
    """Load a mesh: a path (OBJ, PLY, STL, OFF, glTF, ...), a ``trimesh.Trimesh`` or a
    ``(vertices, faces)`` pair. Face order is kept exactly. Raises :class:`MeshError`."""
    if not isinstance(source, (str, os.PathLike)):
        return as_mesh(source)
    path = os.fspath(source)
    if not os.path.exists(path):
        raise MeshError(f"file not found: {path}")
    if os.path.isdir(path):
        raise MeshError(f"{path} is a directory, not a mesh file")
    if path.lower().endswith(".obj"):
        return read_obj(path)
    return _load_with_trimesh(path)


def _load_with_trimesh(path: str) -> Mesh:
    import trimesh  # imported lazily: it is slow to import and OBJ does not need it

    try:
        loaded = trimesh.load(path, process=False)
    except Exception as exc:  # trimesh raises many types for malformed files
        raise MeshError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    if isinstance(loaded, trimesh.Scene):
        geometries = [g for g in loaded.dump() if isinstance(g, trimesh.Trimesh)]
        if not geometries:
            raise MeshError(f"{path}: no triangles found (empty or unrecognised file)")
        if len(geometries) > 1:
            raise MeshError(
                f"{path}: the file holds {len(geometries)} meshes; hsr cannot keep one face "
                "order across them, export a single mesh"
            )
        loaded = geometries[0]
    if not isinstance(loaded, trimesh.Trimesh):
        raise MeshError(f"{path}: no triangles found ({type(loaded).__name__})")
    return _from_trimesh(loaded, os.path.basename(path))


def _from_trimesh(tm, name: str) -> Mesh:
    faces = np.asarray(tm.faces)
    corner_uv = None
    uv = getattr(tm.visual, "uv", None)
    if uv is not None and len(uv) == len(tm.vertices):
        corner_uv = np.asarray(uv, dtype=np.float64)[faces]
    return Mesh(np.asarray(tm.vertices), faces, corner_uv=corner_uv, name=name)


def read_obj(path: str) -> Mesh:
    """Read a Wavefront OBJ file keeping file order; n-gons are fan-triangulated.

    Supports ``v``, ``vt``, ``vn``, ``f`` with ``i``, ``i/j``, ``i//k``, ``i/j/k`` and
    negative (relative) indices, ``mtllib``/``usemtl`` (``Kd`` colours and the first
    ``map_Kd`` texture). Other statements are ignored. Raises :class:`MeshError` with the
    line number on anything malformed. One pass over the lines sorts them by tag; the
    numbers are then converted by NumPy in bulk (the bunny's 105k lines in ~0.1 s).
    """
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            text = fh.read()
    except OSError as exc:
        raise MeshError(f"{path}: cannot read ({exc.strerror})") from None
    name = os.path.basename(path)
    plain = _read_plain_triangles(text, name)
    if plain is not None:
        return plain
    scanned = _scan_fast(text)
    if scanned is not None:
        try:
            return _build_obj(path, name, *scanned)
        except MeshError:
            pass  # read it again carefully, to report the line
    return _build_obj(path, name, *_scan_careful(text, name))


def _read_plain_triangles(text: str, name: str):
    """The most common OBJ of all (scans such as the bunny): only ``v x y z`` and
    ``f i j k`` with positive indices. Two regular expressions and two NumPy conversions;
    None when the file has anything else (the general reader takes it)."""
    if "/" in text or "\t" in text or "vt" in text or "vn" in text or "mtl" in text \
            or "-" in text.split("\nf", 1)[-1]:
        return None
    tri = re.findall(r"^f +(\d+) +(\d+) +(\d+) *$", text, re.M)
    pos = re.findall(r"^v +(\S+) +(\S+) +(\S+) *$", text, re.M)
    if (not tri or len(tri) != len(re.findall(r"^f", text, re.M))
            or len(pos) != len(re.findall(r"^v", text, re.M))):
        return None
    try:
        positions = np.array(pos, dtype=np.float64)
    except ValueError:
        return None  # let the careful reader name the line
    faces = np.array(tri, dtype=np.int64) - 1
    if faces.min() < 0 or faces.max() >= len(positions):
        return None
    return Mesh(positions, faces, name=name)


def _scan_careful(text: str, name: str):
    """Sort the lines of an OBJ file by tag, keeping line numbers and, for each face, how
    many v / vt / vn came before it (for negative indices)."""
    v_rows, vt_rows, vn_rows = [], [], []
    f_rows, f_lines, f_nv, f_nt, f_nn = [], [], [], [], []
    mat_events: list[tuple[int, str]] = []  # (face number where it starts, material)
    mtllibs: list[str] = []
    for lineno, line in enumerate(text.splitlines(), 1):
        head = line[:2]
        if head == "v ":
            v_rows.append((lineno, line))
        elif head == "f ":
            f_rows.append(line[2:])
            f_lines.append(lineno)
            f_nv.append(len(v_rows))
            f_nt.append(len(vt_rows))
            f_nn.append(len(vn_rows))
        elif head == "vt":
            vt_rows.append((lineno, line))
        elif head == "vn":
            vn_rows.append((lineno, line))
        elif line.startswith("usemtl"):
            parts = line.split()
            mat_events.append((len(f_rows), parts[1] if len(parts) > 1 else ""))
        elif line.startswith("mtllib"):
            mtllibs.extend(line.split()[1:])
        elif head.strip() == "f" or head in ("v\t", "f\t"):
            raise MeshError(f"{name}:{lineno}: cannot parse {line.strip()[:60]!r}")
    return v_rows, vt_rows, vn_rows, f_rows, f_lines, f_nv, f_nt, f_nn, mat_events, mtllibs


def _scan_fast(text: str):
    """The same as :func:`_scan_careful` with regular expressions (C speed), for the
    common files: no tabs, no materials, no negative indices. None when not applicable;
    line numbers are left 0 (a failure is re-read carefully to report its line)."""
    if "\t" in text or "usemtl" in text or "mtllib" in text:
        return None
    f_rows = re.findall(r"^f (.*)$", text, re.M)
    if len(f_rows) != len(re.findall(r"^f", text, re.M)) or "-" in "".join(f_rows):
        return None
    v_rows = [(0, r) for r in re.findall(r"^(v .*)$", text, re.M)]
    if len(v_rows) != len(re.findall(r"^v(?![tn])", text, re.M)):
        return None
    vt_rows = [(0, r) for r in re.findall(r"^(vt .*)$", text, re.M)]
    vn_rows = [(0, r) for r in re.findall(r"^(vn .*)$", text, re.M)]
    zeros = [0] * len(f_rows)
    return v_rows, vt_rows, vn_rows, f_rows, zeros, zeros, zeros, zeros, [], []


def _build_obj(path, name, v_rows, vt_rows, vn_rows, f_rows, f_lines, f_nv, f_nt, f_nn,
               mat_events, mtllibs) -> Mesh:
    if not f_rows:
        raise MeshError(f"{name}: mesh is empty (no faces)")
    positions = _obj_numbers(v_rows, 3, 3, name, "vertex")
    uvs = _obj_numbers(vt_rows, 1, 2, name, "texture coordinate")
    normals = _obj_numbers(vn_rows, 3, 3, name, "normal")

    tokens = [row.split() for row in f_rows]
    counts = np.fromiter((len(t) for t in tokens), dtype=np.int64, count=len(tokens))
    if counts.min() < 3:
        bad = int(np.argmax(counts < 3))
        raise MeshError(f"{name}:{f_lines[bad]}: a face needs at least 3 vertices")
    flat = [tok for toks in tokens for tok in toks]
    refs = _obj_face_refs(flat, name)  # (corners, 3) int64: v, vt, vn (0 = absent)
    corner_face = np.repeat(np.arange(len(counts)), counts)
    limits = (np.array(f_nv)[corner_face], np.array(f_nt)[corner_face],
              np.array(f_nn)[corner_face])
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
            raise MeshError(f"{name}:{f_lines[corner_face[k]]}: {what[c]} index {int(ref[k])} "
                            f"outside 1..{totals[c]}")
        resolved[:, c] = np.where(present, idx, -1)

    # Fan triangulation in file order: polygon (c0, c1, ..., cn-1) -> (c0, ck, ck+1).
    n_tris = counts - 2
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    tri_poly = np.repeat(np.arange(len(counts)), n_tris)
    k = np.arange(int(n_tris.sum())) - np.repeat(np.cumsum(n_tris) - n_tris, n_tris) + 1
    corner = np.stack([start[tri_poly], start[tri_poly] + k, start[tri_poly] + k + 1], axis=1)
    faces = resolved[corner, 0]
    corner_uv = uvs[resolved[corner, 1]] if len(uvs) and (resolved[:, 1] >= 0).all() else None
    corner_normals = (normals[resolved[corner, 2]]
                      if len(normals) and (resolved[:, 2] >= 0).all() else None)
    materials: list[str] = []
    poly_mat = np.full(len(counts), -1, dtype=np.int64)
    for first_face, mat in mat_events:
        if mat not in materials:
            materials.append(mat)
        poly_mat[first_face:] = materials.index(mat)
    face_colors, texture = _read_materials(path, mtllibs, materials, poly_mat[tri_poly])
    return Mesh(positions, faces, corner_uv=corner_uv, corner_normals=corner_normals,
                face_colors=face_colors, texture=texture, name=name)


def _obj_numbers(rows, min_count, keep, name, what) -> np.ndarray:
    """(N, keep) float64 from OBJ lines ``tag a b c ...``; extra values (w, colours) are
    dropped, missing optional ones are zero."""
    if not rows:
        return np.zeros((0, keep))
    fields = [line.split()[1:] for _, line in rows]
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
        for (lineno, line), f in zip(rows, fields):
            try:
                if len(f) < min_count:
                    raise ValueError
                [float(x) for x in f[:keep]]
            except ValueError:
                raise MeshError(f"{name}:{lineno}: bad {what} {line.strip()[:60]!r}") from None
        raise MeshError(f"{name}: bad {what} data") from None


def _obj_face_refs(flat, name) -> np.ndarray:
    """(corners, 3) int64 (v, vt, vn) from face tokens like ``7``, ``7/2``, ``7//3``,
    ``7/2/3``; absent fields are 0."""
    out = np.zeros((len(flat), 3), dtype=np.int64)
    joined = " ".join(flat)
    n_slash = joined.count("/")
    try:
        if n_slash == 0:
            out[:, 0] = np.array(flat, dtype=np.int64)
            return out
        n_double = joined.count("//")
        if n_slash == 2 * len(flat) and (n_double in (0, len(flat))):
            # Uniform v/t/n or v//n: bulk conversion.
            nums = np.array(joined.replace("//", "/0/").replace("/", " ").split(),
                            dtype=np.int64).reshape(-1, 3)
            return nums
        if n_slash == len(flat) and n_double == 0:
            out[:, :2] = np.array(joined.replace("/", " ").split(), dtype=np.int64).reshape(-1, 2)
            return out
    except ValueError:
        pass
    for i, tok in enumerate(flat):  # mixed forms, or a bad token to report
        parts = tok.split("/")
        try:
            if len(parts) > 3 or not parts[0]:
                raise ValueError
            for c, p in enumerate(parts):
                out[i, c] = int(p) if p else 0
        except ValueError:
            raise MeshError(f"{name}: bad face vertex {tok!r}") from None
    return out


def _read_materials(obj_path, mtllibs, materials, face_mat):
    """Kd colours per face and the first map_Kd texture path from the OBJ's .mtl files.
    A missing .mtl is not an error (many OBJ files name one they do not ship)."""
    if not mtllibs or not materials:
        return None, None
    base = os.path.dirname(obj_path)
    kd: dict[str, tuple] = {}
    texture = None
    for lib in mtllibs:
        mtl_path = os.path.join(base, lib)
        if not os.path.exists(mtl_path):
            continue
        current = None
        with open(mtl_path, encoding="utf-8", errors="replace") as fh:
            for line in fh:
                parts = line.split()
                if not parts:
                    continue
                if parts[0] == "newmtl" and len(parts) > 1:
                    current = parts[1]
                elif parts[0] == "Kd" and current is not None and len(parts) >= 4:
                    try:
                        kd[current] = tuple(float(x) for x in parts[1:4])
                    except ValueError:
                        continue
                elif parts[0] == "map_Kd" and texture is None and len(parts) > 1:
                    candidate = os.path.join(base, parts[-1])
                    if os.path.exists(candidate):
                        texture = candidate
    if not kd:
        return None, texture
    table = np.array([kd.get(m, (0.8, 0.8, 0.8)) for m in materials] + [(0.8, 0.8, 0.8)])
    colors = np.round(np.clip(table[face_mat], 0, 1) * 255).astype(np.uint8)
    return colors, texture
