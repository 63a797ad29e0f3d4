"""Eye depth, distance and normals per pixel (issue #14, buffers): checked against the
surface point found independently, by intersecting the pixel-centre ray (un-projected
through the inverse view-projection, as tests/reference.py does) with the plane of the
visible face in world space."""

import numpy as np
import pytest

import hsr
from hsr import scenes
from reference import unproject, world_triangles

W, H = 64, 48


def ray_points(scene, camera, face_id):
    """World points where each covered pixel's centre ray meets its face's plane."""
    rows, cols = np.nonzero(face_id >= 0)
    x, y = cols + 0.5, (H - 1 - rows) + 0.5  # window coordinates, y up
    near = unproject(camera, W, H, np.c_[x, y, np.zeros(len(x))])
    far = unproject(camera, W, H, np.c_[x, y, np.ones(len(x))])
    tri = world_triangles(scene)[face_id[rows, cols]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    d = far - near
    s = np.einsum("kj,kj->k", tri[:, 0] - near, n) / np.einsum("kj,kj->k", d, n)
    return rows, cols, near + s[:, None] * d, n / np.linalg.norm(n, axis=1, keepdims=True)


@pytest.mark.parametrize("algorithm", list(hsr.ALGORITHMS))
@pytest.mark.parametrize("ortho", [False, True])
def test_eye_depth_distance_and_normals(algorithm, ortho):
    scene, cam = scenes.get("cubes")
    if ortho:
        cam = hsr.Camera.orthographic(cam.eye, cam.target, height=8.0, near=0.5, far=30)
    frame = hsr.render(scene, cam, W, H, algorithm=algorithm)
    rows, cols, points, normal = ray_points(scene, cam, frame.face_id)
    eye, forward = np.asarray(cam.eye), np.asarray(cam.forward)
    expected_depth = (points - eye) @ forward
    assert np.allclose(frame.eye_depth[rows, cols], expected_depth, rtol=1e-6)
    expected_dist = expected_depth if ortho else np.linalg.norm(points - eye, axis=1)
    assert np.allclose(frame.distance[rows, cols], expected_dist, rtol=1e-6)
    assert np.allclose(frame.normals[rows, cols], normal, atol=1e-6)
    background = frame.face_id < 0
    assert np.isinf(frame.eye_depth[background]).all()
    assert np.isinf(frame.distance[background]).all()
    assert (frame.normals[background] == 0).all()


def test_eye_depth_is_exact_where_the_depth_buffer_is_coarse():
    """Far from the camera float32 window depth loses digits (step ~ e^2 / near * 2^-24);
    the eye depth comes from the face, not from the buffer."""
    tri = hsr.Mesh(np.array([[-50.0, -50, -900], [50, -50, -900], [0, 50, -900]]), [[0, 1, 2]])
    cam = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=20, near=0.01, far=1000)
    frame = hsr.render(tri, cam, W, H)
    covered = frame.face_id >= 0
    assert np.allclose(frame.eye_depth[covered], 900.0, rtol=1e-7)
    from hsr.appearance.shading import linear_eye_depth

    from_buffer = linear_eye_depth(frame.depth, cam)[covered]
    assert np.abs(from_buffer - 900).max() > 1e-3  # the buffer alone is far coarser


def test_gouraud_frame_interpolates_corner_normals():
    scene, cam = scenes.spheres(detail=12)
    flat = hsr.render(scene, cam, W, H)
    smooth = hsr.render(scene, cam, W, H, shading="gouraud")
    covered = flat.face_id >= 0
    # A sphere's smooth normals point away from its centre better than face normals do.
    assert np.allclose(np.linalg.norm(smooth.normals[covered], axis=1), 1, atol=1e-5)
    assert not np.allclose(flat.normals[covered], smooth.normals[covered], atol=1e-3)


def test_frame_repr_is_short_and_notebooks_get_a_png():
    scene, cam = scenes.get("cubes")
    frame = hsr.render(scene, cam, W, H)
    assert repr(frame).startswith("Frame(64x48, zbuffer, 48 triangles, ") and len(repr(frame)) < 100
    assert repr(scene) == "<hsr.Scene: 4 instances of 1 mesh, 48 faces>"
    assert frame._repr_png_()[:8] == b"\x89PNG\r\n\x1a\n"


def test_color_false_keeps_every_buffer_and_paints_the_background():
    """``color=False`` skips shading only: the ids and depth (checked against OpenGL and
    the ray reference elsewhere) are those of the shaded render, bit for bit."""
    scene, cam = hsr.scenes.get("cubes")
    shaded = hsr.render(scene, cam, 160, 120, shading="gouraud")
    for background in ((1, 2, 3), (0, 0, 0)):
        plain = hsr.render(scene, cam, 160, 120, color=False, background=background)
        assert np.array_equal(plain.face_id, shaded.face_id)
        assert np.array_equal(plain.depth, shaded.depth)
        assert np.array_equal(plain.eye_depth, shaded.eye_depth)
        assert (plain.color == np.array(background, np.uint8)).all()
        assert plain.stats["pixels_covered"] == int((shaded.face_id >= 0).sum())


@pytest.mark.parametrize("extra", [{"hidden_line": True}, {"color": "no"}])
def test_color_false_refuses_what_needs_colour(extra):
    scene, cam = hsr.scenes.get("cubes")
    kwargs = {"color": False, **extra}
    with pytest.raises(hsr.RenderError, match="color"):
        hsr.render(scene, cam, 32, 24, **kwargs)


def _numpy_barycentrics(screen, rows, cols, faces):
    """The array form of the perspective-correct barycentrics (Olano & Greer 1997), as
    hsr computed them before its per-pixel kernel: the kernel must give these values
    bit for bit, so that shading, textures and the derived buffers do not move."""
    corners = screen.pos_clip[screen.faces[faces]]  # (K, 3, 4)
    x_ndc = (cols + 0.5) * (2.0 / screen.width) - 1.0
    y_ndc = ((screen.height - 1 - rows) + 0.5) * (2.0 / screen.height) - 1.0
    u = corners[:, :, 0] - x_ndc[:, None] * corners[:, :, 3]
    v = corners[:, :, 1] - y_ndc[:, None] * corners[:, :, 3]
    b = np.cross(u, v)
    total = b.sum(axis=1, keepdims=True)
    return b / np.where(total == 0.0, 1.0, total)


@pytest.mark.parametrize("name", ["cubes", "spheres"])
@pytest.mark.parametrize("algorithm", ["zbuffer", "raycast"])
def test_surface_points_equal_the_array_formulas_bit_for_bit(name, algorithm):
    """Each covered pixel's barycentrics and world point, from the per-pixel kernels,
    equal NumPy's array formulas (the corners gathered for every pixel, ``np.cross``,
    ``einsum``) exactly, on scenes of several placed instances and a clipped view."""
    from hsr.appearance.buffers import surface_points

    scene, cam = scenes.get(name)
    views = [cam, hsr.Camera.look_at(cam.target, np.asarray(cam.eye) * 0.2
                                     + np.asarray(cam.target) * 0.8, near=0.05, far=50)]
    for camera in views:
        frame = hsr.render(scene, camera, 160, 120, algorithm=algorithm)
        screen = frame.fragments.screen
        rows, cols, faces, points, bary = surface_points(frame.scene, screen, frame.face_id)
        assert len(rows) > 500
        want = _numpy_barycentrics(screen, rows, cols, faces)
        np.testing.assert_array_equal(bary, want)
        corners = frame.scene.world_triangles()[faces]
        np.testing.assert_array_equal(points, np.einsum("kc,kcj->kj", want, corners))
