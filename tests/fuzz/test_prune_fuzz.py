"""``hsr prune`` with options and output paths drawn from valid, odd and wrong values
(issue #32): every run exits 0, or 2 with one line; the input model is never changed;
an output that is the input (or a link to it) is refused even with ``--force``; a file
that exists (the output, or an OBJ's .mtl beside it) is replaced only with ``--force``,
and a refused run writes nothing."""

from __future__ import annotations

import hashlib
import os

from hypothesis import event, given, settings
from hypothesis import strategies as st

import hsr
from conftest import assert_one_line_or_success, run_cli

from . import scaled
from .guards import time_limit

_options = {
    "--views": st.sampled_from(["sphere:6", "hemisphere:4", "orbit:3", "orbit:3:45",
                                "sphere:0", "sphere:-2", "orbit:3:100", "nope", "", "auto",
                                "/dev/zero", "missing.json", "sphere:x"]),
    "--size": st.sampled_from(["16", "24", "0", "-3", "x", "40000", "1e3", ""]),
    "--max-views": st.sampled_from(["8", "0", "-1", "x"]),
    "--level": st.sampled_from(["faces", "objects", "vertices"]),
    "--min-pixels": st.sampled_from(["1", "0", "5", "-1", "x"]),
    "--keep-neighbors": st.sampled_from(["0", "1", "3", "-1", "1000", "x"]),
    "--algorithm": st.sampled_from(["zbuffer", "raycast", "painter", "nope"]),
    "--cull": st.sampled_from(["none", "back", "sideways"]),
    "--depth-func": st.sampled_from(["less", "lequal", "always", "often"]),
    "--verify": st.sampled_from(["0", "2", "-1", "x"]),
    "--seed": st.sampled_from(["0", "7", "-1", "x", "99999999999999999999999"]),
    "--threads": st.sampled_from(["1", "2", "0", "x"]),
    "--near": st.sampled_from(["0.1", "0", "-1", "nan"]),
    "--far": st.sampled_from(["100", "0.01", "inf"]),
}


def _digest(path) -> str:
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def _model(folder):
    """Two boxes, a small one hidden inside a large one, as an OBJ with an .mtl."""
    scene = hsr.Scene()
    scene.add(hsr.scenes.cube(), name="outer")
    scene.add(hsr.scenes.cube(), model=[[0.2, 0, 0, 0], [0, 0.2, 0, 0], [0, 0, 0.2, 0],
                                        [0, 0, 0, 1]], name="inner")
    path = folder / "model.obj"
    hsr.write_mesh(scene, path)
    return path


@settings(max_examples=scaled(120))
@given(data=st.data(),
       target=st.sampled_from(["new.obj", "new.ply", "new.glb", "existing.obj",
                               "existing.glb", "model.obj", "link.obj", "./model.obj",
                               "model.mtl", "clash.obj", "out.fbx", "nodir/o.obj", "dir",
                               "new"]),
       force=st.booleans())
def test_prune_options_and_outputs(tmp_path_factory, data, target, force):
    folder = tmp_path_factory.mktemp("prune")
    model = _model(folder)
    (folder / "existing.obj").write_text("# mine\n")
    (folder / "existing.glb").write_bytes(b"mine")
    (folder / "clash.mtl").write_text("# my materials\n")
    (folder / "dir").mkdir()
    os.symlink(model, folder / "link.obj")
    before = {p: _digest(folder / p) for p in ("model.obj", "model.mtl", "existing.obj",
                                                 "existing.glb", "clash.mtl")}
    out = str(folder / target) if target != "./model.obj" else os.path.join(
        str(folder), ".", "model.obj")
    args = ["prune", str(model), "-o", out, "--quiet"]
    for key in data.draw(st.lists(st.sampled_from(sorted(_options)), max_size=4, unique=True)):
        args += [key, data.draw(_options[key])]
    if "--views" not in args:
        args += ["--views", "sphere:6"]
    if "--size" not in args:
        args += ["--size", "16"]
    if force:
        args.append("--force")
    with time_limit(120):
        code, lines = run_cli(args)
    event(f"{target} force={force}: exit {code}")
    assert_one_line_or_success(args, code, lines)
    if code == 0:
        assert all(not line.startswith("hsr: error") for line in lines), lines
    # The input is never changed; other files only when asked.
    assert _digest(model) == before["model.obj"]
    assert _digest(folder / "model.mtl") == before["model.mtl"]
    for name in ("existing.obj", "existing.glb", "clash.mtl"):
        replaced = _digest(folder / name) != before[name]
        assert not replaced or (force and code == 0), (name, args)
    if target in ("model.obj", "link.obj", "./model.obj", "model.mtl"):
        assert code == 2, args
    if code == 2:
        assert not os.path.exists(out) or target in ("existing.obj", "existing.glb",
                                                     "model.obj", "link.obj", "./model.obj",
                                                     "model.mtl", "dir"), args
