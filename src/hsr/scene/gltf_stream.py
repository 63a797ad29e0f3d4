"""A binary glTF (.glb) read for the streamed partition: the instances exactly as
:func:`hsr.load_scene` makes them, the geometry straight from the file, a chunk at a time.

The node tree (which nodes hold meshes, their order, names and world matrices) is what
hsr.load_scene reads through trimesh; to get it bit for bit without loading the buffers,
the same reader loads a *skeleton* of the file: its JSON with every primitive's data
replaced by one small triangle whose corners encode (mesh, primitive), and no materials.
The instances it gives carry the real names and matrices, and their first corner says
which primitive's positions and indices to read. Those are read from the GLB's binary
chunk through their accessors (float32 VEC3 positions; unsigned 8, 16 or 32-bit
indices, or none), geometry only. Primitives that are not plain triangles (other modes,
sparse or compressed accessors, required extensions) are refused: hsr.load_scene
reads those, streaming does not.
"""

from __future__ import annotations

import io
import json
import os
import struct

import numpy as np

from ..errors import MeshError
from .assets import check_gltf_assets, check_gltf_nodes, folder_resolver, glb_chunks, gltf_json
from .files import MAX_STREAM_BYTES, check_regular
from .images import MAX_TEXTURE_PIXELS
from .mesh import check_face_indices

__all__ = ["GlbStream", "is_glb"]

MAX_JSON_BYTES = 1 << 26
_INDEX_TYPES = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32}


def is_glb(path: str) -> bool:
    """True when ``path`` is a regular file that starts like a binary glTF."""
    if not os.path.isfile(path):
        return False
    with open(path, "rb") as f:
        return f.read(4) == b"glTF"


class GlbStream:
    """The instances of a .glb (``instances``: name, mesh name, 4x4 model matrix and a
    geometry key, in hsr.load_scene's order), each geometry's ``positions`` (V, 3)
    float64, and :meth:`face_chunks` of a geometry. Raises
    :class:`~hsr.errors.MeshError` for a file it cannot stream (see the module)."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = os.fspath(path)
        check_regular(self.path, "mesh file", MAX_STREAM_BYTES)
        self.name = os.path.basename(self.path)
        self.header, self.bin_offset, self.bin_length = _chunks(self.path)
        header = self.header
        if header.get("extensionsRequired"):
            raise MeshError(f"{self.name}: streaming does not read required extensions "
                            f"{header['extensionsRequired']}")
        self.instances = _instances(self.path, header)
        self.mesh_names = {inst[3]: inst[1] for inst in self.instances}
        self.positions: dict = {}
        self.counts: dict = {}
        for key in {inst[3] for inst in self.instances}:
            primitive = _primitive(header, key, self.name)
            self.positions[key] = self._read(primitive["attributes"]["POSITION"], "VEC3",
                                             (5126,)).astype(np.float64)
            if "indices" in primitive:
                self.counts[key] = _item(header, "accessors", primitive["indices"],
                                         self.name)["count"] // 3
            else:
                self.counts[key] = len(self.positions[key]) // 3
        self.n_faces = sum(self.counts[inst[3]] for inst in self.instances)

    def face_chunks(self, key: tuple, chunk: int = 1 << 20):
        """Yield ``(first face, (n, 3) int64 corners)`` of geometry ``key``, in order."""
        primitive = _primitive(self.header, key, self.name)
        n = self.counts[key]
        vertices = len(self.positions[key])
        for start in range(0, n, chunk):
            count = min(chunk, n - start)
            if "indices" in primitive:
                corners = self._read(primitive["indices"], "SCALAR", tuple(_INDEX_TYPES),
                                     3 * start, 3 * count).astype(np.int64)
            else:
                corners = np.arange(3 * start, 3 * (start + count), dtype=np.int64)
            corners = corners.reshape(-1, 3)
            check_face_indices(corners, vertices, f"{self.name}: {self.mesh_names[key]}",
                               start)
            yield start, corners

    def _read(self, index: int, kind: str, types: tuple, first: int = 0,
              count: int | None = None) -> np.ndarray:
        """Elements ``first .. first + count - 1`` of accessor ``index`` from the binary
        chunk (that its elements lie inside their view, and the view inside the chunk,
        was checked as the stream opened: :func:`~hsr.scene.assets.check_gltf_assets`)."""
        acc = _item(self.header, "accessors", index, self.name)
        if acc.get("type") != kind or acc.get("componentType") not in types \
                or acc.get("sparse") or acc.get("normalized") or "bufferView" not in acc:
            raise MeshError(f"{self.name}: accessor {index} is not a plain {kind} "
                            f"accessor streaming reads")
        view = _item(self.header, "bufferViews", acc["bufferView"], self.name)
        if view.get("buffer", 0) != 0:
            raise MeshError(f"{self.name}: streaming reads the GLB's own binary chunk only")
        dtype = np.dtype(_INDEX_TYPES.get(acc["componentType"], np.float32)).newbyteorder("<")
        width = 3 if kind == "VEC3" else 1
        stride = int(view.get("byteStride", dtype.itemsize * width))
        count = int(acc["count"]) - first if count is None else count
        start = int(view.get("byteOffset", 0)) + int(acc.get("byteOffset", 0))
        if count == 0:
            return np.zeros((0, width) if width > 1 else (0,), dtype=dtype)
        row = dtype.itemsize * width
        with open(self.path, "rb") as f:
            f.seek(self.bin_offset + start + stride * first)
            raw = np.fromfile(f, dtype=np.uint8, count=stride * (count - 1) + row)
        if len(raw) != stride * (count - 1) + row:
            raise MeshError(f"{self.name}: accessor {index} is cut short")
        # Interleaved rows (byteStride): each element's bytes, gathered without a copy.
        rows = np.lib.stride_tricks.as_strided(raw, shape=(count, row), strides=(stride, 1))
        values = np.ascontiguousarray(rows).view(dtype)
        return values.reshape(count, width) if width > 1 else values.reshape(count)


def _chunks(path: str) -> tuple:
    """(JSON header, offset of the binary chunk's data, its length) of a GLB, checked by
    the functions hsr.load uses (:func:`~hsr.scene.assets.glb_chunks`,
    :func:`~hsr.scene.assets.gltf_json`, :func:`~hsr.scene.assets.check_gltf_nodes`,
    :func:`~hsr.scene.assets.check_gltf_assets`), reading the JSON and what the checks
    need (images), never the geometry."""
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        def read(offset: int, count: int) -> bytes:
            f.seek(offset)
            return f.read(count)

        (start, length), bin_span = glb_chunks(read, size, path)
        if length > MAX_JSON_BYTES:
            raise MeshError(f"{path}: the first GLB chunk is not JSON of at most "
                            f"{MAX_JSON_BYTES:,} bytes")
        header = gltf_json(read(start, length), path)
    check_gltf_nodes(header, path)
    chunk = None if bin_span is None else _FileBytes(path, *bin_span)
    resolver = folder_resolver(os.path.dirname(os.path.abspath(path)), path)
    check_gltf_assets(header, chunk, resolver, path, MAX_TEXTURE_PIXELS)
    if bin_span is None:
        raise MeshError(f"{path}: no binary chunk to stream")
    return header, bin_span[0], bin_span[1]


class _FileBytes:
    """``length`` bytes of a file from ``offset``, sliced like bytes (read on slicing):
    a GLB's binary chunk as the asset checks see it, without holding it."""

    def __init__(self, path: str, offset: int, length: int) -> None:
        self.path, self.offset, self.length = path, offset, length

    def __len__(self) -> int:
        return self.length

    def __getitem__(self, span: slice) -> bytes:
        start, stop, _ = span.indices(self.length)
        with open(self.path, "rb") as f:
            f.seek(self.offset + start)
            return f.read(max(0, stop - start))


def _item(header: dict, kind: str, index, name: str) -> dict:
    items = header.get(kind)
    if not isinstance(items, list) or not isinstance(index, int) \
            or not 0 <= index < len(items) or not isinstance(items[index], dict):
        raise MeshError(f"{name}: {kind} {index!r} does not exist")
    return items[index]


def _primitive(header: dict, key: tuple, name: str) -> dict:
    mesh = _item(header, "meshes", key[0], name)
    primitives = mesh.get("primitives")
    if not isinstance(primitives, list) or not 0 <= key[1] < len(primitives):
        raise MeshError(f"{name}: mesh {key[0]} has no primitive {key[1]}")
    primitive = primitives[key[1]]
    if primitive.get("mode", 4) != 4 or primitive.get("extensions") \
            or "POSITION" not in primitive.get("attributes", {}):
        raise MeshError(f"{name}: mesh {key[0]} primitive {key[1]} is not plain triangles "
                        f"with positions; streaming does not read it (hsr.load_scene does)")
    return primitive


def _instances(path: str, header: dict) -> list:
    """(name, mesh name, model matrix, (mesh, primitive)) of every instance, from
    hsr.load_scene's reader run on the skeleton of the file (see the module)."""
    import trimesh

    from .load import file_scene

    skeleton = {k: v for k, v in header.items()
                if k in ("asset", "scene", "scenes", "nodes")}
    data = bytearray()
    views, accessors, meshes = [], [], []
    for m, mesh in enumerate(header.get("meshes") or []):
        prims = []
        for p, prim in enumerate((mesh or {}).get("primitives") or []):
            corners = np.array([[m, p, 0], [m + 0.5, p, 0], [m, p + 0.5, 0]], dtype="<f4")
            views.append({"buffer": 0, "byteOffset": len(data), "byteLength": 36})
            data += corners.tobytes()
            accessors.append({"bufferView": len(views) - 1, "componentType": 5126,
                              "count": 3, "type": "VEC3",
                              "min": corners.min(0).tolist(), "max": corners.max(0).tolist()})
            prims.append({"attributes": {"POSITION": len(accessors) - 1},
                          "mode": (prim or {}).get("mode", 4)})
        meshes.append({"primitives": prims, **({"name": mesh["name"]} if isinstance(
            mesh, dict) and "name" in mesh else {})})
    skeleton.update(meshes=meshes, accessors=accessors, bufferViews=views,
                    buffers=[{"byteLength": len(data)}])
    nodes = []
    for node in header.get("nodes") or []:
        nodes.append({k: v for k, v in (node or {}).items()
                      if k in ("name", "children", "matrix", "translation", "rotation",
                               "scale", "mesh")})
    skeleton["nodes"] = nodes
    text = json.dumps(skeleton).encode()
    text += b" " * (-len(text) % 4)
    data += b"\0" * (-len(data) % 4)
    glb = (struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(data))
           + struct.pack("<I4s", len(text), b"JSON") + text
           + struct.pack("<I4s", len(data), b"BIN\x00") + bytes(data))
    try:
        loaded = trimesh.load(io.BytesIO(glb), file_type="glb", process=False)
    except Exception as exc:  # noqa: BLE001 - trimesh's errors on a malformed tree vary
        raise MeshError(f"{path}: cannot read its node tree ({type(exc).__name__}: "
                        f"{exc})") from None
    scene = file_scene(loaded, skeleton, path)
    out = []
    for inst in scene.instances:
        m, p = (int(round(c)) for c in inst.mesh.positions[0, :2])
        out.append((inst.name, inst.mesh.name, np.asarray(inst.model, dtype=np.float64),
                    (m, p)))
    return out
