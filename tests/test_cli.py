"""The command line: results on success; on bad input exit code 2 and exactly one line
on stderr, never a traceback."""

import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from hsr.cli import main

GOOD_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def run(args, capsys):
    code = main(args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_one_line_error(code, err):
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hsr: error: ")
    assert "Traceback" not in err


def test_render_builtin_scene(tmp_path, capsys):
    out = tmp_path / "cubes.png"
    code, stdout, _ = run(["render", "-o", str(out), "--size", "160x120"], capsys)
    assert code == 0 and "wrote" in stdout
    image = np.asarray(Image.open(out))
    assert image.shape == (120, 160, 3)
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 5  # not blank


def test_render_model_with_all_outputs(tmp_path, capsys, models_dir):
    out, depth_png, depth_npy, ids = (str(tmp_path / n) for n in
                                      ("b.png", "d.png", "d.npy", "ids.npy"))
    args = ["render", os.path.join(models_dir, "suzanne.obj"), "-o", out, "--size", "120x90",
            "--depth-out", depth_png, "--ids-out", ids, "--cull", "back", "--shading",
            "normal", "--quiet"]
    code, stdout, err = run(args, capsys)
    assert code == 0 and stdout == "" and err == ""
    face_id = np.load(ids)
    assert face_id.shape == (90, 120) and face_id.dtype == np.int32
    assert face_id.max() < 968 and (face_id >= 0).sum() > 1000
    depth16 = np.asarray(Image.open(depth_png))
    assert depth16.dtype in (np.uint16, np.int32) and depth16.max() == 65535
    code, _, _ = run(args[:-1] + ["--depth-out", depth_npy], capsys)
    depth = np.load(depth_npy)
    assert depth.dtype == np.float32
    assert np.array_equal(depth == 1.0, face_id < 0)


def test_camera_options(tmp_path, capsys, models_dir):
    model = os.path.join(models_dir, "cow.obj")
    for extra in (["--eye", "0,0,5", "--target", "0,0,0", "--fov", "30"],
                  ["--ortho", "2.0"], ["--eye", "1,1,1", "--near", "0.1", "--far", "20"],
                  ["--depth-func", "greater", "--clear-depth", "0"],
                  ["--no-depth-test"], ["--no-depth-write"], ["--depth-range", "0.2,0.8"],
                  ["--front-face", "cw", "--cull", "front"]):
        code, _, err = run(["render", model, "-o", str(tmp_path / "x.png"), "--size", "64x48",
                            "--ids-out", str(tmp_path / "i.npy")] + extra, capsys)
        assert code == 0, (extra, err)
        assert (np.load(tmp_path / "i.npy") >= 0).any(), extra


@pytest.mark.parametrize("contents,args", [
    (None, ["{missing}"]),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", ["{model}"]),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", ["{model}"]),
    ("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", ["{model}"]),
    ("v 0 0 0\n", ["{model}"]),
    (GOOD_OBJ, ["{model}", "--size", "0x10"]),
    (GOOD_OBJ, ["{model}", "--size", "-5x10"]),
    (GOOD_OBJ, ["{model}", "--size", "big"]),
    (GOOD_OBJ, ["{model}", "--size", "100000x10"]),
    (GOOD_OBJ, ["{model}", "--near", "0"]),
    (GOOD_OBJ, ["{model}", "--near", "-1"]),
    (GOOD_OBJ, ["{model}", "--near", "2", "--far", "1"]),
    (GOOD_OBJ, ["{model}", "--fov", "0"]),
    (GOOD_OBJ, ["{model}", "--fov", "180"]),
    (GOOD_OBJ, ["{model}", "--fov", "nan"]),
    (GOOD_OBJ, ["{model}", "--ortho", "-1"]),
    (GOOD_OBJ, ["{model}", "--eye", "1,2"]),
    (GOOD_OBJ, ["{model}", "--eye", "0,0,1", "--target", "0,0,1"]),
    (GOOD_OBJ, ["{model}", "--up", "0,0,0"]),
    (GOOD_OBJ, ["{model}", "--depth-range", "0,2"]),
    (GOOD_OBJ, ["{model}", "--depth-func", "sometimes"]),
    (GOOD_OBJ, ["{model}", "--cull", "sideways"]),
    (GOOD_OBJ, ["{model}", "--algorithm", "magic"]),
    (GOOD_OBJ, ["{model}", "-o", "/no/such/dir/x.png"]),
    (GOOD_OBJ, ["{model}", "-o", "{tmp}/x.unknownext"]),
    (GOOD_OBJ, ["{model}", "--depth-out", "{tmp}/d.txt"]),
    (GOOD_OBJ, ["{model}", "--bogus-flag"]),
])
def test_errors_are_one_line_exit_2(tmp_path, capsys, contents, args):
    model = tmp_path / "m.obj"
    if contents is not None:
        model.write_text(contents)
    args = [a.format(model=model, missing=tmp_path / "missing.obj", tmp=tmp_path)
            for a in args]
    code, _, err = run(["render", "-o", str(tmp_path / "out.png")] + args, capsys)
    assert_one_line_error(code, err)


def test_installed_command_reports_errors_without_traceback(tmp_path):
    for cmd in (["hsr"], [sys.executable, "-m", "hsr"]):
        proc = subprocess.run(cmd + ["render", str(tmp_path / "nope.obj")],
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2
        assert proc.stderr.strip().splitlines() == [
            f"hsr: error: file not found: {tmp_path / 'nope.obj'}"]


def test_no_command_prints_help(capsys):
    code, out, _ = run([], capsys)
    assert code == 2 and "render" in out


def test_compare_prints_table_and_montage(tmp_path, capsys):
    out = tmp_path / "m.png"
    code, stdout, _ = run(["compare", "--scene", "penetration", "--size", "64x48",
                           "--montage", str(out)], capsys)
    assert code == 0
    lines = stdout.strip().splitlines()
    assert lines[0].split()[:2] == ["algorithm", "ms"]
    from hsr.algorithms import ALGORITHMS
    names = [line.split()[0] for line in lines[1:] if line.split()[0] in ALGORITHMS]
    assert names == list(ALGORITHMS)
    assert "100.000%" in lines[1]
    image = Image.open(out)
    assert image.size[0] == 64 * len(ALGORITHMS)


@pytest.mark.parametrize("args", [["compare", "--algorithms", "bogus"],
                                  ["render", "--option", "novalue"],
                                  ["render", "--threads", "0"],
                                  ["render", "--algorithm", "raycast", "--option", "accel=warp"],
                                  ["render", "--algorithm", "raycast", "--option", "acel=none"],
                                  ["render", "--option", "key=max"],
                                  ["render", "--fog", "linear:5"],
                                  ["render", "--fog", "mist:1"],
                                  ["render", "--fog", "exp:0.1", "--fog-color", "1,2"],
                                  ["render", "--texture", "missing.png"],
                                  ["render", "--opacity", "1.5"],
                                  ["render", "--opacity", "0.5,0.5"],
                                  ["render", "--polygon-mode", "line", "--algorithm", "bsp"],
                                  ["render", "--polygon-offset", "1"],
                                  ["render", "--hidden-line", "--algorithm", "scanline"],
                                  ["render", "--hidden-layer"],
                                  ["render", "--line-color", "300,0,0", "--hidden-line"],
                                  ["render", "--opacity", "0.5", "--algorithm", "raycast"]])
def test_more_errors_are_one_line(tmp_path, capsys, args):
    code, _, err = run(args + ["--size", "32x24"] + (["-o", str(tmp_path / "x.png")]
                                                     if args[0] == "render" else []), capsys)
    assert_one_line_error(code, err)


def test_appearance_options(tmp_path, capsys, models_dir):
    head = os.path.join(models_dir, "african_head.obj")
    texture = os.path.join(models_dir, "african_head_diffuse.tga")
    out = tmp_path / "head.png"
    code, _, err = run(["render", head, "--texture", texture, "-o", str(out), "--size",
                        "100x100", "--quiet", "--shading", "gouraud", "--fog", "exp:0.1"], capsys)
    assert code == 0, err
    image = np.asarray(Image.open(out)).astype(int)
    covered = image.sum(axis=2) > 0
    assert covered.sum() > 1500
    # textured skin: red above blue on average, and many different colours
    assert image[covered][:, 0].mean() > image[covered][:, 2].mean()
    assert len(np.unique(image[covered], axis=0)) > 200
    code, _, err = run(["render", os.path.join(models_dir, "cow.obj"), "--texture", texture,
                        "-o", str(out)], capsys)
    assert_one_line_error(code, err)
    for extra in (["--polygon-mode", "line"], ["--polygon-mode", "point"],
                  ["--hidden-line", "--edges", "feature"], ["--opacity", "0.4"],
                  ["--opacity", "0.4", "--transparency", "exact"]):
        code, _, err = run(["render", "-o", str(out), "--size", "80x60", "--quiet"] + extra,
                           capsys)
        assert code == 0, (extra, err)


@pytest.mark.parametrize("argv", [
    ["compare", "{case}", "--size", "48x36"],
    ["report", "{case}", "--size", "48x36", "-o", "{tmp}/r.html"],
    ["explain", "bsp", "{case}", "--size", "48x36", "-o", "{tmp}/e.png"],
    ["render", "{case}", "--algorithm", "bsp", "--size", "48x36", "-o", "{tmp}/o.png"],
])
def test_all_degenerate_model_through_every_command(cases_dir, tmp_path, capsys, argv):
    """An IndexError from the empty BSP tree reached render, compare, report and explain."""
    case = os.path.join(cases_dir, "all_degenerate.obj")
    argv = [a.replace("{case}", case).replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(argv) == 0, capsys.readouterr().err


def test_summary_line_says_what_newell_left_unresolved(tmp_path, capsys):
    code, out, _ = run(["render", "--scene", "cyclic", "--algorithm", "newell", "--size",
                        "48x36", "--option", "max_actions=0", "-o", str(tmp_path / "c.png")],
                       capsys)
    assert code == 0
    assert "3 unresolved polygons" in out and "pixels drawn by the depth-test fallback" in out


def test_version(capsys):
    import hsr

    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"hsr {hsr.__version__}"


def test_view_frames_the_model_from_azimuth_and_elevation(models_dir, tmp_path, capsys):
    import hsr

    model = os.path.join(models_dir, "spot.obj")
    ids = tmp_path / "ids.npy"
    assert main(["render", model, "--view", "30,20", "--size", "64x48", "-o",
                 str(tmp_path / "s.png"), "--ids-out", str(ids), "--quiet"]) == 0
    mesh = hsr.load(model)
    # Framed as tight as the vertices allow (Camera.frame fit="points", 5% margin).
    cam = hsr.Camera.frame(mesh.bounds(), hsr.views.direction(30, 20), margin=1.05,
                           aspect=64 / 48, fit="points", points=mesh.positions)
    assert np.array_equal(np.load(ids), hsr.render(mesh, cam, 64, 48).face_id)


def test_metric_depth_and_normals_out(tmp_path, capsys):
    from PIL import Image

    import hsr

    scene, cam = hsr.scenes.get("cubes")
    frame = hsr.render(scene, cam, 64, 48)
    for kind, buffer in (("eye", frame.eye_depth), ("distance", frame.distance),
                         ("window", frame.depth)):
        assert main(["render", "--size", "64x48", "-o", str(tmp_path / "c.png"), "--quiet",
                     "--depth-out", str(tmp_path / f"{kind}.npy"), "--depth-kind", kind]) == 0
        assert np.array_equal(np.load(tmp_path / f"{kind}.npy"), buffer)
        assert main(["render", "--size", "64x48", "-o", str(tmp_path / "c.png"), "--quiet",
                     "--depth-out", str(tmp_path / f"{kind}.png"), "--depth-kind", kind]) == 0
        png = Image.open(tmp_path / f"{kind}.png")
        scale = 65535.0 if kind == "window" else 1000.0
        assert f"/ {scale:g}" in png.text["hsr"]
        drawn = frame.face_id >= 0
        assert np.allclose(np.asarray(png)[drawn] / scale, buffer[drawn], atol=0.6 / scale)
    assert main(["render", "--size", "64x48", "-o", str(tmp_path / "c.png"), "--quiet",
                 "--normals-out", str(tmp_path / "n.npy")]) == 0
    assert np.array_equal(np.load(tmp_path / "n.npy"), frame.normals)


def test_exr_buffers_read_back_with_openexr(tmp_path):
    """.exr depth and normals, read back with the OpenEXR binding: float32, bit for bit,
    +inf kept on the background of eye depth, row 0 at the top."""
    import OpenEXR

    import hsr

    scene, cam = hsr.scenes.get("cubes")
    frame = hsr.render(scene, cam, 64, 48)
    assert main(["render", "--size", "64x48", "-o", str(tmp_path / "c.png"), "--quiet",
                 "--depth-out", str(tmp_path / "d.exr"), "--depth-kind", "eye",
                 "--normals-out", str(tmp_path / "n.exr")]) == 0
    with OpenEXR.File(str(tmp_path / "d.exr")) as exr:
        depth = exr.channels()["Z"].pixels
    assert depth.dtype == np.float32 and depth.shape == (48, 64)
    assert np.array_equal(depth, frame.eye_depth)  # +inf included
    with OpenEXR.File(str(tmp_path / "n.exr")) as exr:
        ch = exr.channels()
        normals = np.stack([ch[k].pixels for k in "XYZ"], axis=2)
    assert np.array_equal(normals, frame.normals)


def test_camera_from_transforms_json_and_colmap(tmp_path, capsys):
    import json

    import hsr

    scene, cam = hsr.scenes.get("cubes")
    cams = [cam, hsr.Camera.look_at((4, 3, 2), (0, 0, -6), near=0.5, far=30)]
    hsr.write_transforms(tmp_path / "t.json", cams, 64, 48)
    ids = tmp_path / "ids.npy"
    assert main(["render", "--camera", f"{tmp_path / 't.json'}:1", "--near", "0.5",
                 "--far", "30", "-o", str(tmp_path / "c.png"), "--ids-out", str(ids),
                 "--quiet"]) == 0
    expected = hsr.render(scene, hsr.read_transforms(tmp_path / "t.json", 0.5, 30)[0][1],
                          64, 48).face_id
    got = np.load(ids)
    assert got.shape == (48, 64)  # the file's size when --size is not given
    assert np.array_equal(got, expected)
    colmap = tmp_path / "sparse"
    colmap.mkdir()
    (colmap / "cameras.txt").write_text("1 PINHOLE 40 30 30 30 20 15\n")
    (colmap / "images.txt").write_text("1 1 0 0 0 0 0 10 1 a.png\n\n")
    assert main(["render", "--camera", str(colmap), "-o", str(tmp_path / "c.png"),
                 "--ids-out", str(ids), "--quiet"]) == 0
    assert np.load(ids).shape == (30, 40)
    assert main(["render", "--camera", f"{tmp_path / 't.json'}:5", "-o",
                 str(tmp_path / "c.png")]) == 2
    assert "has 2 cameras, no index 5" in capsys.readouterr().err
    assert main(["render", "--camera", str(tmp_path / "t.json"), "--eye", "1,2,3"]) == 2
    assert json.loads((tmp_path / "t.json").read_text())["frames"]


def test_svg_alone_writes_no_png_and_compare_takes_o(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["render", "--scene", "cyclic", "--algorithm", "bsp", "--svg", "c.svg",
                 "--size", "48x36", "--quiet"]) == 0
    assert sorted(os.listdir(tmp_path)) == ["c.svg"]
    assert main(["compare", "--size", "48x36", "-o", "m.png", "--quiet"]) == 0
    assert (tmp_path / "m.png").exists()


def test_help_states_defaults(capsys):
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        main(["render", "--help"])
    text = out.getvalue()
    assert "(default: 45.0)" in text and "(default: none)" in text  # --fov, --cull
    assert "default: None" not in text


def test_orbit_writes_numbered_views(models_dir, tmp_path, capsys):
    import hsr

    model = os.path.join(models_dir, "spot.obj")
    assert main(["render", model, "--orbit", "3", "--view", "30,10", "--size", "48x36",
                 "-o", str(tmp_path / "s.png"), "--ids-out", str(tmp_path / "i.npy"),
                 "--quiet"]) == 0
    mesh = hsr.load(model)
    cams = hsr.views.orbit(mesh.bounds(), 3, 10, 48 / 36, azimuth=30)
    for k, cam in enumerate(cams):
        assert (tmp_path / f"s_{k:03d}.png").exists()
        assert np.array_equal(np.load(tmp_path / f"i_{k:03d}.npy"),
                              hsr.render(mesh, cam, 48, 36).face_id)
    assert np.allclose(np.asarray(cams[0].eye) - np.asarray(cams[0].target),
                       np.linalg.norm(np.asarray(cams[0].eye) - np.asarray(cams[0].target))
                       * hsr.views.direction(30, 10))
    assert main(["render", model, "--orbit", "3", "--eye", "1,2,3"]) == 2
    assert "does not combine with --eye" in capsys.readouterr().err


def test_first_look_of_a_model(tmp_path, capsys, models_dir):
    """``hsr render MODEL``: the view hsr.best_view chooses (tests/test_viewpoint.py
    checks the choice) framed for the image's aspect, lit by the studio rig; a built-in
    scene keeps its camera and the headlight. Negative numbers after an option are values
    (--view -55,25)."""
    import hsr

    path = os.path.join(models_dir, "fandisk.obj")
    out = tmp_path / "f.png"
    assert main(["render", path, "-o", str(out), "--size", "200x120", "--quiet"]) == 0
    mesh = hsr.load(path)
    cam = hsr.first_look(mesh, 200 / 120)
    assert np.allclose(cam.forward, -hsr.views.direction(*hsr.best_view(mesh)))
    want = hsr.render(mesh, cam, 200, 120, light="studio")
    assert np.array_equal(np.asarray(Image.open(out)), want.color)
    # Python without a camera: the same first look.
    assert np.array_equal(hsr.render(mesh, width=200, height=120).color, want.color)
    # The fandisk's faces show several shades, not one flat silhouette.
    assert len(np.unique(want.color[want.face_id >= 0][:, 0])) > 15
    assert main(["render", "-o", str(out), "--size", "160x120", "--quiet"]) == 0
    scene, camera = hsr.scenes.get("cubes")
    assert np.array_equal(np.asarray(Image.open(out)), hsr.render(scene, camera, 160, 120).color)
    assert main(["render", path, "--view", "-55,25", "-o", str(out), "--size", "200x120",
                 "--quiet"]) == 0
    cam = hsr.Camera.frame(mesh.bounds(), hsr.views.direction(-55, 25), margin=1.05,
                           aspect=200 / 120, fit="points", points=mesh.positions)
    assert np.array_equal(np.asarray(Image.open(out)),
                          hsr.render(mesh, cam, 200, 120, light="studio").color)
