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
from .mesh import Instance, Mesh, Scene

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
    return PartitionedScene(path, meta)


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
        group = zarr.open_group(os.path.join(self.path, f"part_{p:04d}"), mode="r")
        return {name: np.asarray(array[...]) for name, array in group.arrays()}

    def _instance_runs(self, arrays: dict):
        """``(instance, its faces' mask, first vertex, end vertex)`` for each original
        instance with faces in the part whose ``arrays`` these are."""
        offsets = self.face_offsets()
        owner = np.searchsorted(offsets, arrays["face_id"], side="right") - 1
        vertex_start = arrays["vertex_start"]
        for k in range(len(self.instances)):
            mine = owner == k
            if mine.any():
                yield k, mine, vertex_start[k], vertex_start[k + 1]
