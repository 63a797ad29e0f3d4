"""What hsr accepts and what it refuses, and that every algorithm agrees on it: cameras
that float32 depth cannot represent, coordinates whose products overflow, projective model
matrices, frames that cannot fit in memory, outputs that cannot be written. Each refusal
is an HsrError (one line from the CLI, exit code 2), never a ZeroDivisionError, a NumPy
MemoryError, a RuntimeWarning or a picture that differs between algorithms."""

import warnings

import numpy as np
import pytest

import hsr
from hsr import scenes
from hsr.cli import main

ALGORITHMS = list(hsr.ALGORITHMS)


@pytest.fixture(scope="module")
def cubes():
    return scenes.get("cubes")


def render_all(scene, camera, w=48, h=36):
    """Outcome per algorithm: covered pixel count, or the HsrError type; no warnings."""
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for name in ALGORITHMS:
            try:
                out[name] = int((hsr.render(scene, camera, w, h, algorithm=name).face_id
                                 >= 0).sum())
            except hsr.HsrError as exc:
                out[name] = type(exc).__name__
    return out


@pytest.mark.parametrize("make", [
    lambda c: hsr.Camera(c.eye, c.target, c.up, 45.0, 1e-9, 100.0),       # far/near 1e11
    lambda c: hsr.Camera(c.eye, c.target, c.up, 45.0, 0.1, 1e30),         # far/near 1e31
    lambda c: hsr.Camera(c.eye, c.target, c.up, 45.0, 0.1, 100.0, 1e-300),  # ortho 1e-300
    lambda c: hsr.Camera(c.eye, c.target, c.up, 1e-9, 0.1, 100.0),        # fov 1e-9 degrees
])
def test_unrepresentable_cameras_are_refused_by_every_algorithm(cubes, make):
    """near 1e-9: zbuffer, scanline and raycast drew nothing, painter, newell and bsp 656
    pixels; ortho height 1e-300: 0, 768 or 3,072 pixels by algorithm; far 1e30: a
    ZeroDivisionError from the ray caster. Now one CameraError for all."""
    scene, cam = cubes
    assert set(render_all(scene, make(cam)).values()) == {"CameraError"}


def test_depth_ratio_limit_message(cubes):
    scene, cam = cubes
    with pytest.raises(hsr.CameraError, match=r"far / near = 1e\+11 is more than 2\*\*24"):
        hsr.Camera.look_at(cam.eye, cam.target, fov_y=45, near=1e-9, far=100)
    ok = hsr.Camera.look_at(cam.eye, cam.target, fov_y=45, near=1e-4, far=1e-4 * 2 ** 24)
    assert len(set(render_all(scene, ok).values())) == 1  # accepted, all agree


def test_accepted_extremes_agree_across_algorithms():
    big = hsr.Mesh(np.array([[0, 0, -1e29], [1e29, 0, -1e29], [0, 1e29, -1e29]]), [[0, 1, 2]])
    cam = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=45, near=1e23, far=1e30)
    outcomes = render_all(big, cam)
    assert len(set(outcomes.values())) == 1 and outcomes["zbuffer"] > 0


def test_model_matrices_must_be_affine():
    cube = scenes.cube()
    with pytest.raises(hsr.MeshError, match="affine"):
        hsr.Scene().add(cube, np.zeros((4, 4)))  # was a ZeroDivisionError in every kernel
    with pytest.raises(hsr.MeshError, match="finite 4x4"):
        hsr.Scene().add(cube, [[1, 2], [3, 4]])
    flat = hsr.Scene().add(cube, np.diag([0.0, 0.0, 0.0, 1.0]))  # singular but affine
    cam = hsr.Camera.look_at((0, 0, 5), (0, 0, 0))
    assert set(render_all(flat, cam).values()) == {0}


def test_coordinates_whose_products_overflow_are_refused(cases_dir):
    import os

    with pytest.raises(hsr.MeshError, match=r"vertex 1 has a coordinate beyond \+-1e\+100"):
        hsr.load(os.path.join(cases_dir, "coords_1e300.obj"))
    with pytest.raises(hsr.MeshError, match="places vertices beyond"):
        hsr.Scene().add(scenes.cube(), np.diag([1e102, 1e102, 1e102, 1.0]))
    with pytest.raises(hsr.CameraError, match="eye coordinates must be within"):
        hsr.Camera.look_at((1e300, 0, 0), (0, 0, 0))


def test_frame_that_cannot_fit_is_refused_before_allocating(cubes):
    from hsr.geometry.viewport import available_memory

    scene, cam = cubes
    have = available_memory()
    side = 32768
    if have is None or side * side * 64 <= have:
        pytest.skip("this machine could hold a 32768^2 frame")
    with pytest.raises(hsr.RenderError, match="32768x32768 render needs about 64.0 GiB"):
        hsr.render(scene, cam, side, side)


@pytest.mark.parametrize("argv,message", [
    (["render", "--size", "32768x32768"], "needs about"),
    (["render", "--eye", "1e300,1e300,1e300"], "--eye values must be within"),
    (["render", "-o", "{tmp}/x.xyz"], "unknown extension '.xyz'"),
    (["render", "--depth-out", "{tmp}/d.txt"], "unknown extension '.txt'"),
    (["compare", "--size", "48x36", "--montage", "{tmp}/missing/m.png"], "does not exist"),
    (["compare", "--size", "48x36", "--montage", "{tmp}/m.xyz"], "unknown extension"),
    (["explain", "overdraw", "--size", "5x4", "-o", "{tmp}/o.png"], "at least 32x32"),
    (["report", "--size", "1x1", "-o", "{tmp}/r.html"], "at least 32x32"),
    (["render", "--algorithm", "raycast", "--option", "bvh=5"], "bvh must be an hsr.BVH"),
    (["render", "--algorithm", "bsp", "--option", "tree=5"], "tree must be an hsr.BSPTree"),
    (["render", "--algorithm", "raycast", "--option", "force=maybe"], "true or false"),
])
def test_cli_refusals_are_one_line(tmp_path, capsys, argv, message):
    if message == "needs about":
        from hsr.geometry.viewport import available_memory

        if (available_memory() or 0) >= 32768 * 32768 * 64:
            pytest.skip("this machine could hold a 32768^2 frame")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv] + ["-o", str(tmp_path / "o.png")] \
        if argv[0] == "render" and "-o" not in argv else \
        [a.replace("{tmp}", str(tmp_path)) for a in argv]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("hsr: error: ")
    assert message in err[0]


def test_framing_a_model_the_camera_cannot_hold_names_the_options(tmp_path, capsys):
    path = tmp_path / "big.obj"
    path.write_text("v 0 0 0\nv 9e99 0 0\nv 0 9e99 0\nf 1 2 3\n")
    assert main(["render", str(path), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert "framed from the model's bounds" in err and "set --eye" in err


def test_render_arguments_of_the_wrong_name_or_type_are_refused(cubes):
    """A mistyped state field escaped as TypeError, a state of the wrong type as
    AttributeError."""
    scene, cam = cubes
    with pytest.raises(hsr.RenderError, match="render\\(\\) has no argument cul"):
        hsr.render(scene, cam, 32, 24, cul="back")
    with pytest.raises(hsr.RenderError, match="state must be an hsr.RenderState"):
        hsr.render(scene, cam, 32, 24, state="back")
    with pytest.raises(hsr.RenderError, match="camera must be an hsr.Camera"):
        hsr.render(scene, "camera", 32, 24)


def test_gouraud_with_a_flattening_model_matrix():
    """A singular (affine) model matrix flattens a mesh onto a plane: Gouraud shading took
    the inverse transpose and raised LinAlgError."""
    flat = hsr.Scene().add(scenes.cube(), np.diag([1.0, 1.0, 0.0, 1.0]))
    cam = hsr.Camera.look_at((3, 2, 5), (0, 0, 0))
    frame = hsr.render(flat, cam, 48, 36, shading="gouraud")
    covered = frame.face_id >= 0
    assert covered.any() and np.allclose(np.abs(frame.normals[covered][:, 2]), 1.0)


def test_choice_options_of_any_type_are_refused(cubes):
    """A choice option compared with ``in`` raised ValueError for an array value."""
    scene, cam = cubes
    with pytest.raises(hsr.RenderError, match="bsp option traversal must be one of"):
        hsr.render(scene, cam, 32, 24, algorithm="bsp", options={"traversal": np.zeros(3)})
    with pytest.raises(hsr.RenderError, match="painter option key must be one of"):
        hsr.render(scene, cam, 32, 24, algorithm="painter", options={"key": ["max"]})
