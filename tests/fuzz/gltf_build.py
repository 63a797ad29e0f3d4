"""A small valid glTF 2.0 model written by hand (not by trimesh's exporter, so every field
is ours to break): a textured box as two nodes, parent and child, with its positions,
texture coordinates, indices and a PNG in one buffer. ``parts()`` gives the JSON and the
bytes; ``write_gltf`` / ``write_glb`` put them on disk."""

from __future__ import annotations

import copy
import io
import json
import struct
import zlib

import numpy as np
from PIL import Image

BOX_POSITIONS = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.4, 0.4)
                          for z in (-0.3, 0.3)], dtype=np.float32)
BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]],
                     dtype=np.uint16)


def png_bytes(width=4, height=4) -> bytes:
    rng = np.random.default_rng(1)
    out = io.BytesIO()
    Image.fromarray(rng.integers(0, 255, (height, width, 3), dtype=np.uint8)).save(out, "PNG")
    return out.getvalue()


def _pad(blob: bytes) -> bytes:
    return blob + b"\x00" * (-len(blob) % 4)


def parts():
    """(header dict, buffer bytes): positions at 0, uv after them, indices, then a PNG."""
    uv = (BOX_POSITIONS[:, :2] + 0.5).astype(np.float32)
    pieces = [BOX_POSITIONS.tobytes(), uv.tobytes(), BOX_FACES.tobytes(), png_bytes()]
    views, blob = [], b""
    for k, piece in enumerate(pieces):
        view = {"buffer": 0, "byteOffset": len(blob), "byteLength": len(piece)}
        if k < 2:
            view["target"] = 34962
        elif k == 2:
            view["target"] = 34963
        views.append(view)
        blob += _pad(piece)
    header = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "root", "mesh": 0, "children": [1]},
                  {"name": "child", "mesh": 0, "translation": [1.5, 0.0, 0.0],
                   "rotation": [0.0, 0.38268343, 0.0, 0.92387953]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1},
                                    "indices": 2, "material": 0, "mode": 4}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                "baseColorFactor": [1, 1, 1, 1]}}],
        "textures": [{"source": 0}],
        "images": [{"bufferView": 3, "mimeType": "image/png"}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
             "min": BOX_POSITIONS.min(axis=0).tolist(),
             "max": BOX_POSITIONS.max(axis=0).tolist()},
            {"bufferView": 1, "componentType": 5126, "count": 8, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": BOX_FACES.size,
             "type": "SCALAR"}],
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    return header, blob


def glb(header: dict, blob: bytes) -> bytes:
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text
    body += struct.pack("<I4s", len(blob), b"BIN\x00") + _pad(blob)
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def write_glb(path, header, blob) -> None:
    with open(path, "wb") as fh:
        fh.write(glb(header, blob))


def write_gltf(folder, header, blob, name="model.gltf", bin_name="model.bin") -> str:
    """The model as a .gltf with its buffer in ``bin_name`` beside it (unless the header
    already gives the buffer a uri)."""
    header = copy.deepcopy(header)
    if isinstance(header.get("buffers"), list) and header["buffers"] \
            and isinstance(header["buffers"][0], dict) and "uri" not in header["buffers"][0]:
        header["buffers"][0]["uri"] = bin_name
    (folder / bin_name).write_bytes(blob)
    path = folder / name
    path.write_text(json.dumps(header))
    return str(path)


def bomb_png(width=100_000, height=100_000) -> bytes:
    """A PNG whose header claims ``width`` x ``height`` pixels over a few bytes of data."""
    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0"))
            + chunk(b"IEND", b""))
