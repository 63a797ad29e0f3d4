"""The z-buffer's streamed path: faces classified, culled and set up chunk by chunk
straight from clip space, then filled. Checked against the ray reference with chunk sizes
that put the pieces of clipped faces in many chunks, and against filling the prepared
screen triangles (same face ids, same depth bits, same counts)."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_zbuffer_reference import check, small_scene

import hsr
from hsr import scenes
from hsr.algorithms import zbuffer
from hsr.geometry.stage import CULLED, prepare, status_counts
from hsr.geometry.state import RenderState
from hsr.parallel import release_default_workspace
from hsr.scene.mesh import as_scene

W, H = 96, 72


@pytest.fixture(params=[1, 7, 1 << 16], ids=["chunk1", "chunk7", "chunk64k"])
def chunk(request, monkeypatch):
    monkeypatch.setattr(zbuffer, "STREAM_CHUNK", request.param)
    return request.param


def inside_cubes():
    scene, _ = small_scene("cubes")
    cam = hsr.Camera.look_at(eye=(-1.5, 0.2, -6.6), target=(1.0, 0.5, -10.0), fov_y=80,
                             near=0.2, far=30.0)
    return scene, cam


def soup(seed=3, n=120):
    """Random triangles around and behind the eye, some degenerate: every status at once."""
    rng = np.random.default_rng(seed)
    verts = rng.uniform(-4.0, 4.0, size=(3 * n, 3)) + np.array([0.0, 0.0, -3.0])
    faces = np.arange(3 * n).reshape(n, 3)
    faces[::17, 2] = faces[::17, 1]  # repeated index
    verts[faces[5::19, 2]] = verts[faces[5::19, 0]]  # zero area
    cam = hsr.Camera.look_at(eye=(0, 0, 0), target=(0, 0, -1), fov_y=70, near=0.5, far=9.0)
    return hsr.Mesh(verts, faces), cam


def test_streamed_path_is_taken():
    scene, cam = small_scene("cubes")
    screen = prepare(as_scene(scene), np.eye(4), W, H, RenderState(), {}, deferred=True)
    assert screen.pending
    frame = hsr.render(scene, cam, W, H)
    assert frame.fragments.screen.pending  # nothing asked for window-space triangles


@pytest.mark.parametrize("scene_name", ["inside-cubes", "soup", "city"])
def test_clipped_faces_across_chunks_match_the_reference(chunk, scene_name):
    if scene_name == "inside-cubes":
        scene, cam = inside_cubes()
    elif scene_name == "soup":
        scene, cam = soup()
    else:
        scene, _ = small_scene("city")
        cam = hsr.Camera.look_at(eye=(0.0, 1.0, -2.0), target=(4.0, 0.5, -9.0), fov_y=90,
                                 near=0.3, far=60.0)
    frame, ref = check(scene, cam, max_ambiguous=0.05)
    assert frame.stats["clipped"] > 0
    assert (ref >= 0).sum() > 200


CASES = {
    "default": ("cubes", {}),
    "inside-back": ("inside-cubes", {"cull": "back"}),
    "soup-cw-front": ("soup", {"front_face": "cw", "cull": "front"}),
    "soup-no-test": ("soup", {"depth_test": False}),
    "offset": ("city", {"polygon_offset": (1.5, 4.0)}),
    "greater": ("spheres", {"depth_func": "greater", "clear_depth": 0.0}),
    "range": ("terrain", {"depth_range": (0.75, 0.25), "depth_func": "lequal"}),
    "mask-off": ("penetration", {"depth_mask": False}),
}
KEYS = ["triangles_in", "degenerate", "outside", "clipped", "culled", "screen_triangles",
        "triangles_rasterized", "fragments_tested", "fragments_written"]


def case_scene(name):
    if name == "inside-cubes":
        return inside_cubes()
    if name == "soup":
        return soup()
    return small_scene(name)


def prepared(scene, cam, **state_fields):
    """The z-buffer over the prepared (eagerly classified) screen triangles."""
    state = RenderState(**state_fields)
    stats = {}
    view_proj = cam.projection_matrix(W / H) @ cam.view_matrix
    screen = prepare(as_scene(scene), view_proj, W, H, state, stats)
    fragments = zbuffer.resolve(screen, state, counts=True)
    return fragments, {**stats, **fragments.stats}


@pytest.mark.parametrize("case", list(CASES))
def test_streamed_equals_prepared(chunk, case):
    name, state = CASES[case]
    scene, cam = case_scene(name)
    frame = hsr.render(scene, cam, W, H, counts=True, **state)
    fragments, stats = prepared(scene, cam, **state)
    assert np.array_equal(frame.face_id, fragments.face_id)
    assert np.array_equal(frame.depth.view(np.uint32), fragments.depth.view(np.uint32))
    assert np.array_equal(frame.fragments.count_tested, fragments.count_tested)
    assert np.array_equal(frame.fragments.count_written, fragments.count_written)
    assert {k: frame.stats[k] for k in KEYS} == {k: stats[k] for k in KEYS}
    assert frame.stats["fragments_tested"] > 0 or case == "soup-cw-front"


def kept_scratch_sequence():
    """(scene, camera, state) in an order that makes kept scratch matter: more faces,
    fewer, clipped pieces, other states."""
    return [(*soup(seed=5, n=300), {}),
            (*inside_cubes(), {"cull": "back"}),
            (*soup(seed=8, n=40), {"depth_func": "lequal"}),
            (*small_scene("city"), {"depth_range": (0.9, 0.2), "depth_func": "greater",
                                    "clear_depth": 0.0}),
            (*soup(seed=5, n=300), {"front_face": "cw"})]


def test_one_workspace_through_many_scenes_matches_the_reference(chunk):
    """Set-up records and face status kept in one Workspace from render to render (more
    faces, fewer, clipped pieces, other states, two threads): every frame still matches
    the ray reference, so nothing of an earlier render leaks into a later one (kept
    buffers hold old records where fresh pages would hold zeros)."""
    with hsr.Workspace(threads=2) as workspace:
        for scene, cam, state in kept_scratch_sequence():
            check(scene, cam, max_ambiguous=0.05, workspace=workspace, **state)


def test_plain_renders_keep_scratch_per_thread_and_stay_exact(chunk):
    """Plain calls (no workspace) keep their scratch in the calling thread's default
    workspace from render to render: the same sequence as above, each frame against the
    ray reference; the kept workspace is the same object from call to call, another
    thread gets its own, and a render nested in another on the same thread gets fresh
    scratch instead of failing."""
    import threading

    from hsr import parallel

    parallel.release_default_workspace()
    for scene, cam, state in kept_scratch_sequence():
        check(scene, cam, max_ambiguous=0.05, **state)
    mine = parallel._THREAD_DEFAULTS.workspace
    assert mine.kept_bytes() > 0 and not mine.busy
    other = []
    thread = threading.Thread(target=lambda: (hsr.render(*soup(seed=1, n=50), W, H),
                                              other.append(parallel._THREAD_DEFAULTS.workspace)))
    thread.start()
    thread.join()
    assert other[0] is not mine
    mesh, cam = soup(seed=3, n=100)
    with parallel.default_workspace(None) as outer:
        assert outer is mine
        nested = hsr.render(mesh, cam, W, H)  # the same thread, inside a held one
    assert np.array_equal(nested.face_id, hsr.render(mesh, cam, W, H).face_id)
    assert parallel._THREAD_DEFAULTS.workspace is mine


def test_the_default_workspace_keeps_no_more_than_its_cap(monkeypatch):
    from hsr import parallel

    parallel.release_default_workspace()
    mesh, cam = soup(seed=2, n=200)
    hsr.render(mesh, cam, W, H)
    kept = parallel._THREAD_DEFAULTS.workspace.kept_bytes()
    assert kept > 0
    monkeypatch.setattr(parallel, "DEFAULT_KEEP_BYTES", kept - 1)
    hsr.render(mesh, cam, W, H)
    assert parallel._THREAD_DEFAULTS.workspace.kept_bytes() == 0
    with hsr.Workspace(1) as ws:  # an explicit workspace releases the default
        hsr.render(mesh, cam, W, H, workspace=ws)
    assert parallel._THREAD_DEFAULTS.workspace is None


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 300), st.integers(0, 1000)), min_size=2,
                max_size=4),
       st.sampled_from([1, 2]), st.integers(1, 40))
def test_renders_through_a_workspace_equal_fresh_ones(soups, threads, chunk_size):
    """A sequence of soups through one Workspace gives, render by render, the buffers
    and counts of renders with fresh buffers."""
    before = zbuffer.STREAM_CHUNK
    zbuffer.STREAM_CHUNK = chunk_size
    try:
        with hsr.Workspace(threads) as workspace:
            for n_faces, seed in soups:
                mesh, cam = soup(seed=seed, n=n_faces)
                kept = hsr.render(mesh, cam, W, H, counts=True, workspace=workspace)
                release_default_workspace()  # plain calls keep scratch too: start empty
                fresh = hsr.render(mesh, cam, W, H, counts=True, threads=threads)
                release_default_workspace()
                assert np.array_equal(kept.face_id, fresh.face_id)
                assert np.array_equal(kept.depth.view(np.uint32),
                                      fresh.depth.view(np.uint32))
                assert np.array_equal(kept.fragments.count_written,
                                      fresh.fragments.count_written)
                assert {k: kept.stats[k] for k in KEYS} == {k: fresh.stats[k] for k in KEYS}
    finally:
        zbuffer.STREAM_CHUNK = before


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 160), st.integers(1, 40), st.sampled_from([1, 2]), st.integers(1, 9))
@example(100, 7, 2, 8192)  # 14 chunks of 8 faces were counted for 13
def test_any_face_count_and_chunk_size_equal_prepared(n_faces, chunk_size, threads, part):
    """Chunk k's fill and chunk k + 1's set-up share a hand-off (two record buffers),
    the set-up cut into parts of ``part`` faces that the threads take in turn: every
    split of the faces into chunks and parts gives the prepared path's buffers and
    counts, and no chunk is empty (a size rounded up used to leave the last of the
    chunks counted without faces; walking it in the pipeline read records of a negative
    size)."""
    mesh, cam = soup(seed=n_faces, n=n_faces)
    before = zbuffer.STREAM_CHUNK, zbuffer.SETUP_PART
    zbuffer.STREAM_CHUNK, zbuffer.SETUP_PART = chunk_size, part
    try:
        frame = hsr.render(mesh, cam, W, H, counts=True, threads=threads)
    finally:
        zbuffer.STREAM_CHUNK, zbuffer.SETUP_PART = before
    fragments, stats = prepared(mesh, cam)
    assert np.array_equal(frame.face_id, fragments.face_id)
    assert np.array_equal(frame.depth.view(np.uint32), fragments.depth.view(np.uint32))
    assert np.array_equal(frame.fragments.count_written, fragments.count_written)
    assert {k: frame.stats[k] for k in KEYS} == {k: stats[k] for k in KEYS}
    chunks = frame.stats["chunks"]
    assert len(range(0, n_faces, -(-n_faces // chunks))) == chunks


def test_second_draw_into_a_frame(chunk):
    """into=: the streamed fill goes over the earlier depth buffer without clearing."""
    scene, cam = small_scene("cubes")
    first = hsr.render(scene, cam, W, H)
    mover = hsr.Scene()
    for inst in scene.instances:
        mover.add(inst.mesh, scenes.translate(0.4, 0.1, 0.3) @ inst.model)
    second = hsr.render(mover, cam, W, H, into=first, depth_func="lequal")
    state = RenderState(depth_func="lequal")
    view_proj = cam.projection_matrix(W / H) @ cam.view_matrix
    screen = prepare(mover, view_proj, W, H, state, {})
    expect = zbuffer.resolve(screen, state, depth_buffer=first.depth.copy())
    drawn = expect.face_id >= 0
    assert np.array_equal(second.depth.view(np.uint32), expect.depth.view(np.uint32))
    assert np.array_equal(second.face_id, np.where(drawn, expect.face_id, first.face_id))
    assert drawn.any() and (~drawn & (first.face_id >= 0)).any()


def test_window_coordinates_read_after_the_z_buffer():
    """The z-buffer reads the vertices' window coordinates, computed once per vertex with
    the transform, and drops them when done (the frame keeps its geometry, not that
    copy). Window-space triangles asked for afterwards are computed again: they must be
    the viewport transform of the clip coordinates (evaluated here in NumPy, as
    glViewport and glDepthRange define it: x_w = (x_c / w_c + 1) * W / 2, with 1 / w_c
    taken once), bit for bit, and equal those of the eagerly prepared path."""
    mesh, cam = soup()
    near, far = 0.2, 0.9
    frame = hsr.render(mesh, cam, W, H, depth_range=(near, far))
    screen = frame.fragments.screen
    assert screen.pending and screen.geometry.pos_window is None  # released
    pos_clip, faces = screen.pos_clip, screen.faces
    inv_w = 1.0 / pos_clip[:, 3]
    expect = np.stack([(pos_clip[:, 0] * inv_w + 1.0) * (0.5 * W),
                       (pos_clip[:, 1] * inv_w + 1.0) * (0.5 * H),
                       pos_clip[:, 2] * inv_w * (0.5 * (far - near)) + 0.5 * (far + near)],
                      axis=1)
    xy, depth, face_id = screen.xy_window, screen.depth_window, screen.face_id
    # Pieces of clipped faces come from the clipper; whole faces from their corners.
    corners = faces[face_id]
    whole = np.all(np.isin(corners, np.flatnonzero(screen.geometry.codes < 64)), axis=1)
    assert 20 < whole.sum() < len(face_id)
    assert np.array_equal(xy[whole], expect[corners[whole]][..., :2])
    assert np.array_equal(depth[whole], expect[corners[whole]][..., 2])
    state = RenderState(depth_range=(near, far))
    view_proj = cam.projection_matrix(W / H) @ cam.view_matrix
    eager = prepare(as_scene(mesh), view_proj, W, H, state, {})
    assert np.array_equal(face_id, eager.face_id)
    assert np.array_equal(xy, eager.xy_window) and np.array_equal(depth, eager.depth_window)


def test_ray_caster_transforms_vertices_only_when_read():
    """The ray caster walks world space: its frame's screen triangles are not made, nor
    even its vertices transformed, until something reads them; then they are those of
    the eager geometry stage, and a per-pixel look (Gouraud, fog) that reads the
    clip-space corners colours the ray caster's pixels as it colours the z-buffer's."""
    mesh, cam = soup()
    frame = hsr.render(mesh, cam, W, H, algorithm="raycast")
    screen = frame.fragments.screen
    assert screen._geometry is None and screen.pending
    view_proj = cam.projection_matrix(W / H) @ cam.view_matrix
    eager = prepare(as_scene(mesh), view_proj, W, H, RenderState(), {})
    assert np.array_equal(screen.pos_clip, eager.pos_clip)
    assert np.array_equal(screen.faces, eager.faces)
    assert np.array_equal(screen.xy_window, eager.xy_window)
    assert np.array_equal(screen.face_id, eager.face_id)
    look = dict(shading="gouraud", fog=hsr.Fog("linear", 1.0, 9.0))
    ray = hsr.render(mesh, cam, W, H, algorithm="raycast", **look)
    ref = hsr.render(mesh, cam, W, H, **look)
    same = ray.face_id == ref.face_id
    assert same.mean() > 0.99 and (ray.face_id >= 0).sum() > 100
    assert (ray.color[same] == ref.color[same]).all()


@pytest.mark.parametrize("threads", [1, 2])
def test_band_counts(threads):
    """Each triangle that covers a pixel centre is filled in every band it overlaps: once
    with one band, at least once and at most once per band with more."""
    scene, cam = small_scene("spheres")
    frame = hsr.render(scene, cam, W, H, threads=threads)
    stats = frame.stats
    assert stats["bands"] == threads
    if threads == 1:
        assert stats["band_triangles"] == stats["triangles_rasterized"]
    else:
        assert stats["triangles_rasterized"] < stats["band_triangles"] \
            <= threads * stats["triangles_rasterized"]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, CULLED), max_size=300))
def test_status_counts_equal_numpy_bincount(codes):
    status = np.array(codes, dtype=np.int8)
    expect = np.bincount(status.astype(np.int64), minlength=CULLED + 1)
    assert status_counts(status).tolist() == expect.tolist()
