"""Every command's output paths against every input path (issue #61): an output named
as one of the inputs (the model, its .mtl, its texture, a hard or symbolic link to one,
the camera or points file) or as another output of the same call is refused in one line
with exit 2, and no file in the folder changes."""

from __future__ import annotations

import hashlib
import os
import tempfile

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hsr
from conftest import run_cli

OBJ = ("mtllib look.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 -1\nvt 0 0\nvt 1 0\nvt 0 1\n"
       "usemtl skin\nf 1/1 2/2 3/3\nf 2/2 4/3 3/1\n")

# Inputs by role; each command's outputs by flag, with the extension it accepts (an input
# is given that extension's name by a link, so the output check is what refuses it).
MODEL = ("m.obj", "look.mtl", "tex.png", "hard.png", "soft.png")
COMMANDS = {  # arguments, outputs by flag, the inputs of the call
    "render": (["render", "m.obj", "--size", "16x16", "--camera", "cams.json"],
               {"-o": ".png", "--depth-out": ".npy", "--ids-out": ".npy",
                "--normals-out": ".png", "--error-map": ".png"}, MODEL + ("cams.json",)),
    "render --fill": (["render", "m.obj", "--size", "16x16", "--camera", "cams.json",
                       "--fill", "--shading", "flat"], {"--svg": ".svg", "--pdf": ".pdf"},
                      MODEL + ("cams.json",)),
    "lines": (["lines", "m.obj", "--size", "16x16", "--camera", "cams.json", "--page", "A6"],
              {"-o": ".svg"}, MODEL + ("cams.json",)),
    "explain": (["explain", "depth", "m.obj", "--size", "32x32"], {"-o": ".png"}, MODEL),
    "compare": (["compare", "m.obj", "--size", "32x32", "--algorithms", "zbuffer,painter"],
                {"--montage": ".png"}, MODEL),
    "visibility": (["visibility", "m.obj", "--views", "cams.json", "--size", "16",
                    "--what", "points:pts.npy", "--force"], {"-o": ".npz"},
                   MODEL + ("cams.json", "pts.npy")),
    "prune": (["prune", "m.ply", "--views", "cams.json", "--size", "16", "--force"],
              {"-o": ".ply"}, ("m.ply", "cams.json")),
}


def _folder(root):
    from PIL import Image

    with open(os.path.join(root, "m.obj"), "w") as fh:
        fh.write(OBJ)
    with open(os.path.join(root, "look.mtl"), "w") as fh:
        fh.write("newmtl skin\nKd 1 1 1\nmap_Kd tex.png\n")
    Image.fromarray(np.full((4, 4, 3), 200, np.uint8)).save(os.path.join(root, "tex.png"))
    os.link(os.path.join(root, "tex.png"), os.path.join(root, "hard.png"))
    os.symlink("tex.png", os.path.join(root, "soft.png"))
    mesh = hsr.load(os.path.join(root, "m.obj"))
    hsr.write_mesh(mesh, os.path.join(root, "m.ply"))
    cam = hsr.views.default(mesh, 1.0)
    hsr.write_transforms(os.path.join(root, "cams.json"), [cam], 16, 16)
    np.save(os.path.join(root, "pts.npy"), np.array([[0.2, 0.2, 0.0]]))


def _fingerprint(root) -> dict:
    out = {}
    for name in sorted(os.listdir(root)):
        path = os.path.join(root, name)
        with open(path, "rb") as fh:
            out[name] = hashlib.sha256(fh.read()).hexdigest()
    return out


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(command=st.sampled_from(sorted(COMMANDS)), data=st.data())
def test_no_output_lands_on_an_input_or_another_output(command, data):
    base, flags, inputs = COMMANDS[command]
    flag = data.draw(st.sampled_from(sorted(flags)))
    target = data.draw(st.sampled_from(inputs + ("OTHER",)))
    with tempfile.TemporaryDirectory() as root:
        _folder(root)
        args, ext = list(base), flags[flag]
        if target == "OTHER":  # another output of the same call, or the only output
            others = [f for f in flags if f != flag]
            if not others:
                return
            other = data.draw(st.sampled_from(others))
            if flags[other] != ext:
                return
            args += [other, os.path.join(root, "out" + ext)]
            target_path = os.path.join(root, "out" + ext)
        elif os.path.splitext(target)[1] == ext:
            target_path = os.path.join(root, target)
        else:  # the input under the output's extension, through a symbolic link
            target_path = os.path.join(root, "link" + ext)
            os.symlink(target, target_path)
        before = _fingerprint(root)
        cwd = os.getcwd()
        os.chdir(root)
        try:
            code, err = run_cli(args + [flag, target_path])
        finally:
            os.chdir(cwd)
        assert code == 2, (args, flag, target, err)
        assert len(err) == 1 and err[0].startswith("hsr: error: "), err
        assert "input" in err[0] or "same file" in err[0] or "is MODEL itself" in err[0], err
        assert _fingerprint(root) == before, (args, flag, target)
