"""``hsr.load``: a mesh from a file (OBJ by hsr's own reader, every other format through
trimesh with ``process=False``: no merging, no reordering), a trimesh object or arrays.

trimesh keeps file order for single-material OBJ files but regroups faces by material when
an OBJ has several ``usemtl`` blocks, so OBJ files are read by :mod:`hsr.scene.obj`.
"""

from __future__ import annotations

import os

from ..errors import MeshError
from .mesh import Mesh, as_mesh, from_trimesh
from .files import MAX_MESH_BYTES, check_regular
from .obj import read_obj

__all__ = ["load"]


def load(source, max_bytes: int = MAX_MESH_BYTES) -> Mesh:
    """Load a mesh: a path (OBJ, PLY, STL, OFF, glTF, ...), a ``trimesh.Trimesh`` or a
    ``(vertices, faces)`` pair. Face order is kept exactly. Only regular files of at most
    ``max_bytes`` are read. Raises :class:`MeshError` for anything missing, unreadable,
    malformed, too large or invalid (bad indices, NaN or infinite coordinates used by a
    face, no faces)."""
    if not isinstance(source, (str, os.PathLike)):
        return as_mesh(source)
    path = os.fspath(source)
    if path.lower().endswith(".obj"):
        return read_obj(path, max_bytes=max_bytes)
    check_regular(path, "mesh file", max_bytes)
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
    return from_trimesh(loaded, os.path.basename(path))
