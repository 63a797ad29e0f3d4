"""First contact, round two (issue #62): real files look as their authors meant them.
Each case failed before its fix."""

from __future__ import annotations

import json
import os
import shlex
import struct

import numpy as np
import pytest

import hsr


def _glb_materials(path) -> list:
    data = open(path, "rb").read()
    (length,) = struct.unpack_from("<I", data, 12)
    return json.loads(data[20:20 + length]).get("materials", [])


def test_a_gltf_texture_without_a_factor_is_drawn_as_it_is(tmp_path):
    """A material with no baseColorFactor means 1 (glTF 2.0, 3.9.2); the loader took
    trimesh's grey main colour (102) as the factor, drawing the Duck at 40% brightness,
    and hsr prune wrote baseColorFactor 0.4 into its output."""
    import trimesh
    from PIL import Image

    texel = np.array([234, 193, 16], np.uint8)
    box = trimesh.creation.box()
    uv = np.random.default_rng(0).random((len(box.vertices), 2))
    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(np.tile(texel, (8, 8, 1))))
    box.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    path = tmp_path / "duck.glb"
    box.export(path)
    assert "baseColorFactor" not in _glb_materials(path)[0]["pbrMetallicRoughness"]
    mesh = hsr.load(path)
    assert mesh.face_colors is None
    # Seen square on under the headlight, a texel is drawn as the texture holds it.
    cam = hsr.Camera.look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 30, 1, 10)
    frame = hsr.render(mesh, cam, 32, 32, light="headlight")
    assert np.abs(frame.color[16, 16].astype(int) - texel).max() <= 1
    hsr.write_mesh(mesh, tmp_path / "out.glb")
    factor = _glb_materials(tmp_path / "out.glb")[0]["pbrMetallicRoughness"].get(
        "baseColorFactor", [1, 1, 1, 1])
    assert factor == [1.0, 1.0, 1.0, 1.0]


def _textured_obj(folder, map_line, texel=(10, 200, 30)):
    from PIL import Image

    Image.fromarray(np.tile(np.array(texel, np.uint8), (4, 4, 1))).save(
        os.path.join(folder, "fuze uv.png"))
    with open(os.path.join(folder, "m.mtl"), "w") as fh:
        fh.write(f"newmtl skin\nKd 1 1 1\n{map_line}\n")
    with open(os.path.join(folder, "m.obj"), "w") as fh:
        fh.write("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.1 0.2\nvt 0.3 0.2\n"
                 "vt 0.1 0.4\nusemtl skin\nf 1/1 2/2 3/3\n")
    return os.path.join(folder, "m.obj")


def test_mtl_texture_names_with_spaces_and_options(tmp_path):
    """map_Kd took the last word of 'fuze uv.png' (no texture at all) and ignored the
    -s / -o options; the MTL grammar: options first, then the file name to the end of
    the line."""
    from hsr.scene.obj import map_statement

    assert map_statement("fuze uv.png") == ("fuze uv.png", {})
    assert map_statement("-s 2 3 1 -o 0.5 -clamp on  my tex.jpg") == (
        "my tex.jpg", {"-s": ["2", "3", "1"], "-o": ["0.5"], "-clamp": ["on"]})
    assert map_statement("-bm 0.5 sub/dir/a.png")[0] == "sub/dir/a.png"
    mesh = hsr.load(_textured_obj(tmp_path, "map_Kd fuze uv.png"))
    assert os.path.basename(mesh.texture) == "fuze uv.png"
    np.testing.assert_allclose(mesh.corner_uv[0], [[0.1, 0.2], [0.3, 0.2], [0.1, 0.4]])
    scaled = hsr.load(_textured_obj(tmp_path, "map_Kd -s 2 3 -o 0.5 0.25 fuze uv.png"))
    np.testing.assert_allclose(scaled.corner_uv[0], [[0.7, 0.85], [1.1, 0.85],
                                                      [0.7, 1.45]])


def test_a_missing_texture_is_one_warning_naming_it(tmp_path):
    import contextlib
    import io
    import warnings

    from hsr.cli import main

    path = _textured_obj(tmp_path, "map_Kd gone.png")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mesh = hsr.load(path)
    assert mesh.texture is None
    assert [str(w.message) for w in caught if issubclass(w.category, hsr.HsrWarning)] == [
        "m.mtl:3: map_Kd names 'gone.png', which is not a file beside the model; drawn "
        "without it"]
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        assert main(["render", path, "--size", "16x16", "-o",
                     str(tmp_path / "o.png")]) == 0
    assert err.getvalue().strip().splitlines() == [
        "hsr: warning: m.mtl:3: map_Kd names 'gone.png', which is not a file beside the "
        "model; drawn without it"]


def _scaled(models_dir, tmp_path, scale):
    mesh = hsr.load(os.path.join(models_dir, "spot.obj"))
    scaled = hsr.Mesh(mesh.positions * scale, mesh.faces, name="scaled")
    path = tmp_path / f"spot_{scale:g}.ply"
    hsr.write_mesh(scaled, path)
    return scaled, str(path)


def test_camera_files_carry_their_planes_at_any_scale(models_dir, tmp_path):
    """read_transforms used near 0.1 / far 100 and hsr's own transforms.json stored no
    planes: a model in millimetres, re-rendered from hsr's camera file, covered 0 pixels
    with exit 0. Now the file carries them, and a file without them fits the scene."""
    import json as _json

    for scale in (1e-3, 1e3, 1e5):
        scene, _ = _scaled(models_dir, tmp_path, scale)
        cam = hsr.views.default(scene, 64 / 48)
        want = hsr.render(scene, cam, 64, 48)
        assert (want.face_id >= 0).sum() > 300
        path = tmp_path / f"cams_{scale:g}.json"
        hsr.write_transforms(path, [cam], 64, 48)
        back = hsr.read_transforms(path)[0][0]
        assert back.near == cam.near and back.far == cam.far
        assert np.array_equal(hsr.render(scene, back, 64, 48).face_id >= 0,
                              want.face_id >= 0)
        doc = _json.loads(path.read_text())
        del doc["near"], doc["far"]
        path.write_text(_json.dumps(doc))
        fitted = hsr.read_transforms(path, bounds=scene.bounds())[0][0]
        got = hsr.render(scene, fitted, 64, 48)
        assert np.array_equal(got.face_id >= 0, want.face_id >= 0), scale
        assert (got.face_id == want.face_id).mean() > 0.99
        assert fitted.near < np.linalg.norm(np.subtract(cam.eye, cam.target)) < fitted.far


def test_the_command_line_fits_camera_file_planes_and_takes_its_size(models_dir, tmp_path,
                                                                     capsys):
    from hsr.cli import main

    scene, model = _scaled(models_dir, tmp_path, 1000.0)
    cam = hsr.views.default(scene, 320 / 240)
    path = tmp_path / "cams.json"
    hsr.write_transforms(path, [cam], 320, 240)
    doc = json.loads(path.read_text())
    del doc["near"], doc["far"]  # as other tools write them
    path.write_text(json.dumps(doc))
    assert main(["render", model, "--camera", str(path), "-o", str(tmp_path / "r.png"),
                 "--ids-out", str(tmp_path / "ids.npy")]) == 0
    ids = np.load(tmp_path / "ids.npy")
    assert ids.shape == (240, 320) and (ids >= 0).sum() > 1000
    capsys.readouterr()
    assert main(["visibility", model, "--views", str(path), "-o",
                 str(tmp_path / "v.npz")]) == 0
    out = capsys.readouterr().out
    assert "1 views at 320x240" in out and "min 0 " not in out, out
    # A view that sees nothing says so in one line (it exited 0 in silence).
    assert main(["render", model, "--camera", str(path), "--near", "1", "--far", "2",
                 "-o", str(tmp_path / "empty.png")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["hsr: warning: the view covers no pixel of the scene (is it behind the "
                   "camera, or outside --near/--far?)"]


def test_pixel_rays_meet_opencv_pixel_centres_and_the_renderer(models_dir):
    """Camera.pixel_rays (Open3D's create_rays_pinhole, in hsr's convention): a point on
    the ray of pixel (x, y) projects with OpenCV to (x, y) (its centres are on integers,
    hsr's at + 0.5), and casting the rays finds the faces the z-buffer draws."""
    cv2 = pytest.importorskip("cv2")
    K = np.array([[70.0, 0, 31.0], [0, 64.0, 22.5], [0, 0, 1]])
    R = cv2.Rodrigues(np.array([0.2, -0.4, 0.1]))[0]
    t = np.array([0.1, -0.2, 3.0])
    cam = hsr.Camera.from_opencv(K, R, t, 64, 48, near=0.1, far=20)
    origins, directions = cam.pixel_rays(64, 48)
    assert origins.shape == directions.shape == (48, 64, 3)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=-1), 1.0)
    points = (origins + 2.5 * directions).reshape(-1, 3)
    uv, _ = cv2.projectPoints(points, cv2.Rodrigues(R)[0], t, K, None)
    xs, ys = np.meshgrid(np.arange(64), np.arange(48))
    np.testing.assert_allclose(uv.reshape(48, 64, 2), np.stack([xs, ys], -1), atol=1e-6)
    mesh = hsr.load(os.path.join(models_dir, "spot.obj"))
    for view in (hsr.views.default(mesh, 4 / 3),
                 hsr.Camera.orthographic((0, 0.3, 3), (0, 0.3, 0), height=2.0, near=0.5,
                                         far=6)):
        origins, directions = view.pixel_rays(64, 48)
        hits = hsr.RayScene(mesh).cast(origins.reshape(-1, 3), directions.reshape(-1, 3))
        drawn = hsr.render(mesh, view, 64, 48).face_id.reshape(-1)
        assert (hits.face_id == drawn).mean() > 0.98 and (drawn >= 0).sum() > 500


def test_a_camera_reads_as_numbers():
    cam = hsr.Camera.look_at((1, 2, 3), (0, 0, 0), (0, 1, 0), 45, 0.5, 20)
    assert repr(cam) == ("Camera(eye=(1, 2, 3), target=(0, 0, 0), up=(0, 1, 0), fov_y=45, "
                         "near=0.5, far=20)")
    assert "np.float64" not in repr(hsr.views.default(hsr.scenes.cube()))


def test_sort_last_takes_the_outputs_the_command_line_takes(tmp_path):
    """render_partitioned(outputs=("ids",)) was refused though hsr batch takes ids."""
    pytest.importorskip("zarr")
    from hsr.batch import render_partitioned

    scene = hsr.scenes.cube()
    store = hsr.partition(scene, 2, tmp_path / "s.zarr")
    cam = hsr.views.default(scene)
    frame = render_partitioned(store, [cam], 32, 32, outputs=("ids", "window_depth"))[0]
    assert np.array_equal(frame.face_id, hsr.render(scene, cam, 32, 32).face_id)


def test_an_exr_output_without_its_extra_fails_before_anything_is_written(tmp_path):
    """--depth-out d.exr without OpenEXR failed after the colour PNG was written."""
    import subprocess
    import sys

    code = ("import sys; sys.modules['OpenEXR'] = None\n"
            "from hsr.cli import main\n"
            f"sys.exit(main(['render', '-o', {str(tmp_path / 'c.png')!r}, '--depth-out', "
            f"{str(tmp_path / 'd.exr')!r}, '--size', '16x16']))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "hsr[exr]" in lines[0], lines
    assert os.listdir(tmp_path) == []


def test_the_first_run_says_it_compiles_and_warmup_compiles(tmp_path, monkeypatch):
    """hsr render took 16.5 s the first time and printed nothing."""
    import io

    from conftest import run_cli
    from hsr.cli.warmup import kernels_cached, note_first_run

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))  # an empty cache
    assert not kernels_cached()
    for command, quiet, said in (("render", False, True), ("render", True, False),
                                 ("warmup", False, False)):
        err = Terminal()
        monkeypatch.setattr("sys.stderr", err)
        note_first_run(command, quiet)
        lines = err.getvalue().splitlines()
        assert lines == (["hsr: compiling kernels, first run only (15 s for a render, "
                          "minutes for every kernel; `hsr warmup` compiles them all "
                          "ahead)"] if said else []), (command, quiet, lines)
    (tmp_path / "hsr_kernel.nbi").write_bytes(b"")
    assert kernels_cached()
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert run_cli(["warmup"]) == (0, [])


def test_render_alone_is_what_the_docs_and_the_command_line_draw(models_dir, tmp_path):
    """rendering.md said hsr.render(spot) alone gives its 800x600 picture; the library
    drew 640x480, the command line 800x600."""
    from conftest import run_cli

    path = os.path.join(models_dir, "spot.obj")
    spot = hsr.load(path)
    alone = hsr.render(spot)
    documented = hsr.render(spot, hsr.first_look(spot, aspect=4 / 3), 800, 600,
                            light="studio")
    assert alone.color.shape == (600, 800, 3)
    assert np.array_equal(alone.color, documented.color)
    code, err = run_cli(["render", path, "-o", str(tmp_path / "c.png"), "--ids-out",
                         str(tmp_path / "ids.npy"), "--quiet"])
    assert code == 0, err
    assert np.array_equal(np.load(tmp_path / "ids.npy"), alone.face_id)


def test_a_z_up_model_stands_up(models_dir, tmp_path):
    """The first look assumed +Y up (a Z-up scan was seen from below) and --up 0,0,1
    without --eye tilted the view. With up_axis="z" (--up-axis z) a model turned Z-up is
    drawn as the Y-up one is: the same faces at the same pixels."""
    from conftest import run_cli

    spot = hsr.load(os.path.join(models_dir, "spot.obj"))
    p = spot.positions
    turned = hsr.Mesh(np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1), spot.faces)
    want = hsr.render(spot, hsr.first_look(spot, 4 / 3), 160, 120).face_id
    got = hsr.render(turned, hsr.first_look(turned, 4 / 3, up_axis="z"), 160, 120).face_id
    assert (got == want).mean() > 0.999
    assert (hsr.render(turned, hsr.first_look(turned, 4 / 3), 160, 120).face_id
            == want).mean() < 0.9  # the +Y first look of a Z-up model is another picture
    for y_cam, z_cam in zip(hsr.views.orbit(spot.bounds(), 3, 20, 4 / 3),
                            hsr.views.orbit(turned.bounds(), 3, 20, 4 / 3, up_axis="z")):
        assert (hsr.render(spot, y_cam, 80, 60).face_id
                == hsr.render(turned, z_cam, 80, 60).face_id).mean() > 0.999
    hsr.write_mesh(turned, tmp_path / "zup.ply")
    code, err = run_cli(["render", str(tmp_path / "zup.ply"), "--up-axis", "z", "--view",
                         "35,25", "--size", "160x120", "--ids-out",
                         str(tmp_path / "ids.npy"), "-o", str(tmp_path / "c.png"), "--quiet"])
    assert code == 0, err
    framed = hsr.render(spot, hsr.views.default(spot, 4 / 3), 160, 120, light="studio")
    assert (np.load(tmp_path / "ids.npy") == framed.face_id).mean() > 0.999
    code, err = run_cli(["render", str(tmp_path / "zup.ply"), "--up", "0,0,1", "-o",
                         str(tmp_path / "d.png")])
    assert code == 2 and "--up-axis z" in err[0], err


def test_the_viewer_opens_a_model_at_its_first_look(models_dir):
    """hsr view opened every model at the fixed three-quarter view, not the side hsr
    render MODEL draws."""
    from hsr.viewer.frames import Library

    path = os.path.join(models_dir, "spot.obj")
    library = Library([path], builtin=False)
    az, el = hsr.best_view(hsr.load(path))
    assert library.initial("spot.obj") == {"az": az, "el": el}
    assert (az, el) != hsr.views.DEFAULT_VIEW  # spot's face, not its flank


def _sphere_files(tmp_path):
    """An icosphere as a GLB that carries vertex normals and as an STL (which cannot)."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=2)
    # The sphere's true normals (its unit positions), exported as glTF NORMAL.
    sphere.vertex_normals = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1,
                                                             keepdims=True)
    sphere.export(tmp_path / "ball.glb")
    sphere.export(tmp_path / "ball.stl")
    return str(tmp_path / "ball.glb"), str(tmp_path / "ball.stl")


def test_smooth_shading_is_the_default_where_the_file_carries_normals(tmp_path):
    """Every glTF viewer draws a file's normals smooth; hsr drew them flat (it did not
    even read them). The expected colour is Lambert of the interpolated true normal of
    the sphere (its position), at the reference rasteriser's barycentrics."""
    from reference import reference_render

    glb, stl = _sphere_files(tmp_path)
    mesh = hsr.load(glb)
    assert mesh.corner_normals is not None
    truth = mesh.positions / np.linalg.norm(mesh.positions, axis=1, keepdims=True)
    assert np.abs(mesh.corner_normals - truth[mesh.faces]).max() < 1e-6
    cam = hsr.Camera.look_at((0.4, 0.3, 4), (0, 0, 0), (0, 1, 0), 35, 1, 10)
    frame = hsr.render(glb, cam, 96, 96)  # shading "auto"
    face, _, bary = reference_render(mesh, cam, 96, 96, with_barycentrics=True)
    seen = face >= 0
    assert np.array_equal(frame.face_id >= 0, seen)
    normal = np.einsum("kc,kcj->kj", bary[seen], truth[mesh.faces[face[seen]]])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    forward = -np.asarray(cam.eye) / np.linalg.norm(cam.eye)
    expected = 230 * np.abs(normal @ forward)
    assert np.abs(frame.color[seen][:, 0] - expected).max() <= 1.5
    flat = hsr.render(glb, cam, 96, 96, shading="flat").color[seen][:, 0].astype(float)
    assert np.abs(flat - expected).max() > 10  # the flat look stays, and differs
    # An STL has no vertex normals: drawn flat, as before.
    assert hsr.load(stl).corner_normals is None
    assert np.array_equal(hsr.render(stl, cam, 96, 96).color,
                          hsr.render(stl, cam, 96, 96, shading="flat").color)


def test_computed_normals_keep_creases_and_unlit_is_the_albedo():
    """smooth / gouraud on a mesh without normals average the faces round a vertex within
    30 degrees only: a cube keeps its edges (its corner normals are its face normals),
    where welding every face round a vertex rounded it off."""
    from hsr.appearance.shading import vertex_normals

    cube = hsr.scenes.cube()
    corners = vertex_normals(cube)
    tri = cube.positions[cube.faces]
    face_normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    face_normal /= np.linalg.norm(face_normal, axis=1, keepdims=True)
    assert np.abs(corners - face_normal[:, None, :]).max() < 1e-12
    rounded = vertex_normals(cube, crease_angle=180.0)  # the old welding
    assert np.abs(rounded - face_normal[:, None, :]).max() > 0.3
    cam = hsr.Camera.look_at((2, 1.5, 3), (0, 0, 0), (0, 1, 0), 40, 1, 10)
    smooth = hsr.render(cube, cam, 64, 64, shading="smooth").color.astype(int)
    flat = hsr.render(cube, cam, 64, 64, shading="flat").color.astype(int)
    assert np.abs(smooth - flat).max() <= 1
    colored = hsr.Mesh(cube.positions, cube.faces,
                       face_colors=np.tile([200, 90, 30], (cube.n_faces, 1)))
    unlit = hsr.render(colored, cam, 64, 64, shading="unlit")
    assert {tuple(c) for c in unlit.color[unlit.face_id >= 0]} == {(200, 90, 30)}
    with pytest.raises(hsr.RenderError, match="crease_angle"):
        hsr.Look(crease_angle=200)


def _tall_box_stl(tmp_path) -> str:
    """A box 1 x 1 x 4, standing on +Z as a printer's STL does."""
    import trimesh

    box = trimesh.creation.box(extents=(1.0, 1.0, 4.0))
    path = tmp_path / "tower.stl"
    box.export(path)
    return str(path)


def test_the_up_axis_a_file_declares(tmp_path, models_dir):
    """glTF is +Y up by its specification, STL +Z (the printer's build direction); OBJ
    and PLY say nothing. The teapot STL lay on its side in the first look."""
    glb, stl = _sphere_files(tmp_path)
    assert hsr.load(glb).up_axis == "y" and hsr.load(stl).up_axis == "z"
    spot = os.path.join(models_dir, "spot.obj")
    assert hsr.load(spot).up_axis is None
    assert hsr.load_scene(spot).up_axis() == "y"
    assert hsr.load(spot, up_axis="z").up_axis == "z"
    assert hsr.load_scene([spot, stl]).up_axis() == "z"  # the one declared
    assert hsr.load_scene([glb, stl]).up_axis() == "y"  # they disagree: OpenGL's
    mine = hsr.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    assert hsr.load(mine, up_axis="z").up_axis == "z" and mine.up_axis is None
    with pytest.raises(hsr.MeshError, match="up_axis"):
        hsr.load(spot, up_axis="x")
    # The tower stands: its image is taller than wide, first look and command line alike.
    tower = _tall_box_stl(tmp_path)
    ids = hsr.render(tower, width=120, height=120).face_id
    rows, cols = np.nonzero(ids >= 0)
    assert np.ptp(rows) > 1.8 * np.ptp(cols)
    from conftest import run_cli

    code, err = run_cli(["render", tower, "--size", "120x120", "--ids-out",
                         str(tmp_path / "ids.npy"), "-o", str(tmp_path / "t.png"), "--quiet"])
    assert code == 0, err
    rows, cols = np.nonzero(np.load(tmp_path / "ids.npy") >= 0)
    assert np.ptp(rows) > 1.8 * np.ptp(cols)
    code, err = run_cli(["render", tower, "--up-axis", "y", "--size", "120x120", "--ids-out",
                         str(tmp_path / "ids.npy"), "-o", str(tmp_path / "t.png"), "--quiet"])
    assert code == 0, err
    rows, cols = np.nonzero(np.load(tmp_path / "ids.npy") >= 0)
    assert np.ptp(rows) < 1.8 * np.ptp(cols)  # told Y is up: lying down


def test_view_sets_turn_about_the_models_up(models_dir, tmp_path):
    """hsr visibility, prune and batch framed their orbits about +Y whatever the model:
    a Z-up model turned from spot sees, per view, what spot sees."""
    from conftest import run_cli

    spot = hsr.load(os.path.join(models_dir, "spot.obj"))
    p = spot.positions
    turned = hsr.Mesh(np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1), spot.faces)
    hsr.write_mesh(turned, tmp_path / "zup.ply")
    want = np.asarray(hsr.visibility.face_visibility(spot, "orbit:3", 64))
    got = hsr.visibility.face_visibility(hsr.load(tmp_path / "zup.ply", up_axis="z"),
                                         "orbit:3", 64)
    assert np.abs(got - want).sum() <= 0.002 * want.sum()
    code, err = run_cli(["visibility", str(tmp_path / "zup.ply"), "--views", "orbit:3",
                         "--up-axis", "z", "--size", "64", "-o", str(tmp_path / "v.npz"),
                         "--quiet"])
    assert code == 0, err
    written = np.load(tmp_path / "v.npz")
    per_face = np.bincount(written["face"], written["pixels"], minlength=len(want))
    assert np.abs(per_face - want).sum() <= 0.002 * want.sum()
    code, err = run_cli(["prune", str(tmp_path / "zup.ply"), "--views", "orbit:4",
                         "--up-axis", "z", "--size", "64", "-o", str(tmp_path / "p.ply"),
                         "--quiet"])
    assert code == 0, err


def test_the_viewer_orbits_a_z_up_model_about_z(tmp_path):
    """The page's orbit turned about +Y whatever the model: a Z-up tower opened lying down.
    Its camera's up is now +Z, the tower stands in the frame, and the page's 'reproduce'
    command draws the same picture."""
    from conftest import run_cli
    from hsr.viewer.frames import Library, render_request, reproduce
    from hsr.viewer.params import parse

    tower = _tall_box_stl(tmp_path)
    library = Library([tower], builtin=False)
    view = library.initial("tower.stl")
    request = parse({"scene": "tower.stl", "w": "96", "h": "96", "az": str(view["az"]),
                     "el": str(view["el"])}, library.names)
    frame, _, _ = render_request(library.get("tower.stl"), request)
    rows, cols = np.nonzero(frame.face_id >= 0)
    assert np.ptp(rows) > 1.8 * np.ptp(cols)
    command = reproduce(library.get("tower.stl"), request, tower)["command"]
    assert "--up-axis z" in command
    args = shlex.split(command)[1:] + ["--ids-out", str(tmp_path / "ids.npy"), "-o",
                                  str(tmp_path / "r.png"), "--quiet"]
    code, err = run_cli(args)
    assert code == 0, err
    assert np.array_equal(np.load(tmp_path / "ids.npy"), frame.face_id)


# Real files nobody here wrote (trimesh's test models: the Khronos Duck, BoxTextured and
# CesiumMilkTruck, fuze.obj with its MTL and 'fuze uv.jpg', teapot.stl), read from
# ../shared/models when the shared folder holds them: developers may not commit them.
REAL = {"Duck.glb": "y", "BoxTextured.glb": "y", "CesiumMilkTruck.glb": "y",
        "fuze.obj": None, "teapot.stl": "z"}


@pytest.mark.parametrize("name", sorted(REAL))
def test_real_sample_files_look_as_their_authors_meant(models_dir, name, tmp_path):
    """Each real file's unlit colour is its texture's, sampled independently (the
    reference rasteriser's barycentrics, trimesh's texture coordinates, Pillow's texels),
    its up axis is the one its format declares, and its first look frames it whole."""
    import trimesh

    from reference import reference_render

    path = os.path.join(models_dir, name)
    if not os.path.exists(path):
        pytest.skip(f"{name} is not in the shared models")
    scene = hsr.load_scene(path)
    assert scene.up_axis() == (REAL[name] or "y")
    frame = hsr.render(scene, width=160, height=120, shading="unlit")
    seen = frame.face_id >= 0
    assert 0.1 < seen.mean() and not seen[0].any() and not seen[-1].any()
    textured = [k for k, inst in enumerate(scene.instances) if inst.mesh.texture is not None]
    if not textured:
        return
    cam = hsr.first_look(scene, 160 / 120)
    mesh = scene.instances[textured[0]].mesh
    loaded = trimesh.load(path, process=False, force="scene" if name.endswith(".glb")
                          else "mesh")
    tm = loaded if name.endswith(".obj") else list(loaded.geometry.values())[textured[0]]
    image = np.asarray(tm.visual.material.to_simple().image.convert("RGB")
                       if name.endswith(".glb") else tm.visual.material.image.convert("RGB"),
                       dtype=np.float64)
    inst = scene.instances[textured[0]]
    alone = hsr.Scene([hsr.Instance(mesh, inst.model)])
    face, _, bary = reference_render(alone, cam, 160, 120, with_barycentrics=True)
    hit = face >= 0
    uv = np.einsum("kc,kcj->kj", bary[hit], np.asarray(tm.visual.uv)[np.asarray(tm.faces)][
        face[hit]])
    h, w = image.shape[:2]
    texel = image[np.clip(((1 - uv[:, 1] % 1) * h).astype(int), 0, h - 1),
                  np.clip(((uv[:, 0] % 1) * w).astype(int), 0, w - 1)]
    factor = 1.0 if mesh.face_colors is None else mesh.face_colors[face[hit]] / 255.0
    want = (texel * factor).mean(axis=0)
    got = hsr.render(alone, cam, 160, 120, shading="unlit").color[hit].astype(float).mean(0)
    assert np.abs(got - want).max() <= 0.05 * 255, (got, want)
