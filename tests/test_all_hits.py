"""``RayScene.all_hits``: every hit along each ray, nearest first, against a brute-force
list of Moller-Trumbore hits (test_rays' reference test), Open3D's
``list_intersections``, and the scene's own ``count`` and ``cast`` (each crossing listed
once, the first hit the nearest)."""

from __future__ import annotations

import os
import tracemalloc

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_rays import _closed_meshes, _soup, pixel_rays, random_rays

import hsr
from conftest import require
from hsr.visibility import RayError, RayHitLists
from reference import moller_trumbore


def brute_lists(tris, origins, directions, t_min=0.0, t_max=np.inf, slack=0.0):
    """Per ray, its hits as rows (t, face, u, v) sorted by t then face: Moller-Trumbore
    in float64 over every triangle (a hit at a shared edge is listed for each triangle
    there; ``slack`` widens the triangles so that rounding loses none of them)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = b - a, c - a
    lists = []
    for o, d in zip(origins, directions):
        ok, u, v, t = moller_trumbore(o, d, a, e1, e2)
        hit = np.flatnonzero(ok & (u >= -slack) & (v >= -slack) & (u + v <= 1 + slack)
                             & (t >= t_min) & (t <= t_max))
        order = np.lexsort((hit, t[hit]))
        f = hit[order]
        lists.append(np.column_stack([t[f], f, u[f], v[f]]))
    return lists


def _check_against_brute_force(lists, brute, tris, max_hits=None):
    assert isinstance(lists, RayHitLists) and len(lists) == len(brute)
    for i, expected in enumerate(brute):
        if max_hits is not None:
            expected = expected[:max_hits]
        rows = slice(lists.offsets[i], lists.offsets[i + 1])
        np.testing.assert_array_equal(lists.face_id[rows], expected[:, 1].astype(int))
        np.testing.assert_allclose(lists.t[rows], expected[:, 0], rtol=1e-9)
        np.testing.assert_allclose(lists.barycentric[rows], expected[:, 2:], atol=1e-9)
    corners = tris[lists.face_id]
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    np.testing.assert_allclose(lists.normal, n / np.linalg.norm(n, axis=1)[:, None],
                               atol=1e-12)
    assert (lists.object_id == 0).all()


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 60),
       t_min=st.sampled_from([0.0, 0.0, 0.3]), t_max=st.sampled_from([np.inf, 2.0, 0.5]),
       max_hits=st.sampled_from([None, None, 1, 2, 5]))
@example(seed=1, n=60, t_min=0.0, t_max=np.inf, max_hits=None)
def test_all_hits_equal_brute_force_on_random_soups(seed, n, t_min, t_max, max_hits):
    """Every hit, sorted by distance, equals the brute-force list (the nearest
    ``max_hits`` of it when capped); each ray lists as many as ``count`` counts, and
    its first hit is ``cast``'s."""
    rng = np.random.default_rng(seed)
    tris = _soup(rng, n)
    mesh = hsr.Mesh(tris.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    origins, directions = random_rays(
        (tris.reshape(-1, 3).min(0), tris.reshape(-1, 3).max(0)), 300, rng)
    rays = hsr.RayScene(mesh, threads=1)
    lists = rays.all_hits(origins, directions, t_min, t_max, max_hits=max_hits)
    brute = brute_lists(tris, origins, directions, t_min, t_max)
    _check_against_brute_force(lists, brute, tris, max_hits)
    count = rays.count(origins, directions, t_min, t_max)
    cap = count if max_hits is None else np.minimum(count, max_hits)
    np.testing.assert_array_equal(lists.counts, cap)
    hits = rays.cast(origins, directions, t_min, t_max)
    first = lists.offsets[:-1][count > 0]
    np.testing.assert_array_equal(lists.t[first], hits.t[count > 0])
    np.testing.assert_array_equal(lists.face_id[first], hits.face_id[count > 0])
    points = lists.points(origins, directions)
    np.testing.assert_array_equal(points, origins[lists.ray_id]
                                  + lists.t[:, None] * directions[lists.ray_id])


def test_rays_through_many_layers_list_them_all_in_order_capped_or_not():
    """A stack of 300 parallel squares, two triangles each, listed in submission order
    shuffled: a ray through all of them lists 300 hits (longer than the short lists
    sorted by insertion), sorted by distance; ``max_hits`` keeps the nearest, whichever
    order the walk meets them in; rays that miss list nothing; a scene of instances
    numbers objects."""
    rng = np.random.default_rng(4)
    layers = 300
    z = rng.permutation(layers).astype(np.float64)
    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float64)
    positions = np.concatenate([square + [0, 0, zi] for zi in z])
    base = 4 * np.arange(layers)[:, None]
    faces = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]])
    mesh = hsr.Mesh(positions, faces)
    rays = hsr.RayScene(mesh)
    origins = np.concatenate([rng.uniform(-0.9, 0.9, (500, 3)) * [1, 1, 0] + [0, 0, -5],
                              [[5.0, 5.0, -5.0]]])
    directions = np.tile([0.0, 0.0, 1.0], (len(origins), 1))
    lists = rays.all_hits(origins, directions)
    np.testing.assert_array_equal(lists.counts, [layers] * 500 + [0])
    for i in (0, 250, 499):
        rows = slice(lists.offsets[i], lists.offsets[i + 1])
        np.testing.assert_allclose(lists.t[rows], np.arange(layers) + 5.0)
        layer = lists.face_id[rows] % layers
        np.testing.assert_array_equal(z[layer], np.arange(layers))
    nearest = rays.all_hits(origins, directions, max_hits=7)
    np.testing.assert_array_equal(nearest.counts, [7] * 500 + [0])
    np.testing.assert_allclose(nearest.t, np.tile(np.arange(7) + 5.0, 500))
    # From the middle of the stack, t_max cutting it: the layers between.
    some = rays.all_hits(origins[:500] + [0, 0, 100.5], directions[:500], t_max=10.0)
    np.testing.assert_array_equal(some.counts, 10)
    np.testing.assert_allclose(some.t, np.tile(np.arange(10) + 0.5, 500))
    two = hsr.Scene().add(mesh, name="a").add(mesh, np.array(
        [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.25], [0, 0, 0, 1.0]]), name="b")
    both = hsr.RayScene(two).all_hits(origins[:1], directions[:1])
    assert both.counts[0] == 2 * layers
    np.testing.assert_array_equal(both.object_id, np.tile([0, 1], layers))
    assert (both.face_id[1::2] >= mesh.n_faces).all()


@pytest.mark.parametrize("name", ["cube", "octahedron", "icosphere"])
def test_a_crossing_through_an_edge_or_vertex_is_listed_once(name):
    """Rays aimed exactly at a closed mesh's vertices and edge midpoints, from inside
    and outside: each crossing is listed once, for one of the faces there (the brute
    force lists it for each of them), at the brute-force distance; lists as long as
    ``count``, odd from inside."""
    mesh = _closed_meshes()[name]
    tris = mesh.positions[mesh.faces]
    rays = hsr.RayScene(mesh)
    verts = mesh.positions
    edges = {tuple(sorted((int(a), int(b)))) for f in mesh.faces for a, b in
             ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    targets = np.concatenate([verts, [(verts[a] + verts[b]) / 2 for a, b in edges]])
    rng = np.random.default_rng(8)
    for origin in np.concatenate([np.zeros((1, 3)), rng.uniform(-0.2, 0.2, (5, 3))]):
        for inside, o, d in ((True, np.broadcast_to(origin, targets.shape), targets - origin),
                             (False, 3.0 * targets, origin - 3.0 * targets)):
            lists = rays.all_hits(o, d)
            np.testing.assert_array_equal(lists.counts, rays.count(o, d))
            assert (lists.counts % 2 == (1 if inside else 0)).all()
            for i, expected in enumerate(brute_lists(tris, o, d, slack=1e-12)):
                rows = slice(lists.offsets[i], lists.offsets[i + 1])
                # The brute force's hits at one crossing, one group each.
                groups = np.split(expected, np.flatnonzero(np.diff(expected[:, 0]) > 1e-9)
                                  + 1)
                assert len(groups) == lists.counts[i]
                for t, face, group in zip(lists.t[rows], lists.face_id[rows], groups):
                    assert t == pytest.approx(group[0, 0], rel=1e-9, abs=1e-12)
                    assert face in group[:, 1]


def test_all_hits_agree_with_open3d_list_intersections(models_dir):
    """100k rays at the bunny, origins inside its box and outside it: the same hits as
    Open3D's list_intersections (Embree, float32), ray for ray and hit for hit, but
    where two of a ray's hits lie at one distance in float32 (a tie either may order
    or merge)."""
    o3d = require("open3d")
    bunny = hsr.load(os.path.join(models_dir, "stanford-bunny.obj"))
    rng = np.random.default_rng(21)
    origins, directions = random_rays(bunny.bounds(), 100_000, rng)
    lists = hsr.RayScene(bunny).all_hits(origins, directions)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(bunny.positions.astype(np.float32)),
                        o3d.core.Tensor(bunny.faces.astype(np.uint32)))
    ref = {k: v.numpy() for k, v in scene.list_intersections(o3d.core.Tensor(
        np.hstack([origins, directions]).astype(np.float32))).items()}
    assert lists.offsets[-1] > 30_000  # many rays cross several layers
    close_to = 1e-6 * np.linalg.norm(np.subtract(*bunny.bounds()))  # float32 rounding
    ref_counts = np.diff(ref["ray_splits"])
    same_count = ref_counts == lists.counts
    assert same_count.mean() >= 0.9995, same_count.mean()
    ours, theirs = lists.offsets[:-1], ref["ray_splits"][:-1].astype(np.int64)
    checked = 0
    for i in np.flatnonzero(same_count & (lists.counts > 0)):
        a = slice(ours[i], ours[i] + lists.counts[i])
        b = slice(theirs[i], theirs[i] + lists.counts[i])
        t_ref = ref["t_hit"][b].astype(np.float64)
        # Open3D's lists are in the order Embree met the hits: sort them as ours.
        order = np.lexsort((ref["primitive_ids"][b], t_ref))
        t_ref, face_ref = t_ref[order], ref["primitive_ids"][b][order]
        np.testing.assert_allclose(lists.t[a], t_ref, rtol=1e-4, atol=close_to)
        tie = np.zeros(len(t_ref), dtype=bool)
        close = np.abs(np.diff(t_ref)) <= 1e-4 * t_ref[1:] + close_to
        tie[1:] |= close
        tie[:-1] |= close
        assert (lists.face_id[a][~tie] == face_ref[~tie]).all(), i
        checked += 1
    assert checked > 10_000


def test_the_walks_and_threads_list_the_same_hits(models_dir):
    """A camera's rays listed by the packet walk and by the interleaved walk (each forced
    in turn), and shuffled (whose order the lists follow): the same lists, bit for bit;
    one thread, two, and part of the query alike; max_hits 1 lists the nearest hits."""
    from unittest import mock

    from hsr.algorithms.bvh.packets import trace_packets
    from hsr.algorithms.bvh.walk import trace_range

    bunny = hsr.load(os.path.join(models_dir, "stanford-bunny.obj"))
    origins, directions = pixel_rays(hsr.Camera.frame(bunny.bounds()), 200, 180)
    rays = hsr.RayScene(bunny, threads=2)
    walked = []
    for kernel in (trace_packets, trace_range):
        with mock.patch.object(hsr.RayScene, "_walk", lambda *_, k=kernel: k):
            walked.append(rays.all_hits(origins, directions))
            walked.append(rays.all_hits(origins, directions, max_hits=2))
    order = np.random.default_rng(2).permutation(len(origins))
    shuffled = hsr.RayScene(bunny, threads=1).all_hits(origins[order], directions[order])
    back = np.argsort(order)
    fields = ("offsets", "t", "face_id", "object_id", "barycentric", "normal")
    for field in fields:
        np.testing.assert_array_equal(getattr(walked[0], field), getattr(walked[2], field))
        np.testing.assert_array_equal(getattr(walked[1], field), getattr(walked[3], field))
        if field != "offsets":
            theirs = np.concatenate([getattr(shuffled, field)[
                shuffled.offsets[j]:shuffled.offsets[j + 1]] for j in back])
            np.testing.assert_array_equal(getattr(walked[0], field), theirs)
    landed = walked[0].counts[walked[0].counts > 0]
    assert (landed >= 2).mean() > 0.5  # the bunny's far side too
    part = rays.all_hits(origins[:777], directions[:777])
    np.testing.assert_array_equal(part.t, walked[0].t[:walked[0].offsets[777]])
    capped = rays.all_hits(origins, directions, max_hits=1)
    hits = rays.cast(origins, directions)
    np.testing.assert_array_equal(capped.t, hits.t[hits.hit])


@pytest.mark.parametrize("max_hits, message", [
    (0, "max_hits must be a positive integer, got 0"),
    (-3, "max_hits must be a positive integer, got -3"),
    (2.5, "max_hits must be a positive integer or None, got 2.5"),
    (True, "max_hits must be a positive integer or None, got True"),
    ("4", "max_hits must be a positive integer or None, got '4'"),
])
def test_a_bad_max_hits_is_refused(max_hits, message):
    rays = hsr.RayScene(hsr.scenes.cube())
    with pytest.raises(RayError) as info:
        rays.all_hits([[0, 0, 5]], [[0, 0, -1]], max_hits=max_hits)
    assert str(info.value) == message and "\n" not in str(info.value)
    assert len(rays.all_hits([[0, 0, 5]], [[0, 0, -1]], max_hits=np.int64(1)).t) == 1
    with pytest.raises(RayError, match="ray 0 is \\(0, 0, 0\\)"):
        rays.all_hits([[0, 0, 5]], [[0, 0, 0]])


def test_lists_past_the_memory_cap_are_refused_before_they_are_allocated():
    """A 2,000-layer stack and 20,000 rays through it: 40M hits (2.1 GiB of lists), past
    MAX_LIST_BYTES; refused by a one-line error that names max_hits, counted without
    allocating the lists (traced memory stays far below them). With max_hits they fit."""
    from hsr.visibility.rays import HIT_BYTES, MAX_LIST_BYTES

    layers, n = 2000, 20_000
    assert layers * n * HIT_BYTES > MAX_LIST_BYTES
    square = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], dtype=np.float64)
    positions = np.concatenate([square + [0, 0, z] for z in range(layers)])
    base = 4 * np.arange(layers)[:, None]
    mesh = hsr.Mesh(positions, np.concatenate([base + [0, 1, 2], base + [0, 2, 3]]))
    rays = hsr.RayScene(mesh)
    rng = np.random.default_rng(0)
    origins = rng.uniform(-0.9, 0.9, (n, 3)) * [1, 1, 0] + [0, 0, -1]
    directions = np.tile([0.0, 0.0, 1.0], (n, 1))
    tracemalloc.start()
    try:
        with pytest.raises(RayError) as info:
            rays.all_hits(origins, directions)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    message = str(info.value)
    assert "40,000,000 hits" in message and "max_hits" in message and "\n" not in message
    assert peak < 64 << 20, peak
    lists = rays.all_hits(origins, directions, max_hits=3)
    np.testing.assert_array_equal(lists.counts, 3)
    np.testing.assert_allclose(lists.t, np.tile([1.0, 2.0, 3.0], n))


def test_empty_queries_and_scenes_list_nothing():
    """No rays: one offset, no hits; a scene whose faces are all degenerate (no tree to
    walk): every list empty; points() of other rays than the query's is refused."""
    rays = hsr.RayScene(hsr.scenes.cube())
    none = rays.all_hits(np.zeros((0, 3)), np.zeros((0, 3)))
    assert len(none) == 0 and none.offsets.tolist() == [0] and none.t.shape == (0,)
    assert none.barycentric.shape == (0, 2) and none.normal.shape == (0, 3)
    flat = hsr.Mesh([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    lists = hsr.RayScene(flat).all_hits([[0.5, 1.0, 0.0], [1.0, -1.0, 0.0]],
                                        [[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    assert lists.offsets.tolist() == [0, 0, 0] and len(lists.t) == 0
    hits = rays.all_hits([[0, 0, 5]], [[0, 0, -1]])
    assert hits.counts.tolist() == [2]
    with pytest.raises(RayError, match="1 rays were cast; got 2"):
        hits.points([[0, 0, 5], [0, 0, 6]], [[0, 0, -1], [0, 0, -1]])


def test_per_ray_intervals_cut_each_list():
    """t_min and t_max given per ray (as arrays): each ray's list is the brute-force
    list within its own interval."""
    rng = np.random.default_rng(17)
    tris = _soup(rng, 80)
    mesh = hsr.Mesh(tris.reshape(-1, 3), np.arange(240).reshape(-1, 3))
    origins, directions = random_rays(
        (tris.reshape(-1, 3).min(0), tris.reshape(-1, 3).max(0)), 400, rng)
    t_min = np.where(rng.random(400) < 0.5, 0.0, rng.uniform(0.0, 0.5, 400))
    t_max = np.where(rng.random(400) < 0.3, np.inf, t_min + rng.uniform(0.0, 2.0, 400))
    rays = hsr.RayScene(mesh)
    lists = rays.all_hits(origins, directions, t_min, t_max)
    brute = [brute_lists(tris, origins[i:i + 1], directions[i:i + 1], t_min[i], t_max[i])[0]
             for i in range(400)]
    _check_against_brute_force(lists, brute, tris)
    uncut = rays.all_hits(origins, directions).counts
    assert (lists.counts < uncut).sum() > 10 and (lists.counts > 1).sum() >= 5
