"""The z-buffer against the brute-force ray reference (tests/reference.py): face ids equal
on every pixel whose centre is not on an edge, depth within float32 rounding."""

import numpy as np
import pytest

import hsr
from hsr import scenes
from hsr.algorithms.fragments import face_barycentrics
from reference import ambiguous_pixels, compare, reference_render

W, H = 96, 72
FUNCS = ["never", "less", "equal", "lequal", "greater", "notequal", "gequal", "always"]


def small_scene(name):
    """The built-in scenes, the large ones made small enough for the brute-force reference."""
    if name == "spheres":
        return scenes.spheres(detail=8)
    if name == "terrain":
        return scenes.terrain(1500)
    if name == "city":
        return scenes.city(blocks=3, segments=2)
    return scenes.get(name)


def check(scene, camera, width=W, height=H, max_ambiguous=0.03, workspace=None, **state):
    frame = hsr.render(scene, camera, width, height, workspace=workspace, **state)
    # Transparent instances write neither depth nor ids (depth mask off): the truth for
    # face_id and depth is the opaque part of the scene, numbered as in the whole scene.
    # (Transparent instances are squashed to a point: their faces keep their numbers but
    # the reference skips them as degenerate.)
    opaque = hsr.Scene([hsr.Instance(i.mesh, i.model if i.opacity == 1.0 else
                                     np.diag([0.0, 0.0, 0.0, 1.0]))
                        for i in scene.instances]) if hasattr(scene, "instances") else scene
    ref_face, ref_depth = reference_render(opaque, camera, width, height, **state)
    amb = ambiguous_pixels(opaque, camera, width, height, **state)
    face_bad, depth_bad, compared = compare(frame.face_id, frame.depth, ref_face, ref_depth, amb)
    assert amb.mean() <= max_ambiguous, f"too many pixel centres on edges: {amb.mean():.3f}"
    assert face_bad == 0, f"{face_bad} of {compared} pixels have another face than the reference"
    assert depth_bad == 0, f"{depth_bad} pixels differ in depth from the reference"
    return frame, ref_face


def moved(camera, eye=None, target=None, ortho=None):
    eye = camera.eye if eye is None else eye
    target = camera.target if target is None else target
    if ortho:
        return hsr.Camera.orthographic(eye, target, camera.up, ortho, camera.near, camera.far)
    return hsr.Camera.look_at(eye, target, camera.up, camera.fov_y, camera.near, camera.far)


@pytest.mark.parametrize("name", list(scenes.SCENES))
@pytest.mark.parametrize("view", ["default", "oblique", "ortho"])
def test_builtin_scenes(name, view):
    scene, cam = small_scene(name)
    if view == "oblique":
        eye = np.asarray(cam.target) + np.array([2.5, 1.5, 4.0])
        cam = moved(cam, eye=eye)
    elif view == "ortho":
        cam = moved(cam, ortho=4.0)
    frame, ref = check(scene, cam)
    assert (ref >= 0).sum() > 200, "the view should show the scene"


@pytest.mark.parametrize("cull", ["none", "back", "front", "front_and_back"])
@pytest.mark.parametrize("front_face", ["ccw", "cw"])
@pytest.mark.parametrize("name", ["cubes", "spheres"])
def test_cull_modes(name, cull, front_face):
    scene, cam = small_scene(name)
    frame, ref = check(scene, cam, cull=cull, front_face=front_face)
    if cull == "front_and_back":
        assert (frame.face_id < 0).all()
        assert frame.stats["culled"] == frame.stats["triangles_in"]


def test_back_culling_hides_back_faces_of_closed_meshes():
    scene, cam = small_scene("cubes")
    front = hsr.render(scene, cam, W, H, cull="back").face_id
    nothing = hsr.render(scene, cam, W, H, cull="none").face_id
    # With a closed mesh the visible surface is front-facing: culling changes nothing...
    assert np.array_equal(front, nothing)
    # ...and culling front faces shows the insides instead.
    inside = hsr.render(scene, cam, W, H, cull="front").face_id
    assert np.count_nonzero((inside != nothing) & (nothing >= 0)) > 0.5 * np.count_nonzero(
        nothing >= 0)


def test_near_plane_crossing_camera_inside_cube_scene():
    scene, cam = small_scene("cubes")
    # Eye inside the first cube's neighbourhood: many faces cross the near plane and the
    # eye plane (w changes sign).
    cam = hsr.Camera.look_at(eye=(-1.5, 0.2, -6.6), target=(1.0, 0.5, -10.0), fov_y=80,
                             near=0.2, far=30.0)
    frame, _ = check(scene, cam)
    assert frame.stats["clipped"] > 0


def test_triangle_behind_and_in_front_of_the_eye():
    # A ground quad that extends far behind the camera: without homogeneous clipping its
    # corners behind the eye would project to the wrong side of the screen.
    verts = np.array([[-50, -1, 20], [50, -1, 20], [50, -1, -60], [-50, -1, -60]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    mesh = hsr.Mesh(verts, faces)
    cam = hsr.Camera.look_at(eye=(0, 0, 0), target=(0, -0.3, -1), fov_y=60, near=0.1, far=100)
    frame, ref = check(mesh, cam)
    assert frame.stats["clipped"] == 2
    assert (ref >= 0).mean() > 0.3


def test_near_and_far_planes_cut_geometry():
    scene, cam = small_scene("spheres")
    cam = hsr.Camera.look_at(cam.eye, cam.target, cam.up, cam.fov_y, near=5.6, far=6.3)
    frame, _ = check(scene, cam)
    assert frame.stats["clipped"] > 0


@pytest.mark.parametrize("func", FUNCS)
def test_depth_funcs_single_draw(func):
    scene, cam = small_scene("cubes")
    check(scene, cam, depth_func=func, clear_depth=0.97)


@pytest.mark.parametrize("func", FUNCS)
def test_depth_funcs_second_draw(func):
    """Draw once with LESS, then again with FUNC into the same depth buffer (no clear):
    EQUAL redraws exactly the visible surface, NOTEQUAL the hidden ones, and so on."""
    scene, cam = small_scene("penetration")
    first = hsr.render(scene, cam, W, H)
    second = hsr.render(scene, cam, W, H, depth_func=func, into=first)
    ref_face1, ref_depth1 = reference_render(scene, cam, W, H)
    ref_face2, ref_depth2 = reference_render(scene, cam, W, H, depth_func=func,
                                             depth_buffer=ref_depth1)
    # Where the second draw wrote nothing, the first draw's result stays.
    ref_face = np.where(ref_face2 >= 0, ref_face2, ref_face1)
    amb = ambiguous_pixels(scene, cam, W, H)
    face_bad, depth_bad, _ = compare(second.face_id, second.depth, ref_face, ref_depth2, amb)
    assert face_bad == 0 and depth_bad == 0
    if func == "equal":
        assert np.array_equal(second.face_id, first.face_id)


@pytest.mark.parametrize("func", ["less", "lequal", "always"])
def test_depth_mask_off(func):
    scene, cam = small_scene("cubes")
    frame, _ = check(scene, cam, depth_mask=False, depth_func=func)
    assert (frame.depth == 1.0).all(), "depth mask off must leave the depth buffer cleared"


def test_depth_test_off_last_submitted_wins():
    scene, cam = small_scene("cubes")
    frame, ref = check(scene, cam, depth_test=False)
    assert (frame.depth == 1.0).all(), "OpenGL writes no depth with the test disabled"
    with_test = hsr.render(scene, cam, W, H).face_id
    assert np.count_nonzero(frame.face_id != with_test) > 100, "painting order must show"


@pytest.mark.parametrize("depth_range", [(0.0, 1.0), (0.25, 0.75), (1.0, 0.0), (0.5, 0.5)])
def test_depth_range(depth_range):
    scene, cam = small_scene("spheres")
    reversed_range = depth_range[0] > depth_range[1]
    state = dict(depth_range=depth_range)
    if reversed_range:  # reversed depth: nearer is greater
        state.update(depth_func="greater", clear_depth=0.0)
    frame, _ = check(scene, cam, **state)
    covered = frame.face_id >= 0
    lo, hi = min(depth_range), max(depth_range)
    assert (frame.depth[covered] >= lo).all() and (frame.depth[covered] <= hi).all()


def coplanar_pair():
    """Two overlapping triangles in the plane z = -5, facing the camera."""
    verts = np.array([[-1, -1, -5], [1, -1, -5], [0, 1, -5],
                      [-1, 1, -5], [0, -1, -5], [1, 1, -5]], float)
    return hsr.Mesh(verts + [0.013, 0.007, 0], np.array([[0, 1, 2], [3, 4, 5]]))


@pytest.mark.parametrize("func,winner", [("less", 0), ("lequal", 1), ("gequal", 1),
                                         ("greater", 0), ("equal", 1), ("notequal", 0)])
def test_ties_follow_submission_order(func, winner):
    mesh = coplanar_pair()
    cam = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=40, near=1, far=10)
    state = dict(depth_func=func)
    if func in ("greater", "gequal"):
        state["clear_depth"] = 0.0
    if func in ("equal", "notequal"):
        # Clear to exactly the plane's depth so the first triangle passes EQUAL.
        first = hsr.render(mesh, cam, W, H)
        state["clear_depth"] = float(first.depth[first.face_id >= 0][0])
    frame, ref = check(mesh, cam, **state)
    both = (hsr.render(hsr.Mesh(mesh.positions, mesh.faces[:1]), cam, W, H).face_id >= 0) & (
        hsr.render(hsr.Mesh(mesh.positions, mesh.faces[1:]), cam, W, H).face_id >= 0)
    assert both.sum() > 50
    if func == "notequal":
        assert (frame.face_id[both] == -1).all()  # nothing differs from the cleared depth
    else:
        assert (frame.face_id[both] == winner).all()


@pytest.mark.parametrize("seed", range(6))
def test_random_triangle_soup(seed):
    rng = np.random.default_rng(seed)
    n = 40
    centers = rng.uniform([-2, -2, -9], [2, 2, -3], size=(n, 1, 3))
    verts = (centers + rng.normal(scale=0.9, size=(n, 3, 3))).reshape(-1, 3)
    mesh = hsr.Mesh(verts, np.arange(3 * n).reshape(-1, 3))
    eye = rng.uniform(-1, 1, 3) + [0, 0, 1]
    cam = hsr.Camera.look_at(eye, (0, 0, -6), fov_y=rng.uniform(30, 90), near=0.5, far=20)
    check(mesh, cam, cull=["none", "back"][seed % 2], max_ambiguous=0.06)


def test_degenerate_triangles_are_skipped_and_counted():
    verts = np.array([[0, 0, -5], [1, 0, -5], [0, 1, -5], [2, 2, -5], [3, 3, -5]], float)
    faces = np.array([[0, 1, 2], [0, 0, 1], [0, 3, 4], [1, 2, 2]])
    cam = hsr.Camera.look_at((0.3, 0.3, 0), (0.3, 0.3, -5), fov_y=40, near=1, far=10)
    frame = hsr.render(hsr.Mesh(verts, faces), cam, W, H)
    assert frame.stats["degenerate"] == 3
    assert set(np.unique(frame.face_id)) == {-1, 0}


def test_multiple_instances_have_global_face_ids_and_object_ids():
    scene, cam = small_scene("cubes")
    frame = hsr.render(scene, cam, W, H)
    covered = frame.face_id >= 0
    assert np.array_equal(frame.object_id[covered], frame.face_id[covered] // 12)
    assert (frame.object_id[~covered] == -1).all()
    assert len(np.unique(frame.object_id[covered])) == len(scene)


@pytest.mark.parametrize("view", ["default", "inside"])
def test_perspective_correct_barycentrics(view):
    """Barycentrics on the source face, also for faces cut by the near plane."""
    scene, cam = small_scene("cubes")
    if view == "inside":
        cam = hsr.Camera.look_at(eye=(-1.5, 0.2, -6.6), target=(1.0, 0.5, -10.0), fov_y=80,
                                 near=0.2, far=30.0)
    frame = hsr.render(scene, cam, W, H)
    ref_face, _, ref_bary = reference_render(scene, cam, W, H, with_barycentrics=True)
    amb = ambiguous_pixels(scene, cam, W, H)
    same = (frame.face_id == ref_face) & (ref_face >= 0) & ~amb
    bary = face_barycentrics(frame.fragments)
    assert same.sum() > 1000
    assert np.abs(bary[same] - ref_bary[same]).max() < 1e-6
    if view == "inside":
        assert frame.stats["clipped"] > 0


@pytest.mark.parametrize("seed", range(3))
def test_long_thin_slivers(seed):
    """Needles across the whole image: their boxes are wide and mostly empty, so the fill
    takes each row's span from the edge functions instead of testing every pixel."""
    rng = np.random.default_rng(seed)
    n = 30
    start = rng.uniform([-3, -2, -9], [-2, 2, -4], size=(n, 3))
    end = rng.uniform([2, -2, -9], [3, 2, -4], size=(n, 3))
    side = start + rng.normal(scale=0.05, size=(n, 3))
    verts = np.stack([start, end, side], axis=1).reshape(-1, 3)
    mesh = hsr.Mesh(verts, np.arange(3 * n).reshape(-1, 3))
    cam = hsr.Camera.look_at((0, 0, 1), (0, 0, -6), fov_y=60, near=0.5, far=20)
    frame, _ = check(mesh, cam, max_ambiguous=0.06)
    assert (frame.face_id >= 0).mean() > 0.02  # the needles do cover pixels


def test_row_span_is_the_per_pixel_edge_test():
    """``row_span`` (a division per edge) against the rule it replaces: pixel k is inside
    when e + k * step >= 0 for all three edges; exact crossings included, and values past
    2**53 where the float64 estimate of the crossing is off and must be corrected."""
    from hypothesis import example, given, settings
    from hypothesis import strategies as st

    from hsr.raster.fill import row_span

    step = st.one_of(st.sampled_from([0, 1, -1, 256, -256]),
                     st.integers(-(1 << 36), 1 << 36), st.integers(-(1 << 55), 1 << 55))
    # An edge value near an exact crossing at pixel k0, or anywhere.
    edge = st.one_of(st.tuples(step, st.integers(-3, 40), st.integers(-2, 2)).map(
        lambda t: (-t[0] * t[1] + t[2], t[0])),
        st.tuples(st.integers(-(1 << 50), 1 << 50), step))

    row_span(0, 1, 0, 1, 0, 1, 1)  # compiled before the timed examples

    # Exact crossings (at pixels 25 and 15) whose float64 estimate lands past them.
    @example([(-878844378623478725, 35153775144939149), (0, 0), (0, 0)], 40)
    @example([(251932595178902565, -16795506345260171), (0, 0), (0, 0)], 40)
    @settings(max_examples=300, deadline=None)
    @given(st.lists(edge, min_size=3, max_size=3), st.integers(1, 40))
    def check_span(edges, n):
        first, last = row_span(edges[0][0], edges[0][1], edges[1][0], edges[1][1],
                               edges[2][0], edges[2][1], n)
        inside = [k for k in range(n) if all(e + k * s >= 0 for e, s in edges)]
        assert list(range(first, last + 1)) == inside

    check_span()


def test_sliver_inside_a_closed_box_stays_hidden():
    """Found by ``hsr prune --verify``: a bunny face inside a closed box, nearly collinear
    in window space (3e-7 pixel high), covered a pixel centre after snapping, where its
    plane, extrapolated across it, gave depth 0: it showed through the box wall. OpenGL
    (llvmpipe) and the ray reference show the wall there. The world coordinates are the
    case's (box of bunnies, verify view 62 of seed 11 at 1024 x 1024)."""
    wall = [[2.0, -2.0, -2.0], [-2.0, -2.0, 2.0], [-2.0, -2.0, -2.0]]
    sliver = [[-1.2190434749099224, -1.6523876197021177, 0.37730171677403196],
              [-1.2173973500150932, -1.6634654044020833, 0.38220476688996075],
              [-1.2106432925066957, -1.6631898727673269, 0.3795554242480684]]
    mesh = hsr.Mesh(np.array(wall + sliver), np.array([[0, 1, 2], [3, 4, 5]]))
    cam = hsr.Camera.look_at((-2.8254904630518802, -8.062265573988933, 4.166121495836128),
                             (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), fov_y=45.0,
                             near=4.308588018798968, far=14.700892864212232)
    frame = hsr.render(mesh, cam, 1024, 1024)
    alone = hsr.render(hsr.Mesh(np.array(sliver), np.array([[0, 1, 2]])), cam, 1024, 1024)
    assert alone.face_id[517, 382] == 0  # the sliver does cover this centre
    assert frame.face_id[517, 382] == 0  # ... but behind the wall
    ref_face, ref_depth = reference_render(mesh, cam, 1024, 1024)
    assert ref_face[517, 382] == 0 and frame.depth[517, 382] == np.float32(ref_depth[517, 382])


@pytest.mark.parametrize("seed", range(3))
def test_sliver_depth_stays_within_its_corners(seed):
    """Slivers far thinner than the snapping step (1/256 pixel), with a corner off the
    line in depth: wherever one covers a pixel centre, its depth lies within its corners'
    depths (a weighted mean of them, as OpenGL interpolates), never extrapolated across
    its width to anything. The z-buffer (nearest and farthest wins) and the scan-line."""
    from reference import unproject

    rng = np.random.default_rng(seed)
    width, height, n = 256, 192, 1500
    a = rng.uniform([10, 10], [width - 10, height - 10], size=(n, 2))
    direction = rng.normal(size=(n, 2))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    b = a + direction * rng.uniform(20, 120, size=(n, 1))
    b = np.clip(b, 1, [width - 1, height - 1])
    s = rng.uniform(0.2, 0.8, size=(n, 1))
    normal = np.c_[-direction[:, 1], direction[:, 0]]
    c = a + s * (b - a) + normal * rng.uniform(-1e-6, 1e-6, size=(n, 1))
    z_ab = rng.uniform(0.3, 0.7, size=(n, 2))
    z_c = z_ab[:, :1] + s[:, 0:1] * (z_ab[:, 1:] - z_ab[:, :1]) + rng.uniform(-0.05, 0.05, (n, 1))
    window = np.stack([np.c_[a, z_ab[:, 0]], np.c_[b, z_ab[:, 1]], np.c_[c, z_c[:, 0]]], axis=1)
    cam = hsr.Camera.look_at((0, 0, 5), (0, 0, 0), fov_y=50, near=1, far=20)
    world = unproject(cam, width, height, window.reshape(-1, 3))
    mesh = hsr.Mesh(world, np.arange(3 * n).reshape(-1, 3))
    lo, hi = window[:, :, 2].min(axis=1), window[:, :, 2].max(axis=1)
    covered = 0
    for algorithm, func in (("zbuffer", "less"), ("zbuffer", "greater"), ("scanline", "less")):
        frame = hsr.render(mesh, cam, width, height, algorithm=algorithm, depth_func=func,
                           clear_depth=1.0 if func == "less" else 0.0)
        face = frame.face_id
        shown = face >= 0
        covered += int(shown.sum())
        depth = frame.depth[shown].astype(np.float64)
        assert (depth >= lo[face[shown]] - 1e-6).all() and (depth <= hi[face[shown]] + 1e-6).all()
    assert covered > 20  # snapping does make slivers cover centres
