"""Partitioned scenes on disk: a scene's faces in spatially coherent parts, in a Zarr v3
store that opens lazily, so that no process needs the whole scene (written by
:func:`hsr.partition`, :mod:`hsr.scene.partition`; rendered by
:mod:`hsr.batch.sortlast`).

Layout of ``STORE`` (a folder)::

    zarr.json                 group; attributes["hsr"]: kind, version, parts, n_faces,
                              bounds, instances (name, model, opacity, face offset), and
                              per part its face count and bounds
    part_0000/positions       (V, 3) float64 model-space vertices the part's faces use,
                              instance by instance
    part_0000/faces           (F, 3) int64 into positions
    part_0000/face_id         (F,) int64 global face ids, ascending
    part_0000/vertex_start    (I + 1,) int64 where each instance's vertices begin
    part_0000/vertex_id       (V,) int64 each vertex's index in its instance's mesh

    part_0000/corner_uv, corner_normals, face_colors, corner_colors
                              per-face attributes, where any instance has them
    texture_0003              an instance's texture given as an array (a texture given as
                              a path is named in the metadata)

A store is read from disk, where it may be damaged or made by hand, so it is checked
before it is trusted (:func:`open_partitioned`, :meth:`PartitionedScene.part`): every
entry of the folder a regular file or folder (no links, FIFOs or devices), every
metadata file capped and parsed, every array's declared shape, dtype, chunk grid,
chunk-key encoding and codecs the ones hsr writes and every chunk file present (hsr
writes every chunk, so a missing one is a loss, never read as the fill value), the
sizes capped before anything is read, and the face ids of the parts disjoint and
covering 0..n_faces - 1. Each refusal is a :class:`PartitionError` naming the store, the
part and the array.
"""

from __future__ import annotations

import json
import math
import os
import stat
import warnings
from typing import Any

import numpy as np

from ..errors import HsrError
from .files import read_regular
from .images import MAX_TEXTURE_PIXELS
from .mesh import Instance, Mesh, Scene, instance_of

__all__ = ["PartitionError", "PartitionedScene", "open_partitioned", "is_partitioned"]

KIND = "hsr-partitioned-scene"
# Version 2 writes every chunk (version 1 let Zarr skip chunks equal to the fill value, so
# a lost chunk could not be told from a skipped one).
VERSION = 2
# What hsr reads of a store: its metadata files, its faces (a part's arrays are read
# whole, about 100 bytes a face), and the folder entries it walks.
MAX_METADATA_BYTES = 64 << 20
MAX_ARRAY_METADATA_BYTES = 1 << 20
MAX_STORE_FACES = 1 << 36
MAX_PART_FACES = 1 << 27
MAX_STORE_ENTRIES = 1 << 22
# The codecs hsr's writer uses (Zarr's defaults: bytes, then zstd); a store declaring
# others (sharding, transposes, ...) was not written by hsr.
_CODECS = ("zstd", "gzip", "blosc", "crc32c")


class PartitionError(HsrError):
    """A partitioned scene that cannot be written, opened or rendered as asked."""


def is_partitioned(path: str | os.PathLike) -> bool:
    """True when ``path`` is a folder (not a link) holding a partitioned scene's
    ``zarr.json`` (a regular file, read within its cap: never a FIFO or a device)."""
    return store_kind(path) == KIND


def store_kind(path: str | os.PathLike) -> str | None:
    """The ``kind`` hsr wrote into the Zarr store folder ``path`` (``attributes["hsr"]``
    of its ``zarr.json``), or None for anything else: how hsr recognises its own stores
    (read as :func:`is_partitioned` reads them)."""
    try:
        kind = _root_attributes(os.fspath(path)).get("kind")
    except HsrError:
        return None
    return kind if isinstance(kind, str) else None


def _zarr_json(folder: str, cap: int, where: str, unreadable: str):
    """The parsed ``zarr.json`` of ``folder`` (a regular file of at most ``cap`` bytes);
    a :class:`PartitionError` starting ``unreadable`` when it cannot be read, ``where``
    when it is not JSON."""
    try:
        data = read_regular(os.path.join(folder, "zarr.json"), "metadata file", cap,
                            PartitionError)
    except PartitionError as exc:
        raise PartitionError(f"{unreadable}: {exc}") from None
    try:
        return json.loads(data)
    except (ValueError, UnicodeDecodeError, RecursionError) as exc:
        raise PartitionError(f"{where}: zarr.json is not JSON ({exc})") from None


def _root_attributes(path: str) -> dict:
    """``attributes["hsr"]`` of the store folder ``path``'s ``zarr.json`` (or a
    :class:`PartitionError`)."""
    if os.path.islink(path) or not os.path.isdir(path):
        raise PartitionError(f"{path} is not a partitioned scene (not a folder)")
    meta = _zarr_json(path, MAX_METADATA_BYTES, path, f"{path} is not a partitioned scene")
    attrs = meta.get("attributes") if isinstance(meta, dict) else None
    hsr_attrs = attrs.get("hsr") if isinstance(attrs, dict) else None
    if not isinstance(hsr_attrs, dict):
        raise PartitionError(f"{path} is not a partitioned scene (hsr partition writes "
                             f"them)")
    return hsr_attrs


def open_partitioned(path: str | os.PathLike, check_parts: bool = True) -> PartitionedScene:
    """The partitioned scene at ``path``, checked (see the module: its folder and
    metadata; with ``check_parts``, every part's array layout and chunk files and the
    parts' face ids, reading those arrays alone) but with no part loaded (parts load on
    :meth:`PartitionedScene.part`, which checks that part again: a worker that reads
    one part opens the store with ``check_parts=False``). Raises
    :class:`PartitionError` for a path that is not one, or a damaged one."""
    path = os.fspath(path)
    meta = _root_attributes(path)
    if meta.get("kind") != KIND:
        raise PartitionError(f"{path} is not a partitioned scene (hsr partition writes "
                             f"them)")
    if meta.get("version") != VERSION:
        raise PartitionError(f"{path}: partitioned scene version {meta.get('version')!r}, "
                             f"this hsr reads version {VERSION} (partition the model again)")
    problem = _metadata_problem(meta)
    if problem:
        raise PartitionError(f"{path}: damaged partitioned scene: {problem}")
    _check_entries(path)
    store = PartitionedScene(path, meta)
    for inst in store.instances:
        if isinstance(inst["texture"], dict):
            store._layout(None, inst["texture"]["array"], None, "uint8")
    if check_parts:
        for p in range(store.parts):
            store._layouts(p)
        store._check_face_ids()
    return store


def _check_entries(path: str) -> None:
    """Every entry under the store folder is a folder or a regular file: no links (which
    could lead out of the store), FIFOs, devices or sockets (which could block or never
    end); at most :data:`MAX_STORE_ENTRIES`."""
    count, stack = 0, [path]
    while stack:
        folder = stack.pop()
        try:
            entries = list(os.scandir(folder))
        except OSError as exc:
            raise PartitionError(f"{path}: cannot list {folder}: {exc.strerror}") from None
        for entry in entries:
            count += 1
            if count > MAX_STORE_ENTRIES:
                raise PartitionError(f"{path}: more than {MAX_STORE_ENTRIES:,} files; hsr "
                                     f"reads stores up to that")
            mode = entry.stat(follow_symlinks=False).st_mode
            if stat.S_ISDIR(mode):
                stack.append(entry.path)
            elif not stat.S_ISREG(mode):
                raise PartitionError(f"{path}: {os.path.relpath(entry.path, path)} is not a "
                                     f"regular file or folder (a link, FIFO, device or "
                                     f"socket); hsr reads only regular files in a store")


def _array_problem(meta, shape, dtype, texture: bool = False) -> str | None:
    """What is wrong with an array's ``zarr.json`` (see :meth:`PartitionedScene._layout`),
    or None."""
    if not isinstance(meta, dict) or meta.get("zarr_format") != 3 \
            or meta.get("node_type") != "array":
        return "zarr.json is not a Zarr v3 array's"
    got = meta.get("shape")
    if not isinstance(got, list) or not all(isinstance(n, int) and not isinstance(n, bool)
                                            and n >= 0 for n in got):
        return f"its shape must be whole numbers, got {got!r}"[:200]
    if texture:
        if len(got) != 3 or got[2] not in (3, 4) or got[0] * got[1] > MAX_TEXTURE_PIXELS \
                or meta.get("data_type") != "uint8":
            return (f"a texture must be (H, W, 3 or 4) uint8 of at most "
                    f"{MAX_TEXTURE_PIXELS:,} pixels, got {got} {meta.get('data_type')!r}")
    elif shape is None:
        if len(got) != 2 or got[1] != 3:
            return f"shape must be (N, 3), got {got}"
    elif tuple(got) != tuple(shape):
        return f"shape must be {list(shape)} (from the metadata), got {got}"
    if dtype is not None and meta.get("data_type") != dtype:
        return f"dtype must be {dtype}, got {meta.get('data_type')!r}"[:200]
    grid = meta.get("chunk_grid")
    chunks = (grid.get("configuration") or {}).get("chunk_shape") \
        if isinstance(grid, dict) and grid.get("name") == "regular" else None
    if not isinstance(chunks, list) or len(chunks) != len(got) or not all(
            isinstance(c, int) and not isinstance(c, bool) and c >= 1 for c in chunks):
        return "its chunk grid must be regular, a positive chunk size per axis"
    keys = meta.get("chunk_key_encoding")
    if keys != {"name": "default", "configuration": {"separator": "/"}}:
        return "its chunk keys must be Zarr's default ('c/i/j', separator '/')"
    codecs = meta.get("codecs")
    if not isinstance(codecs, list) or not codecs or not all(isinstance(c, dict)
                                                             for c in codecs) \
            or codecs[0].get("name") != "bytes" \
            or any(c.get("name") not in _CODECS for c in codecs[1:]) \
            or meta.get("storage_transformers") not in (None, []):
        return (f"its codecs must be bytes then any of {', '.join(_CODECS)} (what hsr "
                f"writes)")
    return None


def _metadata_problem(meta: dict) -> str | None:
    """What is wrong with a store's metadata (written by hsr, but read from disk: a file
    may be damaged or made by hand), or None."""
    def count(value, low=0) -> bool:
        return isinstance(value, int) and not isinstance(value, bool) and value >= low

    parts, n_faces, instances = meta.get("parts"), meta.get("n_faces"), meta.get("instances")
    if not count(parts, 1) or not count(n_faces, 1) or not isinstance(parts, int) \
            or not isinstance(n_faces, int):  # (the isinstance tells the type checker)
        return "parts and n_faces must be positive integers"
    if n_faces > MAX_STORE_FACES or parts > 65536:
        return (f"n_faces {n_faces:,} or parts {parts:,} over what hsr reads "
                f"({MAX_STORE_FACES:,} faces, 65,536 parts)")
    sizes, boxes = meta.get("part_faces"), meta.get("part_bounds")
    if not (isinstance(sizes, list) and len(sizes) == parts and all(map(count, sizes))
            and sum(sizes) == n_faces):
        return "part_faces must be one face count per part, adding up to n_faces"
    if max(sizes) > MAX_PART_FACES:
        return (f"a part of {max(sizes):,} faces; hsr reads parts of up to "
                f"{MAX_PART_FACES:,} faces")
    if not isinstance(boxes, list) or len(boxes) != parts:
        return "part_bounds must be one box per part"
    try:
        for box in boxes + [meta.get("bounds")]:
            if np.asarray(box, dtype=np.float64).shape != (2, 3):
                return "a box is not 2 x 3 numbers"
    except (TypeError, ValueError):
        return "a box is not 2 x 3 numbers"
    if not isinstance(instances, list) or not instances:
        return "instances must be a non-empty list"
    offsets: list = []
    for inst in instances:
        if not isinstance(inst, dict):
            return "an instance is not an object"
        if not isinstance(inst.get("name"), str) or not isinstance(inst.get("mesh_name"), str):
            return "an instance needs a name and a mesh_name (strings)"
        try:
            model = np.asarray(inst.get("model"), dtype=np.float64)
            opacity = float(inst.get("opacity", "nan"))
        except (TypeError, ValueError):
            return "an instance's model or opacity is not numbers"
        if model.shape != (16,) or not np.isfinite(model).all() or not 0 <= opacity <= 1:
            return "an instance's model must be 16 finite numbers, its opacity in 0..1"
        attributes = inst.get("attributes")
        if not isinstance(attributes, list) or not all(isinstance(a, str) for a in attributes) \
                or len(set(attributes)) != len(attributes) \
                or not set(attributes) <= set(FACE_ATTRIBUTES):
            return f"an instance's attributes must be among {', '.join(FACE_ATTRIBUTES)}"
        texture = inst.get("texture")
        if texture is not None and not isinstance(texture, str) and not (
                isinstance(texture, dict) and isinstance(texture.get("array"), str)
                and texture["array"].startswith("texture_")
                and texture["array"][8:].isdigit()):
            return "an instance's texture must be a path, an array's name or null"
        offsets.append(inst.get("face_offset"))
    if not all(map(count, offsets)) or offsets[0] != 0 or offsets != sorted(offsets) \
            or offsets[-1] >= n_faces:
        return "instance face offsets must ascend from 0 below n_faces"
    return None


# The per-face attributes of a Mesh a part may hold: the shape of one face's value and
# the dtype they are stored in.
FACE_ATTRIBUTES = {"corner_uv": ((3, 2), np.float64), "corner_normals": ((3, 3), np.float64),
                   "face_colors": ((3,), np.uint8), "corner_colors": ((3, 3), np.uint8)}


class PartitionedScene:
    """A scene on disk in parts (see the module): its metadata in memory, each part read
    on demand as a :class:`~hsr.Scene` whose instances carry the original model matrices,
    so its faces land in clip space exactly where the whole scene's do.

    path : the store; parts : how many; n_faces : faces of the whole scene; part_faces :
    faces per part; instances : the original instances' names, model matrices, opacities
    and face offsets."""

    def __init__(self, path: str, meta: dict) -> None:
        self.path = path
        self.meta = meta
        self.kind = KIND
        self.parts: int = int(meta["parts"])
        self.n_faces: int = int(meta["n_faces"])
        self.part_faces: list = list(meta["part_faces"])
        self.instances: list = list(meta["instances"])

    def __repr__(self) -> str:
        return (f"PartitionedScene({self.path!r}, parts={self.parts}, "
                f"n_faces={self.n_faces:,})")

    def bounds(self) -> np.ndarray:
        """(2, 3) world-space box of the whole scene."""
        return np.asarray(self.meta["bounds"], dtype=np.float64)

    def part_bounds(self, p: int) -> np.ndarray:
        """(2, 3) world-space box of part ``p``."""
        return np.asarray(self.meta["part_bounds"][p], dtype=np.float64)

    def _texture(self, ref):
        if isinstance(ref, dict):
            return self._read(None, ref["array"])
        return ref

    def face_offsets(self) -> np.ndarray:
        """(I,) global id of each original instance's first face."""
        return np.asarray([inst["face_offset"] for inst in self.instances], dtype=np.int64)

    def part(self, p: int) -> tuple:
        """``(scene, face_id)``: part ``p`` as a Scene of the original instances' faces
        that fall in it (in global order), and (F,) int64 the global id of each of its
        faces. Raises :class:`PartitionError` for a part that does not exist."""
        arrays = self._arrays(p)
        positions, faces, face_id = arrays["positions"], arrays["faces"], arrays["face_id"]
        instances = []
        for k, mine, lo, hi in self._instance_runs(arrays):
            inst = self.instances[k]
            attributes = {name: arrays[name][mine] for name in inst["attributes"]}
            mesh = Mesh(positions[lo:hi], faces[mine] - lo, name=inst["mesh_name"],
                        texture=self._texture(inst["texture"]), **attributes)
            instances.append(Instance(mesh, np.asarray(inst["model"]).reshape(4, 4),
                                      inst["opacity"], inst["name"]))
        return Scene(instances), face_id

    def assemble(self) -> Scene:
        """The whole scene in memory again, from every part: each instance's faces in
        their original order over the vertices they use (in their original order), with
        their attributes and textures, as :func:`hsr.load_scene` gave it less unused
        vertices. Needs the memory the whole scene needs (what hsr prune of a store
        uses to grow rings and write the result; rendering stays part by part)."""
        gathered: dict = {}
        for p in range(self.parts):
            arrays = self._arrays(p)
            for k, mine, lo, hi in self._instance_runs(arrays):
                vertex_id = arrays["vertex_id"][lo:hi]
                got = gathered.setdefault(k, {"ids": [], "faces": [], "vertex_id": [],
                                              "positions": [], "attributes": {}})
                got["ids"].append(arrays["face_id"][mine])
                got["faces"].append(vertex_id[arrays["faces"][mine] - lo])
                got["vertex_id"].append(vertex_id)
                got["positions"].append(arrays["positions"][lo:hi])
                for name in self.instances[k]["attributes"]:
                    got["attributes"].setdefault(name, []).append(arrays[name][mine])
        instances = []
        for k in sorted(gathered):
            got, inst = gathered[k], self.instances[k]
            order = np.argsort(np.concatenate(got["ids"]), kind="stable")
            vertex_id, first = np.unique(np.concatenate(got["vertex_id"]), return_index=True)
            faces = np.searchsorted(vertex_id, np.concatenate(got["faces"])[order])
            attributes: dict[str, Any] = {name: np.concatenate(parts)[order]
                                          for name, parts in got["attributes"].items()}
            mesh = Mesh(np.concatenate(got["positions"])[first], faces,
                        name=inst["mesh_name"], texture=self._texture(inst["texture"]),
                        **attributes)
            instances.append(Instance(mesh, np.asarray(inst["model"]).reshape(4, 4),
                                      inst["opacity"], inst["name"]))
        return Scene(instances)

    def _arrays(self, p: int) -> dict:
        """Every array of part ``p``, its layout checked before it is read."""
        if isinstance(p, bool) or not isinstance(p, (int, np.integer)) \
                or not 0 <= p < self.parts:
            raise PartitionError(f"part must be in 0..{self.parts - 1}, got {p!r}")
        arrays = {name: self._read(p, name) for name in self._layouts(p)}
        problem = self._part_problem(p, arrays)
        if problem:
            raise PartitionError(f"{self.path}: damaged part {p}: {problem}")
        return arrays

    def _where(self, p, name: str) -> str:
        return f"{self.path}: " + ("" if p is None else f"part {p}, ") + f"array {name}"

    def _folder(self, p, name: str) -> str:
        """The folder of array ``name`` of part ``p`` (of the root for None)."""
        return os.path.join(self.path, *(() if p is None else (f"part_{p:04d}",)), name)

    def _ids_ascend(self, face_id: np.ndarray) -> bool:
        """Whether part face ids ascend strictly within 0..n_faces - 1."""
        return not len(face_id) or bool(face_id.min() >= 0 and face_id.max() < self.n_faces
                                        and np.all(np.diff(face_id) > 0))

    def _layouts(self, p: int) -> dict:
        """Array name -> its checked layout, for the arrays part ``p`` must hold: the
        shapes follow from the metadata (a part of F faces uses at most 3 F vertices)."""
        n_faces = self.part_faces[p]
        positions = self._layout(p, "positions", None, "float64")
        n_vertices = positions["shape"][0]
        if n_vertices > 3 * n_faces:
            raise PartitionError(f"{self._where(p, 'positions')}: {n_vertices:,} vertices "
                                 f"for {n_faces:,} faces (at most 3 a face)")
        layouts = {"positions": positions}
        expected = {"faces": (n_faces, 3), "face_id": (n_faces,),
                    "vertex_start": (len(self.instances) + 1,), "vertex_id": (n_vertices,)}
        for name, shape in expected.items():
            layouts[name] = self._layout(p, name, shape, "int64")
        wanted = {a for inst in self.instances for a in inst["attributes"]}
        for name in FACE_ATTRIBUTES:
            if name in wanted:
                shape, dtype = FACE_ATTRIBUTES[name]
                layouts[name] = self._layout(p, name, (n_faces,) + shape,
                                             np.dtype(dtype).name)
        return layouts

    def _layout(self, p, name: str, shape: tuple | None, dtype: str | None = None) -> dict:
        """The checked ``zarr.json`` of array ``name`` of part ``p`` (or of the root, for
        ``p`` None: a texture, (H, W, 3 | 4) uint8): its shape (``shape``, or for None
        any (N, 3)), dtype, regular chunk grid, default chunk keys with '/', the codecs
        hsr writes, and every chunk file present."""
        where = self._where(p, name)
        folder = self._folder(p, name)
        meta = _zarr_json(folder, MAX_ARRAY_METADATA_BYTES, where, where)
        problem = _array_problem(meta, shape, dtype, texture=p is None)
        if problem:
            raise PartitionError(f"{where}: {problem}")
        grid = [math.ceil(n / c) for n, c in
                zip(meta["shape"], meta["chunk_grid"]["configuration"]["chunk_shape"])]
        if math.prod(grid) > MAX_STORE_ENTRIES:
            raise PartitionError(f"{where}: more than {MAX_STORE_ENTRIES:,} chunks")
        for index in np.ndindex(*grid):
            chunk = os.path.join(folder, "c", *map(str, index))
            if not os.path.isfile(chunk) or os.path.islink(chunk):
                raise PartitionError(f"{where}: chunk {'/'.join(map(str, index))} is "
                                     f"missing (hsr writes every chunk: the store is "
                                     f"damaged)")
        return meta

    def _read(self, p, name: str) -> np.ndarray:
        """Array ``name`` of part ``p`` (or of the root for None), whose layout the caller
        checked (:meth:`_layout`); Zarr's errors and warnings are a
        :class:`PartitionError` naming it."""
        import zarr

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                return np.asarray(zarr.open_array(self._folder(p, name), mode="r")[...])
        except Exception as exc:  # noqa: BLE001 - zarr's errors for a damaged chunk vary
            raise PartitionError(f"{self._where(p, name)} cannot be read "
                                 f"({type(exc).__name__}: {str(exc)[:120]})") from None

    def _check_face_ids(self) -> None:
        """The parts' face ids are disjoint and cover 0..n_faces - 1 (each part's ascend
        strictly within range: checked with the part's other arrays)."""
        seen = np.zeros(self.n_faces, dtype=bool)
        for p in range(self.parts):
            face_id = self._read(p, "face_id")
            if face_id.shape != (self.part_faces[p],) or not self._ids_ascend(face_id):
                raise PartitionError(f"{self._where(p, 'face_id')}: face ids must ascend "
                                     f"strictly within 0..{self.n_faces - 1}")
            if seen[face_id].any():
                k = int(face_id[np.argmax(seen[face_id])])
                raise PartitionError(f"{self._where(p, 'face_id')}: face {k} is in an "
                                     f"earlier part too (parts must not share faces)")
            seen[face_id] = True
        if not seen.all():
            raise PartitionError(f"{self.path}: face {int(np.argmin(seen))} is in no part")

    def _part_problem(self, p: int, arrays: dict) -> str | None:
        """What is wrong with part ``p``'s arrays, or None: every index in range, the
        shapes agreeing with the metadata, before anything is built from them."""
        names = ("positions", "faces", "face_id", "vertex_start", "vertex_id")
        if any(name not in arrays for name in names):
            return f"it needs the arrays {', '.join(names)}"
        positions, faces = arrays["positions"], arrays["faces"]
        face_id, starts = arrays["face_id"], arrays["vertex_start"]
        n_faces = self.part_faces[p]
        if positions.ndim != 2 or positions.shape[1] != 3 or positions.dtype.kind != "f":
            return "positions must be (V, 3) floats"
        for name in ("faces", "face_id", "vertex_start", "vertex_id"):
            if arrays[name].dtype.kind not in "iu":
                return f"{name} must be integers"
        if faces.shape != (n_faces, 3) or face_id.shape != (n_faces,):
            return f"faces and face_id must hold the {n_faces:,} faces the metadata says"
        if arrays["vertex_id"].shape != (len(positions),):
            return "vertex_id must have one entry per position"
        if starts.shape != (len(self.instances) + 1,) or starts[0] != 0 \
                or starts[-1] != len(positions) or np.any(np.diff(starts) < 0):
            return "vertex_start must ascend from 0 to the vertex count, one per instance"
        if not self._ids_ascend(face_id):
            return "face_id must ascend strictly within 0..n_faces - 1"
        owner = instance_of(self.face_offsets(), face_id)
        if n_faces and (np.any(faces < starts[owner][:, None])
                        or np.any(faces >= starts[owner + 1][:, None])):
            return "a face indexes a vertex outside its instance's range"
        for inst in self.instances:
            for name in inst["attributes"]:
                shape = (n_faces,) + FACE_ATTRIBUTES[name][0]
                if name not in arrays or arrays[name].shape != shape:
                    return f"{name} must hold one value per face"
        return None

    def _instance_runs(self, arrays: dict):
        """``(instance, its faces' mask, first vertex, end vertex)`` for each original
        instance with faces in the part whose ``arrays`` these are."""
        owner = instance_of(self.face_offsets(), arrays["face_id"])
        vertex_start = arrays["vertex_start"]
        for k in range(len(self.instances)):
            mine = owner == k
            if mine.any():
                yield k, mine, vertex_start[k], vertex_start[k + 1]
