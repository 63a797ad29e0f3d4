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
import tempfile

import numpy as np

from ..errors import require_extra
from .load import load_scene
from .mesh import Scene, SceneLike, as_scene
from .partitioned import (
    KIND,
    VERSION,
    PartitionedScene,
    PartitionError,
    is_partitioned,
    open_partitioned,
)

__all__ = ["partition", "morton_order", "MAX_PARTS"]

# The per-face attributes of a Mesh a part keeps: shape of one face's value and dtype.
FACE_ATTRIBUTES = {"corner_uv": ((3, 2), np.float64), "corner_normals": ((3, 3), np.float64),
                   "face_colors": ((3,), np.uint8), "corner_colors": ((3, 3), np.uint8)}

MAX_PARTS = 65536


def morton_order(centroids: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Stable order of (N, 3) ``centroids`` along the 3-D Morton curve of the box
    [``lo``, ``hi``], 21 bits per axis (ties keep their index order)."""
    extent = np.where(hi > lo, hi - lo, 1.0)
    cells = np.clip((centroids - lo) / extent * (2 ** 21), 0, 2 ** 21 - 1).astype(np.uint64)
    code = np.zeros(len(centroids), dtype=np.uint64)
    for axis in range(3):
        code |= _spread_bits(cells[:, axis]) << np.uint64(axis)
    return np.argsort(code, kind="stable")


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
              overwrite: bool = False) -> PartitionedScene:
    """Split ``scene`` (a Scene, Mesh, path, ...) into ``parts`` spatially coherent parts
    and write them to the Zarr store ``out`` (see the module); returns it opened.
    Raises :class:`PartitionError` for a part count outside 1..min(faces, 65536), an
    ``out`` that exists (unless ``overwrite``) or whose folder does not, and
    :class:`~hsr.errors.MissingExtraError` without Zarr."""
    require_extra("hsr partition", "zarr")
    import zarr

    if isinstance(scene, (str, os.PathLike)):
        scene = load_scene(scene)
    scene = as_scene(scene)
    n_faces = scene.n_faces
    if isinstance(parts, bool) or not isinstance(parts, (int, np.integer)) \
            or not 1 <= parts <= min(n_faces, MAX_PARTS):
        raise PartitionError(f"parts must be an integer in 1..{min(n_faces, MAX_PARTS)} "
                             f"(the scene has {n_faces:,} faces), got {parts!r}")
    out = os.fspath(out)
    folder = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(folder):
        raise PartitionError(f"cannot write {out}: folder {folder} does not exist")
    if os.path.lexists(out) and not overwrite:
        raise PartitionError(f"{out} exists; choose another name or replace it "
                             f"(overwrite=True; hsr partition --force)")

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
    part_faces: list = []
    part_bounds: list = []
    meta = {"kind": KIND, "version": VERSION, "parts": int(parts), "n_faces": int(n_faces),
            "bounds": [lo.tolist(), hi.tolist()], "instances": instances,
            "part_faces": part_faces, "part_bounds": part_bounds}
    tmp = tempfile.mkdtemp(prefix=".hsr-partition-", dir=folder)
    try:
        root = zarr.open_group(os.path.join(tmp, "store"), mode="w")
        for k, inst in enumerate(scene.instances):
            if isinstance(instances[k]["texture"], dict):  # an image given as an array
                image = np.ascontiguousarray(inst.mesh.texture)
                root.create_array(instances[k]["texture"]["array"], data=image,
                                  chunks=image.shape)
        for p in range(parts):
            face_id = np.sort(order[cuts[p]:cuts[p + 1]])
            arrays = _part_arrays(scene, offsets, face_id)
            group = root.create_group(f"part_{p:04d}")
            for name, array in arrays.items():
                group.create_array(name, data=array, chunks=_chunks(array))
            part_corners = triangles[face_id].reshape(-1, 3)
            part_faces.append(int(len(face_id)))
            part_bounds.append([part_corners.min(axis=0).tolist(),
                                        part_corners.max(axis=0).tolist()])
        root.attrs["hsr"] = json.loads(json.dumps(meta))
        if os.path.lexists(out):
            _remove(out)
        os.replace(os.path.join(tmp, "store"), out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return open_partitioned(out)


def _chunks(array: np.ndarray) -> tuple:
    rows = max(1, min(len(array), 1 << 20))
    return (rows,) + array.shape[1:]


def _remove(path: str) -> None:
    if os.path.isdir(path) and not os.path.islink(path):
        if not is_partitioned(path):
            raise PartitionError(f"{path} exists and is not a partitioned scene; not "
                                 f"overwriting it")
        shutil.rmtree(path)
    else:
        os.remove(path)


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
    owner = np.searchsorted(offsets, face_id, side="right") - 1
    positions, faces, vertex_start = [], [], [0]
    attributes: dict = {}
    for k, inst in enumerate(scene.instances):
        local = face_id[owner == k] - offsets[k]
        corners = inst.mesh.faces[local]
        used, remapped = np.unique(corners, return_inverse=True)
        positions.append(inst.mesh.positions[used])
        faces.append(remapped.reshape(-1, 3) + vertex_start[-1])
        vertex_start.append(vertex_start[-1] + len(used))
        for name, (shape, dtype) in FACE_ATTRIBUTES.items():
            values = getattr(inst.mesh, name)
            attributes.setdefault(name, []).append(
                np.zeros((len(local),) + shape, dtype) if values is None
                else np.asarray(values, dtype)[local])
    arrays = {"positions": np.concatenate(positions).astype(np.float64),
              "faces": np.concatenate(faces).astype(np.int64).reshape(-1, 3),
              "face_id": face_id.astype(np.int64),
              "vertex_start": np.asarray(vertex_start, dtype=np.int64)}
    for name, parts in attributes.items():
        if any(getattr(inst.mesh, name) is not None for inst in scene.instances):
            arrays[name] = np.concatenate(parts)
    return arrays
