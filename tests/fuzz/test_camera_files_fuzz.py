"""Camera files mutated (issue #32): NeRF transforms.json with keys missing or set to odd
values (zero, negative, NaN, huge focal lengths and sizes, matrices of the wrong shape,
scaled or singular), and COLMAP text models with tokens and lines replaced (unknown
models, zero or unnormalised quaternions, duplicate ids, images naming missing cameras,
counts out of range). Every read gives cameras that render, or a CameraError that names
the file; never another exception, a warning or a hang. The CLI's ``--camera FILE:INDEX``
takes the same files and answers 0 or 2 with one line."""

from __future__ import annotations

import copy
import json
import os
import warnings

from hypothesis import event, example, given, settings
from hypothesis import strategies as st

import hsr
from conftest import assert_one_line_or_success, run_cli

from . import scaled
from .guards import time_limit

_ODD = [0, -1, 1, 0.5, 1e-300, 1e9, 10 ** 9, 2 ** 63, 1e300, float("nan"), float("inf"),
        -float("inf"), "", "x", "12", None, True, [], {}, [1, 2], [[1, 0], [0, 1]],
        [[0] * 4] * 4, [[2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]],
        [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]],
        [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]], [[float("nan")] * 4] * 4, 3.14159]
_KEYS = ["w", "h", "fl_x", "fl_y", "cx", "cy", "camera_angle_x", "camera_angle_y",
         "frames", "transform_matrix", "file_path"]

TRANSFORMS = {"w": 32, "h": 24, "fl_x": 30.0, "fl_y": 30.0, "cx": 16.0, "cy": 12.0,
              "frames": [{"file_path": "a.png",
                          "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4],
                                               [0, 0, 0, 1]]},
                         {"file_path": "b.png", "camera_angle_x": 0.9,
                          "transform_matrix": [[0, 0, 1, 4], [0, 1, 0, 0], [-1, 0, 0, 0],
                                               [0, 0, 0, 1]]}]}
CAMERAS_TXT = ["# Camera list", "1 PINHOLE 32 24 30 30 16 12", "2 SIMPLE_PINHOLE 40 30 35 20 15"]
IMAGES_TXT = ["# Image list", "1 1 0 0 0 0 0 4 1 a.png", "",
              "2 0.7071068 0 0.7071068 0 0 0 4 2 b.png", "10 20 1"]
_TOKENS = ["0", "-1", "1", "0.5", "nan", "inf", "-inf", "1e300", "1e9", "1000000000", "x", "",
           "PINHOLE", "SIMPLE_PINHOLE", "OPENCV", "SIMPLE_RADIAL", "RADIAL", "1", "2", "3",
           "0 0 0 0", "1.5", "a.png", "#", "\t"]
SCENE = hsr.Scene().add(hsr.scenes.cube(), None)


def check_cameras(cameras, sizes):
    """Each camera read renders the unit cube at a small size with its own aspect."""
    for cam, (w, h) in zip(cameras, sizes):
        scale = max(w, h) / 16.0
        hsr.render(SCENE, cam, max(1, int(w / scale)), max(1, int(h / scale)))


@st.composite
def transforms_edits(draw):
    doc = copy.deepcopy(TRANSFORMS)
    for _ in range(draw(st.integers(1, 3))):
        where = draw(st.sampled_from(["top", "frame0", "frame1"]))
        target = doc if where == "top" else (
            doc["frames"][int(where[-1])] if isinstance(doc.get("frames"), list)
            and len(doc["frames"]) > int(where[-1])
            and isinstance(doc["frames"][int(where[-1])], dict) else doc)
        key = draw(st.sampled_from(_KEYS))
        if draw(st.booleans()):
            target.pop(key, None)
        else:
            target[key] = draw(st.sampled_from(_ODD))
    return doc


@settings(max_examples=scaled(250))
@example(doc={**TRANSFORMS, "camera_angle_x": 0.0, "fl_x": None} | {"frames": [
    {k: v for k, v in TRANSFORMS["frames"][0].items()}]})
@given(doc=transforms_edits())
def test_transforms_json_reads_or_refuses(tmp_path_factory, doc):
    path = tmp_path_factory.mktemp("tj") / "transforms.json"
    path.write_text(json.dumps(doc))
    with warnings.catch_warnings(), time_limit(30):
        warnings.simplefilter("error")
        try:
            cameras, _, size = hsr.read_transforms(path)
        except hsr.HsrError as exc:
            assert str(path) in str(exc), exc
            event("refused")
            return
        check_cameras(cameras, [size] * len(cameras))
    event("read")


@st.composite
def colmap_edits(draw):
    files = {"cameras": list(CAMERAS_TXT), "images": list(IMAGES_TXT)}
    for _ in range(draw(st.integers(1, 3))):
        name = draw(st.sampled_from(["cameras", "images"]))
        lines = files[name]
        op = draw(st.sampled_from(["token", "token", "token", "dup", "drop", "append"]))
        k = draw(st.integers(0, len(lines) - 1)) if lines else 0
        if op == "token" and lines:
            parts = lines[k].split(" ")
            i = draw(st.integers(0, max(0, len(parts) - 1)))
            parts[i] = draw(st.sampled_from(_TOKENS))
            lines[k] = " ".join(parts)
        elif op == "dup" and lines:
            lines.insert(k, lines[k])
        elif op == "drop" and lines:
            del lines[k]
        elif op == "append":
            lines.append(" ".join(draw(st.lists(st.sampled_from(_TOKENS), max_size=12))))
    return files


@settings(max_examples=scaled(250))
@example(files={"cameras": CAMERAS_TXT + [CAMERAS_TXT[1].replace("30 30", "60 60")],
                "images": IMAGES_TXT})
@example(files={"cameras": CAMERAS_TXT, "images": IMAGES_TXT[:2] + ["", IMAGES_TXT[1]]})
@example(files={"cameras": CAMERAS_TXT, "images": ["1 0 0 0 0 0 0 4 1 a.png", ""]})
@example(files={"cameras": ["1 PINHOLE 32 24 0 30 16 12"], "images": IMAGES_TXT[:2]})
@example(files={"cameras": ["1 PINHOLE 1000000000 24 30 30 16 12"], "images": IMAGES_TXT[:2]})
@given(files=colmap_edits())
def test_colmap_text_reads_or_refuses(tmp_path_factory, files):
    folder = tmp_path_factory.mktemp("colmap")
    for name, lines in files.items():
        (folder / f"{name}.txt").write_text("\n".join(lines) + "\n")
    with warnings.catch_warnings(), time_limit(30):
        warnings.simplefilter("error")
        try:
            cameras, _, sizes = hsr.read_colmap(folder)
        except hsr.HsrError as exc:
            assert str(folder) in str(exc), exc
            event("refused")
            return
        check_cameras(cameras, sizes)
    event("read")


@settings(max_examples=scaled(120))
@given(kind=st.sampled_from(["transforms", "colmap"]), doc=transforms_edits(),
       files=colmap_edits(), index=st.sampled_from(["", ":0", ":1", ":2", ":-1", ":x",
                                                     ":99999999999999999999"]),
       extra=st.sampled_from([[], ["--size", "16x12"], ["--near", "0.5"], ["--far", "2"],
                              ["--view", "10,10"], ["--depth-out", "d.png",
                                                    "--depth-kind", "eye"]]))
def test_cli_camera_file_index(tmp_path_factory, kind, doc, files, index, extra):
    folder = tmp_path_factory.mktemp("cam")
    if kind == "transforms":
        path = folder / "transforms.json"
        path.write_text(json.dumps(doc))
    else:
        path = folder
        for name, lines in files.items():
            (folder / f"{name}.txt").write_text("\n".join(lines) + "\n")
    extra = [str(folder / e) if e.endswith(".png") else e for e in extra]
    args = ["render", "--camera", f"{path}{index}", "-o", str(folder / "o.png"), "--quiet",
            *extra]
    with time_limit(60):
        code, lines = run_cli(args)
    event(f"{kind} exit {code}")
    assert_one_line_or_success(args, code, lines)
    if code == 0:
        assert os.path.getsize(folder / "o.png") > 0
