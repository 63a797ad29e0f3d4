"""Argument sets for the ``hsr`` command drawn from its options with valid, odd and wrong
values: every run ends with exit code 0, or 2 and exactly one line on stderr starting
``hsr: error:``; never a traceback, a warning or another exit code."""

import contextlib
import io
import os
import warnings

from hypothesis import event, given, settings
from hypothesis import strategies as st

from hsr.cli import main

from . import scaled
from .gltf_build import bomb_png

CASES = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "cases")
MODELS = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "models")

_numbers = st.sampled_from(["0", "1", "-1", "0.5", "1e300", "-1e300", "nan", "inf", "x", "",
                            "3", "1e-9", "100", "1e30", "45", "180", "0,0,0", "1,2,3",
                            "0,1,0", "1,1", "255,0,0", "300,0,0", "0.2,0.8", "1,0", "1e-300"])
_sizes = st.sampled_from(["64x48", "32x32", "1x1", "0x10", "5x4", "40000x10", "axb", "64",
                          "48x36", "-4x4", "32768x32768"])
_files = st.sampled_from(([os.path.join(CASES, n) for n in sorted(os.listdir(CASES))
                           if n.endswith(".obj")] if os.path.isdir(CASES) else ["missing.obj"])
                         + [os.path.join(MODELS, "african_head.obj")])
_options = {
    "--size": _sizes, "--eye": _numbers, "--target": _numbers, "--up": _numbers,
    "--fov": _numbers, "--near": _numbers, "--far": _numbers, "--ortho": _numbers,
    "--cull": st.sampled_from(["none", "back", "front", "front_and_back", "sideways"]),
    "--front-face": st.sampled_from(["ccw", "cw", "up"]),
    "--depth-func": st.sampled_from(["less", "lequal", "greater", "always", "never", "often"]),
    "--clear-depth": _numbers, "--depth-range": _numbers,
    "--shading": st.sampled_from(["flat", "gouraud", "normal", "random", "depth", "toon"]),
    "--polygon-mode": st.sampled_from(["fill", "line", "point", "dots"]),
    "--polygon-offset": _numbers, "--opacity": _numbers, "--background": _numbers,
    "--fog": st.sampled_from(["linear:1,10", "exp:0.3", "exp2:x", "fog", "linear:5,1"]),
    "--threads": st.sampled_from(["1", "2", "0", "-3", "x"]),
    "--option": st.sampled_from(["accel=none", "bvh=5", "tree=5", "force=maybe", "key=min",
                                 "max_actions=0", "max_polygons=1", "heuristic=first", "x",
                                 "traversal=front_to_back", "progress=true"]),
    "--scene": st.sampled_from(["cubes", "cyclic", "penetration", "glass", "checker", "nope"]),
    "--view": _numbers,
    "--orbit": st.sampled_from(["2", "0", "-1", "x", "100001"]),
    "--depth-kind": st.sampled_from(["window", "eye", "distance", "metric"]),
    "--camera": st.sampled_from(["missing.json", "/dev/zero", os.path.dirname(__file__),
                                 "{tmp}/t.json", "{tmp}/t.json:1", "{tmp}/t.json:7",
                                 "{tmp}/t.json:x", "{tmp}/colmap", "{tmp}/colmap:1"]),
    "--texture": st.sampled_from(["{tmp}/tex.png", "tri.obj={tmp}/tex.png", "x=y",
                                  "{tmp}/missing.png", "/dev/zero", "{tmp}/bad.png",
                                  "{tmp}/big.png", "{tmp}"]),
    "--depth-out": st.sampled_from(["{tmp}/d.npy", "{tmp}/d.exr", "{tmp}/d.png",
                                    "{tmp}/d.tiff", "{tmp}/no/d.npy", "{tmp}/d"]),
    "--normals-out": st.sampled_from(["{tmp}/n.npy", "{tmp}/n.exr", "{tmp}/n.png",
                                      "{tmp}/n.jpg"]),
    "--ids-out": st.sampled_from(["{tmp}/i.npy", "{tmp}/i.png"]),
}
_flags = ["--no-depth-test", "--no-depth-write", "--hidden-line", "--occlusion-cull",
          "--no-texture"]


def _fixtures(tmp):
    """Camera files and images the options above name."""
    import json

    import numpy as np
    from PIL import Image

    frame = {"transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]}
    with open(os.path.join(tmp, "t.json"), "w") as fh:
        json.dump({"w": 40, "h": 30, "fl_x": 30.0, "frames": [frame, frame]}, fh)
    os.makedirs(os.path.join(tmp, "colmap"), exist_ok=True)
    with open(os.path.join(tmp, "colmap", "cameras.txt"), "w") as fh:
        fh.write("1 PINHOLE 40 30 30 30 20 15\n")
    with open(os.path.join(tmp, "colmap", "images.txt"), "w") as fh:
        fh.write("1 1 0 0 0 0 0 4 1 a.png\n\n2 1 0 0 0 0 0 5 1 b.png\n\n")
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(os.path.join(tmp, "tex.png"))
    with open(os.path.join(tmp, "bad.png"), "wb") as fh:
        fh.write(b"\x89PNG\r\n\x1a\nnot really")
    with open(os.path.join(tmp, "big.png"), "wb") as fh:
        fh.write(bomb_png())


@st.composite
def argv(draw, tmp):
    command = draw(st.sampled_from(["render", "render", "render", "compare", "explain",
                                    "report"]))
    args = [command]
    if command == "explain":
        args.append(draw(st.sampled_from(["depth", "overdraw", "culling", "painter",
                                          "precision", "nope"])))
    if draw(st.booleans()):
        args.append(draw(_files))
    for key in draw(st.lists(st.sampled_from(sorted(_options)), max_size=4, unique=True)):
        args += [key, draw(_options[key]).replace("{tmp}", tmp)]
    for flag in draw(st.lists(st.sampled_from(_flags), max_size=2, unique=True)):
        args.append(flag)
    if command in ("render", "compare"):
        args += ["--algorithm" if command == "render" else "--algorithms",
                 draw(st.sampled_from(["zbuffer", "scanline", "raycast", "painter", "newell",
                                       "bsp", "nope"]))]
    if "--size" not in args:
        args += ["--size", "48x36"]
    out = {"render": "o.png", "compare": None, "explain": "e.png", "report": "r.html"}[command]
    if out:
        args += ["-o", os.path.join(tmp, draw(st.sampled_from([out, "o.xyz", "no/" + out])))]
    return args


@settings(max_examples=scaled(150))
@given(data=st.data())
def test_cli_exits_0_or_2_with_one_line(tmp_path_factory, data):
    tmp = str(tmp_path_factory.mktemp("cli"))
    _fixtures(tmp)
    args = data.draw(argv(tmp))
    err = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stderr(err), \
            contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("error")
        code = main(args + ["--quiet"])
    lines = err.getvalue().strip().splitlines()
    event(f"{args[0]} exit {code}")
    assert code in (0, 2), (args, code, lines)
    if code == 2:
        assert len(lines) == 1 and lines[0].startswith("hsr: error: "), (args, lines)
    else:
        assert lines == [], (args, lines)
