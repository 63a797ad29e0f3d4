"""Occlusion culling is conservative: identical results with it on and off."""

import numpy as np
import pytest

import hsr
from hsr import scenes
from hsr.algorithms.hiz import screen_box


@pytest.mark.parametrize("func", ["less", "lequal"])
def test_city_identical_with_and_without_culling(func):
    scene, cam = scenes.city(blocks=8, segments=4)
    plain = hsr.render(scene, cam, 320, 180, depth_func=func)
    culled = hsr.render(scene, cam, 320, 180, depth_func=func, occlusion_cull=True)
    assert np.array_equal(plain.face_id, culled.face_id)
    assert np.array_equal(plain.depth, culled.depth)
    assert culled.stats["objects_culled"] > 20, "the street view hides most buildings"
    assert culled.stats["fragments_tested"] < plain.stats["fragments_tested"]


def test_ties_between_objects_follow_submission_order_when_reordered():
    """Coplanar squares in two objects, the far-away one submitted first: drawing front to
    back must still give LESS's first-submitted / LEQUAL's last-submitted winner."""
    square = hsr.Mesh(np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float),
                      np.array([[0, 1, 2], [0, 2, 3]]))
    scene = hsr.Scene()
    scene.add(square, hsr.scenes.translate(0.5, 0, -6))   # bounding box is farther ...
    # ... than this one's, which reaches towards the camera with an off-screen sliver.
    near_sliver = hsr.Mesh(np.vstack([square.positions, [[40, 0, 3], [41, 0, 3], [40, 1, 3]]]),
                           np.vstack([square.faces, [[4, 5, 6]]]))
    scene.add(near_sliver, hsr.scenes.translate(-0.5, 0, -6))
    cam = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=40, near=1, far=20)
    for func in ("less", "lequal"):
        a = hsr.render(scene, cam, 96, 72, depth_func=func)
        b = hsr.render(scene, cam, 96, 72, depth_func=func, occlusion_cull=True)
        assert np.array_equal(a.face_id, b.face_id), func


@pytest.mark.parametrize("seed", range(5))
def test_random_boxes_random_views(seed):
    rng = np.random.default_rng(seed)
    scene = hsr.Scene()
    box = scenes.tessellated_cube(3)
    for _ in range(40):
        m = hsr.scenes.translate(*rng.uniform([-6, -2, -30], [6, 2, -4])) @ hsr.scenes.scale(
            rng.uniform(0.3, 2.5))
        scene.add(box, m)
    eye = rng.uniform([-3, -1, -2], [3, 1, 3])
    cam = hsr.Camera.look_at(eye, (0, 0, -15), fov_y=rng.uniform(40, 90), near=0.3, far=60)
    a = hsr.render(scene, cam, 200, 150)
    b = hsr.render(scene, cam, 200, 150, occlusion_cull=True)
    assert np.array_equal(a.face_id, b.face_id) and np.array_equal(a.depth, b.depth)


def test_occlusion_cull_refuses_states_it_cannot_keep_exact():
    scene, cam = scenes.get("cubes")
    with pytest.raises(hsr.RenderError):
        hsr.render(scene, cam, 64, 48, occlusion_cull=True, depth_func="greater")
    with pytest.raises(hsr.RenderError):
        hsr.render(scene, cam, 64, 48, occlusion_cull=True, depth_mask=False)


def test_screen_box_of_a_corner_projected_past_the_integers():
    """A box whose corner projects 1e30 pixels to the right reaches the image's right
    edge: its rectangle runs from its left side (window x 32, so column 31 with the
    pixel of margin) to the last column, rows 19-27 (window y 21.6-26.4, y up, with the
    margin). Converting the far bound to an integer before clamping it gave the most
    negative integer, and the box counted as off the image (culled, or pruned)."""
    corners = np.array([[x, y, -0.5, 1.0] for x in (0.0, 1e30) for y in (-0.1, 0.1)
                        for _ in range(2)])
    x0, x1, r0, r1, z_min, ok = screen_box(corners, 64, 48, 0.5, 0.5)
    assert ok and (x0, x1, r0, r1) == (31, 63, 19, 27) and z_min == 0.25
    far_left = corners.copy()
    far_left[:, 0] = np.where(far_left[:, 0] > 0, 0.0, -1e30)
    assert screen_box(far_left, 64, 48, 0.5, 0.5)[:4] == (0, 33, 19, 27)
