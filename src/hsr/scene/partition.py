"""Writing partitioned scenes (:func:`partition`; the store's layout and reading are in
:mod:`hsr.scene.partitioned`).

Faces are ordered along the Morton (Z-order) curve of their centroids in the scene's box
(Morton 1966; the order LBVH builders such as Lauterbach et al. 2009 sort by) and that
order is cut into ``parts`` runs of equal face counts: each part is a compact region of
space, and any cut is as good as another for correctness. Inside a part the faces keep
their global (submission) order, which is what makes sort-last compositing exact (see
:mod:`hsr.batch.sortlast`). A store is written under a temporary name and renamed when
complete, so an interrupted write leaves nothing under the output name.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile

import numpy as np

from ..errors import MeshError, OutputError, require_extra
from ..parallel import progress_bar
from .gltf_stream import GlbStream, is_glb
from .load import load_scene
from .mesh import Scene, SceneLike, as_scene, check_used_positions, instance_of, place_vertices
from .obj_stream import ObjStream
from .outputs import check_store_target, input_inside
from .partitioned import (
    FACE_ATTRIBUTES,
    KIND,
    VERSION,
    PartitionedScene,
    PartitionError,
    is_partitioned,
    open_partitioned,
)
from .ply import PlyLayout, face_chunks, is_binary_ply, read_layout, read_positions

__all__ = ["partition", "partition_streamed", "morton_order", "morton_codes", "MAX_PARTS"]

MAX_PARTS = 65536
# Every chunk written, those equal to the fill value too, so that a reader can refuse a
# missing chunk as a loss (see hsr.scene.partitioned).
_EVERY_CHUNK = {"write_empty_chunks": True}


def morton_order(centroids: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Stable order of (N, 3) ``centroids`` along the 3-D Morton curve of the box
    [``lo``, ``hi``], 21 bits per axis (ties keep their index order)."""
    return np.argsort(morton_codes(centroids, lo, hi), kind="stable")


def morton_codes(centroids: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(N,) uint64 Morton codes of (N, 3) points in the box [``lo``, ``hi``]: each axis
    quantised to 21 bits, the bits interleaved (x lowest)."""
    extent = np.where(hi > lo, hi - lo, 1.0)
    cells = np.clip((centroids - lo) / extent * (2 ** 21), 0, 2 ** 21 - 1).astype(np.uint64)
    code = np.zeros(len(centroids), dtype=np.uint64)
    for axis in range(3):
        code |= _spread_bits(cells[:, axis]) << np.uint64(axis)
    return code


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """Insert two zero bits between each of the low 21 bits of ``v`` (the standard
    magic-number dilation for 3-D Morton codes)."""
    v = v & np.uint64(0x1FFFFF)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF),
                        (8, 0x100F00F00F00F00F), (4, 0x10C30C30C30C30C3),
                        (2, 0x1249249249249249)):
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def partition(scene: SceneLike, parts: int, out: str | os.PathLike,
              overwrite: bool = False, progress: bool | None = None,
              stream: bool | None = None) -> PartitionedScene:
    """Split ``scene`` (a Scene, Mesh, path, ...) into ``parts`` spatially coherent parts
    and write them to the Zarr store ``out`` (see the module); returns it opened.
    ``stream``: read a path (binary PLY, OBJ or GLB) in chunks (:func:`partition_streamed`),
    so its faces never all sit in memory, keeping geometry only; by default (None) a
    binary PLY that holds nothing but geometry streams and everything else is loaded. A
    streamed file shows a progress bar on a terminal (``progress`` forces it on or off).
    Raises :class:`PartitionError` for a part count outside
    1..min(faces, 65536), an ``out`` that exists (unless ``overwrite``) or whose folder
    does not, :class:`~hsr.errors.MeshError` for a model that does not load and
    :class:`~hsr.errors.MissingExtraError` without Zarr."""
    require_extra("hsr partition", "zarr")
    if not isinstance(scene, (str, os.PathLike)):
        scene = as_scene(scene)
    out = _check_out(out, overwrite, [scene] if isinstance(scene, (str, os.PathLike))
                     else scene.sources())
    if stream not in (None, True, False):
        raise PartitionError(f"stream must be True, False or None, got {stream!r}")
    if isinstance(scene, (str, os.PathLike)):
        path = os.fspath(scene)
        if stream is None:
            stream = is_binary_ply(path) and read_layout(path).geometry_only
        if stream:
            return partition_streamed(path, parts, out, overwrite, progress=progress)
        scene = load_scene(path)
        _check_out(out, overwrite, getattr(scene, "sources", list)())
    elif stream:
        raise PartitionError("stream=True reads a file: give its path")
    scene = as_scene(scene)
    _check_parts(parts, scene.n_faces)

    def write(root, scratch) -> dict:
        return _write_in_memory(scene, parts, root)

    return _write_store(out, write)


def _check_out(out: str | os.PathLike, overwrite: bool, inputs=()) -> str:
    """``out`` where a store may be written (:func:`hsr.scene.outputs.check_store_target`:
    nothing, an empty folder, or with ``overwrite`` a partitioned scene), holding none of
    the ``inputs`` (the model files) and being none of them."""
    out = os.fspath(out)
    folder = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(folder):
        raise PartitionError(f"cannot write {out}: folder {folder} does not exist")
    found = input_inside(inputs, [out])
    if found:
        raise PartitionError(f"--out {out} would replace the model {found[0]}, an input: "
                             f"write the store elsewhere")
    try:
        check_store_target(out, overwrite, is_partitioned, "--out", "partitioned scene")
    except OutputError as exc:
        raise PartitionError(str(exc)) from None
    return out


def _check_parts(parts, n_faces: int) -> None:
    if isinstance(parts, bool) or not isinstance(parts, (int, np.integer)) \
            or not 1 <= parts <= min(n_faces, MAX_PARTS):
        raise PartitionError(f"parts must be an integer in 1..{min(n_faces, MAX_PARTS)} "
                             f"(the scene has {n_faces:,} faces), got {parts!r}")


def _write_store(out: str, write) -> PartitionedScene:
    """``write(root group, scratch folder) -> metadata`` into a store under a temporary
    name beside ``out``, renamed to ``out`` when complete (nothing left behind if not)."""
    import zarr

    folder = os.path.dirname(os.path.abspath(out))
    tmp = tempfile.mkdtemp(prefix=".hsr-partition-", dir=folder)
    try:
        root = zarr.open_group(os.path.join(tmp, "store"), mode="w")
        meta = write(root, tmp)
        root.attrs["hsr"] = json.loads(json.dumps(meta))
        if os.path.lexists(out):
            _remove(out)
        os.replace(os.path.join(tmp, "store"), out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return open_partitioned(out)


def _metadata(parts: int, n_faces: int, bounds, instances: list) -> dict:
    return {"kind": KIND, "version": VERSION, "parts": int(parts), "n_faces": int(n_faces),
            "bounds": [list(map(float, bounds[0])), list(map(float, bounds[1]))],
            "instances": instances, "part_faces": [], "part_bounds": []}


def _add_part(root, meta: dict, p: int, arrays: dict) -> None:
    """Part ``p``'s arrays as a group of the store, its size and box in the metadata."""
    box = arrays.pop("box")  # the world box of the part's face corners
    group = root.create_group(f"part_{p:04d}")
    for name, array in arrays.items():
        group.create_array(name, data=array, chunks=_chunks(array), config=_EVERY_CHUNK)
    meta["part_faces"].append(int(len(arrays["face_id"])))
    meta["part_bounds"].append(box)


def _write_in_memory(scene: Scene, parts: int, root) -> dict:
    n_faces = scene.n_faces
    triangles = scene.world_triangles()
    lo, hi = scene.bounds()
    order = morton_order(triangles.mean(axis=1), lo, hi)
    offsets = scene.face_offsets()
    cuts = np.linspace(0, n_faces, parts + 1).round().astype(np.int64)
    instances = [{"name": inst.name, "mesh_name": inst.mesh.name,
                  "model": np.asarray(inst.model).ravel().tolist(),
                  "opacity": float(inst.opacity), "face_offset": int(offsets[k]),
                  "attributes": [a for a in FACE_ATTRIBUTES
                                 if getattr(inst.mesh, a) is not None],
                  "texture": _texture_ref(inst.mesh.texture, k)}
                 for k, inst in enumerate(scene.instances)]
    meta = _metadata(parts, n_faces, (lo, hi), instances)
    for k, inst in enumerate(scene.instances):
        if isinstance(instances[k]["texture"], dict):  # an image given as an array
            image = np.ascontiguousarray(inst.mesh.texture)
            root.create_array(instances[k]["texture"]["array"], data=image,
                              chunks=image.shape, config=_EVERY_CHUNK)
    for p in range(parts):
        face_id = np.sort(order[cuts[p]:cuts[p + 1]])
        arrays = _part_arrays(scene, offsets, face_id)
        corners = triangles[face_id].reshape(-1, 3)  # world space, whatever the instances
        arrays["box"] = [corners.min(axis=0).tolist(), corners.max(axis=0).tolist()]
        _add_part(root, meta, p, arrays)
    return meta


def partition_streamed(path: str | os.PathLike, parts: int, out: str | os.PathLike,
                       overwrite: bool = False, chunk: int = 1 << 20,
                       progress: bool | None = None) -> PartitionedScene:
    """:func:`partition` of a binary PLY of triangles, a Wavefront OBJ or a binary glTF
    (.glb), read ``chunk`` faces (OBJ: 64 MB of text) at a time so that memory stays near
    40 bytes a face (vertex positions, one Morton code and one part number per face, and
    one part's faces at a time) where loading the scene takes about 140. The same
    instances, faces and parts as loading the file and partitioning it (the same Morton
    order and cuts); only geometry is kept (colours, texture coordinates and materials
    are not). Raises :class:`~hsr.errors.MeshError` for a file that does not stream (see
    :mod:`hsr.scene.ply`, :mod:`hsr.scene.obj_stream`, :mod:`hsr.scene.gltf_stream`) and
    :class:`PartitionError` as :func:`partition` does."""
    require_extra("hsr partition", "zarr")
    out = _check_out(out, overwrite, [path])
    path = os.fspath(path)
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise PartitionError(f"chunk must be a positive integer, got {chunk!r}")
    kind = ("obj" if path.lower().endswith(".obj") else "glb" if is_glb(path) else "ply")
    if kind == "ply" and not path.lower().endswith(".ply") and not is_binary_ply(path):
        raise MeshError(f"{path}: streaming reads binary PLY, OBJ and GLB files; load "
                        f"this one (without --stream)")
    source = (_Single(read_layout(path)) if kind == "ply"
              else GlbStream(path) if kind == "glb" else None)
    if source is not None:
        _check_parts(parts, source.n_faces)
    if progress is None:
        progress = sys.stderr.isatty()

    def write(root, scratch) -> dict:
        streamed = source if source is not None else _Single(ObjStream(path, scratch))
        _check_parts(parts, streamed.n_faces)
        # The bar counts faces read (three passes) and parts written (one face each).
        with progress_bar(progress, 4 * streamed.n_faces, "partition", unit="face") as bar:
            return _write_streamed(streamed, parts, root, scratch, chunk, bar)

    return _write_store(out, write)


class _Single:
    """A one-mesh file (a binary PLY's layout, or an :class:`ObjStream`) as the source
    :func:`_write_streamed` reads: the protocol :class:`GlbStream` follows (instances of
    (name, mesh name, model, geometry key); positions, face counts and face chunks per
    geometry key)."""

    def __init__(self, reader) -> None:
        self.reader = reader
        self.name = os.path.basename(reader.path)
        self.n_faces = reader.n_faces
        self.instances = [(self.name, self.name, np.eye(4), 0)]
        self.positions = {0: read_positions(reader) if isinstance(reader, PlyLayout)
                          else reader.positions}
        self.counts = {0: reader.n_faces}

    def face_chunks(self, key, chunk: int):
        if isinstance(self.reader, PlyLayout):
            return face_chunks(self.reader, chunk)
        return self.reader.face_chunks(chunk)


def _write_streamed(source, parts: int, root, scratch: str, chunk: int, bar) -> dict:
    instances = source.instances
    offsets = np.concatenate([[0], np.cumsum([source.counts[key]
                                               for *_, key in instances])]).astype(np.int64)
    # Pass 1: which vertices each geometry's faces use; the scene's box is that of the
    # used vertices placed by each instance (Scene.bounds()).
    used = {key: np.zeros(len(source.positions[key]), dtype=bool) for key in source.positions}
    for key in used:
        for _, corners in source.face_chunks(key, chunk):
            used[key][corners.ravel()] = True
            bar.update(len(corners) * sum(1 for *_, k in instances if k == key))
        check_used_positions(source.positions[key], used[key], source.name)
    points = np.concatenate([
        source.positions[key][used[key]] @ model[:3, :3].T + model[:3, 3]
        for _, _, model, key in instances])
    lo, hi = points.min(axis=0), points.max(axis=0)
    del points
    # Pass 2: a Morton code per face, from its world centroid (morton_order's formula).
    codes = np.empty(source.n_faces, dtype=np.uint64)
    for k, (_, _, model, key) in enumerate(instances):
        world = place_vertices(source.positions[key], model)
        for start, corners in source.face_chunks(key, chunk):
            at = offsets[k] + start
            codes[at:at + len(corners)] = morton_codes(world[corners].mean(axis=1), lo, hi)
    # The parts: runs of the stable Morton order, as the in-memory path cuts them.
    part_of = np.empty(source.n_faces, dtype=np.uint16)
    order = np.argsort(codes, kind="stable")
    del codes
    cuts = np.linspace(0, source.n_faces, parts + 1).round().astype(np.int64)
    for p in range(parts):
        part_of[order[cuts[p]:cuts[p + 1]]] = p
    del order
    # Pass 3: each chunk's faces to their part's scratch file, as (face id, corners), and
    # each part's world box from its corners (each instance placed once, not per part).
    box_lo = np.full((parts, 3), np.inf)
    box_hi = np.full((parts, 3), -np.inf)
    for k, (_, _, model, key) in enumerate(instances):
        world = place_vertices(source.positions[key], model)
        for start, corners in source.face_chunks(key, chunk):
            at = offsets[k] + start
            mine = part_of[at:at + len(corners)]
            for p in np.unique(mine):
                sel = np.flatnonzero(mine == p)
                rows = np.column_stack([sel + at, corners[sel]]).astype(np.int64)
                with open(os.path.join(scratch, f"{p}.faces"), "ab") as f:
                    rows.tofile(f)
                placed = world[corners[sel].ravel()]
                box_lo[p] = np.minimum(box_lo[p], placed.min(axis=0))
                box_hi[p] = np.maximum(box_hi[p], placed.max(axis=0))
            bar.update(len(corners))
        del world
    del part_of
    meta = _metadata(parts, source.n_faces, (lo, hi), [
        {"name": name, "mesh_name": mesh_name, "model": np.asarray(model).ravel().tolist(),
         "opacity": 1.0, "face_offset": int(offsets[k]), "attributes": [], "texture": None}
        for k, (name, mesh_name, model, _) in enumerate(instances)])
    # Pass 4: one part at a time from its scratch file into the store.
    for p in range(parts):
        rows = np.fromfile(os.path.join(scratch, f"{p}.faces"), dtype=np.int64).reshape(-1, 4)
        face_id = rows[:, 0]
        owner = instance_of(offsets, face_id)
        positions, vertex_ids, faces, starts = [], [], [], [0]
        for k, (*_, key) in enumerate(instances):
            local = rows[owner == k, 1:]
            vertices, remapped = np.unique(local, return_inverse=True)
            positions.append(source.positions[key][vertices])
            vertex_ids.append(vertices)
            faces.append(remapped.reshape(-1, 3) + starts[-1])
            starts.append(starts[-1] + len(vertices))
        _add_part(root, meta, p, {
            "box": [box_lo[p].tolist(), box_hi[p].tolist()],
            "positions": np.concatenate(positions), "vertex_id":
            np.concatenate(vertex_ids).astype(np.int64),
            "faces": np.concatenate(faces).astype(np.int64).reshape(-1, 3),
            "face_id": face_id, "vertex_start": np.asarray(starts, dtype=np.int64)})
        os.remove(os.path.join(scratch, f"{p}.faces"))
        bar.update(len(face_id))
    return meta


def _chunks(array: np.ndarray) -> tuple:
    rows = max(1, min(len(array), 1 << 20))
    return (rows,) + array.shape[1:]


def _remove(path: str) -> None:
    """Remove the partitioned scene at ``path`` (checked by :func:`_check_out`; checked
    again here, as the folder may have changed since)."""
    if os.path.isdir(path) and not os.path.islink(path) and (is_partitioned(path)
                                                            or not os.listdir(path)):
        shutil.rmtree(path)
    else:
        raise PartitionError(f"{path} is not a partitioned scene; not replacing it")


def _texture_ref(texture, k: int):
    """How the metadata names an instance's texture: None, its path, or the root array
    that holds it."""
    if texture is None:
        return None
    if isinstance(texture, (str, os.PathLike)):
        return os.path.abspath(os.fspath(texture))
    return {"array": f"texture_{k:04d}"}


def _part_arrays(scene: Scene, offsets: np.ndarray, face_id: np.ndarray) -> dict:
    """The arrays of one part: its faces (global ids ``face_id``, ascending) re-indexed
    into the model-space vertices they use, instance by instance, and their per-face
    attributes (zeros for the faces of instances that have none)."""
    owner = instance_of(offsets, face_id)
    positions, vertex_ids, faces, vertex_start = [], [], [], [0]
    attributes: dict = {}
    for k, inst in enumerate(scene.instances):
        local = face_id[owner == k] - offsets[k]
        corners = inst.mesh.faces[local]
        used, remapped = np.unique(corners, return_inverse=True)
        positions.append(inst.mesh.positions[used])
        vertex_ids.append(used)
        faces.append(remapped.reshape(-1, 3) + vertex_start[-1])
        vertex_start.append(vertex_start[-1] + len(used))
        for name, (shape, dtype) in FACE_ATTRIBUTES.items():
            values = getattr(inst.mesh, name)
            attributes.setdefault(name, []).append(
                np.zeros((len(local),) + shape, dtype) if values is None
                else np.asarray(values, dtype)[local])
    arrays = {"positions": np.concatenate(positions).astype(np.float64),
              "vertex_id": np.concatenate(vertex_ids).astype(np.int64),
              "faces": np.concatenate(faces).astype(np.int64).reshape(-1, 3),
              "face_id": face_id.astype(np.int64),
              "vertex_start": np.asarray(vertex_start, dtype=np.int64)}
    for name, parts in attributes.items():
        if any(getattr(inst.mesh, name) is not None for inst in scene.instances):
            arrays[name] = np.concatenate(parts)
    return arrays
