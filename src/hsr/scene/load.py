"""``hsr.load``: a mesh from a file (OBJ by hsr's own reader, every other format through
trimesh with ``process=False``: no merging, no reordering), a trimesh object or arrays.
``hsr.load_scene``: a :class:`Scene` with one instance per node of a glTF / GLB file (or of
a ``trimesh.Scene``).

trimesh keeps file order for single-material OBJ files but regroups faces by material when
an OBJ has several ``usemtl`` blocks, so OBJ files are read by :mod:`hsr.scene.obj`.

Node order (and so the global face ids) is the glTF file's: a depth-first walk of the
default scene from its root nodes, each node before its children, in the order the file
lists them (glTF 2.0, section 3.5 "Scenes"). trimesh keeps the node hierarchy and the
transforms but not that order, so the walk is done here on the file's own JSON; node names
are made unique exactly as trimesh makes them, which is how the two are matched.
"""

from __future__ import annotations

import copy
import io
import os
from typing import cast

import numpy as np

from ..choices import UpAxisChoice
from ..errors import HsrError, MeshError
from .assets import check_gltf_assets, check_gltf_nodes, folder_resolver, glb_chunks, gltf_json
from .cad import is_cad, read_cad
from .files import MAX_MESH_BYTES, check_regular, read_regular
from .images import MAX_TEXTURE_PIXELS
from .mesh import (
    Mesh,
    Scene,
    SceneLike,
    as_mesh,
    as_scene,
    from_trimesh,
    is_trimesh_scene,
    normal_matrix,
)
from .obj import read_obj
from .partitioned import PartitionedScene, open_partitioned

__all__ = ["load", "load_scene", "scene_of", "UpAxisChoice"]



_GLTF_EXTENSIONS = (".gltf", ".glb")
# The up axis a format declares: glTF 2.0 is +Y up (section 3.4); STL is written in the
# printer's frame, +Z the build direction, and 3MF says so (core spec, section 3.1).
# OBJ, PLY and OFF say nothing, so their meshes' up is unknown (None).
DECLARED_UP = {".gltf": "y", ".glb": "y", ".stl": "z", ".3mf": "z"}
UP_AXIS_CHOICES = ("auto", "y", "z")


def load(source: str | os.PathLike | SceneLike, max_bytes: int = MAX_MESH_BYTES,
         up_axis: UpAxisChoice = "auto") -> Mesh:
    """Load a mesh: a path (OBJ, PLY, STL, OFF, glTF, ...; STEP, IGES and BREP with the
    ``[cad]`` extra, see :mod:`hsr.scene.cad`), a ``trimesh.Trimesh``, a
    ``trimesh.Scene`` holding one mesh, or a ``(vertices, faces)`` pair. Face order is kept
    exactly. Only regular files of at most ``max_bytes`` are read. A file or scene with
    several meshes or nodes is refused: :func:`load_scene` keeps each node as an instance.

    Raises :class:`MeshError` for anything missing, unreadable, malformed, too large or
    invalid (bad indices, NaN or infinite coordinates used by a face, no faces), for a
    source of several meshes and for an unknown ``up_axis``.

    ``up_axis``: which world axis points up (:attr:`Mesh.up_axis`, which orients
    :func:`hsr.first_look` and the view sets): ``"auto"`` takes what the format declares
    (glTF +Y; STL and 3MF +Z) and leaves it unknown for the others; ``"y"`` or ``"z"``
    says it. Coordinates are never changed."""
    up = _up_choice(up_axis)
    return _declared(_load(source, max_bytes), source, up)


def _load(source, max_bytes: int) -> Mesh:
    if is_trimesh_scene(source):
        return _single(_scene_from_trimesh(source, None, "trimesh scene"), "the trimesh scene")
    if not isinstance(source, (str, os.PathLike)):
        return as_mesh(source)
    path = os.fspath(source)
    if path.lower().endswith(".obj"):
        return read_obj(path, max_bytes=max_bytes)
    if is_cad(path):
        return read_cad(path, max_bytes)
    loaded, header, read = _read_with_trimesh(path, max_bytes)
    if is_trimesh_scene(loaded):
        return _single(file_scene(loaded, header, path, read), path)
    return _with_sources(from_trimesh(loaded, os.path.basename(path)), read)


def load_scene(source: str | os.PathLike | SceneLike, max_bytes: int = MAX_MESH_BYTES,
               up_axis: UpAxisChoice = "auto") -> Scene | PartitionedScene:
    """A :class:`Scene` from a glTF / GLB file (or any file trimesh reads as a scene), a
    ``trimesh.Scene``, or anything :func:`load` takes (one instance).

    One instance per node that holds a mesh (a node whose mesh has several primitives
    gives one instance per primitive, named ``NODE/1``, ``NODE/2``, ...), placed by the
    node's world transform, named after the node; nodes that use the same mesh share one
    :class:`Mesh`. Instances come in the file's node order (see the module notes), so
    ``face_id`` is global in node order and ``object_id`` is the instance index.
    Materials: base-colour textures (embedded or external) and factors, vertex colours and
    face colours (see :func:`hsr.scene.mesh.from_trimesh`).

    A list (or tuple) of any of these is one scene of their instances in order, as the
    command line's several MODELs are.

    A folder written by :func:`hsr.partition` opens as a
    :class:`~hsr.scene.partitioned.PartitionedScene`, reading only its metadata.

    ``up_axis`` as for :func:`load`, for every mesh of the scene (a list: of each item).

    Raises :class:`MeshError` as :func:`load` does, and for a file without triangles."""
    up = _up_choice(up_axis)
    if isinstance(source, (list, tuple)) and not _is_arrays_pair(source):
        return _joined(source, max_bytes, up)
    loaded = _load_scene(source, max_bytes)
    if isinstance(loaded, PartitionedScene):
        return loaded
    for inst in loaded.instances:
        inst.mesh = _declared(inst.mesh, source, up)
    return loaded


def _up_choice(up_axis) -> UpAxisChoice:
    if not isinstance(up_axis, str) or up_axis not in UP_AXIS_CHOICES:
        raise MeshError(f"up_axis must be one of {', '.join(UP_AXIS_CHOICES)}, got "
                        f"{up_axis!r}")
    return cast(UpAxisChoice, up_axis)


def _declared(mesh: Mesh, source, up: str) -> Mesh:
    """``mesh`` with its up axis: ``up`` when given, else the one the format of the file
    ``source`` declares (a mesh given in memory keeps its own)."""
    is_path = isinstance(source, (str, os.PathLike))
    declared = (up if up != "auto" else None if not is_path
                else DECLARED_UP.get(os.path.splitext(os.fspath(source))[1].lower()))
    if declared is None or mesh.up_axis == declared:
        return mesh
    if not is_path:
        mesh = copy.copy(mesh)  # never relabel the caller's own mesh
    mesh.up_axis = declared
    return mesh


def _load_scene(source, max_bytes: int) -> Scene | PartitionedScene:
    if isinstance(source, (str, os.PathLike)) and os.path.isdir(source) \
            and os.path.lexists(os.path.join(source, "zarr.json")):
        return open_partitioned(source)  # a store, or the reason it is not one
    if is_trimesh_scene(source):
        return _scene_from_trimesh(source, None, "trimesh scene")
    if not isinstance(source, (str, os.PathLike)) or os.fspath(source).lower().endswith(".obj") \
            or is_cad(source):
        return Scene([_load(source, max_bytes)])
    path = os.fspath(source)
    loaded, header, read = _read_with_trimesh(path, max_bytes)
    if is_trimesh_scene(loaded):
        return file_scene(loaded, header, path, read)
    return Scene([_with_sources(from_trimesh(loaded, os.path.basename(path)), read)])


def _with_sources(mesh: Mesh, read: tuple) -> Mesh:
    """``mesh`` with the files it was read from (:attr:`Mesh.sources`) recorded."""
    mesh.sources = tuple(read)
    return mesh


def scene_of(source: str | os.PathLike | SceneLike) -> Scene:
    """A :class:`Scene` from what :func:`load_scene` takes (a path, a list of paths and
    meshes, a Scene, a Mesh, a trimesh, Open3D or PyVista mesh, a ``(vertices, faces)``
    pair); a partitioned scene is refused (see :func:`hsr.scene.mesh.as_scene`)."""
    if isinstance(source, (str, os.PathLike)) or (
            isinstance(source, (list, tuple)) and not _is_arrays_pair(source)):
        source = load_scene(source)
    return as_scene(source)


def _is_arrays_pair(source) -> bool:
    """True for a ``(vertices, faces)`` pair of arrays (not a list of two models)."""
    return isinstance(source, tuple) and len(source) == 2 and all(
        isinstance(a, np.ndarray) or (isinstance(a, list) and a and isinstance(a[0], (list,
                                                                                    tuple)))
        for a in source)


def _joined(sources, max_bytes: int, up: UpAxisChoice = "auto") -> Scene:
    """One scene of every item's instances, in order (as the CLI's several MODELs)."""
    if not sources:
        raise MeshError("an empty list of models: give at least one path or mesh")
    scene = Scene()
    for item in sources:
        loaded = load_scene(item, max_bytes, up)
        if isinstance(loaded, PartitionedScene):
            raise MeshError(f"{item}: a partitioned scene cannot join other models (hsr "
                            f"batch renders it on its own)")
        scene.instances.extend(loaded.instances)
    return scene


def file_scene(loaded, header, path: str, read: tuple = ()) -> Scene:
    """:func:`_scene_from_trimesh` of a file's trimesh scene, each mesh recording the
    files ``read`` for it; trimesh's scene graph fails in its own ways on files its
    loader let through, each a :class:`MeshError` here."""
    try:
        scene = _scene_from_trimesh(loaded, header, os.path.basename(path))
        for inst in scene.instances:
            inst.mesh.sources = tuple(read)
        return scene
    except HsrError:
        raise
    except Exception as exc:  # noqa: BLE001 - third-party code on untrusted data
        raise MeshError(f"{path}: cannot read its node tree ({type(exc).__name__}: "
                        f"{exc})") from None


def _single(scene: Scene, what: str) -> Mesh:
    """The one mesh of ``scene``, its node transform applied to the positions."""
    if len(scene.instances) != 1:
        raise MeshError(f"{what}: holds {len(scene.instances)} mesh nodes; use "
                        f"hsr.load_scene to keep each as an instance")
    inst = scene.instances[0]
    mesh = inst.mesh
    if np.array_equal(inst.model, np.eye(4)):
        return mesh
    positions = mesh.positions @ inst.model[:3, :3].T + inst.model[:3, 3]
    normals = (None if mesh.corner_normals is None
               else mesh.corner_normals @ normal_matrix(inst.model).T)  # shading normalises
    return Mesh(positions, mesh.faces, mesh.corner_uv, normals, mesh.face_colors, mesh.texture,
                mesh.name, mesh.corner_colors, mesh.sources, mesh.up_axis)


def _read_with_trimesh(path: str, max_bytes: int):
    """(trimesh object, glTF JSON header or None, the files read: the model and what it
    names) of a file."""
    import trimesh  # imported lazily: it is slow to import and OBJ does not need it

    check_regular(path, "mesh file", max_bytes)
    header, kind = None, None
    source: str | io.BytesIO = path
    # Every file the model names is read through this resolver: inside the model's
    # folder, regular files only, capped (see hsr.scene.assets).
    resolver = folder_resolver(os.path.dirname(os.path.abspath(path)), path)
    if path.lower().endswith(_GLTF_EXTENSIONS):
        data = read_regular(path, "mesh file", max_bytes)
        header, chunk = _gltf_header(data, path)
        check_gltf_nodes(header, path)
        check_gltf_assets(header, chunk, resolver, path, MAX_TEXTURE_PIXELS)
        # trimesh reads the bytes already in memory (a GLB with its textures can be
        # hundreds of MB), and the buffers and images through the resolver, which holds
        # those the checks read.
        source, kind = io.BytesIO(data), path.lower().rsplit(".", 1)[1]
    try:
        loaded = trimesh.load(source, file_type=kind, process=False, resolver=resolver)
    except HsrError:
        raise
    except Exception as exc:  # trimesh raises many types for malformed files
        raise MeshError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    if not is_trimesh_scene(loaded) and type(loaded).__name__ != "Trimesh":
        raise MeshError(f"{path}: no triangles found ({type(loaded).__name__})")
    return loaded, header, (os.path.abspath(path), *resolver.paths)


def _gltf_header(data: bytes, path: str) -> tuple:
    """(JSON, the binary chunk or None) of a .gltf file or a .glb (glTF 2.0, section
    4.4), through the checks the streamed reader shares (:func:`glb_chunks`,
    :func:`gltf_json`)."""
    if data[:4] != b"glTF":
        return gltf_json(data, path), None
    (start, length), bin_span = glb_chunks(lambda o, n: data[o:o + n], len(data), path)
    chunk = None if bin_span is None else data[bin_span[0]:bin_span[0] + bin_span[1]]
    return gltf_json(data[start:start + length], path), chunk


def _gltf_node_order(header: dict) -> list | None:
    """Node names (as trimesh names them) of the default scene, depth first, parents
    before children, in file order; None when the header does not describe a tree."""
    from trimesh.util import unique_name

    nodes = header.get("nodes", [])
    names: dict = {}
    counts: dict = {}
    for i, node in enumerate(nodes):  # the same loop as trimesh.exchange.gltf
        names[unique_name(node.get("name", str(i)), names, counts=counts)] = i
    by_index = {i: name for name, i in names.items()}
    scenes = header.get("scenes") or [{}]
    scene_index = header.get("scene", 0)
    if not isinstance(scene_index, int) or not 0 <= scene_index < len(scenes):
        return None
    order, stack, seen = [], list(reversed(scenes[scene_index].get("nodes", []))), set()
    while stack:
        i = stack.pop()
        if not isinstance(i, int) or not 0 <= i < len(nodes) or i in seen:
            return None
        seen.add(i)
        order.append(by_index[i])
        stack.extend(reversed(nodes[i].get("children", [])))
    return order


def _scene_from_trimesh(ts, header, label: str) -> Scene:
    """One instance per geometry node of the trimesh scene ``ts``, in glTF node order when
    ``header`` gives it, else in the order the geometry was added to ``ts``."""
    graph = ts.graph
    geometry_order = {name: k for k, name in enumerate(ts.geometry)}
    holders = {}  # frame -> geometry name, for frames that hold a triangle mesh
    for frame in graph.nodes_geometry:
        _, geom_name = graph[frame]
        if type(ts.geometry.get(geom_name)).__name__ == "Trimesh":
            holders[frame] = geom_name
    if not holders:
        raise MeshError(f"{label}: no triangles found (empty or unrecognised file)")
    children = graph.transforms.children if hasattr(graph.transforms, "children") else {}
    order = _gltf_node_order(header) if header is not None else None
    frames = []  # (frame, instance name)
    if order is not None:
        for node in order:
            if node in holders:
                frames.append((node, node))
            else:  # several primitives: trimesh hangs one child frame per primitive
                prims = sorted((f for f in children.get(node, ()) if f in holders
                                and f not in order), key=lambda f: geometry_order[holders[f]])
                frames += [(f, f"{node}/{k + 1}") for k, f in enumerate(prims)]
    if len(frames) != len(holders):  # not a glTF file, or a tree trimesh read differently
        frames = [(f, f) for f in sorted(holders, key=lambda f: geometry_order[holders[f]])]
    meshes, scene = {}, Scene()
    for frame, name in frames:
        geom_name = holders[frame]
        if geom_name not in meshes:
            try:
                meshes[geom_name] = from_trimesh(ts.geometry[geom_name], geom_name)
            except MeshError as exc:
                raise MeshError(f"{label}: {exc}") from None
        transform, _ = graph[frame]
        scene.add(meshes[geom_name], np.asarray(transform, dtype=np.float64), name=name)
    return scene
