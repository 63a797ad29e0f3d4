"""Trust, round three (issue #32): each failure found on the new surfaces, kept as a
regression test that failed before its fix. Inputs that need a file live in
``tests/cases`` (as ``../shared/cases`` does for the OBJ reader); every one must be
refused with an HsrError naming what is wrong, or (for the huge texture coordinates)
render the picture it means."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

import hsr
from conftest import run_cli

CASES = os.path.join(os.path.dirname(__file__), "cases")


# --- the command line: options named, size checked before it is used -----------------

@pytest.mark.parametrize("args, message", [
    (["--size", "0x0"], "--size sides must be in 1..32768, got '0x0'"),  # ZeroDivisionError
    (["--size", "0x10"], "--size sides must be in 1..32768"),  # blamed the framing
    (["--size", "10x40000"], "--size sides must be in 1..32768"),
    (["--near", "0"], "--near must be > 0 for a perspective camera"),
    (["--near", "-1"], "--near must be > 0"),
    (["--far", "0"], "--far must be > 0"),
    (["--fov", "200"], "--fov must be in (0, 180) degrees, got 200"),
    (["--fov", "0"], "--fov must be in (0, 180)"),
    (["--fov", "nan"], "--fov must be a finite number"),
    (["--ortho", "0"], "--ortho (the visible height) must be > 0"),
    (["--near", "2", "--far", "1"], "--far (1) must be greater than --near (2)"),
    (["--far", "0.01"], "--far 0.01: no valid camera for this model with this value"),
])
def test_camera_options_are_named_when_wrong(models_dir, tmp_path, args, message):
    code, err = run_cli(["render", os.path.join(models_dir, "spot.obj"), "-o",
                         str(tmp_path / "o.png"), *args])
    assert code == 2 and len(err) == 1, err
    assert message in err[0], err[0]
    assert "--eye" not in err[0]  # the old message blamed options the user never gave
    assert not os.path.exists(tmp_path / "o.png")


def test_size_zero_is_refused_for_builtin_scenes_and_batch(models_dir, tmp_path):
    assert run_cli(["render", "--size", "0x0", "-o", str(tmp_path / "o.png")])[0] == 2
    code, err = run_cli(["batch", os.path.join(models_dir, "spot.obj"), "--size", "0x0",
                         "--out", str(tmp_path / "b")])
    assert code == 2 and "size" in err[0]


_BLOCK = """
import sys
for name in {blocked!r}:
    sys.modules[name] = None  # what an uninstalled package looks like to import
from hsr.cli import main
sys.exit(main({argv!r}))
"""


@pytest.mark.parametrize("blocked, argv, extra", [
    (["distributed"], ["batch", "MODEL", "--out", "OUT"], "hsr[dask]"),
    (["zarr"], ["batch", "MODEL", "--out", "OUT", "--format", "zarr"], "hsr[dask]"),
    (["uvicorn"], ["view", "--no-browser", "--port", "PORT"], "hsr[view]"),
    (["starlette"], ["view", "--no-browser", "--port", "PORT"], "hsr[view]"),
    (["distributed"], ["prune", "MODEL", "-o", "OUT/p.obj", "--scheduler",
                       "tcp://127.0.0.1:1"], "hsr[dask]"),
])
def test_a_missing_extra_is_one_line_naming_it(models_dir, tmp_path, blocked, argv, extra):
    """The Quick start installs no extras; `hsr batch` then ended in a
    ModuleNotFoundError traceback, `hsr view` likewise."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = str(s.getsockname()[1])
    argv = [a.replace("MODEL", os.path.join(models_dir, "spot.obj")).replace(
        "OUT", str(tmp_path)).replace("PORT", port) for a in argv]
    proc = subprocess.run([sys.executable, "-c", _BLOCK.format(blocked=blocked, argv=argv)],
                          capture_output=True, text=True, timeout=300)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith("hsr: error: "), lines
    assert extra in lines[0] and blocked[0] in lines[0]


def test_the_all_extra_names_every_optional_dependency():
    import tomllib

    with open(os.path.join(os.path.dirname(__file__), "..", "pyproject.toml"), "rb") as fh:
        extras = tomllib.load(fh)["project"]["optional-dependencies"]
    wanted = {d for name in ("exr", "dask", "view") for d in extras[name]}
    assert wanted <= set(extras["all"])


# --- files: each case refused, naming what is wrong -------------------------------------

@pytest.mark.parametrize("name, message", [
    ("gltf_node_cycle.glb", "node 0 is its own ancestor (a cycle)"),  # ValueError
    ("gltf_node_deep.glb", "levels deep"),  # minutes in trimesh's multi_dot
    ("gltf_index_past_count.glb", "vertex index 65535 outside 0..7"),  # IndexError
    ("gltf_node_mesh_negative.glb", "node 0's mesh must be an index below 1"),  # ValueError
    ("gltf_texture_bomb.glb", "claims more pixels than hsr reads (67,108,864)"),
    ("gltf_uri_list.glb", "a file reference must be a non-empty string"),  # TypeError
    ("gltf_uri_outside.glb", "points outside the model's folder"),
])
def test_gltf_cases_are_refused(name, message):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(hsr.MeshError) as info:
            hsr.load_scene(os.path.join(CASES, name))
    assert message in str(info.value) and name in str(info.value), str(info.value)


def test_a_uri_never_reaches_a_fifo_or_a_file_outside(tmp_path):
    """A FIFO named by a buffer URI blocked trimesh's reader forever; a secret outside
    the folder is never opened (watched through Python's audit hook)."""
    from fuzz.gltf_build import parts, write_gltf
    from fuzz.guards import time_limit, touched, watch_opens

    header, blob = parts()
    (tmp_path / "m").mkdir()
    os.mkfifo(tmp_path / "m" / "fifo")
    (tmp_path / "secret.bin").write_bytes(blob)
    os.symlink(tmp_path / "secret.bin", tmp_path / "m" / "link.bin")
    for uri, message in (("fifo", "not a regular file"), ("link.bin", "outside"),
                         ("../secret.bin", "outside"), (str(tmp_path / "secret.bin"),
                                                        "relative path"),
                         ("%2e%2e/secret.bin", "outside"), ("file:///etc/passwd",
                                                            "relative path")):
        header["buffers"][0]["uri"] = uri
        path = write_gltf(tmp_path / "m", header, blob)
        with watch_opens() as opened, time_limit(20), pytest.raises(hsr.MeshError) as info:
            hsr.load_scene(path)
        assert message in str(info.value)
        assert touched(opened, [tmp_path / "secret.bin", tmp_path / "m" / "fifo",
                                "/etc/passwd"]) == []


def test_texture_coordinates_far_outside_repeat_and_clamp_as_gl_does():
    """uv = 1e30 overflowed the texel index (a RuntimeWarning and texels from nowhere);
    GL_REPEAT of an integer is the texel at 0, GL_CLAMP_TO_EDGE of +-1e30 the edge."""
    texture = np.arange(4 * 4 * 3, dtype=np.uint8).reshape(4, 4, 3)
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    cam = hsr.Camera.look_at((0, 0, 3), (0, 0, 0), fov_y=30, near=1, far=10)

    def draw(u, v, wrap):
        mesh = hsr.Mesh(quad, faces, corner_uv=np.full((2, 3, 2), (u, v)), texture=texture)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            return hsr.render(mesh, cam, 16, 16, shading="flat", texture_wrap=wrap,
                              texture_filter="nearest").color

    assert np.array_equal(draw(1e30, -1e30, "repeat"), draw(0.0, 0.0, "repeat"))
    assert np.array_equal(draw(1e30, -1e30, "clamp"), draw(1.0, 0.0, "clamp"))
    scene = hsr.load_scene(os.path.join(CASES, "gltf_uv_1e30.glb"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hsr.render(scene, hsr.views.default(scene, 1.0), 16, 16)


@pytest.mark.parametrize("name, reader, message", [
    ("transforms_w_inf.json", "read_transforms", "w must be a whole number of pixels"),
    ("transforms_angle_zero.json", "read_transforms", "camera_angle_x must be in (0, pi)"),
    ("colmap_duplicate_camera", "read_colmap", "camera 1 is defined twice"),
    ("colmap_duplicate_image", "read_colmap", "image 1 is listed twice"),
])
def test_camera_file_cases_are_refused(name, reader, message):
    with pytest.raises(hsr.CameraError) as info:
        getattr(hsr, reader)(os.path.join(CASES, name))
    assert message in str(info.value) and name in str(info.value), str(info.value)


# --- prune: nothing overwritten unless asked, the input never -------------------------

def test_prune_never_writes_over_its_input_and_asks_before_replacing(tmp_path):
    src = tmp_path / "m.obj"
    hsr.write_mesh(hsr.scenes.cube(), src)
    mine = src.read_bytes()
    for out, force in ((src, False), (src, True), (tmp_path / "." / "m.obj", True)):
        code, err = run_cli(["prune", str(src), "-o", str(out), "--views", "sphere:4",
                             "--size", "16"] + (["--force"] if force else []))
        assert code == 2 and "is MODEL itself" in err[0], err
    assert src.read_bytes() == mine
    (tmp_path / "o.obj").write_text("# mine\n")
    code, err = run_cli(["prune", str(src), "-o", str(tmp_path / "o.obj"), "--views",
                         "sphere:4", "--size", "16"])
    assert code == 2 and "exists" in err[0] and "--force" in err[0]
    assert (tmp_path / "o.obj").read_text() == "# mine\n"
    (tmp_path / "p.mtl").write_text("# my materials\n")
    code, err = run_cli(["prune", str(src), "-o", str(tmp_path / "p.obj"), "--views",
                         "sphere:4", "--size", "16"])
    assert code == 2 and "p.mtl exists" in err[0]
    assert run_cli(["prune", str(src), "-o", str(tmp_path / "o.obj"), "--views", "sphere:4",
                    "--size", "16", "--force", "--quiet"])[0] == 0
    assert hsr.load(tmp_path / "o.obj").n_faces == 12
    with pytest.raises(hsr.OutputError):
        hsr.write_mesh(hsr.scenes.cube(), tmp_path / "o.obj")


@pytest.mark.parametrize("bad", [["--verify", "-1"], ["--threads", "0"]])
def test_prune_checks_every_option_before_writing(tmp_path, bad):
    """--verify -1 and --threads 0 were refused after the pruned model was written."""
    src = tmp_path / "m.obj"
    hsr.write_mesh(hsr.scenes.cube(), src)
    code, err = run_cli(["prune", str(src), "-o", str(tmp_path / "o.obj"), "--views",
                         "sphere:4", "--size", "16", *bad])
    assert code == 2 and bad[0] in err[0]
    assert not os.path.exists(tmp_path / "o.obj")


def test_threads_zero_is_refused_by_face_visibility():
    """Workers took threads=0 for "all cores" where render refuses it."""
    scene = hsr.Scene().add(hsr.scenes.cube())
    with pytest.raises(hsr.RenderError, match="threads must be a positive integer"):
        hsr.visibility.face_visibility(scene, ["sphere:2"], 8, threads=0)


def test_batch_outputs_of_another_type_are_refused(tmp_path):
    with pytest.raises(hsr.batch.BatchError, match="outputs must be names"):
        hsr.batch.render_views(["x.obj"], "orbit:2", (8, 8), None, str(tmp_path))
