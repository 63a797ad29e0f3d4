"""Every visibility algorithm against the brute-force reference, and against the z-buffer
on the shared models. An algorithm registered later joins these tests by name."""

import itertools
import os
import platform

import numpy as np
import pytest
from bvh_tree import build_keeping_tree, outwards32
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit
from test_zbuffer_reference import small_scene

import hsr
from conftest import against_zbuffer, coplanar_soup
from hsr import scenes
from hsr.algorithms import ALGORITHMS
from hsr.algorithms.bvh import collapse, layout, sah
from hsr.algorithms.bvh.ranking import clip_zw as _clip_zw
from hsr.algorithms.bvh.ranking import depth32 as _depth32
from hsr.algorithms.bvh.ranking import t_bound as _t_bound
from hsr.algorithms.fragments import face_barycentrics
from reference import ambiguous_pixels, compare, reference_render

W, H = 96, 72
# Algorithms that must equal the reference wherever a pixel centre is not on an edge.
EXACT = ["zbuffer", "scanline", "raycast", "bsp", "newell"]


def cameras(cam):
    eye = np.asarray(cam.target) + np.array([2.5, 1.5, 4.0])
    yield "default", cam
    yield "oblique", hsr.Camera.look_at(eye, cam.target, cam.up, cam.fov_y, cam.near, cam.far)
    yield "ortho", hsr.Camera.orthographic(cam.eye, cam.target, cam.up, 4.0, cam.near, cam.far)


def test_registry_lists_the_algorithms():
    assert set(EXACT) <= set(ALGORITHMS)
    for module in ALGORITHMS.values():
        assert module.NAME and module.DESCRIPTION and callable(module.resolve)


@pytest.mark.parametrize("algorithm", EXACT)
@pytest.mark.parametrize("name", ["cubes", "cyclic", "penetration", "spheres", "city",
                                  "terrain"])
def test_exact_algorithms_match_reference(algorithm, name):
    scene, cam0 = small_scene(name)
    for view, cam in cameras(cam0):
        frame = hsr.render(scene, cam, W, H, algorithm=algorithm)
        ref_face, ref_depth = reference_render(scene, cam, W, H)
        amb = ambiguous_pixels(scene, cam, W, H)
        face_bad, depth_bad, compared = compare(frame.face_id, frame.depth, ref_face,
                                                ref_depth, amb)
        assert face_bad == 0, f"{view}: {face_bad} of {compared} pixels differ"
        assert depth_bad == 0, f"{view}: {depth_bad} depths differ"


@pytest.mark.parametrize("algorithm", EXACT)
@pytest.mark.parametrize("state", [dict(cull="back"), dict(cull="front", front_face="cw"),
                                   dict(depth_range=(0.2, 0.6))])
def test_exact_algorithms_follow_state(algorithm, state):
    scene, cam = small_scene("cubes")
    frame = hsr.render(scene, cam, W, H, algorithm=algorithm, **state)
    ref_face, ref_depth = reference_render(scene, cam, W, H, **state)
    amb = ambiguous_pixels(scene, cam, W, H, **state)
    assert compare(frame.face_id, frame.depth, ref_face, ref_depth, amb)[:2] == (0, 0)


@pytest.mark.parametrize("algorithm", ["scanline", "raycast", "bsp", "newell"])
def test_near_plane_crossing(algorithm):
    scene, _ = small_scene("cubes")
    cam = hsr.Camera.look_at(eye=(-1.5, 0.2, -6.6), target=(1.0, 0.5, -10.0), fov_y=80,
                             near=0.2, far=30.0)
    frame = hsr.render(scene, cam, W, H, algorithm=algorithm)
    ref_face, ref_depth = reference_render(scene, cam, W, H)
    amb = ambiguous_pixels(scene, cam, W, H)
    assert compare(frame.face_id, frame.depth, ref_face, ref_depth, amb)[:2] == (0, 0)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), kind=st.sampled_from(["look_at", "ortho", "opencv"]),
       accel=st.sampled_from(["bvh", "none"]))
def test_ray_caster_clips_at_the_near_plane_as_the_reference(seed, kind, accel):
    """Triangles all about the near plane, many cut by it: the ray caster's rays (from
    the eye for a perspective camera, the near plane a fraction near / far along them)
    keep exactly the hits the reference's rays from the near plane keep; for a camera
    looking down -Z from the origin, an orthographic one, and an OpenCV camera (K, R, t)
    rotated anyhow, off-centre, its eye up to 100 units from the origin. (Checked to
    fail with that fraction 1.5 times too large, or 0.)"""
    rng = np.random.default_rng(seed)
    near = float(rng.uniform(0.05, 2.0))
    far = near * float(rng.uniform(4.0, 50.0))
    width, height = 40, 32
    # Camera space: x right, y up, looking down -z (OpenGL's eye space).
    n = int(rng.integers(5, 40))
    centres = np.c_[rng.uniform(-0.6, 0.6, (n, 2)) * near, -near * rng.uniform(0.3, 2.5, n)]
    corners = centres[:, None, :] + rng.uniform(-0.6, 0.6, (n, 3, 3)) * near
    if kind == "opencv":
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        rot = q * np.sign(np.linalg.det(q))  # world -> OpenCV camera (x right, y down, z on)
        eye = rng.uniform(-100, 100, 3)
        focal = float(rng.uniform(20, 60))
        k = np.array([[focal, 0, width / 2 + rng.uniform(-5, 5)],
                      [0, focal * rng.uniform(0.8, 1.2), height / 2 + rng.uniform(-5, 5)],
                      [0, 0, 1]])
        cam = hsr.Camera.from_opencv(k, rot, -rot @ eye, width, height, near=near, far=far)
        flip = np.array([1.0, -1.0, -1.0])  # OpenGL eye space -> OpenCV camera space
        corners = (corners * flip) @ rot + eye
    else:
        cam = hsr.Camera(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), up=(0, 1, 0),
                         fov_y=float(rng.uniform(30, 100)), near=near, far=far,
                         ortho_height=2.0 * near if kind == "ortho" else None)
    scene = hsr.Mesh(corners.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    frame = hsr.render(scene, cam, width, height, algorithm="raycast",
                       options={"accel": accel})
    ref_face, ref_depth = reference_render(scene, cam, width, height)
    amb = ambiguous_pixels(scene, cam, width, height)
    assert (frame.face_id >= 0).any() or (ref_face < 0).all()
    assert compare(frame.face_id, frame.depth, ref_face, ref_depth, amb)[:2] == (0, 0)


def test_scanline_equals_zbuffer_bit_for_bit_on_coplanar_ties():
    mesh, cam = coplanar_soup(200)
    for func in ("less", "lequal"):
        a = hsr.render(mesh, cam, 200, 150, depth_func=func)
        b = hsr.render(mesh, cam, 200, 150, depth_func=func, algorithm="scanline")
        assert np.array_equal(a.face_id, b.face_id)
        assert np.array_equal(a.depth, b.depth)


MODELS = ["stanford-bunny.obj", "spot.obj", "teapot.obj", "fandisk.obj", "suzanne.obj"]


@pytest.mark.parametrize("model", MODELS)
def test_scanline_agrees_with_zbuffer_on_shared_models(models_dir, model):
    mesh = hsr.load(os.path.join(models_dir, model))
    for _, _, share in against_zbuffer(mesh, "scanline", 400, 300):
        assert share >= 0.9999


@pytest.mark.parametrize("model", MODELS)
def test_raycast_agrees_with_zbuffer_on_shared_models(models_dir, model):
    """The rasterizer snaps corners to 1/256 pixel (as OpenGL does), the ray caster does
    not: they may differ only where a pixel centre lies on an edge the two faces share."""
    mesh = hsr.load(os.path.join(models_dir, model))
    for a, b, share in against_zbuffer(mesh, "raycast", 1920, 1080, options={"buffers": True}):
        covered = (a.face_id >= 0) | (b.face_id >= 0)
        differ = a.face_id != b.face_id
        assert share >= 0.999
        both = differ & (a.face_id >= 0) & (b.face_id >= 0)
        shared = [len(set(p) & set(q)) >= 2 for p, q in
                  zip(mesh.faces[a.face_id[both]], mesh.faces[b.face_id[both]])]
        # ... or the centre is within a sliver of an edge of either face (snapping moves
        # edges by up to 1/512 pixel).
        near_edge = (b.fragments.buffers["barycentrics"][both].min(axis=1) < 0.02) | (
            face_barycentrics(a.fragments)[both].min(axis=1) < 0.02)
        assert np.all(np.array(shared) | near_edge), "a difference away from any edge"
        assert np.count_nonzero(differ & ~both) <= 0.0005 * covered.sum()  # silhouette


def test_naive_and_bvh_ray_casting_are_identical(models_dir):
    mesh = hsr.load(os.path.join(models_dir, "suzanne.obj"))
    cam = hsr.Camera.frame(mesh.bounds(), direction=(0.3, 0.2, 1))
    a = hsr.render(mesh, cam, 120, 90, algorithm="raycast",
                   options={"accel": "none", "buffers": True})
    b = hsr.render(mesh, cam, 120, 90, algorithm="raycast", options={"buffers": True})
    assert np.array_equal(a.face_id, b.face_id) and np.array_equal(a.depth, b.depth)
    da, db = a.fragments.buffers["distance"], b.fragments.buffers["distance"]
    assert np.array_equal(da, db)
    assert a.stats["ray_triangle_tests"] > 20 * b.stats["ray_triangle_tests"]


def _naive_and_bvh(scene, cam, width, height, state):
    """The naive and the BVH ray caster's frames (with buffers) of one view."""
    return [hsr.render(scene, cam, width, height, algorithm="raycast", state=state,
                       options={"accel": accel, "buffers": True}) for accel in ("none", "bvh")]


def _assert_same_hits(naive, bvh):
    """Face ids and depths bit for bit; distances and barycentrics within rounding (the
    walks carry two barycentrics and take the third as their complement)."""
    np.testing.assert_array_equal(naive.face_id, bvh.face_id)
    np.testing.assert_array_equal(naive.depth, bvh.depth)
    a, b = naive.fragments.buffers, bvh.fragments.buffers
    np.testing.assert_array_equal(a["distance"], b["distance"])
    np.testing.assert_allclose(a["barycentrics"], b["barycentrics"], rtol=0, atol=1e-12)


@pytest.mark.parametrize("size, walk", [((100, 75), "packets"), ((16, 12), "interleaved")])
def test_bvh_ray_caster_ranks_hits_as_the_naive_loop_in_every_state(models_dir, size, walk):
    """Both walks of the BVH ray caster (packets of four pixels unless the faces are
    more than PACKET_FACES_PER_PIXEL a pixel, then single rays interleaved) against the naive
    loop, which tests every face for every pixel in submission order: the same hits
    under each glCullFace mode, winding, depth function and a clear depth that cuts the
    model, on a scene whose faces are partly repeated (exact depth ties, which
    submission order decides: the later face under GL_LEQUAL, the earlier under
    GL_LESS) and partly repeated reversed (the same place, opposite facing)."""
    mesh = hsr.load(os.path.join(models_dir, "suzanne.obj"))
    faces = np.concatenate([mesh.faces, mesh.faces[::3], mesh.faces[1::3, ::-1]])
    scene = hsr.Mesh(mesh.positions, faces)
    cam = hsr.Camera.frame(mesh.bounds(), direction=(0.3, 0.2, 1))
    width, height = size
    from hsr.algorithms.bvh.choice import PACKET_FACES_PER_PIXEL

    assert (len(faces) <= PACKET_FACES_PER_PIXEL * width * height) == (walk == "packets")
    z = hsr.render(scene, cam, width, height).depth
    cut = float(np.median(z[z < 1]))  # the clear depth that hides the far half
    for cull in ("none", "back", "front", "front_and_back"):
        for func in ("less", "lequal"):
            for front in ("ccw", "cw"):
                for clear in (1.0, cut):
                    state = hsr.RenderState(cull=cull, depth_func=func, front_face=front,
                                            clear_depth=clear)
                    naive, bvh = _naive_and_bvh(scene, cam, width, height, state)
                    assert bvh.stats["ray_walk"] == walk
                    _assert_same_hits(naive, bvh)
                    if cull == "none" and clear == 1.0:  # ties were there to decide
                        tied = bvh.face_id >= len(mesh.faces)
                        assert tied.any() == (func == "lequal")


def test_bvh_ray_caster_switching_walk_ranks_hits_as_the_naive_loop():
    """A scene above INTERLEAVE_BYTES (a 60k-face terrain, half its faces repeated and
    half of those reversed: 120k faces) walks its rays eight in turn, switching between
    them (a grazing view: rays cross leaves they do not hit first), with the render
    state's ranking carried across each switch: the same hits as
    the naive loop under culling, both depth functions and both windings (the repeated
    faces tie exactly; submission order decides)."""
    from hsr.algorithms.bvh.walk import INTERLEAVE_BYTES

    mesh = scenes.terrain_mesh(60_000)
    n = len(mesh.faces)
    scene = hsr.Mesh(mesh.positions, np.concatenate(
        [mesh.faces, mesh.faces[::2], mesh.faces[1::2, ::-1]]))
    bvh = hsr.RayScene(scene).bvh  # the tree the ray caster builds
    assert bvh.corners.nbytes + bvh.node_box.nbytes > INTERLEAVE_BYTES
    # Grazing: rays cross boxes and leaves they do not hit before the ones they do.
    cam = hsr.Camera.frame(mesh.bounds(), direction=(1.0, 0.12, 0.3))
    for cull in ("none", "back"):
        for func in ("less", "lequal"):
            for front in ("ccw", "cw"):
                state = hsr.RenderState(cull=cull, depth_func=func, front_face=front)
                naive, fast = _naive_and_bvh(scene, cam, 16, 12, state)
                assert fast.stats["ray_walk"] == "interleaved"
                _assert_same_hits(naive, fast)
                if cull == "none":
                    assert (fast.face_id >= n).any() == (func == "lequal")


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 60),
       cull=st.sampled_from(["none", "back", "front", "front_and_back"]),
       func=st.sampled_from(["less", "lequal"]), front=st.sampled_from(["ccw", "cw"]),
       width=st.integers(1, 48), height=st.integers(1, 48))
def test_bvh_ray_caster_equals_the_naive_loop_on_random_soups(seed, n, cull, func, front,
                                                              width, height):
    """Random soups (a third of the triangles repeated, some in one plane facing the
    camera: ties), random views and states, images from 1x1 (each walk's part-full
    packet or round) to wider than the faces (packets) and smaller (interleaved)."""
    rng = np.random.default_rng(seed)
    corners = rng.uniform(-1, 1, size=(n, 3, 3))
    corners[rng.random(n) < 0.3, :, 2] = 0.25
    corners = np.concatenate([corners, corners[rng.random(n) < 0.35]])
    scene = hsr.Mesh(corners.reshape(-1, 3), np.arange(3 * len(corners)).reshape(-1, 3))
    direction = rng.normal(size=3)
    direction[2] = abs(direction[2]) + 0.3
    cam = hsr.Camera.frame(scene.bounds(), direction=direction)
    state = hsr.RenderState(cull=cull, depth_func=func, front_face=front)
    naive, bvh = _naive_and_bvh(scene, cam, width, height, state)
    _assert_same_hits(naive, bvh)


@njit  # not cached: a cache would not see a change to the inlined _t_bound
def _bound_misses(rank, o, d, ts):
    """Per hit parameter t of the ray o + t d: -1 if the ray caster's bound on it
    (_t_bound) holds, else 0 (the bound is before t) or 1 (just past the bound the
    float32 window depth is as near as the hit's: a hit there could rank first but
    would be pruned); and the bounds."""
    zc0, zc1, wc0, wc1 = _clip_zw(rank, o[0], o[1], o[2], d[0], d[1], d[2])
    out, bounds = np.full(len(ts), -1), np.empty(len(ts))
    for i in range(len(ts)):
        t = ts[i]
        z = _depth32(t, zc0, zc1, wc0, wc1, rank[8], rank[9])
        bound = _t_bound(t, z, zc0, zc1, wc0, wc1, rank)
        bounds[i] = bound
        past = np.nextafter(bound, np.inf)
        if bound < t:
            out[i] = 0
        elif past <= 1.0 and not _depth32(past, zc0, zc1, wc0, wc1, rank[8], rank[9]) > z:
            out[i] = 1
    return out, bounds


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), ratio=st.sampled_from([1.01, 2.0, 30.0, 120.0, 1e4,
                                                               1e7]),
       ortho=st.booleans(), depth_range=st.sampled_from([(0.0, 1.0), (0.2, 0.7), (0.0, 1e-3),
                                                         (0.999, 1.0)]))
def test_ray_caster_bound_keeps_every_hit_that_could_rank_first(seed, ratio, ortho,
                                                                depth_range):
    """The ray caster prunes a pixel ray's walk past the bound of its best hit
    (hsr.algorithms.bvh.ranking.t_bound): no point past it may have a float32 window depth
    as near as the hit's (a tie, which submission order decides, or nearer). Checked
    with the walk's own depth arithmetic on the rays the ray caster makes, for hits
    all along random pixel rays, with far / near from 1.01 to 1e7 (the rays' tie reach
    where it is small enough, else solving at each hit), perspective and orthographic,
    and depth ranges wide and narrow. Where the reach is used the bound stays within
    REACH_MAX of the hit (it prunes)."""
    from hsr.algorithms.bvh.ranking import REACH_MAX, window_ranking
    from hsr.algorithms.raycast import row_rays

    rng = np.random.default_rng(seed)
    near = float(rng.uniform(0.01, 2.0))
    direction = rng.normal(size=3)
    cam = hsr.Camera(eye=tuple(rng.uniform(-3, 3, 3)), target=tuple(rng.uniform(-3, 3, 3)
                                                                     + direction),
                     up=(0, 1, 0) if abs(direction[1]) < 0.9 * np.linalg.norm(direction)
                     else (1, 0, 0), fov_y=float(rng.uniform(10, 120)), near=near,
                     far=near * ratio, ortho_height=2.0 if ortho else None)
    width, height = int(rng.integers(1, 50)), int(rng.integers(1, 50))
    view_proj = cam.projection_matrix(width / height) @ cam.view_matrix
    rank = window_ranking(view_proj, depth_range)
    reach = rank[10]
    if depth_range == (0.0, 1.0) and (ratio <= 30 or ortho):
        assert reach == reach  # the reach is what the ray caster's usual views use
    rays = np.empty((6, width))
    inverse = np.linalg.inv(view_proj)
    # Perspective rays run from the eye, the near plane at t = near / far.
    t_near = 0.0 if ortho else near / cam.far
    ts = t_near + (1.0 - t_near) * np.concatenate([rng.uniform(0, 1, 200),
                                                   rng.uniform(0, 1, 50) ** 8, [0.0, 1.0]])
    eye = np.asarray(cam.eye, dtype=np.float64)
    for _ in range(20):
        r, c = int(rng.integers(0, height)), int(rng.integers(0, width))
        row_rays(inverse, width, height, r, c, c + 1, eye, not ortho, rays)
        misses, bounds = _bound_misses(rank, rays[:3, 0].copy(), rays[3:, 0].copy(), ts)
        assert (misses < 0).all(), (ts[misses >= 0][:3], misses[misses >= 0][:3])
        if reach == reach:
            assert (bounds - ts <= 1.01 * REACH_MAX).all()


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"),
                    reason="reads x86 assembly")
@pytest.mark.parametrize("from_eye", [True, False])
def test_ray_caster_makes_its_rays_in_vector_lanes(from_eye):
    """The ray caster's rays are made a row at a time by a loop LLVM turns into vector
    code (packed divisions, ``divpd``); a branch inside the loop once left it scalar.
    Compiled afresh here (cached code cannot be inspected)."""
    from hsr.algorithms.raycast import row_rays

    fresh = njit(error_model="numpy")(row_rays.py_func)
    rays = np.empty((6, 64))
    fresh(np.eye(4), 64, 64, 3, 0, 64, np.zeros(3), from_eye, rays)
    asm = "\n".join(fresh.inspect_asm().values())
    assert "divpd" in asm


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 80),
       inside=st.booleans(), ortho=st.booleans(), shift=st.floats(-1.5, 1.5),
       width=st.integers(1, 40), height=st.integers(1, 40))
def test_ray_caster_skips_only_pixels_no_face_projects_to(seed, n, inside, ortho, shift,
                                                          width, height):
    """The BVH ray caster casts rays only where the screen rectangles of its top boxes
    reach (``stats["rays_cast"]``); the naive loop casts every pixel's. Views that test
    the rectangles: the eye among the triangles (boxes across the eye plane, or behind
    it), the soup shifted part way out of the image, orthographic cameras, far and
    near planes that cut the soup. Same hits everywhere."""
    rng = np.random.default_rng(seed)
    corners = rng.uniform(-1, 1, size=(n, 3, 3)) * rng.uniform(0.05, 1.0, size=(n, 1, 1))
    corners += rng.uniform(-1, 1, size=(n, 1, 3))
    scene = hsr.Mesh(corners.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    direction = rng.normal(size=3) + (0, 0, 1e-3)
    up = (0, 1, 0) if abs(direction[1]) < 0.9 * np.linalg.norm(direction) else (1, 0, 0)
    right = np.cross(direction, up)
    target = rng.uniform(-0.5, 0.5, size=3) + shift * right / np.linalg.norm(right)
    distance = rng.uniform(0.05, 0.8) if inside else rng.uniform(2.5, 5.0)
    eye = target + distance * direction / np.linalg.norm(direction)
    cam = hsr.Camera(eye=tuple(eye), target=tuple(target), up=up,
                     fov_y=float(rng.uniform(20, 120)), near=float(rng.uniform(0.01, 1.0)),
                     far=float(rng.uniform(2.0, 8.0)),
                     ortho_height=float(rng.uniform(0.5, 3.0)) if ortho else None)
    naive, bvh = _naive_and_bvh(scene, cam, width, height, hsr.RenderState())
    _assert_same_hits(naive, bvh)
    assert naive.stats["rays_cast"] == width * height
    assert bvh.stats["rays_cast"] >= np.count_nonzero(bvh.face_id >= 0)


@pytest.mark.parametrize("width, height, n", [(2101, 5, 60), (37, 29, 400), (7, 1, 300),
                                             (96, 64, 30_000)])
def test_ray_caster_pixels_land_where_the_reference_sees_them(width, height, n):
    """The ray caster makes its rays a block of rows at a time, only within each row's
    span (odd sizes, an image wider than a block of rays, a one-row image) and writes
    each answer back to its pixel: face ids and depths equal the brute-force
    reference's, on both walks (packets; interleaved at 30k faces in 6k pixels), with
    the soup partly out of view. (Checked to fail with one column's answers written a
    pixel to the right.)"""
    rng = np.random.default_rng(width * height + n)
    corners = rng.uniform(-1, 1, size=(n, 3, 3)) * rng.uniform(0.05, 0.6, size=(n, 1, 1))
    corners += rng.uniform(-1.2, 1.2, size=(n, 1, 3)) * (1.0, 1.0, 0.3)
    scene = hsr.Mesh(corners.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    cam = hsr.Camera(eye=(0.3, -0.2, 4.0), target=(0.3, -0.2, 0.0), up=(0, 1, 0), fov_y=40,
                     near=1.0, far=8.0)
    frame = hsr.render(scene, cam, width, height, algorithm="raycast")
    assert frame.stats["ray_walk"] == ("interleaved" if n > 5 * width * height else "packets")
    ref_face, ref_depth = reference_render(scene, cam, width, height)
    amb = ambiguous_pixels(scene, cam, width, height)
    bad_face, bad_depth, compared = compare(frame.face_id, frame.depth, ref_face, ref_depth,
                                            amb)
    assert (bad_face, bad_depth) == (0, 0) and compared >= 0.75 * width * height
    assert 0 < np.count_nonzero(frame.face_id >= 0) < width * height  # hits and misses


def test_ray_caster_casts_no_ray_where_the_model_cannot_be():
    """A model seen edge-on covers a strip of the image, and a camera turned away sees
    nothing: the ray caster casts rays for a strip a little wider than the model's
    (the BVH's top boxes), none for the turned camera, and gets the naive loop's hits."""
    scene, _ = scenes.terrain(20_000)
    mesh = scene.instances[0].mesh
    cam = hsr.Camera.frame(mesh.bounds())  # edge-on: the terrain is a thin slab
    naive, bvh = _naive_and_bvh(mesh, cam, 96, 96, hsr.RenderState())
    _assert_same_hits(naive, bvh)
    covered = np.count_nonzero(bvh.face_id >= 0)
    assert covered > 200 and bvh.stats["rays_cast"] < 0.4 * 96 * 96
    away = hsr.Camera(eye=cam.eye, target=tuple(2 * np.asarray(cam.eye) - np.asarray(
        cam.target)), up=cam.up, fov_y=45)
    frame = hsr.render(mesh, away, 96, 96, algorithm="raycast")
    assert frame.stats["rays_cast"] == 0 and (frame.face_id == -1).all()
    assert (frame.depth == 1.0).all()
    # A floor running from behind the eye to the horizon: its box lies across the eye
    # plane, and the floor fills the bottom rows, which the box's corners in front of
    # the eye project nowhere near.
    floor = hsr.Mesh([[-50, 0, 50], [50, 0, 50], [50, 0, -50], [-50, 0, -50]],
                     [[0, 1, 2], [0, 2, 3]])
    low = hsr.Camera(eye=(0, 1, 0), target=(0, 0.8, -1), up=(0, 1, 0), fov_y=60, near=0.1,
                     far=200)
    naive, bvh = _naive_and_bvh(floor, low, 40, 30, hsr.RenderState())
    _assert_same_hits(naive, bvh)
    assert (bvh.face_id[-1] >= 0).all()


def test_naive_ray_casting_refuses_huge_jobs():
    scene, cam = scenes.terrain(100_000)
    with pytest.raises(hsr.RenderError, match="accel='bvh'"):
        hsr.render(scene, cam, 640, 480, algorithm="raycast", options={"accel": "none"})


def test_ray_distance_and_barycentrics():
    """A triangle facing the camera at distance 5: distance 5 at the centre, barycentrics
    equal to the reference's."""
    mesh = hsr.Mesh(np.array([[-2, -2, -5], [2, -2, -5], [0, 2, -5.0]]), np.array([[0, 1, 2]]))
    cam = hsr.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y=60, near=1, far=10)
    frame = hsr.render(mesh, cam, 64, 64, algorithm="raycast", options={"buffers": True})
    dist = frame.fragments.buffers["distance"]
    offset = (0.5 / 32) * np.tan(np.radians(30))  # pixel centre (32.5, 32.5) off the axis
    assert abs(dist[32, 32] - 5.0 * np.sqrt(1.0 + 2.0 * offset**2)) < 1e-9
    _, _, ref_bary = reference_render(mesh, cam, 64, 64, with_barycentrics=True)
    covered = frame.face_id >= 0
    assert np.abs(frame.fragments.buffers["barycentrics"][covered] - ref_bary[covered]).max() < 1e-9


def _tree_shape(bvh):
    """The tree as the nested (start, count, box) of its nodes, depth first, whatever
    their numbering; every node must be reached exactly once from the root."""
    seen = np.zeros(bvh.n_nodes, dtype=int)
    shape, stack = [], [0]
    while stack:
        node = stack.pop()
        seen[node] += 1
        shape.append((bvh.node_start[node], bvh.node_count[node],
                      *bvh.node_min[node], *bvh.node_max[node]))
        if bvh.node_left[node] >= 0:
            stack += [bvh.node_left[node] + 1, bvh.node_left[node]]
    assert (seen == 1).all()  # no node twice, none unreachable (no gap left in the arrays)
    return shape


def _leaf_groups(first, count):
    """The four-slot groups the leaf test reads for leaves of ``count`` slots from slot
    ``first`` in blocks (from the block of the first slot to that of the last)."""
    return (first + count - 1) // layout.QUAD - first // layout.QUAD + 1


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(-1, 8), min_size=1, max_size=60), st.randoms(use_true_random=False))
def test_packed_leaves_take_the_fewest_blocks(lanes, rnd):
    """pack_leaves on wide records whose lanes hold leaves of 1 .. 8 slots (in runs of
    slots in a shuffled order, as a collapse leaves them), wide nodes (0) and empty lanes
    (-1): each leaf keeps its slots together, in ceil(count / 4) groups, no two slots
    meet, the wide and empty lanes are left as they were, and the blocks are no more
    than the leaves' own."""
    n_wide = -(-len(lanes) // layout.LANES)
    _, link = layout.node_records(n_wide)
    link[:, layout.REF:layout.COUNT_AT], link[:, layout.COUNT_AT:] = 0, -1
    leaves = [i for i, c in enumerate(lanes) if c > 0]
    rnd.shuffle(leaves)
    slot = 0
    for i, c in enumerate(lanes):
        w, lane = divmod(i, layout.LANES)
        link[w, layout.COUNT_AT + lane] = max(c, -1)
        link[w, layout.REF + lane] = rnd.randrange(n_wide) if c == 0 else 0
    for i in leaves:
        w, lane = divmod(i, layout.LANES)
        link[w, layout.REF + lane] = slot
        slot += lanes[i]
    before = link.copy()
    moved, n = layout.pack_leaves(link)
    assert len(moved) == slot and n % layout.QUAD == 0
    assert len(np.unique(moved)) == slot and (moved >= 0).all() and (moved < n).all()
    refs, counts = link[:, layout.REF:layout.COUNT_AT], link[:, layout.COUNT_AT:]
    assert np.array_equal(counts, before[:, layout.COUNT_AT:])
    leaf = counts > 0
    assert np.array_equal(refs[~leaf], before[:, layout.REF:layout.COUNT_AT][~leaf])
    for old, new, c in zip(before[:, layout.REF:layout.COUNT_AT][leaf], refs[leaf], counts[leaf]):
        assert np.array_equal(moved[old:old + c], np.arange(new, new + c))
    first, count = refs[leaf], counts[leaf]
    assert np.array_equal(_leaf_groups(first, count), -(-count // layout.QUAD))
    assert n // layout.QUAD <= (-(-count // layout.QUAD)).sum()


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_bvh_invariants(models_dir, threads):
    """cow: 5,804 faces, so with 2 or 3 threads the subtrees below the top are built in
    parallel and their nodes renumbered; the tree must be the one thread's."""
    mesh = hsr.load(os.path.join(models_dir, "cow.obj"))
    bvh = build_keeping_tree(mesh, threads=threads)
    assert _tree_shape(bvh) == _tree_shape(build_keeping_tree(mesh, threads=1))
    leaves = bvh.node_left < 0
    assert leaves.sum() * 2 - 1 == bvh.n_nodes
    # Every non-degenerate triangle in exactly one leaf.
    in_leaves = np.concatenate([bvh.tri_index[s:s + c] for s, c in
                                zip(bvh.node_start[leaves], bvh.node_count[leaves])])
    held = bvh.tri_index[bvh.tri_index >= 0]  # (the rest: padding of packed blocks)
    assert np.array_equal(np.sort(in_leaves), np.sort(held))
    assert len(np.unique(held)) == len(held) == mesh.n_faces - int(mesh.degenerate_mask().sum())
    # Boxes contain their children and their triangles.
    for node in np.flatnonzero(~leaves):
        for child in (bvh.node_left[node], bvh.node_left[node] + 1):
            assert (bvh.node_min[child] >= bvh.node_min[node]).all()
            assert (bvh.node_max[child] <= bvh.node_max[node]).all()
    for node in np.flatnonzero(leaves):
        slots = slice(bvh.node_start[node], bvh.node_start[node] + bvh.node_count[node])
        tris = layout.slot_corners(bvh.corners, np.arange(len(bvh.tri_index))[slots])
        assert np.array_equal(tris, mesh.positions[mesh.faces[bvh.tri_index[slots]]])
        assert (tris >= bvh.node_min[node]).all() and (tris <= bvh.node_max[node]).all()
        # Tight: the float32 box of the triangles, rounded outwards (the build's boxes
        # come from its bins, not from a pass over the triangles).
        assert np.array_equal(bvh.node_min[node], outwards32(tris.reshape(-1, 3).min(0),
                                                             -np.inf))
        assert np.array_equal(bvh.node_max[node], outwards32(tris.reshape(-1, 3).max(0),
                                                             np.inf))
    for node in np.flatnonzero(~leaves):
        kids = [bvh.node_left[node], bvh.node_left[node] + 1]
        assert np.array_equal(bvh.node_min[node], bvh.node_min[kids].min(0))
        assert np.array_equal(bvh.node_max[node], bvh.node_max[kids].max(0))
    # Built on several threads (whose subtrees leave node numbers unused between them),
    # the walked tree is the one thread's.
    walked = sah.build(mesh, threads=1)
    assert walked.root_ref == bvh.root_ref
    assert np.array_equal(walked.node_box[:, :layout.REF], bvh.node_box[:, :layout.REF])
    assert np.array_equal(walked.node_link, bvh.node_link)
    assert np.array_equal(walked.corners, bvh.corners)
    # The walked 4-wide tree's leaves hold every slot once.
    link = bvh.node_link[:, layout.REF:]
    refs, counts = link[:, :layout.LANES], link[:, layout.LANES:]
    slots = np.concatenate([np.arange(r, r + c) for r, c in zip(refs[counts > 0],
                                                                counts[counts > 0])])
    assert np.array_equal(np.sort(slots), np.flatnonzero(bvh.tri_index >= 0))
    # In blocks, each leaf is read in the fewest four-slot groups (pack_leaves).
    assert bvh.corners.shape[1] == layout.BLOCK_VALUES
    first, count = refs[counts > 0], counts[counts > 0]
    assert np.array_equal(_leaf_groups(first, count), -(-count // layout.QUAD))


def test_bvh_reused_across_views(models_dir):
    mesh = hsr.load(os.path.join(models_dir, "cow.obj"))
    bvh = sah.build(mesh)
    for direction in ((0, 0, 1), (1, 0, 0), (0, 1, 0.1)):
        cam = hsr.Camera.frame(mesh.bounds(), direction=direction)
        a = hsr.render(mesh, cam, 80, 60, algorithm="raycast", options={"bvh": bvh})
        b = hsr.render(mesh, cam, 80, 60, algorithm="raycast")
        assert np.array_equal(a.face_id, b.face_id)
    with pytest.raises(hsr.RenderError, match="another scene"):
        hsr.render(scenes.cube(), cam, 8, 8, algorithm="raycast", options={"bvh": bvh})


@pytest.mark.parametrize("algorithm", ["zbuffer", "scanline", "raycast"])
def test_lequal_state(algorithm):
    scene, cam = small_scene("cubes")
    frame = hsr.render(scene, cam, W, H, algorithm=algorithm, depth_func="lequal")
    ref_face, ref_depth = reference_render(scene, cam, W, H, depth_func="lequal")
    amb = ambiguous_pixels(scene, cam, W, H)
    assert compare(frame.face_id, frame.depth, ref_face, ref_depth, amb)[:2] == (0, 0)


def test_deep_unbalanced_bvh_walks_like_the_naive_loop():
    """Triangles at x = 2^k: the binned SAH peels a few off per level, so the tree is far
    deeper than a balanced one (its depth sizes the walk's stack): 8-wide, a balanced
    tree of 480 faces would be about log8(480) ~ 3 levels deep."""
    n = 480
    x = 2.0 ** (np.arange(n) - 200.0)
    z = -1.0 - 0.001 * np.arange(n)
    one = np.ones(n)
    corners = np.stack([np.stack([x, -one, z], 1), np.stack([1.5 * x, -one, z], 1),
                        np.stack([x, one, z], 1)], 1)
    mesh = hsr.Mesh(corners.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    bvh = sah.build(mesh)
    assert bvh.wide_depth > 3 * np.log(n) / np.log(layout.LANES)
    seen = set()
    for eye_x in (1e-3, 0.3, 40.0, 300.0):
        cam = hsr.Camera(eye=(eye_x, 0, 2), target=(eye_x, 0, -1), up=(0, 1, 0), fov_y=60,
                         near=0.1, far=100)
        a = hsr.render(mesh, cam, 64, 48, algorithm="raycast", options={"bvh": bvh})
        b = hsr.render(mesh, cam, 64, 48, algorithm="raycast", options={"accel": "none"})
        assert np.array_equal(a.face_id, b.face_id) and np.array_equal(a.depth, b.depth)
        seen |= set(np.unique(a.face_id).tolist())
    assert len(seen) > 4


def test_deep_unbalanced_bvh_built_in_parallel_is_the_same_tree():
    """5,000 triangles at x = 2^k/8 ... (a tree far deeper than balanced, as in the test
    above, but large enough for the parallel build): the subtrees built on two and
    three threads, renumbered and closed up, make the one thread's tree, and the ray
    caster walks it like the naive loop."""
    n = 5000
    x = 2.0 ** (np.arange(n) / 8.0 - 300.0)
    z = -1.0 - 1e-4 * np.arange(n)
    one = np.ones(n)
    corners = np.stack([np.stack([x, -one, z], 1), np.stack([1.5 * x, -one, z], 1),
                        np.stack([x, one, z], 1)], 1)
    mesh = hsr.Mesh(corners.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    one_thread = _tree_shape(build_keeping_tree(mesh, threads=1))
    for threads in (2, 3):
        bvh = build_keeping_tree(mesh, threads=threads)
        assert _tree_shape(bvh) == one_thread
    assert bvh.wide_depth > 2 * np.log(n) / np.log(4)
    cam = hsr.Camera(eye=(1e-3, 0, 2), target=(1e-3, 0, -1), up=(0, 1, 0), fov_y=60,
                     near=0.1, far=100)
    a = hsr.render(mesh, cam, 48, 32, algorithm="raycast", options={"bvh": bvh.bvh})
    b = hsr.render(mesh, cam, 48, 32, algorithm="raycast", options={"accel": "none"})
    assert np.array_equal(a.face_id, b.face_id) and np.array_equal(a.depth, b.depth)
    assert (a.face_id >= 0).mean() > 0.2


def _box_area(lo, hi):
    d = np.asarray(hi, dtype=np.float64) - np.asarray(lo, dtype=np.float64)
    return d[0] * d[1] + d[1] * d[2] + d[2] * d[0]


def _least_collapse_cost(bvh):
    """Brute force: over every way of collapsing the binary tree into nodes of at most
    LANES children (each inner node but the root a wide node, merged into the wide node
    above it, or, of at most LEAF_MAX triangles, one leaf of them all), the least cost
    C_NODE x (area of each wide node below the root) + C_LEAF_TRIANGLE x (area x
    triangles of each leaf). Exponential: small trees only."""
    inner = [b for b in range(1, bvh.n_nodes) if bvh.node_left[b] >= 0]
    area = {b: _box_area(bvh.node_min[b], bvh.node_max[b]) for b in range(bvh.n_nodes)}

    def lanes(b, kind):  # the lanes of the wide node made at b, and the leaves' cost
        count, leaves, stack = 0, 0.0, [bvh.node_left[b], bvh.node_left[b] + 1]
        while stack:
            c = stack.pop()
            if bvh.node_left[c] < 0 or kind[c] == "leaf":
                count += 1
                leaves += collapse.C_LEAF_TRIANGLE * area[c] * bvh.node_count[c]
            elif kind[c] == "wide":
                count += 1
            else:
                stack += [bvh.node_left[c], bvh.node_left[c] + 1]
        return count, leaves

    best = np.inf
    options = [("wide", "merged", "leaf") if bvh.node_count[b] <= collapse.LEAF_MAX
               else ("wide", "merged") for b in inner]
    for kinds in itertools.product(*options):
        kind = dict(zip(inner, kinds))
        total, fits = 0.0, True
        for b in [0] + [b for b in inner if kind[b] == "wide"]:
            count, leaves = lanes(b, kind)
            fits &= count <= layout.LANES
            total += leaves + (collapse.C_NODE * area[b] if b != 0 else 0.0)
        if fits:
            best = min(best, total)
    return best


@pytest.mark.parametrize("seed", range(6))
def test_wide_tree_is_the_least_cost_collapse_of_the_binary_tree(seed):
    """The 8-wide tree the walks read (widen, by the dynamic programme of
    _collapse_plan) is a collapse of the binary tree (each lane a binary node's box,
    no node more than LANES lanes, every slot in one leaf) of the least cost by the
    surface area heuristic, found here by trying every collapse of small trees."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(24, 34))
    # A strip of small triangles: a tree of some ten leaves.
    base = np.stack([np.linspace(0, 20, n), rng.normal(size=n) * 0.3, -5 + rng.normal(
        size=n) * 0.3], 1)
    corners = base[:, None, :] + rng.normal(size=(n, 3, 3)) * 0.2
    mesh = hsr.Mesh(corners.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    bvh = build_keeping_tree(mesh, threads=1)
    if int((bvh.node_left >= 0).sum()) > 11:
        pytest.skip("tree too large to try every collapse")
    boxes = {tuple(np.r_[bvh.node_min[b], bvh.node_max[b]]): b for b in range(bvh.n_nodes)}
    total, slots, stack = 0.0, [], [bvh.root_ref]
    while stack:
        w = stack.pop()
        box, link = bvh.node_box[w], bvh.node_link[w]
        for lane in range(layout.LANES):
            count = link[layout.COUNT_AT + lane]
            if count < 0:
                continue
            lo = box[lane:3 * layout.LANES:layout.LANES]
            hi = box[3 * layout.LANES + lane:6 * layout.LANES:layout.LANES]
            b = boxes[tuple(np.r_[lo, hi])]  # a binary node's box
            if count == 0:
                total += collapse.C_NODE * _box_area(lo, hi)
                stack.append(link[layout.REF + lane])
            else:
                # A leaf: the binary node's slots, all of them.
                assert (link[layout.REF + lane], count) == (bvh.node_start[b], bvh.node_count[b])
                assert count <= max(collapse.LEAF_MAX, sah.LEAF_SIZE)
                total += collapse.C_LEAF_TRIANGLE * _box_area(lo, hi) * count
                slots += range(link[layout.REF + lane], link[layout.REF + lane] + count)
    assert sorted(slots) == list(np.flatnonzero(bvh.tri_index >= 0))
    assert total <= _least_collapse_cost(bvh) * (1 + 1e-6)


@pytest.mark.parametrize("copies", [5, 6, 8])
def test_few_overlapping_faces_make_a_wide_root_of_their_leaves(copies):
    """A mesh of a few copies of one triangle: the binary root splits them in two (more
    than LEAF_SIZE), and a single leaf of them all would cost less than any split
    (the boxes coincide), but the root of the walked tree is a wide node: it takes the
    best split into eight lanes, not the plan's one-lane choice (which once stood for
    it: the first child got no lanes, right only because lane count 0 read the plan's
    last column). Every slot in one leaf, and the walks answer as the naive loop."""
    tri = np.array([[0.0, 0.0, -5.0], [1.0, 0.0, -5.0], [0.0, 1.0, -5.0]])
    mesh = hsr.Mesh(np.concatenate([tri] * copies), np.arange(3 * copies).reshape(-1, 3))
    bvh = build_keeping_tree(mesh, threads=1)
    assert bvh.node_left[0] >= 0 and bvh.root_count == 0
    _, _, choice, split = collapse._collapse_plan(
        bvh.node_min.astype(np.float64), bvh.node_max.astype(np.float64),
        bvh.node_left.astype(np.int64), bvh.node_count.astype(np.int64))
    assert choice[0, layout.LANES - 1] == -1 and 1 <= split[0] < layout.LANES
    link = bvh.node_link[:, layout.REF:]
    refs, counts = link[:, :layout.LANES], link[:, layout.LANES:]
    slots = np.concatenate([np.arange(r, r + c) for r, c in zip(refs[counts > 0],
                                                                counts[counts > 0])])
    assert np.array_equal(np.sort(slots), np.flatnonzero(bvh.tri_index >= 0))
    assert len(slots) == copies
    cam = hsr.Camera(eye=(0.25, 0.25, -4.0), target=(0.25, 0.25, -5.0), up=(0, 1, 0),
                     fov_y=60, near=0.1, far=100)
    for depth_func in ("less", "lequal"):  # ties: the first face, or the last
        a = hsr.render(mesh, cam, 32, 24, algorithm="raycast", options={"bvh": bvh.bvh},
                       depth_func=depth_func)
        b = hsr.render(mesh, cam, 32, 24, algorithm="raycast", options={"accel": "none"},
                       depth_func=depth_func)
        assert np.array_equal(a.face_id, b.face_id) and (a.face_id >= 0).sum() > 100


def test_wide_tree_fills_its_nodes():
    """A height field's tree: the collapse of least cost fills the wide nodes (the
    greedy one, expanding the largest child while a node had room, left the bottom
    nodes about half empty: 4.2 lanes a node on the 1M-face terrain, 89,713 nodes;
    32,906 now, 7.7 lanes a node)."""
    n = 200
    xs, ys = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0))
    heights = np.sin(xs * 0.1) * np.cos(ys * 0.13)
    positions = np.stack([xs.ravel(), ys.ravel(), heights.ravel()], 1)
    k = np.arange(n * (n + 1)).reshape(n, n + 1)[:, :n].ravel()
    faces = np.concatenate([np.stack([k, k + 1, k + n + 2], 1),
                            np.stack([k, k + n + 2, k + n + 1], 1)])
    bvh = sah.build(hsr.Mesh(positions, faces))
    counts = bvh.node_link[:, layout.COUNT_AT:]
    assert (counts >= 0).sum() / bvh.n_wide_nodes > 6.5


def test_wide_boxes_round_outwards_as_numpy_does():
    """The wide tree's float32 bounds step to the next float32 by the bits
    (hsr.algorithms.simd.next_float32, not libm's nextafter): the same steps as NumPy's
    nextafter from zero, subnormals, the largest float32 and the infinities, both ways;
    and the rounding of float64 bounds it serves is outwards32's (tests/bvh_tree.py)."""
    from numba import njit

    from hsr.algorithms.bvh.layout import down32 as _down32
    from hsr.algorithms.bvh.layout import up32 as _up32
    from hsr.algorithms.simd import next_float32

    @njit
    def steps(xs, up):
        return np.array([next_float32(x, up) for x in xs], dtype=np.float32)

    @njit
    def rounded(values):
        return (np.array([_down32(v) for v in values], dtype=np.float32),
                np.array([_up32(v) for v in values], dtype=np.float32))

    rng = np.random.default_rng(9)
    tiny = np.float32(1e-45)
    xs = np.concatenate([
        np.array([0.0, -0.0, tiny, -tiny, 1e-40, -1e-40, 1.0, -1.0, 2.0, -2.0,
                  np.finfo(np.float32).max, -np.finfo(np.float32).max, np.inf, -np.inf],
                 dtype=np.float32),
        (rng.normal(size=5000) * 10.0 ** rng.integers(-45, 38, 5000)).astype(np.float32)])
    for up in (True, False):
        with np.errstate(over="ignore"):
            want = np.nextafter(xs, np.full_like(xs, np.inf if up else -np.inf))
        got = steps(xs, up)
        assert np.array_equal(got, want) and np.array_equal(np.signbit(got), np.signbit(want))
    values = np.concatenate([rng.normal(size=5000) * 10.0 ** rng.integers(-50, 50, 5000),
                             [0.0, -0.0, 1e300, -1e300, 1e-300, -1e-300, 0.1, 2.0 ** 127]])
    down, up = rounded(values)
    assert np.array_equal(down, outwards32(values, -np.inf))
    assert np.array_equal(up, outwards32(values, np.inf))


def test_binary_boxes_kept_in_float32_hold_what_they_bound():
    """The tests keep the binary boxes in float32 rounded outwards (bvh_tree.outwards32,
    the reference of the wide boxes' rounding): every value, from tiny to beyond
    float32's range, lies inside its rounding, which is the nearest float32 on that
    side (NumPy's float32 neighbours as the reference)."""
    rng = np.random.default_rng(8)
    values = np.concatenate([rng.normal(size=2000) * 10.0 ** rng.integers(-50, 50, 2000),
                             [0.0, -0.0, 1e300, -1e300, 1e-300, -1e-300, 0.1, 2.0 ** 127]])
    down, up = outwards32(values, -np.inf), outwards32(values, np.inf)
    assert down.dtype == up.dtype == np.float32
    assert (down.astype(np.float64) <= values).all() and (up.astype(np.float64) >= values).all()
    exact = down.astype(np.float64) == values
    assert (down[exact] == up[exact]).all()
    # Otherwise one float32 step apart: nothing float32 lies between.
    with np.errstate(over="ignore"):  # the step above the largest float32 is inf
        assert (np.nextafter(down[~exact], np.float32(np.inf)) == up[~exact]).all()


def test_bvh_refuses_faces_changed_to_index_past_the_vertices():
    """The build's passes gather corners without bounds checks: a mesh whose faces were
    changed after it was made (to a vertex that is not there, or a negative one) is
    refused with a MeshError, not read out of bounds."""
    for bad in (3, -1):
        mesh = hsr.Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
        mesh.faces[0, 2] = bad
        with pytest.raises(hsr.MeshError, match="indexes a vertex"):
            sah.build(mesh)
        with pytest.raises(hsr.MeshError, match="indexes a vertex"):
            hsr.RayScene(mesh)
