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
"""

from __future__ import annotations

import json
import os

import numpy as np

from ..errors import HsrError
from .mesh import Instance, Mesh, Scene, instance_of

__all__ = ["PartitionError", "PartitionedScene", "open_partitioned", "is_partitioned"]

KIND = "hsr-partitioned-scene"
VERSION = 1


class PartitionError(HsrError):
    """A partitioned scene that cannot be written, opened or rendered as asked."""


def is_partitioned(path: str | os.PathLike) -> bool:
    """True when ``path`` is a folder holding a partitioned scene's ``zarr.json``."""
    try:
        with open(os.path.join(os.fspath(path), "zarr.json")) as f:
            attrs = json.load(f).get("attributes", {})
        return attrs.get("hsr", {}).get("kind") == KIND
    except (OSError, ValueError, AttributeError):
        return False


def open_partitioned(path: str | os.PathLike) -> PartitionedScene:
    """The partitioned scene at ``path``, reading only its metadata (parts load on
    :meth:`PartitionedScene.part`). Raises :class:`PartitionError` for a path that is not
    one."""
    path = os.fspath(path)
    if not is_partitioned(path):
        raise PartitionError(f"{path} is not a partitioned scene (hsr partition writes "
                             f"them)")
    with open(os.path.join(path, "zarr.json")) as f:
        meta = json.load(f)["attributes"]["hsr"]
    if meta.get("version") != VERSION:
        raise PartitionError(f"{path}: partitioned scene version {meta.get('version')!r}, "
                             f"this hsr reads version {VERSION}")
    problem = _metadata_problem(meta)
    if problem:
        raise PartitionError(f"{path}: damaged partitioned scene: {problem}")
    return PartitionedScene(path, meta)


def _metadata_problem(meta: dict) -> str | None:
    """What is wrong with a store's metadata (written by hsr, but read from disk: a file
    may be damaged or made by hand), or None."""
    def count(value, low=0) -> bool:
        return isinstance(value, int) and not isinstance(value, bool) and value >= low

    parts, n_faces, instances = meta.get("parts"), meta.get("n_faces"), meta.get("instances")
    if not count(parts, 1) or not count(n_faces, 1):
        return "parts and n_faces must be positive integers"
    sizes, boxes = meta.get("part_faces"), meta.get("part_bounds")
    if not (isinstance(sizes, list) and len(sizes) == parts and all(map(count, sizes))
            and sum(sizes) == n_faces):
        return "part_faces must be one face count per part, adding up to n_faces"
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
        try:
            model = np.asarray(inst.get("model"), dtype=np.float64)
            opacity = float(inst.get("opacity", "nan"))
        except (TypeError, ValueError):
            return "an instance's model or opacity is not numbers"
        if model.shape != (16,) or not np.isfinite(model).all() or not 0 <= opacity <= 1:
            return "an instance's model must be 16 finite numbers, its opacity in 0..1"
        attributes = inst.get("attributes")
        if not isinstance(attributes, list) or not set(attributes) <= set(FACE_ATTRIBUTES):
            return f"an instance's attributes must be among {', '.join(FACE_ATTRIBUTES)}"
        texture = inst.get("texture")
        if texture is not None and not isinstance(texture, str) and not (
                isinstance(texture, dict) and isinstance(texture.get("array"), str)):
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
            import zarr

            root = zarr.open_group(self.path, mode="r")
            return np.asarray(root[ref["array"]][...])
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
            attributes = {name: np.concatenate(parts)[order]
                          for name, parts in got["attributes"].items()}
            mesh = Mesh(np.concatenate(got["positions"])[first], faces,
                        name=inst["mesh_name"], texture=self._texture(inst["texture"]),
                        **attributes)
            instances.append(Instance(mesh, np.asarray(inst["model"]).reshape(4, 4),
                                      inst["opacity"], inst["name"]))
        return Scene(instances)

    def _arrays(self, p: int) -> dict:
        """Every array of part ``p``, read."""
        import zarr

        if isinstance(p, bool) or not isinstance(p, (int, np.integer)) \
                or not 0 <= p < self.parts:
            raise PartitionError(f"part must be in 0..{self.parts - 1}, got {p!r}")
        try:
            group = zarr.open_group(os.path.join(self.path, f"part_{p:04d}"), mode="r")
            arrays = {name: np.asarray(array[...]) for name, array in group.arrays()}
        except Exception as exc:  # noqa: BLE001 - zarr's errors for a damaged folder vary
            raise PartitionError(f"{self.path}: part {p} cannot be read "
                                 f"({type(exc).__name__}: {str(exc)[:120]})") from None
        problem = self._part_problem(p, arrays)
        if problem:
            raise PartitionError(f"{self.path}: damaged part {p}: {problem}")
        return arrays

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
        if n_faces and (face_id.min() < 0 or face_id.max() >= self.n_faces
                        or np.any(np.diff(face_id) <= 0)):
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
