"""Camera matrices against the formulas of gluLookAt, gluPerspective and glOrtho."""

import math

import numpy as np
import pytest

import hsr
from hsr.errors import CameraError


def test_look_at_maps_eye_to_origin_and_target_down_minus_z():
    cam = hsr.Camera.look_at((1, 2, 3), (4, 6, 3), up=(0, 0, 1))
    view = cam.view_matrix
    assert np.allclose(view @ [1, 2, 3, 1], [0, 0, 0, 1])
    t = view @ [4, 6, 3, 1]
    assert np.allclose(t[:3], [0, 0, -5])
    assert np.allclose(view[:3, :3] @ view[:3, :3].T, np.eye(3))
    assert np.linalg.det(view[:3, :3]) > 0  # right-handed, no mirror


def test_perspective_matches_glu_formula():
    cam = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=60, near=0.5, far=50)
    p = cam.projection_matrix(2.0)
    f = 1 / math.tan(math.radians(30))
    expected = np.array([[f / 2, 0, 0, 0], [0, f, 0, 0],
                         [0, 0, 50.5 / -49.5, 2 * 50 * 0.5 / -49.5], [0, 0, -1, 0]])
    assert np.allclose(p, expected)
    # near plane -> ndc z = -1, far plane -> +1
    for z_eye, z_ndc in ((-0.5, -1.0), (-50.0, 1.0)):
        clip = p @ [0, 0, z_eye, 1]
        assert math.isclose(clip[2] / clip[3], z_ndc)


def test_orthographic_matches_gl_ortho():
    cam = hsr.Camera.orthographic((0, 0, 0), (0, 0, -1), height=4, near=1, far=11)
    p = cam.projection_matrix(1.5)
    assert np.allclose(p @ [3, 2, -1, 1], [1, 1, -1, 1])
    assert np.allclose(p @ [-3, -2, -11, 1], [-1, -1, 1, 1])


@pytest.mark.parametrize("kwargs,message", [
    (dict(near=0), "near must be > 0"),
    (dict(near=-1), "near must be > 0"),
    (dict(near=5, far=5), "far"),
    (dict(fov_y=0), "fov"),
    (dict(fov_y=180), "fov"),
    (dict(fov_y=float("nan")), "fov"),
    (dict(eye=(0, 0, -1)), "same point"),
    (dict(up=(0, 0, 1)), "parallel"),
    (dict(eye=(0, float("inf"), 0)), "finite"),
])
def test_nonsense_cameras(kwargs, message):
    args = dict(eye=(0, 0, 0), target=(0, 0, -1), up=(0, 1, 0), fov_y=45, near=0.1, far=10)
    args.update(kwargs)
    with pytest.raises(CameraError, match=message):
        hsr.Camera.look_at(**args)


def test_frame_sees_the_whole_box():
    box = np.array([[-1, -2, -3], [4, 5, 6]], float)
    cam = hsr.Camera.frame(box, fov_y=40)
    view_proj = cam.projection_matrix(1.0) @ cam.view_matrix
    corners = np.array([[x, y, z, 1] for x in box[:, 0] for y in box[:, 1] for z in box[:, 2]])
    clip = corners @ view_proj.T
    ndc = clip[:, :3] / clip[:, 3:]
    assert (np.abs(ndc) <= 1).all()
