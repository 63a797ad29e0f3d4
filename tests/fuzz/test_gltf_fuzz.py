"""glTF and GLB files mutated every way the format can be wrong (issue #32): fields of
accessors, buffer views, buffers, meshes, nodes and scenes set to odd values or deleted;
node cycles and deep trees; singular and non-affine matrices; NaN, infinite and 1e300
positions and indices past the vertex count in the binary data; corrupt and huge images;
URIs that point outside the model's folder, at devices, FIFOs, links and other schemes;
and GLB bytes cut, overwritten and flipped.

Every load ends in a Scene that renders, or an HsrError; never another exception, a
warning or a hang; and no file outside the model's folder (a secret beside it, /etc,
/dev) is ever opened."""

from __future__ import annotations

import base64
import copy
import os
import struct
import warnings

import numpy as np
import pytest
from hypothesis import event, example, given, settings
from hypothesis import strategies as st

import hsr

from . import scaled
from .gltf_build import BOX_POSITIONS, bomb_png, parts, png_bytes, write_glb, write_gltf
from .guards import time_limit, touched, watch_opens

HEADER, BLOB = parts()


def data_uri(blob: bytes, kind="application/octet-stream") -> str:
    return f"data:{kind};base64," + base64.b64encode(blob).decode()


# The URIs a hostile or broken file may name; "@SECRET" is the absolute path of a file
# outside the model's folder, "link.bin" a symbolic link to it, "fifo" a named pipe.
HOSTILE_URIS = ["../outside/secret.bin", "%2e%2e/outside/secret.bin",
                "%2E%2E%2Foutside%2Fsecret.bin",
                "..\\outside\\secret.bin", "sub/../../outside/secret.bin", "@SECRET",
                "file:///etc/passwd", "/etc/passwd", "/dev/zero", "/dev/stdin", "link.bin",
                "fifo", "sub", "", "   ", "missing.bin", "nul\x00.bin", "C:\\Windows\\x.bin",
                "http://127.0.0.1:9/x.bin", "~/x.bin", "model.bin", "tex.png",
                "data:application/octet-stream;base64,@@@@", "data:,plain",
                data_uri(BLOB), data_uri(b"short"), data_uri(png_bytes(), "image/png"),
                data_uri(bomb_png(), "image/png"), data_uri(png_bytes()[:40], "image/png"),
                data_uri(b"GIF89a", "image/gif"), 7, None, ["x"]]
_ODD = [-1, 0, 1, 2, 3, 5, 7, 2 ** 31, 2 ** 53, 10 ** 12, 1.5, float("nan"), float("inf"),
        1e300, "", "x", "VEC4", "MAT4", None, True, [], {}, [0], [1], [0, 1], [0, 0, 0, 0],
        [float("nan"), 0, 0, 1], [0] * 16, [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
        [1, 0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1], [1] * 15, [1e300] * 16,
        [0, 0, 0], [1e-30, 1e-30, 1e-30], [1e300, 1, 1], [5126], {"a": 1}]
_FIELDS = [("accessors", 0, "count"), ("accessors", 0, "byteOffset"),
           ("accessors", 0, "componentType"), ("accessors", 0, "type"),
           ("accessors", 0, "bufferView"), ("accessors", 0, "normalized"),
           ("accessors", 1, "count"), ("accessors", 1, "componentType"),
           ("accessors", 2, "count"), ("accessors", 2, "componentType"),
           ("accessors", 2, "byteOffset"), ("accessors", 2, "type"),
           ("bufferViews", 0, "byteStride"), ("bufferViews", 0, "byteOffset"),
           ("bufferViews", 0, "byteLength"), ("bufferViews", 1, "byteStride"),
           ("bufferViews", 2, "byteOffset"), ("bufferViews", 2, "byteLength"),
           ("bufferViews", 3, "byteLength"), ("bufferViews", 3, "buffer"),
           ("bufferViews", 0, "buffer"), ("buffers", 0, "byteLength"),
           ("meshes", 0, "primitives", 0, "mode"), ("meshes", 0, "primitives", 0, "indices"),
           ("meshes", 0, "primitives", 0, "material"),
           ("meshes", 0, "primitives", 0, "attributes", "POSITION"),
           ("meshes", 0, "primitives", 0, "attributes", "TEXCOORD_0"),
           ("meshes", 0, "primitives", 0, "attributes", "COLOR_0"),
           ("meshes", 0, "primitives"), ("meshes", 0),
           ("nodes", 0, "mesh"), ("nodes", 1, "mesh"), ("nodes", 0, "children"),
           ("nodes", 1, "children"), ("nodes", 1, "matrix"), ("nodes", 0, "matrix"),
           ("nodes", 1, "scale"), ("nodes", 1, "rotation"), ("nodes", 1, "translation"),
           ("nodes", 0, "name"), ("nodes", 1, "name"), ("nodes",), ("scene",),
           ("scenes", 0, "nodes"), ("scenes",), ("images", 0, "bufferView"),
           ("images", 0, "mimeType"), ("textures", 0, "source"), ("textures",),
           ("materials", 0, "pbrMetallicRoughness", "baseColorFactor"),
           ("materials", 0, "pbrMetallicRoughness", "baseColorTexture", "index"),
           ("materials", 0, "pbrMetallicRoughness", "baseColorTexture", "texCoord"),
           ("accessors",), ("bufferViews",), ("buffers",), ("asset", "version")]


def _set(header, path, value, delete=False):
    node = header
    for key in path[:-1]:
        try:
            node = node[key]
        except (KeyError, IndexError, TypeError):
            return
    try:
        if delete:
            del node[path[-1]]
        else:
            node[path[-1]] = copy.deepcopy(value)
    except (KeyError, IndexError, TypeError):
        pass


@st.composite
def edits(draw):
    """One edit: (kind, arguments)."""
    kind = draw(st.sampled_from(["set", "set", "set", "delete", "uri", "cycle", "deep",
                                 "poison", "index", "image"]))
    if kind == "set":
        return kind, (draw(st.sampled_from(_FIELDS)), draw(st.sampled_from(_ODD)))
    if kind == "delete":
        return kind, (draw(st.sampled_from(_FIELDS)),)
    if kind == "uri":
        return kind, (draw(st.sampled_from(["buffer", "image"])),
                      draw(st.sampled_from(HOSTILE_URIS)))
    if kind == "cycle":
        return kind, (draw(st.sampled_from([(1, [0]), (0, [0]), (1, [1]), (0, [1, 1]),
                                             (1, [0, 1])])),)
    if kind == "deep":
        return kind, (draw(st.sampled_from([2, 50, 3000])),)
    if kind == "poison":
        return kind, (draw(st.integers(0, len(BOX_POSITIONS) * 3 - 1)),
                      draw(st.sampled_from([float("nan"), float("inf"), -float("inf"),
                                            1e30, 3e38, -1e38])))
    if kind == "index":
        return kind, (draw(st.integers(0, 35)), draw(st.sampled_from([8, 9, 255, 65535])))
    return kind, (draw(st.sampled_from(["bomb", "truncated", "garbage", "empty", "big"])),)


def apply(edit, header, blob):
    kind, args = edit
    if kind == "set":
        _set(header, *args)
    elif kind == "delete":
        _set(header, args[0], None, delete=True)
    elif kind == "uri":
        which, uri = args
        _set(header, ("buffers", 0, "uri") if which == "buffer" else ("images", 0), {
            "uri": uri} if which == "image" else uri)
    elif kind == "cycle":
        node, children = args[0]
        _set(header, ("nodes", node, "children"), children)
    elif kind == "deep":
        depth = args[0]
        nodes = header.get("nodes")
        if isinstance(nodes, list):
            start = len(nodes)
            for k in range(depth):
                nodes.append({"name": f"d{k}", "mesh": 0, "translation": [0.01, 0, 0],
                              "children": [start + k + 1] if k + 1 < depth else []})
            _set(header, ("scenes", 0, "nodes"), [0, start])
    elif kind == "poison":
        values = np.frombuffer(blob, dtype=np.float32, count=BOX_POSITIONS.size).copy()
        values[args[0]] = args[1]
        blob = values.tobytes() + blob[values.nbytes:]
    elif kind == "index":
        offset = header_offset(HEADER, 2) + 2 * args[0]
        blob = blob[:offset] + struct.pack("<H", args[1]) + blob[offset + 2:]
    elif kind == "image":
        picture = {"bomb": bomb_png(), "truncated": png_bytes()[:50], "garbage": b"\x89PNGxx",
                   "empty": b"", "big": bomb_png(9000, 9000)}[args[0]]
        _set(header, ("images", 0), {"uri": data_uri(picture, "image/png")})
    return header, blob


def header_offset(header, view):
    return header["bufferViews"][view]["byteOffset"]


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """(model folder, forbidden paths): a secret outside the folder, a link to it and a
    FIFO inside, and the devices and system files a URI may name."""
    root = tmp_path_factory.mktemp("gltf")
    model, out = root / "model", root / "outside"
    model.mkdir()
    out.mkdir()
    secret = out / "secret.bin"
    secret.write_bytes(BLOB)
    (out / "secret.png").write_bytes(png_bytes())
    (model / "tex.png").write_bytes(png_bytes())
    (model / "sub").mkdir()
    os.symlink(secret, model / "link.bin")
    os.mkfifo(model / "fifo")
    return model, [str(out), "/etc/passwd", "/dev/zero", "/dev/stdin", str(model / "fifo")]


def load_and_render(path):
    """'scene' or the HsrError's class name; any other exception propagates."""
    try:
        scene = hsr.load_scene(path)
    except hsr.HsrError as exc:
        return type(exc).__name__
    try:
        hsr.render(scene, hsr.views.default(scene, 4 / 3), 16, 12)
    except hsr.HsrError as exc:
        return "render " + type(exc).__name__
    return "scene"


def _substitute(value, name, text):
    """``value`` with every string equal to ``name`` replaced by ``text``."""
    if isinstance(value, dict):
        return {k: _substitute(v, name, text) for k, v in value.items()}
    if isinstance(value, list):
        return [_substitute(v, name, text) for v in value]
    return text if value == name else value


def run(folders, header, blob, form, mangle=None):
    model, forbidden = folders
    secret = os.path.join(forbidden[0], "secret.bin")
    header = _substitute(header, "@SECRET", secret)
    if form == "glb":
        path = str(model / "m.glb")
        write_glb(path, header, blob)
        if mangle is not None:
            data = bytearray(open(path, "rb").read())
            data = mangle(data)
            with open(path, "wb") as fh:
                fh.write(bytes(data))
    else:
        path = write_gltf(model, header, blob)
    with warnings.catch_warnings(), watch_opens() as opened, time_limit(60):
        warnings.simplefilter("error")
        outcome = load_and_render(path)
    assert touched(opened, forbidden) == [], touched(opened, forbidden)
    event(f"{form}: {outcome}")
    return outcome


def test_the_unmutated_files_load_as_two_textured_instances(folders):
    for form in ("glb", "gltf"):
        model, forbidden = folders
        path = str(model / "m.glb") if form == "glb" else None
        if form == "glb":
            write_glb(path, HEADER, BLOB)
        else:
            path = write_gltf(model, HEADER, BLOB)
        scene = hsr.load_scene(path)
        assert len(scene) == 2 and scene.n_faces == 24
        assert scene.instances[0].mesh.texture is not None
        np.testing.assert_allclose(scene.instances[1].model[:3, 3], [1.5, 0, 0])


@settings(max_examples=scaled(400))
@example(edit_list=[("uri", ("buffer", "%2e%2e/outside/secret.bin"))], form="gltf")
@example(edit_list=[("uri", ("image", "@SECRET"))], form="gltf")
@example(edit_list=[("uri", ("buffer", "fifo"))], form="gltf")
@example(edit_list=[("uri", ("buffer", "link.bin"))], form="glb")
@example(edit_list=[("cycle", ((1, [0]),))], form="glb")
@example(edit_list=[("uri", ("buffer", ["x"]))], form="glb")
@example(edit_list=[("set", (("nodes", 0, "mesh"), -1))], form="glb")
@example(edit_list=[("deep", (3000,))], form="glb")
@example(edit_list=[("image", ("bomb",))], form="glb")
@example(edit_list=[("index", (3, 65535))], form="glb")
@given(edit_list=st.lists(edits(), min_size=1, max_size=3),
       form=st.sampled_from(["glb", "gltf"]))
def test_mutated_gltf_loads_or_refuses(folders, edit_list, form):
    header, blob = copy.deepcopy(HEADER), BLOB
    for edit in edit_list:
        header, blob = apply(edit, header, blob)
    run(folders, header, blob, form)


@settings(max_examples=scaled(200))
@given(cuts=st.lists(st.tuples(st.sampled_from(["truncate", "overwrite", "flip"]),
                               st.floats(0, 1), st.integers(0, 2 ** 32 - 1)),
                     min_size=1, max_size=3))
def test_glb_bytes_cut_overwritten_or_flipped(folders, cuts):
    def mangle(data):
        for op, where, value in cuts:
            i = int(where * max(len(data) - 1, 0))
            if op == "truncate":
                data = data[:i]
            elif op == "overwrite":
                data[i:i + 4] = struct.pack("<I", value)[:len(data[i:i + 4])]
            elif data:
                data[i] ^= 1 << (value % 8)
        return data

    run(folders, copy.deepcopy(HEADER), BLOB, "glb", mangle)
