"""The streaming readers (GLB, OBJ, binary PLY: what ``hsr partition --stream`` reads)
against ``hsr.load``: for a file both read, the same instances, positions and faces; for
a file ``hsr.load`` refuses, the streamer refuses too, with the same message where the
check is one they share (issue #61: the streamers accepted what hsr.load refused and then
read wrong data: a negative byteOffset read the JSON as positions, byteStride 0 and index
counts not a multiple of 3 were read anyway, a NaN translation became the identity, a
700-deep node chain streamed for a minute, a byte-order mark at a chunk boundary changed
a vertex, faces past a PLY's declared count were ignored)."""

from __future__ import annotations

import json
import math
import os
import struct
import tempfile

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import hsr
from fuzz.guards import time_limit
from hsr.errors import MeshError
from hsr.scene.gltf_stream import GlbStream
from hsr.scene.obj_stream import ObjStream
from hsr.scene.ply import face_chunks, read_layout, read_positions

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


# --- GLB ---------------------------------------------------------------------------------

def _base_glb() -> bytes:
    from test_scenes_gltf import glb_bytes, three_nodes

    return glb_bytes(three_nodes()[0])


def _rewrite(data: bytes, header) -> bytes:
    length, = struct.unpack_from("<I", data, 12)
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + data[20 + length:]
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def _deep_chain(h, depth=70):
    first = len(h["nodes"])
    h["nodes"] += [{"children": [first + k + 1]} for k in range(depth)] + [{"mesh": 0}]
    h["scenes"][0]["nodes"].append(first)


# (where in the JSON, a function that edits it): each a class of damage the pass found.
EDITS = {
    "view offset": lambda h, v: h["bufferViews"][v % len(h["bufferViews"])].update(
        byteOffset=[-8, -1, 3, 10 ** 9][v % 4]),
    "view stride": lambda h, v: h["bufferViews"][v % len(h["bufferViews"])].update(
        byteStride=[0, "x", 3, 256, 12, 4, 8][v % 7]),
    "accessor count": lambda h, v: h["accessors"][v % len(h["accessors"])].update(
        count=[-1, 0, 1, 2, 4, 10 ** 9, "3"][v % 7]),
    "accessor offset": lambda h, v: h["accessors"][v % len(h["accessors"])].update(
        byteOffset=[-4, 4, 10 ** 6][v % 3]),
    "accessor type": lambda h, v: h["accessors"][v % len(h["accessors"])].update(
        componentType=[5126, 5125, 5121, 1, [5126]][v % 5]),
    "translation": lambda h, v: h["nodes"][v % len(h["nodes"])].update(
        translation=[[math.nan, 0, 0], [1e300, 0, 0], "x", [0, 0], [0.5, 0, 0]][v % 5]),
    "node a list": lambda h, v: h["nodes"].__setitem__(v % len(h["nodes"]), []),
    "deep chain": lambda h, v: _deep_chain(h),
    "indices": lambda h, v: h["meshes"][0]["primitives"][0].update(
        indices=v % len(h["accessors"])),
    "mode": lambda h, v: h["meshes"][0]["primitives"][0].update(mode=[4, 5, 7, "4"][v % 4]),
}


def _outcome_loaded(path):
    try:
        scene = hsr.load_scene(path)
    except MeshError as exc:
        return "refused", str(exc)
    return "read", [(i.name, i.model, i.mesh.positions, i.mesh.faces) for i in scene.instances]


def _outcome_streamed(path, chunk):
    try:
        stream = GlbStream(path)
        got = []
        for name, _, model, key in stream.instances:
            faces = [c for _, c in stream.face_chunks(key, chunk)]
            got.append((name, model, stream.positions[key],
                        np.concatenate(faces) if faces else np.zeros((0, 3), np.int64)))
    except MeshError as exc:
        return "refused", str(exc)
    return "read", got


def _same_instances(a, b) -> bool:
    return len(a) == len(b) and all(
        x[0] == y[0] and np.array_equal(x[1], y[1]) and np.array_equal(x[2], y[2])
        and np.array_equal(x[3], y[3]) for x, y in zip(a, b))


@SETTINGS
@given(edits=st.lists(st.tuples(st.sampled_from(sorted(EDITS)), st.integers(0, 50)),
                      min_size=0, max_size=2),
       chunk=st.sampled_from([1, 5, 1 << 20]))
@example(edits=[("view offset", 0)], chunk=5)  # read the JSON bytes as positions
@example(edits=[("view stride", 0)], chunk=5)  # byteStride 0 read anyway
@example(edits=[("accessor count", 4)], chunk=5)  # an index count of 4
@example(edits=[("translation", 0)], chunk=5)  # NaN became the identity
@example(edits=[("deep chain", 0)], chunk=5)  # a minute to stream
@example(edits=[("node a list", 1)], chunk=5)  # a traceback
@example(edits=[("view stride", 1)], chunk=5)  # byteStride "x": a traceback
def test_a_glb_streams_as_it_loads_or_is_refused_alike(edits, chunk):
    header = json.loads(_base_glb()[20:20 + struct.unpack_from("<I", _base_glb(), 12)[0]])
    for name, value in edits:
        EDITS[name](header, value)
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "m.glb")
        with open(path, "wb") as f:
            f.write(_rewrite(_base_glb(), header))
        with time_limit(30):
            loaded = _outcome_loaded(path)
            streamed = _outcome_streamed(path, chunk)
    if loaded[0] == "refused":
        assert streamed[0] == "refused", (edits, loaded[1])
        if "cannot read mesh" not in loaded[1] and "cannot read its node" not in loaded[1]:
            assert streamed[1] == loaded[1], (edits, loaded[1], streamed[1])
    elif streamed[0] == "refused":  # what streaming does not read, by its own words
        assert "stream" in streamed[1], (edits, streamed[1])
    else:
        assert _same_instances(loaded[1], streamed[1]), edits


def test_a_top_level_array_is_refused_alike(tmp_path):
    path = tmp_path / "a.glb"
    path.write_bytes(_rewrite(_base_glb(), [1, 2]))
    assert _outcome_loaded(path) == _outcome_streamed(path, 5)
    assert "not an object" in _outcome_loaded(path)[1]


# --- OBJ ---------------------------------------------------------------------------------

BOM = "\ufeff"


@st.composite
def obj_texts(draw):
    """OBJ text of a few vertices and triangles (some with negative indices), with
    comments, CR LF line ends, continuation lines and byte-order marks anywhere."""
    n = draw(st.integers(3, 8))
    lines = [f"v {draw(st.integers(-9, 9))} {draw(st.integers(-9, 9))} "
             f"{draw(st.integers(-9, 9))}" for _ in range(n)]
    for _ in range(draw(st.integers(1, 6))):
        corners = draw(st.lists(st.integers(1, n), min_size=3, max_size=4))
        if draw(st.booleans()):
            corners = [c - n - 1 for c in corners]  # negative: counted back
        lines.append("f " + " ".join(map(str, corners)))
    for _ in range(draw(st.integers(0, 3))):
        at = draw(st.integers(0, len(lines)))
        lines.insert(at, draw(st.sampled_from(["# note", "", "g part", "v 1 2 \\\n3",
                                               BOM + "v 0 0 0", "s off"])))
    text = draw(st.sampled_from(["\n", "\r\n"])).join(lines) + "\n"
    if draw(st.booleans()):
        text = BOM + text
    return text


@SETTINGS
@given(text=obj_texts(), chunk=st.integers(4, 40))
@example(text="v 0 0 0\nv 1 0 0\n" + BOM + "v 0 1 0\nf 1 2 3\n", chunk=16)
def test_an_obj_streams_as_it_loads(text, chunk):
    """A byte-order mark that fell exactly at a chunk boundary changed a vertex: the
    streamer dropped it as if it started the file."""
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "m.obj")
        with open(path, "wb") as f:
            f.write(text.encode("utf-8"))
        try:
            mesh = hsr.load(path)
        except MeshError as exc:
            with pytest.raises(MeshError) as info:
                ObjStream(path, folder, chunk_bytes=chunk)
            assert str(info.value) == str(exc)
            return
        stream = ObjStream(path, folder, chunk_bytes=chunk)
        faces = np.concatenate([c for _, c in stream.face_chunks(3)])
        assert np.array_equal(stream.positions, mesh.positions), text
        assert np.array_equal(faces, mesh.faces), text


# --- binary PLY --------------------------------------------------------------------------

def _ply(header_lines, vertices, faces, tail=b"") -> bytes:
    head = "ply\nformat binary_little_endian 1.0\n" + "".join(
        line + "\n" for line in header_lines) + "end_header\n"
    body = np.asarray(vertices, "<f4").tobytes()
    for face in faces:
        body += struct.pack("<B3i", 3, *face)
    return head.encode() + body + tail


VERTICES = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
FACES = [[0, 1, 2], [1, 3, 2]]
STANDARD = ["element vertex 4", "property float x", "property float y", "property float z",
            "element face 2", "property list uchar int vertex_indices"]


@pytest.mark.parametrize("lines, tail, message", [
    (STANDARD, struct.pack("<B3i", 3, 0, 1, 3), "bytes after the elements"),  # ignored
    (STANDARD[:5] + ["property list uchar int count"], b"", None),  # a list named count
    (STANDARD + ["property list uchar int vertex_indices"], b"", "appears twice"),
    (STANDARD[:1] + ["property float x"] + STANDARD[1:], b"", "appears twice"),
    (STANDARD + ["property"], b"", "header line not understood"),  # IndexError
    (["format"] + STANDARD, b"", "header line not understood"),  # IndexError
    (STANDARD + ["element extra 1", "property int k"], struct.pack("<i", 7), None),
])
def test_odd_ply_headers_stream_or_are_refused_in_one_line(tmp_path, lines, tail, message):
    path = tmp_path / "m.ply"
    path.write_bytes(_ply(lines, VERTICES, FACES, tail))
    if message:
        with pytest.raises(MeshError, match=message):
            read_layout(path)
        code, err = _partition(tmp_path, path)
        assert code == 2 and len(err) == 1 and message in err[0], err
        return
    layout = read_layout(path)
    assert np.array_equal(read_positions(layout), np.asarray(VERTICES, float))
    assert np.array_equal(np.concatenate([c for _, c in face_chunks(layout, 1)]), FACES)
    mesh = hsr.load(path)
    assert np.array_equal(mesh.faces, FACES)


def _partition(tmp_path, path):
    from conftest import require, run_cli

    require("zarr")
    return run_cli(["partition", str(path), "--parts", "1", "--out",
                    str(tmp_path / "s.zarr"), "--stream", "--quiet"])
