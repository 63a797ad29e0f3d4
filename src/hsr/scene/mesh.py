"""Triangle meshes and the ``Scene`` of mesh instances that every renderer consumes:
validation, face degeneracy, conversion from trimesh objects and ``(vertices, faces)``.

Face order is part of hsr's contract (``face_id`` is the index in the loaded face list and
ties are decided by submission order): nothing here reorders faces. Reading files is
:mod:`hsr.scene.load` (and :mod:`hsr.scene.obj` for Wavefront OBJ).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, TypeAlias

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from ..errors import MeshError

# Coordinates (and products of two of them) must stay finite in float64.
MAX_COORDINATE = 1e100

__all__ = ["Mesh", "Scene", "Instance", "as_mesh", "as_scene", "instance_of", "is_trimesh_scene",
           "degenerate_faces", "is_degenerate", "normal_matrix"]


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
    face_colors : (F, 3) uint8 or None, a base colour per face (with a texture: a factor
        the texel is multiplied by, as glTF's ``baseColorFactor``).
    corner_colors : (F, 3, 3) uint8 or None, a base colour per face corner (vertex
        colours), interpolated across the face; multiplies ``face_colors`` and the texture.
    texture : path or (H, W, 3|4) uint8 array or None, the diffuse texture.
    name : a label used in messages.
    sources : the files the mesh was read from (the model, its .mtl, buffers and
        textures), which no hsr output may replace; empty for a mesh made in memory.
    up_axis : the world axis that points up, ``"y"`` or ``"z"``, as the file declares it
        (glTF: +Y; STL and 3MF: +Z, the build direction) or as :func:`hsr.load` was told;
        None when unknown (views then take +Y, OpenGL's). Coordinates are never changed:
        it orients the views (:func:`hsr.first_look`, :mod:`hsr.views`, the viewer).
    feature_lines : (S, 2, 3) float64 or None, model-space segments the model itself
        draws as its lines (a CAD model's B-rep edges on its tessellation, see
        :mod:`hsr.scene.cad`): feature-edge drawings take these and the silhouettes in
        place of the triangles' creases and boundaries.

    Raises :class:`~hsr.errors.MeshError` for arrays of the wrong shape or type, indices
    outside the vertices, NaN, infinite or huge (> 1e100) coordinates used by a face, no faces.

    The arrays are used as given when they already have the right type (no copy). Do not
    change them in place afterwards; assign new arrays instead (``mesh.positions = p``):
    what is derived from them once (:meth:`extent`, :meth:`degenerate_mask`) is kept per
    array object.
    """

    positions: np.ndarray
    faces: np.ndarray
    corner_uv: np.ndarray | None = None
    corner_normals: np.ndarray | None = None
    face_colors: np.ndarray | None = None
    texture: object = None
    name: str = "mesh"
    corner_colors: np.ndarray | None = None
    sources: tuple = ()
    up_axis: str | None = None
    feature_lines: np.ndarray | None = None

    def __post_init__(self):
        if self.up_axis is not None and self.up_axis not in ("y", "z"):
            raise MeshError(f"{self.name}: up_axis must be 'y', 'z' or None, got "
                            f"{self.up_axis!r}")
        self.positions, self.faces, extent = _validate_arrays(self.positions, self.faces,
                                                              self.name)
        self._extent = ((self.positions,), extent)
        self.sources = tuple(os.fspath(p) for p in self.sources)
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
            self.face_colors = _colors(colors, self.name, "face_colors")
        if self.corner_colors is not None:
            colors = np.asarray(self.corner_colors)
            if colors.shape != (n_faces, 3, 3):
                raise MeshError(f"{self.name}: corner_colors must have shape ({n_faces}, 3, 3), "
                                f"got {colors.shape}")
            self.corner_colors = _colors(colors, self.name, "corner_colors")
        if self.feature_lines is not None:
            lines = np.asarray(self.feature_lines, dtype=np.float64)
            if lines.ndim != 3 or lines.shape[1:] != (2, 3) or not np.isfinite(lines).all():
                raise MeshError(f"{self.name}: feature_lines must be finite (S, 2, 3) "
                                f"segments, got shape {np.shape(self.feature_lines)}")
            self.feature_lines = lines

    def __repr__(self):
        extras = [what for what, value in (("uv", self.corner_uv), ("normals",
                  self.corner_normals), ("face colours", self.face_colors), ("vertex colours",
                  self.corner_colors), ("texture", self.texture)) if value is not None]
        return (f"<hsr.Mesh {self.name!r}: {len(self.positions)} vertices, {self.n_faces} "
                f"faces{', ' + ', '.join(extras) if extras else ''}>")

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    def face_normals(self) -> np.ndarray:
        """(F, 3) unit normals from the counter-clockwise winding (zero for degenerate faces)."""
        tri = self.positions[self.faces]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        return np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)

    def extent(self) -> float:
        """Largest absolute coordinate of the vertices that faces use (unused vertices
        may hold anything, NaN included). Kept from the validation while ``positions`` is
        the same array: every render places the mesh again, and a scan of a million
        vertices per view is not free."""
        return cached_while_same(self, "_extent", (self.positions,),
                                 lambda: float(np.abs(self.used_positions()).max()))

    def degenerate_mask(self) -> np.ndarray:
        """(F,) bool, read-only: faces with a repeated vertex index or zero area (collinear
        corners). Such faces cover no pixel in OpenGL either; renderers skip and count
        them. Judged in model space, so it does not depend on the view: kept while
        ``positions`` and ``faces`` are the same arrays (every render asks again)."""

        def judge():
            mask = degenerate_faces(self.positions, self.faces)
            mask.flags.writeable = False
            return mask

        return cached_while_same(self, "_degenerate", (self.positions, self.faces), judge)

    def used_positions(self) -> np.ndarray:
        """(N, 3) positions of the vertices that faces use, in vertex order."""
        used = np.zeros(len(self.positions), dtype=bool)
        used[self.faces.ravel()] = True
        return self.positions if used.all() else self.positions[used]

    def bounds(self) -> np.ndarray:
        """(2, 3) array: min and max corner of the vertices that faces use."""
        pos = self.used_positions()
        return np.stack([pos.min(axis=0), pos.max(axis=0)])


def cached_while_same(owner, name, key, compute):
    """``compute()``, kept on ``owner`` as attribute ``name`` while every array of ``key``
    (a tuple) is the same object as when it was computed: what is derived from a mesh's
    arrays once instead of every render (replacing an array recomputes it; changing one
    in place is not noticed, see :class:`Mesh`)."""
    cached = getattr(owner, name, None)
    if cached is not None and len(cached[0]) == len(key) and all(
            a is b for a, b in zip(cached[0], key)):
        return cached[1]
    value = compute()
    setattr(owner, name, (key, value))
    return value


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
    check_face_indices(faces, len(positions), name)
    used = np.zeros(len(positions), dtype=bool)
    used[faces.ravel()] = True
    extent = check_used_positions(positions, used, name)
    return np.ascontiguousarray(positions), np.ascontiguousarray(faces), extent


def check_face_indices(faces: np.ndarray, n_vertices: int, name: str, first: int = 0) -> None:
    """Raise :class:`~hsr.errors.MeshError` for the first face of (F, 3) ``faces`` (face
    ``first`` and on: a streamed chunk's) with an index outside 0..n_vertices - 1: one
    message for the loaded and the streamed readers."""
    bad = (faces < 0) | (faces >= n_vertices)
    if bad.any():
        f = int(np.argwhere(bad)[0][0])
        raise MeshError(f"{name}: face {first + f} has vertex index {int(faces[bad][0])} "
                        f"outside 0..{n_vertices - 1}")


def check_used_positions(positions: np.ndarray, used: np.ndarray, name: str) -> float:
    """The largest absolute coordinate of the ``used`` vertices; raises
    :class:`~hsr.errors.MeshError` for one that is NaN, infinite or beyond
    :data:`MAX_COORDINATE` (unused vertices may hold anything)."""
    chosen = positions if used.all() else positions[used]
    with np.errstate(invalid="ignore"):
        largest = np.abs(chosen).max() if len(chosen) else 0.0
    if largest <= MAX_COORDINATE:  # (False for NaN) one flat pass where all is well
        return float(largest)
    finite = np.isfinite(positions).all(axis=1)
    if not finite[used].all():
        v = int(np.argwhere(~finite & used)[0][0])
        raise MeshError(f"{name}: vertex {v} has a NaN or infinite coordinate")
    with np.errstate(invalid="ignore"):  # unused vertices may be NaN
        magnitude = np.abs(positions).max(axis=1)
    huge = used & (magnitude > MAX_COORDINATE)
    if huge.any():
        v = int(np.argmax(huge))
        raise MeshError(f"{name}: vertex {v} has a coordinate beyond +-{MAX_COORDINATE:g} "
                        f"({np.abs(positions[v]).max():g}); products of coordinates must stay "
                        f"finite in float64")
    return float(magnitude[used].max())


def _colors(values, name, what) -> np.ndarray:
    """uint8 colours from numbers in 0..255 (floats are rounded, out-of-range clipped)."""
    if not (np.issubdtype(values.dtype, np.number) or values.dtype == np.bool_):
        raise MeshError(f"{name}: {what} must be numbers in 0..255")
    if not np.issubdtype(values.dtype, np.integer) and not np.isfinite(values).all():
        raise MeshError(f"{name}: {what} has a NaN or infinite value")
    return np.clip(np.round(values), 0, 255).astype(np.uint8)


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
    ``opacity`` < 1 makes the instance transparent (alpha blended, see hsr.appearance.transparency).
    ``name`` labels it (a glTF node's name; default the mesh's name).

    Raises :class:`~hsr.errors.MeshError` for a model matrix that is not a finite affine
    4x4 (last row 0, 0, 0, 1) or places vertices beyond 1e100, or an opacity outside [0, 1].
    """

    mesh: Mesh
    model: np.ndarray = field(default_factory=lambda: np.eye(4))
    opacity: float = 1.0
    name: str | None = None

    def __post_init__(self):
        if self.name is None:
            self.name = self.mesh.name
        if not isinstance(self.name, str):
            raise MeshError(f"instance name must be a string, got {self.name!r}")
        try:
            model = np.asarray(self.model, dtype=np.float64)
        except (TypeError, ValueError):
            model = np.zeros(0)
        if model.shape != (4, 4) or not np.isfinite(model).all():
            raise MeshError(f"{self.mesh.name}: model matrix must be a finite 4x4 array")
        if not np.array_equal(model[3], [0.0, 0.0, 0.0, 1.0]):
            # A projective model matrix would put points at infinity (w = 0) and is not
            # what a placement means; every stage applies the affine part.
            raise MeshError(f"{self.mesh.name}: model matrix must be affine (last row "
                            f"0, 0, 0, 1), got last row {model[3].tolist()}")
        reach = np.abs(model[:3, :3]).sum(axis=1).max() * self.mesh.extent() + \
            np.abs(model[:3, 3]).max()
        if not reach <= MAX_COORDINATE:
            raise MeshError(f"{self.mesh.name}: the model matrix places vertices beyond "
                            f"+-{MAX_COORDINATE:g}")
        self.model = model
        try:
            opacity = float(self.opacity)
        except (TypeError, ValueError):
            raise MeshError(f"{self.mesh.name}: opacity must be a number, "
                            f"got {self.opacity!r}") from None
        if not 0.0 <= opacity <= 1.0:
            raise MeshError(f"{self.mesh.name}: opacity must be in [0, 1], got {self.opacity!r}")
        self.opacity = opacity


def normal_matrix(model: np.ndarray) -> np.ndarray:
    """(3, 3) matrix that carries normals of a mesh placed by ``model``: the cofactor
    matrix of its 3x3 part, ``cof(M) (a x b) = (M a) x (M b)``. It is ``det(M) inv(M)^T``
    where M is invertible (the inverse transpose, scaled) and still defined where M is
    singular (a mesh flattened onto a plane gets the plane's normal)."""
    c = model[:3, :3]
    return np.stack([np.cross(c[:, 1], c[:, 2]), np.cross(c[:, 2], c[:, 0]),
                     np.cross(c[:, 0], c[:, 1])], axis=1)



def place_vertices(positions: np.ndarray, model: np.ndarray) -> np.ndarray:
    """``positions`` (V, 3) moved to world space by the instance matrix ``model`` (the
    arrays as they are for the identity). One expression wherever vertices are placed,
    so every path gives the same coordinates to the bit."""
    if np.array_equal(model, np.eye(4)):
        return positions
    return positions @ model[:3, :3].T + model[:3, 3]


class Scene:
    """Mesh instances drawn in order. ``face_id`` is global: the faces of the first
    instance come first, then the second's, and so on (submission order)."""

    def __init__(self, instances: Iterable[Instance | Mesh] = ()) -> None:
        self.instances: list[Instance] = []
        for item in instances:
            if isinstance(item, Instance):
                self.instances.append(item)
            elif isinstance(item, Mesh):
                self.add(item)
            else:
                self.add(*item)

    def add(self, mesh: Mesh, model: ArrayLike | None = None, opacity: float = 1.0,
            name: str | None = None) -> Scene:
        """Append an instance of ``mesh`` (a Mesh, trimesh.Trimesh or (vertices, faces))
        placed by ``model`` (4x4, default identity), labelled ``name`` (default the mesh's
        name). Returns the scene.

        Raises :class:`~hsr.errors.MeshError` as :class:`Mesh` and :class:`Instance` do."""
        if not isinstance(mesh, Mesh):
            mesh = as_mesh(mesh)
        self.instances.append(Instance(mesh, np.eye(4) if model is None else np.asarray(model),
                                       opacity, name))
        return self

    def __len__(self):
        return len(self.instances)

    def __getstate__(self):
        # Pickled (sent to Dask workers) without the joined arrays kept by assembled():
        # they would double what is sent, and a worker rebuilds them on first use.
        state = dict(self.__dict__)
        state.pop("_assembled", None)
        return state

    def __repr__(self):
        meshes = len({id(inst.mesh) for inst in self.instances})
        n = len(self.instances)
        return (f"<hsr.Scene: {n} instance{'s' * (n != 1)} of {meshes} "
                f"mesh{'es' * (meshes != 1)}, {self.n_faces} faces>")

    @property
    def n_faces(self) -> int:
        return sum(inst.mesh.n_faces for inst in self.instances)

    def sources(self) -> list:
        """The files the scene was read from (every mesh's :attr:`Mesh.sources` and
        texture paths), in first-use order: the inputs no output may replace."""
        found: dict = {}
        for inst in self.instances:
            texture = inst.mesh.texture
            paths = inst.mesh.sources + ((texture,) if isinstance(texture, str) else ())
            found.update(dict.fromkeys(os.path.abspath(p) for p in paths))
        return list(found)

    def up_axis(self) -> str:
        """The scene's up axis: the one its meshes declare (:attr:`Mesh.up_axis`) when they
        agree, else ``"y"`` (OpenGL's, and glTF's)."""
        declared = {inst.mesh.up_axis for inst in self.instances} - {None}
        return "z" if declared == {"z"} else "y"

    def face_offsets(self) -> np.ndarray:
        """(n_instances + 1,) start of each instance's faces in the global face list."""
        return np.concatenate([[0], np.cumsum([i.mesh.n_faces for i in self.instances])]).astype(
            np.int64
        )

    def instance_of(self, face_id: ArrayLike) -> np.ndarray:
        """Instance index of each global face id (see :func:`instance_of`)."""
        return instance_of(self.face_offsets(), face_id)

    def assembled(self) -> tuple:
        """The instances' meshes joined in submission order, as the geometry stage reads
        them: ``(positions (V, 3), faces (F, 3) into them, degenerate (F,) bool, owner
        (V,) int64 instance of each vertex)`` (model space: each instance's matrix is
        applied per view). Kept while the instances hold the same mesh arrays: a view of
        a scene of many parts would otherwise copy every vertex and face (28 ms of a
        140 ms render of a million faces in 16 parts). Do not modify the arrays."""
        meshes = [inst.mesh for inst in self.instances]

        def join():
            sizes = np.array([len(m.positions) for m in meshes], dtype=np.int64)
            starts = np.concatenate([[0], np.cumsum(sizes)])
            return (np.concatenate([m.positions for m in meshes]),
                    np.concatenate([m.faces + starts[k] if starts[k] else m.faces
                                    for k, m in enumerate(meshes)]),
                    np.concatenate([m.degenerate_mask() for m in meshes]),
                    np.repeat(np.arange(len(meshes), dtype=np.int64), sizes))

        key = tuple(array for m in meshes for array in (m.positions, m.faces))
        return cached_while_same(self, "_assembled", key, join)

    def world_mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """The vertices of every instance placed in world space, (V, 3) float64, and the
        faces indexing them, (F, 3) in submission order: :meth:`world_triangles` before
        its gather (the BVH build gathers corner by corner from these instead of holding
        the (F, 3, 3) corners)."""
        positions, faces, offset = [], [], 0
        for inst in self.instances:
            positions.append(place_vertices(inst.mesh.positions, inst.model))
            faces.append(inst.mesh.faces + offset if offset else inst.mesh.faces)
            offset += len(inst.mesh.positions)
        if len(positions) == 1:
            return positions[0], faces[0]
        if not positions:
            return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
        return np.concatenate(positions), np.concatenate(faces)

    def world_triangles(self) -> np.ndarray:
        """(F, 3, 3) world-space corners of every face, in submission order. Vertices
        are moved to world space once and then gathered, so the faces sharing a vertex
        get exactly the same coordinates for it (six times less arithmetic, too)."""
        positions, faces = self.world_mesh()
        return positions[faces]

    def world_points(self) -> np.ndarray:
        """(N, 3) world-space positions of the vertices that faces use, instance by
        instance (each vertex once, where the face corners repeat it about six times)."""
        parts = [inst.mesh.used_positions() @ inst.model[:3, :3].T + inst.model[:3, 3]
                 for inst in self.instances]
        return np.concatenate(parts) if parts else np.zeros((0, 3))

    def bounds(self) -> np.ndarray:
        """(2, 3) world-space bounding box of all instances."""
        points = self.world_points()
        return np.stack([points.min(axis=0), points.max(axis=0)])


def instance_of(face_offsets: np.ndarray, face_id) -> np.ndarray:
    """Index of the instance owning each global face id, given the scene's face offsets
    (:meth:`Scene.face_offsets`); -1 for face id -1."""
    return np.searchsorted(face_offsets, face_id, side="right") - 1


def as_mesh(source) -> Mesh:
    """A Mesh from a Mesh, a trimesh.Trimesh, an Open3D ``TriangleMesh``, a PyVista
    ``PolyData`` (its polygons triangulated) or a ``(vertices, faces)`` pair; neither
    Open3D nor PyVista is imported (the object is read through its own methods)."""
    if isinstance(source, Mesh):
        return source
    if isinstance(source, tuple) and len(source) == 2:
        return Mesh(source[0], source[1], name="arrays")
    if type(source).__name__ == "Trimesh":
        return from_trimesh(source, "trimesh")
    if type(source).__name__ == "TriangleMesh" and hasattr(source, "triangles"):
        return _from_open3d(source)
    if type(source).__name__ == "PolyData" and hasattr(source, "is_all_triangles"):
        return _from_pyvista(source)
    if is_trimesh_scene(source):
        raise MeshError("a trimesh.Scene holds nodes: make an hsr Scene with "
                        "hsr.load_scene(scene) (one instance per node)")
    raise MeshError(f"cannot make a mesh from {type(source).__name__}")


def _from_open3d(source) -> Mesh:
    """An Open3D ``TriangleMesh``: its vertices, triangles (in order) and vertex colours
    (0..1 floats, as corner colours)."""
    positions = np.asarray(source.vertices, dtype=np.float64)
    faces = np.asarray(source.triangles)
    colors = None
    if source.has_vertex_colors():
        rgb = np.asarray(source.vertex_colors, dtype=np.float64)
        if rgb.shape == positions.shape and np.isfinite(rgb).all() and len(faces) \
                and faces.min() >= 0 and faces.max() < len(rgb):
            colors = np.round(np.clip(rgb, 0, 1) * 255).astype(np.uint8)[faces]
    return Mesh(positions, faces, corner_colors=colors, name="open3d")


def _from_pyvista(source) -> Mesh:
    """A PyVista ``PolyData``: its points and polygons, triangulated by PyVista (as a fan
    from each polygon's first corner) when they are not all triangles; lines and points
    are not surfaces and are left out."""
    if not source.is_all_triangles:
        source = source.triangulate()
    faces = np.asarray(source.faces)
    if faces.size % 4:
        raise MeshError("pyvista: its faces are not all triangles after triangulating")
    return Mesh(np.asarray(source.points, dtype=np.float64), faces.reshape(-1, 4)[:, 1:],
                name="pyvista")


def is_trimesh_scene(value) -> bool:
    """True for a ``trimesh.Scene`` (told by its type's name and scene graph, so that
    trimesh need not be imported to ask)."""
    return type(value).__name__ == "Scene" and hasattr(value, "graph")


# What the public functions take as a scene (see as_scene): a Scene, a Mesh, a
# trimesh.Trimesh, a (vertices, faces) pair or a list of meshes. trimesh has no type
# information, so the alias stays loose on purpose; it names the argument's meaning.
SceneLike: TypeAlias = Any


def as_scene(source: SceneLike) -> Scene:
    """A Scene from a Scene, a Mesh, a trimesh.Trimesh, an Open3D or PyVista mesh (see
    :func:`as_mesh`), a (vertices, faces) pair or a list of these; paths load through
    :func:`hsr.load_scene` (and :func:`hsr.scene.load.scene_of`)."""
    if isinstance(source, Scene):
        if len(source) == 0:
            raise MeshError("scene is empty")
        return source
    if getattr(source, "kind", None) == "hsr-partitioned-scene":
        raise MeshError(f"{source!r} is partitioned: render it with hsr.batch."
                        f"render_partitioned (hsr batch STORE), or one part with .part(p)")
    if isinstance(source, list):
        return Scene([as_mesh(s) for s in source])
    return Scene([as_mesh(source)])


def from_trimesh(tm, name: str) -> Mesh:
    """A Mesh from a ``trimesh.Trimesh``, faces in its order, with what its visual holds:
    texture coordinates and the base-colour texture and factor of its material (glTF PBR
    or OBJ/MTL), vertex colours (interpolated) or face colours. Alpha is not used: hsr
    draws these surfaces opaque (set ``Instance.opacity`` to blend)."""
    # Checked before the per-vertex attributes are gathered through the faces (a file's
    # index past the vertex count would otherwise fail there as an IndexError).
    positions, faces, _ = _validate_arrays(tm.vertices, tm.faces, name)
    visual: Any = getattr(tm, "visual", None)
    kind = getattr(visual, "kind", None)
    corner_uv = texture = face_colors = corner_colors = None
    if kind == "texture":
        uv = getattr(visual, "uv", None)
        material = getattr(visual, "material", None)
        image = getattr(material, "baseColorTexture", None)
        if image is None:
            image = getattr(material, "image", None)
        if uv is not None and len(uv) == len(tm.vertices):
            corner_uv = np.asarray(uv, dtype=np.float64)[faces]
            if image is not None:
                texture = _image_rgb(image, name)
        factor = getattr(material, "baseColorFactor", None)
        if factor is None and type(material).__name__ != "PBRMaterial":
            # A glTF material without baseColorFactor means 1 (glTF 2.0, section 3.9.2:
            # the texture as it is); trimesh's main_color (102 grey) is no default of
            # the file's. Other materials keep their main (diffuse) colour.
            factor = getattr(material, "main_color", None)
        if factor is not None:
            rgb = np.asarray(factor, dtype=np.float64).reshape(-1)[:3]
            if texture is None or not np.all(rgb == 255):
                face_colors = np.broadcast_to(rgb, (len(faces), 3))
        colors = getattr(visual, "vertex_attributes", {}).get("color")
        if colors is not None and len(colors) == len(tm.vertices):
            corner_colors = np.asarray(colors)[:, :3][faces]
    elif kind == "vertex":
        corner_colors = np.asarray(visual.vertex_colors)[:, :3][faces]
    elif kind == "face":
        face_colors = np.asarray(visual.face_colors)[:, :3]
    return Mesh(positions, faces, corner_uv=corner_uv, corner_normals=_file_normals(tm, faces),
                face_colors=face_colors, texture=texture, name=name,
                corner_colors=corner_colors)


def _file_normals(tm, faces) -> np.ndarray | None:
    """(F, 3, 3) corner normals where the file gave vertex normals (glTF NORMAL, PLY nx ny
    nz), else None: trimesh keeps a file's normals in its cache (as its own PLY writer
    reads them) and computes them only when asked."""
    cache = getattr(tm, "_cache", None)
    try:
        given = "vertex_normals" in cache  # type: ignore[operator]
    except TypeError:
        return None
    normals = np.asarray(tm.vertex_normals, dtype=np.float64) if given else None
    if normals is None or normals.shape != (len(tm.vertices), 3):
        return None
    return normals[faces]


def _image_rgb(image, name: str) -> np.ndarray:
    """(H, W, 3) uint8 pixels of a Pillow image trimesh opened lazily: decoding happens
    here, so a truncated or corrupt picture is a :class:`MeshError`, not a traceback."""
    from .images import MAX_TEXTURE_PIXELS

    width, height = image.size
    if width * height > MAX_TEXTURE_PIXELS:
        raise MeshError(f"{name}: texture is {width}x{height} pixels, more than the "
                        f"{MAX_TEXTURE_PIXELS:,} hsr reads")
    try:
        return np.asarray(image.convert("RGB"))
    except (OSError, ValueError, SyntaxError, EOFError) as exc:
        raise MeshError(f"{name}: cannot decode its texture ({type(exc).__name__}: "
                        f"{exc})") from None


@njit(cache=True, nogil=True, inline="always")
def corner_cross(positions, a, b, c):
    """(B - A) x (C - A) of the vertices ``a``, ``b``, ``c`` of ``positions``: the face's
    normal as wound, twice its area long, in float64."""
    e1x, e1y, e1z = (positions[b, 0] - positions[a, 0], positions[b, 1] - positions[a, 1],
                     positions[b, 2] - positions[a, 2])
    e2x, e2y, e2z = (positions[c, 0] - positions[a, 0], positions[c, 1] - positions[a, 1],
                     positions[c, 2] - positions[a, 2])
    return e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x


@njit(cache=True, nogil=True, inline="always")
def is_degenerate(positions, a, b, c):
    # Repeated index, or zero area relative to the edge lengths (collinear corners): such
    # a face covers no pixel in OpenGL either, so it is skipped and counted.
    if a == b or b == c or a == c:
        return True
    e1x, e1y, e1z = (positions[b, 0] - positions[a, 0], positions[b, 1] - positions[a, 1],
                     positions[b, 2] - positions[a, 2])
    e2x, e2y, e2z = (positions[c, 0] - positions[a, 0], positions[c, 1] - positions[a, 1],
                     positions[c, 2] - positions[a, 2])
    nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    area2_sq = nx * nx + ny * ny + nz * nz
    scale = max(e1x * e1x + e1y * e1y + e1z * e1z, e2x * e2x + e2y * e2y + e2z * e2z)
    return area2_sq <= 1e-24 * scale * scale


@njit(cache=True)
def degenerate_faces(positions, faces):
    """(F,) bool: faces with a repeated vertex or zero area (see ``is_degenerate``)."""
    n = faces.shape[0]
    out = np.empty(n, dtype=np.bool_)
    for f in range(n):
        out[f] = is_degenerate(positions, faces[f, 0], faces[f, 1], faces[f, 2])
    return out
