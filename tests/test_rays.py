"""``hsr.RayScene`` (issue #33) against independent references: Embree (through
``embreex``; float32, so distances are compared with a relative tolerance) on 200k random
rays at a shared model, and a brute-force NumPy ray/triangle test (Moller-Trumbore in
float64, written here) on small meshes; the inside/outside parity of closed meshes with
rays aimed exactly at edges and vertices; determinism across thread counts; and bad
input refused with a RayError. (Open3D's RaycastingScene is the benchmark's peer,
``benchmarks/bench_rays.py``: too heavy for the test extra.)"""

from __future__ import annotations

import functools
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hsr
from conftest import require
from hsr.visibility import RayError
from hsr.visibility.rays import _coherent
from reference import moller_trumbore

embreex = require("embreex")


def brute_force(tris, origins, directions, t_min=0.0, t_max=np.inf):
    """(nearest t, face, u, v, all hits count) per ray, Moller-Trumbore in float64 over
    every triangle (a hit at an edge counts for each triangle there)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = b - a, c - a
    n = len(origins)
    best_t = np.full(n, np.inf)
    best_f = np.full(n, -1)
    best_uv = np.zeros((n, 2))
    count = np.zeros(n, dtype=np.int64)
    for i in range(n):
        ok, u, v, t = moller_trumbore(origins[i], directions[i], a, e1, e2)
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= t_min) & (t <= t_max)
        count[i] = hit.sum()
        if hit.any():
            f = np.flatnonzero(hit)[np.argmin(t[hit])]
            best_t[i], best_f[i], best_uv[i] = t[f], f, (u[f], v[f])
    return best_t, best_f, best_uv, count


def random_rays(bounds, n, rng, outside_share=0.5):
    """Origins inside the box and outside it (up to its size away), random directions of
    random lengths."""
    lo, hi = bounds
    size = hi - lo
    inside = rng.uniform(lo, hi, (n, 3))
    outside = rng.uniform(lo - size, hi + size, (n, 3))
    origins = np.where(rng.random((n, 1)) < outside_share, outside, inside)
    directions = rng.normal(size=(n, 3)) * rng.uniform(0.1, 10.0, (n, 1))
    return origins, directions


@pytest.fixture(scope="module")
def bunny(models_dir):
    return hsr.load(os.path.join(models_dir, "stanford-bunny.obj"))


@pytest.fixture(params=["terrain30k", "terrain"])
def walk_model(request):
    """(mesh, RayScene) on either side of INTERLEAVE_BYTES on every CPU family it is set
    for: a 30k-face terrain (2.3 MiB of corners and nodes), whose walks go a ray at a
    time to their end, and a 120k-face terrain, whose walks switch between eight rays in
    turn (checked here, so each test runs both walks). (The bunny, 5.4 MiB, is on one
    side on an AMD CPU and on the other on an Intel one.)"""
    from hsr.algorithms.bvh.walk import INTERLEAVE_BY_VENDOR, INTERLEAVE_BYTES

    mesh = hsr.scenes.terrain_mesh(30_000 if request.param == "terrain30k" else 120_000)
    rays = hsr.RayScene(mesh)
    walked_bytes = rays.bvh.corners.nbytes + rays.bvh.node_box.nbytes
    for threshold in (INTERLEAVE_BYTES, *INTERLEAVE_BY_VENDOR.values()):
        assert (walked_bytes > threshold) == (request.param == "terrain")
    return mesh, rays


def test_the_interleaving_threshold_is_the_cpu_familys(tmp_path):
    """INTERLEAVE_BYTES is the threshold measured for this machine's CPU family, read
    from the vendor in /proc/cpuinfo; an unknown vendor, or no such file, takes the AMD
    one (the first measured)."""
    from hsr.algorithms.bvh.walk import INTERLEAVE_BY_VENDOR, interleave_bytes

    for vendor, want in (("GenuineIntel", 4 << 20), ("AuthenticAMD", 8 << 20),
                         ("HygonGenuine", 8 << 20)):
        cpuinfo = tmp_path / vendor
        cpuinfo.write_text(f"processor\t: 0\nvendor_id\t: {vendor}\ncpu family\t: 6\n")
        assert interleave_bytes(str(cpuinfo)) == want
    assert interleave_bytes(str(tmp_path / "none")) == INTERLEAVE_BY_VENDOR["AuthenticAMD"]


def pixel_rays(camera, width, height):
    """(origins, directions) of a camera's pixel-centre rays, row by row, written here
    from the matrices: from the near plane to the far plane."""
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    inv = np.linalg.inv(view_proj)
    gx, gy = np.meshgrid((np.arange(width) + 0.5) / width * 2 - 1,
                         1 - (np.arange(height) + 0.5) / height * 2)
    ndc = np.stack([gx.ravel(), gy.ravel()], axis=1)
    one = np.ones((len(ndc), 1))
    near = np.hstack([ndc, -one, one]) @ inv.T
    far = np.hstack([ndc, one, one]) @ inv.T
    origins = near[:, :3] / near[:, 3:]
    return origins, far[:, :3] / far[:, 3:] - origins


def test_cast_agrees_with_embree_on_200k_random_rays(bunny):
    rng = np.random.default_rng(7)
    origins, directions = random_rays(bunny.bounds(), 200_000, rng)
    rays = hsr.RayScene(bunny)
    assert not _coherent(origins, directions, rays.scene_size)  # one ray at a time
    _check_against_embree(bunny, origins, directions, rays.cast(origins, directions))


def test_camera_rays_go_in_packets_and_agree_with_embree(bunny):
    """A camera's 200k pixel rays are coherent: RayScene walks them four at a time
    (hsr.algorithms.bvh.packets.trace_packets); the answers are checked as the random rays'."""
    origins, directions = pixel_rays(hsr.Camera.frame(bunny.bounds()), 480, 420)
    rays = hsr.RayScene(bunny)
    assert _coherent(origins, directions, rays.scene_size)
    _check_against_embree(bunny, origins, directions, rays.cast(origins, directions))


@settings(max_examples=60, deadline=None)
@given(n=st.integers(4, 6000), share=st.floats(0.0, 1.0), near_edge=st.integers(-2, 2),
       seed=st.integers(0, 2 ** 32 - 1))
def test_coherence_is_three_of_four_sampled_runs_whatever_their_order(n, share, near_edge,
                                                                     seed):
    """_coherent judges the sampled runs in two groups and may stop after the first:
    its answer is still "at least three of four sampled runs are coherent", checked
    here with the incoherent runs put anywhere among the sampled ones (first, last,
    mixed) and their number on and around the quarter (an off-by-one at the stop
    fails it)."""
    from hsr.visibility.rays import _sample_runs

    runs = _sample_runs(n)
    m = len(runs)
    quarter = m // 4
    k = min(m, max(0, quarter + near_edge if seed % 2 else round(share * m)))
    rng = np.random.default_rng(seed)
    placement = [np.arange(m), np.arange(m)[::-1], rng.permutation(m)][seed % 3]
    origins = np.zeros((n, 3))
    directions = np.tile([0.0, 0.0, -1.0], (n, 1))
    for r in placement[:k]:  # an incoherent run: its last three rays turn 90 degrees
        directions[runs[r, 1:]] = [1.0, 0.0, 0.0]
    assert _coherent(origins, directions, 1.0) == (4 * (m - k) >= 3 * m)


def _looking_down(mesh):
    """A camera above a terrain whose view the terrain fills (as bench_raycast's
    ``fill`` view)."""
    lo, hi = (np.asarray(b, dtype=np.float64) for b in mesh.bounds())
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    reach = min(half[0], half[2]) / np.tan(np.radians(22.5))
    return hsr.Camera(eye=(centre[0], hi[1] + reach, centre[2]), target=tuple(centre),
                      up=(0.0, 0.0, 1.0), fov_y=45.0, near=0.5 * reach,
                      far=reach + 3 * half[1])


def test_camera_rays_walk_in_packets_while_triangles_are_not_much_smaller_than_pixels():
    """Coherent rays fewer than four a triangle: a terrain filling the view with about
    one triangle a pixel goes through packets (it went one ray at a time, 1.85x
    Open3D's time instead of 1.29x on a 1M-face terrain), with seven a pixel through
    the interleaved walk; edge-on (many triangles a pixel where the rays land) too.
    The footprint estimate follows the triangles a pixel counted from the view, and
    the answers of the packet-walked query equal Embree's."""
    from hsr.algorithms.bvh.packets import trace_packets
    from hsr.algorithms.bvh.walk import trace_range
    from hsr.visibility.rays import _sample_runs

    mesh = hsr.scenes.terrain(100_000)[0].instances[0].mesh
    rays = hsr.RayScene(mesh)
    cam = _looking_down(mesh)
    t0, t1 = np.zeros(1), np.full(1, np.inf)
    walks = {}
    for side in (320, 120):
        origins, directions = pixel_rays(cam, side, side)
        assert _coherent(origins, directions, rays.scene_size)
        assert len(origins) < 4 * mesh.n_faces  # (packets on the old rule too)
        per_pixel = mesh.n_faces / side ** 2  # the terrain covers the view
        estimate = rays._faces_per_ray(origins, directions, t0, t1,
                                       _sample_runs(len(origins)))
        assert 0.7 * per_pixel <= estimate <= 2.5 * per_pixel, (estimate, per_pixel)
        walks[side] = rays._walk(origins, directions, t0, t1)
    assert walks == {320: trace_packets, 120: trace_range}
    edge_on = hsr.Camera.frame(mesh.bounds())
    origins, directions = pixel_rays(edge_on, 320, 320)
    assert rays._walk(origins, directions, t0, t1) is trace_range
    # Past the terrain's edge too, for rays that miss.
    origins, directions = pixel_rays(
        hsr.Camera(eye=cam.eye, target=cam.target, up=cam.up, fov_y=60.0, near=cam.near,
                   far=cam.far), 320, 320)
    assert rays._walk(origins, directions, t0, t1) is trace_packets
    _check_against_embree(mesh, origins, directions, rays.cast(origins, directions))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 3000), side=st.integers(2, 90),
       t_cut=st.booleans())
def test_camera_queries_answer_the_same_on_either_walk(seed, n, side, t_cut):
    """Whichever walk RayScene picks for a camera's rays (each forced in turn),
    ``cast``, ``occluded`` and ``count`` answer the same, bit for bit, on random soups
    seen from random eyes, with per-ray t_max cutting some rays short; and the nearest
    hits of a sample equal brute force."""
    from unittest import mock

    from hsr.algorithms.bvh.packets import trace_packets
    from hsr.algorithms.bvh.walk import trace_range

    rng = np.random.default_rng(seed)
    corners = rng.uniform(-1, 1, (n, 3, 3)) * rng.uniform(0.02, 0.8, (n, 1, 1))
    corners += rng.uniform(-1, 1, (n, 1, 3))
    mesh = hsr.Mesh(corners.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    rays = hsr.RayScene(mesh)
    direction = rng.normal(size=3)
    eye = 4.0 * direction / np.linalg.norm(direction)
    up = (0, 1, 0) if abs(direction[1]) < 0.9 * np.linalg.norm(direction) else (1, 0, 0)
    cam = hsr.Camera(eye=tuple(eye), target=(0, 0, 0), up=up, fov_y=float(rng.uniform(20, 90)),
                     near=0.1, far=10.0)
    origins, directions = pixel_rays(cam, side, side)
    k = len(origins)
    t_max = (np.where(rng.random(k) < 0.3, rng.uniform(0.2, 0.6, k), np.inf) if t_cut
             else np.full(k, np.inf))
    answers = []
    for kernel in (trace_packets, trace_range):
        with mock.patch.object(hsr.RayScene, "_walk", lambda *_, k=kernel: k):
            hits = rays.cast(origins, directions, t_max=t_max)
            answers.append((hits.t.copy(), hits.face_id.copy(), hits.barycentric.copy(),
                            rays.occluded(origins, directions, t_max=t_max),
                            rays.count(origins, directions, t_max=t_max)))
    for a, b in zip(*answers):
        np.testing.assert_array_equal(a, b)
    # Brute force on a sample: a hit or a miss alike (but for a ray through an edge,
    # which either test may call), and the hit's distance.
    differ = 0
    for i in rng.choice(k, min(k, 150), replace=False):
        t, _, _, _ = brute_force(corners, origins[i:i + 1], directions[i:i + 1], 0.0,
                                 t_max[i])
        if np.isfinite(t[0]) != (answers[0][1][i] >= 0):
            differ += 1
        elif np.isfinite(t[0]):
            assert answers[0][0][i] == pytest.approx(t[0], rel=1e-9)
    assert differ <= 1


def test_surface_area_sums_the_triangles_or_samples_them_evenly(bunny):
    """The area behind the walk's footprint estimate: every triangle when the samples
    are as many (float32 and float64 corners alike), and within 3% of the sum from
    4096 evenly spread ones at the bunny's 69k."""
    from hsr.algorithms.bvh.hits import surface_area

    tris = bunny.positions[bunny.faces]
    exact = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]),
                                 axis=1).sum()
    assert surface_area(tris, len(tris)) == pytest.approx(exact, rel=1e-12)
    assert surface_area(tris.astype(np.float32), len(tris)) == pytest.approx(exact, rel=1e-6)
    assert surface_area(tris, 4096) == pytest.approx(exact, rel=0.03)
    assert surface_area(tris[:0], 4096) == 0.0


def _check_against_embree(bunny, origins, directions, hits):
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, bunny.positions[bunny.faces].astype(np.float32))
    ref = scene.run(origins.astype(np.float32), directions.astype(np.float32), output=1)
    ref_face = np.where(ref["geomID"] >= 0, ref["primID"], -1)
    ref_t = np.where(ref_face >= 0, ref["tfar"].astype(np.float64), np.inf)
    assert 0.05 < hits.hit.mean() < 0.95  # both kinds of ray are there
    same_hit = (ref_face >= 0) == hits.hit
    assert same_hit.mean() >= 0.9998, same_hit.mean()
    both = (ref_face >= 0) & hits.hit
    rel = np.abs(hits.t[both] - ref_t[both]) / np.maximum(hits.t[both], 1e-300)
    assert np.median(rel) <= 1e-6, np.median(rel)
    other_face = both & (ref_face != hits.face_id)
    # A different face only where Embree's distance ties ours (float32 rounding).
    assert (rel[other_face[both]] <= 1e-4).all()
    assert other_face.mean() < 1e-3
    # The hit point rebuilt from the barycentrics lies on the ray.
    corners = bunny.positions[bunny.faces[hits.face_id[both]]]
    u, v = hits.barycentric[both, 0:1], hits.barycentric[both, 1:2]
    rebuilt = (1 - u - v) * corners[:, 0] + u * corners[:, 1] + v * corners[:, 2]
    on_ray = origins[both] + hits.t[both, None] * directions[both]
    size = np.linalg.norm(np.subtract(*bunny.bounds()[::-1]))
    assert np.abs(rebuilt - on_ray).max() <= 1e-5 * size
    # Normals: unit, as wound.
    n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    np.testing.assert_allclose(hits.normal[both], n / np.linalg.norm(n, axis=1)[:, None],
                               atol=1e-12)
    assert (hits.object_id[both] == 0).all() and (hits.object_id[~hits.hit] == -1).all()


def _soup(rng, n):
    centers = rng.uniform(-1, 1, (n, 1, 3))
    return centers + rng.normal(scale=0.4, size=(n, 3, 3))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 40),
       t_min=st.sampled_from([0.0, 0.0, 0.3]), t_max=st.sampled_from([np.inf, 2.0, 0.5]))
def test_cast_occluded_count_equal_brute_force_on_random_soups(seed, n, t_min, t_max):
    rng = np.random.default_rng(seed)
    tris = _soup(rng, n)
    mesh = hsr.Mesh(tris.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    origins, directions = random_rays((tris.reshape(-1, 3).min(0), tris.reshape(-1, 3).max(0)),
                                      200, rng)
    rays = hsr.RayScene(mesh, threads=1)
    hits = rays.cast(origins, directions, t_min, t_max)
    t, f, uv, count = brute_force(tris, origins, directions, t_min, t_max)
    np.testing.assert_array_equal(hits.face_id, f)
    np.testing.assert_allclose(hits.t[f >= 0], t[f >= 0], rtol=1e-9)
    np.testing.assert_allclose(hits.barycentric[f >= 0], uv[f >= 0], atol=1e-9)
    np.testing.assert_array_equal(rays.occluded(origins, directions, t_min, t_max), f >= 0)
    np.testing.assert_array_equal(rays.count(origins, directions, t_min, t_max), count)


def _closed_meshes():
    """A cube (two triangles a side, diagonals both ways), an octahedron and a
    subdivided icosphere: closed, consistently wound."""
    import trimesh

    cube = trimesh.creation.box(extents=(2, 2, 2))
    faces = np.array(cube.faces)
    faces[::4] = faces[::4][:, [1, 2, 0]]  # other diagonals on some sides: same surface
    octa = hsr.Mesh([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                    [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5],
                     [3, 1, 5], [0, 3, 5]])
    ico = trimesh.creation.icosphere(subdivisions=2)
    return {"cube": hsr.Mesh(cube.vertices, faces), "octahedron": octa,
            "icosphere": hsr.Mesh(ico.vertices, ico.faces)}


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(60, 300),
       t_max=st.sampled_from([np.inf, 1.5]))
def test_axis_parallel_random_rays_equal_brute_force(seed, n, t_max):
    """Rays with one or two zero direction components (the careful box test, which
    keeps its entries where the vector test for any-hit and count walks keeps none),
    from scattered origins in no order (walked one by one, interleaved), through soups
    large enough for a tree of several wide nodes: cast, occluded and count equal a
    brute-force test."""
    rng = np.random.default_rng(seed)
    tris = _soup(rng, n)
    mesh = hsr.Mesh(tris.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3))
    origins = rng.uniform(-2, 2, (400, 3))
    directions = rng.normal(size=(400, 3))
    directions[rng.random((400, 3)) < 0.45] = 0.0
    directions[np.abs(directions).sum(axis=1) == 0, 2] = -1.0
    assert ((directions == 0).sum(axis=1) >= 1).mean() > 0.5
    rays = hsr.RayScene(mesh, threads=1)
    assert rays.bvh.n_wide_nodes > 1
    t, f, _, count = brute_force(tris, origins, directions, 0.0, t_max)
    hits = rays.cast(origins, directions, 0.0, t_max)
    np.testing.assert_array_equal(hits.face_id, f)
    np.testing.assert_allclose(hits.t[f >= 0], t[f >= 0], rtol=1e-9)
    np.testing.assert_array_equal(rays.occluded(origins, directions, 0.0, t_max), f >= 0)
    np.testing.assert_array_equal(rays.count(origins, directions, 0.0, t_max), count)


@pytest.mark.parametrize("name", ["cube", "octahedron", "icosphere"])
def test_count_parity_through_edges_and_vertices(name):
    """From inside a closed mesh every ray crosses it an odd number of times, from
    outside an even number, including rays aimed exactly at its vertices and the
    midpoints of its edges (where two or more triangles meet the ray)."""
    mesh = _closed_meshes()[name]
    rays = hsr.RayScene(mesh)
    verts = mesh.positions
    edges = {tuple(sorted((int(a), int(b)))) for f in mesh.faces for a, b in
             ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    mids = np.array([(verts[a] + verts[b]) / 2 for a, b in edges])
    targets = np.concatenate([verts, mids])
    rng = np.random.default_rng(3)
    inside = np.concatenate([np.zeros((1, 3)), rng.uniform(-0.2, 0.2, (20, 3))])
    for o in inside:
        counts = rays.count(o, targets - o)
        assert (counts % 2 == 1).all(), (o, targets[counts % 2 == 0], counts[counts % 2 == 0])
        assert rays.occluded(o, targets - o).all()
    # From outside, along the same lines (through a vertex or edge midpoint and the
    # centre): the ray enters and leaves.
    far = targets * 3.0
    counts = rays.count(far, -targets)
    assert (counts % 2 == 0).all() and (counts >= 2).all(), counts
    # Exactly once each through an exact vertex / edge from the centre of the cube and
    # octahedron (every coordinate exact in binary).
    if name != "icosphere":
        assert (rays.count(np.zeros(3), targets) == 1).all()
        hits = rays.cast(np.zeros(3), targets)
        np.testing.assert_allclose(hits.t, 1.0)
    o, d = random_rays(mesh.bounds(), 2000, rng)
    _, _, _, brute = brute_force(mesh.positions[mesh.faces], o, d)
    np.testing.assert_array_equal(rays.count(o, d), brute)


def test_results_do_not_depend_on_threads_or_chunks(bunny):
    rng = np.random.default_rng(11)
    origins, directions = random_rays(bunny.bounds(), 30_000, rng)
    one = hsr.RayScene(bunny, threads=1).cast(origins, directions)
    two = hsr.RayScene(bunny, threads=2).cast(origins, directions)
    part = hsr.RayScene(bunny, threads=2).cast(origins[:777], directions[:777])
    for field in ("t", "face_id", "object_id", "barycentric", "normal"):
        np.testing.assert_array_equal(getattr(one, field), getattr(two, field))
        np.testing.assert_array_equal(getattr(one, field)[:777], getattr(part, field))


def test_a_ray_scene_keeps_only_the_walked_tree(bunny):
    """RayScene keeps the walked tree alone (no walk reads the binary one): its arrays
    are those of a build on one thread, and the scene box it keeps is the mesh's own
    bounds."""
    from hsr.algorithms.bvh.sah import build

    rays = hsr.RayScene(bunny)
    full = build(bunny, threads=1)
    assert not hasattr(rays.bvh, "node_min") and not hasattr(rays.bvh, "node_left")
    for field in ("node_box", "node_link", "corners", "leaf_face"):
        np.testing.assert_array_equal(getattr(rays.bvh, field), getattr(full, field))
    assert (rays.bvh.root_ref, rays.bvh.root_count, rays.bvh.wide_depth) == (
        full.root_ref, full.root_count, full.wide_depth)
    np.testing.assert_array_equal(rays.bvh.bounds, np.array(bunny.bounds()))
    assert f"{rays.bvh.n_wide_nodes:,} nodes" in repr(rays)


@pytest.mark.skipif(not os.path.exists("/proc/self/clear_refs"),
                    reason="needs Linux's resettable peak resident size (VmHWM)")
def test_a_ray_scene_build_peaks_at_its_largest_phase():
    """Building a RayScene of a 600k-face terrain in a fresh process: what it holds once
    built is what its arrays take (float64 corners 72 bytes a face, face ids 4, the
    wide records), and its peak while building stays under 200 bytes a face (the
    build's records, 72 + 4, and its binary tree are let go before the walk's arrays
    are made; all held together, with the subtrees' node arrays paged in 2 MB at a
    time, it peaked at 330; Open3D's build peaks at about 140)."""
    import subprocess
    import sys

    code = """
import ctypes, gc
import hsr
libc = ctypes.CDLL("libc.so.6")
def resident():
    gc.collect()
    libc.malloc_trim(0)
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096
def peak():
    with open("/proc/self/status") as fh:
        return next(int(row.split()[1]) * 1024 for row in fh if row.startswith("VmHWM:"))
mesh = hsr.scenes.terrain_mesh(600_000)
# Compiled before the reading, for both layouts of the corners (blocks, rows).
hsr.RayScene(hsr.scenes.terrain_mesh(20_000))
hsr.RayScene(hsr.scenes.terrain_mesh(150_000))
before = resident()
try:
    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")
except OSError:  # (a sandbox may refuse it)
    print("no-reset")
    raise SystemExit(0)
scene = hsr.RayScene(mesh)
top = peak()
b = scene.bvh
arrays = b.corners.nbytes + b.leaf_face.nbytes + b.node_box.nbytes
print((resident() - before) / mesh.n_faces, (top - before) / mesh.n_faces,
      arrays / mesh.n_faces)
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    if "no-reset" in done.stdout:
        pytest.skip("this process may not reset its peak resident size")
    held, peak, arrays = (float(x) for x in done.stdout.split()[-3:])
    assert arrays < 90
    assert held < arrays + 10, (held, arrays)
    assert peak < 200, (peak, held)


def test_concurrent_queries_on_one_scene(bunny):
    from concurrent.futures import ThreadPoolExecutor

    rays = hsr.RayScene(bunny)
    rng = np.random.default_rng(2)
    batches = [random_rays(bunny.bounds(), 5000, rng) for _ in range(8)]
    alone = [rays.cast(o, d).face_id for o, d in batches]
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(lambda od: rays.cast(*od).face_id, batches))
    for a, b in zip(alone, together):
        np.testing.assert_array_equal(a, b)


def test_queries_keep_their_threads_and_leave_a_renders_workspace_alone(bunny):
    """Queries run on the calling thread's kept threads (hsr.parallel.default_workspace),
    not on a pool started and stopped per call: no new pool thread after the first
    call. A query for another thread count leaves the workspace a render kept (with its
    scratch) as it is."""
    import threading

    from hsr import parallel

    parallel.release_default_workspace()
    rays = hsr.RayScene(bunny, threads=2)
    origins, directions = random_rays(bunny.bounds(), 40_000, np.random.default_rng(3))

    first = rays.cast(origins, directions).face_id
    # Every thread started from here on runs this hook first (threading.setprofile).
    started = set()
    threading.setprofile(lambda *_: started.add(threading.current_thread().name))
    try:
        for _ in range(3):
            np.testing.assert_array_equal(rays.cast(origins, directions).face_id, first)
            rays.occluded(origins, directions)
    finally:
        threading.setprofile(None)
    assert not started
    hsr.render(bunny, hsr.Camera.frame(bunny.bounds()), 64, 48, threads=2)
    kept = parallel._THREAD_DEFAULTS.workspace
    scratch = kept.kept_bytes()
    assert scratch > 0
    hsr.RayScene(bunny, threads=3).cast(origins[:9000], directions[:9000])
    assert parallel._THREAD_DEFAULTS.workspace is kept and kept.kept_bytes() == scratch
    parallel.release_default_workspace()


def test_a_scene_of_instances_numbers_faces_and_objects_globally():
    cube = hsr.scenes.cube()
    scene = hsr.Scene().add(cube, name="a").add(cube, np.array(
        [[1, 0, 0, 5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]), name="b")
    rays = hsr.RayScene(scene)
    hits = rays.cast([[0, 0, 10], [5, 0, 10], [10, 0, 10]], [[0, 0, -1]] * 3)
    assert hits.object_id.tolist() == [0, 1, -1]
    assert hits.face_id[1] >= cube.n_faces and hits.face_id[0] < cube.n_faces
    np.testing.assert_allclose(hits.t[:2], 10 - cube.positions[:, 2].max())
    np.testing.assert_allclose(hits.normal[:2], [[0, 0, 1], [0, 0, 1]])
    # Any float dtype, a shared origin, directions of any length.
    h32 = rays.cast(np.float32([0, 0, 10]), np.float32([[0, 0, -2]]))
    assert h32.t[0] == pytest.approx(hits.t[0] / 2)


@pytest.mark.parametrize("origins, directions, kw, message", [
    (np.zeros((2, 3)), np.zeros((3, 3)), {}, "origins must have shape"),
    (np.zeros((2, 2)), np.ones((2, 2)), {}, "directions must have shape (N, 3)"),
    ([[np.nan, 0, 0]], [[0, 0, 1]], {}, "origins must be finite; ray 0"),
    ([[0, 0, 0]], [[0, 0, np.inf]], {}, "directions must be finite"),
    ([[0, 0, 0], [0, 0, 0]], [[0, 0, 1], [0, 0, 0]], {}, "ray 1 is (0, 0, 0)"),
    ([[0, 0, 0]], [[0, 0, 1]], {"t_min": 2.0, "t_max": 1.0}, "t_min must not exceed t_max"),
    ([[0, 0, 0]], [[0, 0, 1]], {"t_min": -1.0}, "t_min must be >= 0"),
    ([[0, 0, 0]], [[0, 0, 1]], {"t_max": np.nan}, "t_max must not be NaN"),
    ([[0, 0, 0]], [[0, 0, 1]], {"t_max": [1.0, 2.0]}, "t_max must be a number or an array"),
    ([["a", 0, 0]], [[0, 0, 1]], {}, "origins must be real numbers"),
    (np.array([[True, False, True]]), [[0, 0, 1]], {}, "origins must be real numbers"),
])
def test_bad_rays_are_refused(origins, directions, kw, message):
    rays = hsr.RayScene(hsr.scenes.cube())
    for query in (rays.cast, rays.occluded, rays.count):
        with pytest.raises(RayError) as info:
            query(origins, directions, **kw)
        assert message in str(info.value)
    assert issubclass(RayError, hsr.HsrError)


def test_empty_queries_and_bad_scenes():
    rays = hsr.RayScene(hsr.scenes.cube())
    assert len(rays.cast(np.zeros((0, 3)), np.zeros((0, 3)))) == 0
    assert rays.count(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0,)
    with pytest.raises(hsr.MeshError):
        hsr.RayScene("missing.obj")
    with pytest.raises(hsr.HsrError):
        hsr.RayScene(hsr.scenes.cube(), threads=0)


def test_a_bad_ray_deep_in_a_large_query_is_the_one_named():
    """Rays are checked chunk by chunk while they are traced: the first bad ray of all
    is reported, whichever chunk finishes first, and per-ray intervals are checked too."""
    rays = hsr.RayScene(hsr.scenes.cube(), threads=2)
    rng = np.random.default_rng(5)
    origins, directions = random_rays(rays.scene.bounds(), 200_000, rng)
    origins[150_001] = np.nan
    directions[77_777] = 0.0
    for query in (rays.cast, rays.occluded, rays.count):
        with pytest.raises(RayError, match="ray 77777 is \\(0, 0, 0\\)"):
            query(origins, directions)
    t_max = np.full(len(origins), 5.0)
    t_max[123_456] = 1.0
    with pytest.raises(RayError, match="ray 123456 has t_min 2.0 > t_max 1.0"):
        rays.cast(origins[:150_000], directions[:150_000] + 1.0, t_min=2.0,
                  t_max=t_max[:150_000])


def test_the_vector_box_test_equals_a_numpy_float32_slab_test():
    """hsr.algorithms.simd.box_keys8 (LLVM vector code; box_mask8, its mask alone)
    against the float32 slab test written here in NumPy lane by lane (NumPy's float32
    operations round as IEEE says, so the bits must agree): boxes around, beside and
    behind the origin, empty lanes (at +inf), thin boxes, a bound cutting some boxes
    off, pads from none to large. A box is entered when t_in <= t_out + pad and t_in <=
    bound; its key (int32) is the bits of max(t_in - pad, 0) (float32) with the lane in
    the lowest three."""
    from numba import njit

    from hsr.algorithms.simd import box_keys8, box_mask8

    @njit
    def entries(box, w, o, inv, pad, bound):
        keys = np.empty(8, dtype=np.int32)
        mask = box_keys8(box, w, o[0], o[1], o[2], inv[0], inv[1], inv[2], pad, bound, keys)
        alone = box_mask8(box, w, o[0], o[1], o[2], inv[0], inv[1], inv[2], pad, bound)
        return keys, mask, alone

    f32 = np.float32
    rng = np.random.default_rng(3)
    n_boxes = 400
    lo = rng.uniform(-2, 2, (n_boxes, 8, 3))
    hi = lo + rng.exponential(0.5, (n_boxes, 8, 3)) * (rng.random((n_boxes, 8, 3)) > 0.1)
    lo[::7, 3], hi[::7, 3] = np.inf, np.inf  # empty lanes
    lo[::5, 7], hi[::5, 7] = np.inf, np.inf
    box = np.concatenate([lo.transpose(0, 2, 1).reshape(n_boxes, 24),
                          hi.transpose(0, 2, 1).reshape(n_boxes, 24),
                          np.zeros((n_boxes, 16))], axis=1).astype(f32)
    lo32, hi32 = box[:, :24].reshape(n_boxes, 3, 8), box[:, 24:48].reshape(n_boxes, 3, 8)
    checked = entered = padded = 0
    with np.errstate(invalid="ignore", over="ignore"):
        for w in range(n_boxes):
            o = rng.uniform(-3, 3, 3).astype(f32)
            aim = (lo[w, w % 3] + hi[w, w % 3]) / 2  # at a box, give or take
            inv = (1.0 / (aim - o + rng.normal(0, 0.3, 3))).astype(f32)
            pad = f32([0.0, 1e-6, 0.05, 0.5][w % 4])
            bound = f32([np.inf, 3.4028235e38, rng.uniform(0, 3)][w % 3])
            t0 = (lo32[w] - o[:, None]) * inv[:, None]
            t1 = (hi32[w] - o[:, None]) * inv[:, None]
            near, far = np.minimum(t0, t1), np.maximum(t0, t1)
            t_in = np.maximum(np.maximum(near[0], near[1]), np.maximum(near[2], f32(0)))
            t_out = np.minimum(np.minimum(far[0], far[1]), far[2])
            hit = (t_in <= t_out + pad) & (t_in <= bound)
            want = np.where(hit, np.maximum(t_in - pad, f32(0)), f32(np.inf)).astype(f32)
            keys, mask, alone = entries(box, w, o, inv, pad, bound)
            np.testing.assert_array_equal(keys & 7, np.arange(8))
            np.testing.assert_array_equal(keys >> 3, want.view(np.int32) >> 3)
            assert mask == alone == sum(1 << k for k in range(8) if hit[k])
            checked += 8
            entered += hit.sum()
            padded += (hit & (t_in > t_out)).sum()
    assert 50 < entered < checked - 50  # both outcomes were exercised
    assert padded > 5  # and boxes entered by the pad alone


def test_the_packet_box_test_equals_a_numpy_slab_test_per_ray():
    """hsr.algorithms.simd.packet_keys8 (four rays against a node's eight boxes, a
    vector of eight boxes per ray) and its careful scalar twin against the slab test
    written here in NumPy for each ray: each ray's entries, the mask of the walking
    rays' entries (bit 4 k + r; rays outside ``active`` count for nothing), and per box
    the key of its walking rays' nearest entry."""
    from numba import njit

    from hsr.algorithms.bvh.boxes import careful_packet_keys8
    from hsr.algorithms.simd import packet_keys8

    @njit
    def run(box, w, rays, bound, active, careful):
        out, keys = np.empty((4, 8)), np.empty(8, dtype=np.int64)
        if careful:
            mask = careful_packet_keys8(box, w, rays, bound, active, out, keys)
        else:
            mask = packet_keys8(box, w, rays, bound, active, out, keys)
        return out, keys, mask

    rng = np.random.default_rng(11)
    n_boxes = 300
    lo = rng.uniform(-2, 2, (n_boxes, 8, 3))
    hi = lo + rng.exponential(0.5, (n_boxes, 8, 3)) * (rng.random((n_boxes, 8, 3)) > 0.1)
    lo[::6, 2], hi[::6, 2] = np.inf, np.inf  # empty lanes
    box = np.concatenate([lo.transpose(0, 2, 1).reshape(n_boxes, 24),
                          hi.transpose(0, 2, 1).reshape(n_boxes, 24),
                          np.zeros((n_boxes, 16))], axis=1).astype(np.float32)
    lo32, hi32 = box[:, :24].reshape(n_boxes, 3, 8), box[:, 24:48].reshape(n_boxes, 3, 8)
    seen = set()
    for w in range(n_boxes):
        o = rng.uniform(-3, 3, (4, 3))
        k = w % 8 if np.isfinite(lo[w, w % 8]).all() else 0  # a lane that is not empty
        aim = (lo[w, k] + hi[w, k]) / 2
        d = aim - o + rng.normal(0, 0.4, (4, 3))
        rays = np.ascontiguousarray(np.concatenate([o.T, (1.0 / d).T]))  # (6, 4)
        bound = rng.choice([np.inf, 1.7976931348623157e308, rng.uniform(0, 3), -1.0], 4)
        bound = np.minimum(bound, 1.7976931348623157e308)
        active = int(rng.integers(1, 16))
        want = np.empty((4, 8))
        for r in range(4):
            t0 = (lo32[w].astype(np.float64) - o[r][:, None]) * rays[3:, r][:, None]
            t1 = (hi32[w].astype(np.float64) - o[r][:, None]) * rays[3:, r][:, None]
            t_in = np.maximum(np.minimum(t0, t1).max(axis=0), 0.0)
            t_out = np.maximum(t0, t1).min(axis=0)
            limit = min(float(bound[r]) * (1.0 + 1e-15) + 1e-300, 1.7976931348623157e308)
            want[r] = np.where((t_in <= t_out * (1.0 + 1e-15) + 1e-300) & (t_in <= limit),
                               t_in, np.inf)
        walking = np.array([(active >> r) & 1 for r in range(4)], dtype=bool)
        nearest = np.where(walking[:, None], want, np.inf).min(axis=0)
        mask_want = sum(1 << (4 * k + r) for k in range(8) for r in range(4)
                        if walking[r] and want[r, k] < np.inf)
        for careful in (False, True):
            out, keys, mask = run(box, w, rays, bound, active, careful)
            np.testing.assert_array_equal(out, want)
            assert mask == mask_want
            np.testing.assert_array_equal(keys & 7, np.arange(8))
            np.testing.assert_array_equal(keys >> 3, nearest.view(np.int64) >> 3)
        seen.add((mask_want != 0, bool(np.isfinite(want[~walking]).any())))
    # Nodes entered and not, and entries of rays not walking that had to be left out.
    assert {(True, True), (False, False), (True, False)} <= seen


def _leaf_trials(rng, tris, layout, trials=800):
    """The four-triangle tests' cases: (n, base, k0, origin, direction), a leaf of n = 1
    .. 4 slots from k0 (in blocks, within the block from base, from any lane it fits
    from; in rows base = k0) and a ray aimed at a corner, an edge's midpoint or the
    inside of one of its triangles, now and then a little off."""
    for trial in range(trials):
        n = 1 + trial % 4
        if layout == "blocks":
            base = 4 * int(rng.integers(0, len(tris) // 4))
            k0 = base + int(rng.integers(0, 5 - n))
        else:
            base = k0 = int(rng.integers(0, len(tris) - n + 1))
        o = rng.normal(size=3) * 3
        target = tris[k0 + trial % n].astype(np.float64)
        aim = [target[0], 0.5 * (target[0] + target[1]), target.mean(axis=0)][trial % 3]
        yield n, base, k0, o, aim - o + (rng.normal(size=3) * 0.05 if trial % 5 == 0 else 0.0)


@pytest.mark.parametrize("layout", ["rows", "blocks"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_four_triangle_filter_equals_the_scalar_tests_first_check(dtype, layout):
    """hsr.algorithms.simd.leaf_filter4 (the watertight test's edge values for four
    slots as vector lanes) against the same check written here in NumPy on the
    triangles' rows, and against the scalar test (bvh._intersect) it stands in front
    of, reading the same corners: a lane is kept exactly when the scalar test does not
    return its early miss. Both layouts of the corners (rows; blocks of four slots,
    the leaf anywhere in its block), leaves of one to four triangles, corners in
    float64 and float32, rays through corners and edges (zero edge values), and
    degenerate triangles (zero sum)."""
    from numba import njit

    from hsr.algorithms.bvh.triangle import intersect as _intersect
    from hsr.algorithms.bvh.triangle import ray_frame
    from hsr.algorithms.simd import leaf_filter4

    @njit
    def run(corners, base, k0, n, o, d):
        kx, ky, kz, sx, sy, sz, okx, oky, okz = ray_frame(o[0], o[1], o[2], d[0], d[1], d[2])
        lanes = ((1 << n) - 1) << (k0 - base)
        mask = leaf_filter4(corners, base, lanes, okx, oky, okz, kx, ky, kz, sx, sy)
        scalar = np.empty(n)
        for i in range(n):
            scalar[i] = _intersect(corners, k0 + i, okx, oky, okz, kx, ky, kz, sx, sy, sz,
                                   0, True, d[0], d[1], d[2])[0]
        return mask, scalar, (kx, ky, kz, sx, sy, okx, oky, okz)

    rng = np.random.default_rng(8)
    tris = rng.normal(size=(4000, 3, 3))
    tris[::9, 2] = tris[::9, 0] + 0.5 * (tris[::9, 1] - tris[::9, 0])  # degenerate
    tris = tris.astype(dtype)
    corners = corner_blocks_of(tris) if layout == "blocks" else tris.reshape(-1, 9)
    kept = cleared = 0
    for n, base, k0, o, d in _leaf_trials(rng, tris, layout):
        mask, scalar, (kx, ky, kz, sx, sy, okx, oky, okz) = run(corners, base, k0, n, o, d)
        assert mask & ~(((1 << n) - 1) << (k0 - base)) == 0  # the leaf's lanes alone
        mask >>= k0 - base
        c = tris[k0:k0 + n].astype(np.float64)
        z = c[:, :, kz] - okz
        x = c[:, :, kx] - okx - sx * z
        y = c[:, :, ky] - oky - sy * z
        u = x[:, 2] * y[:, 1] - y[:, 2] * x[:, 1]
        v = x[:, 0] * y[:, 2] - y[:, 0] * x[:, 2]
        w = x[:, 1] * y[:, 0] - y[:, 1] * x[:, 0]
        miss = (((u < 0) | (v < 0) | (w < 0)) & ((u > 0) | (v > 0) | (w > 0))) | (u + v + w == 0)
        want = sum(1 << i for i in range(n) if not miss[i])
        assert mask == want
        for i in range(n):  # cleared lanes are the scalar test's early misses
            assert ((mask >> i) & 1) == (scalar[i] != -1.0)
        kept += bin(mask).count("1")
        cleared += n - bin(mask).count("1")
    assert kept > 200 and cleared > 200


@pytest.mark.parametrize("layout", ["rows", "blocks"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_the_four_triangle_test_gives_the_scalar_tests_values_bit_for_bit(dtype, layout):
    """hsr.algorithms.simd.leaf_test4 (the whole watertight test in four vector lanes,
    which the interleaved walk takes in place of the scalar test) against the scalar
    test (triangle.intersect, no culling) on the same corners: its bits are
    leaf_filter4's, and for each lane kept, t = row 0 / det and the barycentrics =
    rows 1 .. 3 / det are the scalar test's (t, u, v, w) bit for bit. Both layouts,
    float64 and float32 corners, leaves of one to four slots anywhere in their block,
    rays at corners, edges and insides, degenerate triangles."""
    from numba import njit

    from hsr.algorithms.bvh.triangle import intersect as _intersect
    from hsr.algorithms.bvh.triangle import ray_frame
    from hsr.algorithms.simd import leaf_filter4, leaf_test4

    @njit(error_model="numpy")  # (a missed lane's det may be zero)
    def run(corners, base, k0, n, o, d):
        kx, ky, kz, sx, sy, sz, okx, oky, okz = ray_frame(o[0], o[1], o[2], d[0], d[1], d[2])
        lanes = ((1 << n) - 1) << (k0 - base)
        out = np.full((5, 4), np.nan)
        mask = leaf_test4(corners, base, lanes, okx, oky, okz, kx, ky, kz, sx, sy, sz, out)
        filtered = leaf_filter4(corners, base, lanes, okx, oky, okz, kx, ky, kz, sx, sy)
        got, want = np.zeros((n, 4)), np.zeros((n, 4))
        for i in range(n):
            t, u, v, w = _intersect(corners, k0 + i, okx, oky, okz, kx, ky, kz, sx, sy, sz,
                                    0, True, d[0], d[1], d[2])
            want[i] = t, u, v, w
            lane = k0 - base + i
            det = out[4, lane]
            got[i] = (out[0, lane] / det, out[1, lane] / det, out[2, lane] / det,
                      out[3, lane] / det)
        return mask, filtered, got, want

    rng = np.random.default_rng(18)
    tris = rng.normal(size=(4000, 3, 3))
    tris[::9, 2] = tris[::9, 0] + 0.5 * (tris[::9, 1] - tris[::9, 0])  # degenerate
    tris = tris.astype(dtype)
    corners = corner_blocks_of(tris) if layout == "blocks" else tris.reshape(-1, 9)
    hits = 0
    for n, base, k0, o, d in _leaf_trials(rng, tris, layout):
        mask, filtered, got, want = run(corners, base, k0, n, o, d)
        assert mask == filtered
        for i in range(n):
            if (mask >> (k0 - base + i)) & 1:
                assert want[i, 0] != -1.0  # (no culling: a kept lane is a hit)
                np.testing.assert_array_equal(got[i].view(np.int64), want[i].view(np.int64))
                hits += 1
            else:
                assert want[i, 0] == -1.0
    assert hits > 200


def test_both_layouts_of_the_corners_hold_each_slots_face_and_answer_alike(bunny):
    """The build keeps a scene's corners in blocks of four slots when corners and nodes
    fit in layout.BLOCKS_BYTES (the bunny), else in rows (a 120k-face terrain); either
    way each slot holds its face's corners (checked against the mesh, the blocks'
    padding slots, face -1, zeros: the bunny's leaves are packed, pack_leaves). The same
    tree walked over its blocks and over the same corners as rows (made here from the
    mesh) gives the same answers bit for bit, in
    both walks and for every query, on random, inside and camera rays, with the ray
    caster's ranking too."""
    from hsr.algorithms.bvh import layout
    from hsr.algorithms.bvh.packets import trace_packets
    from hsr.algorithms.bvh.ranking import window_ranking
    from hsr.algorithms.bvh.walk import trace_range

    blocks = hsr.RayScene(bunny).bvh
    terrain = hsr.scenes.terrain_mesh(120_000)
    in_rows = hsr.RayScene(terrain).bvh
    for mesh, bvh, width in ((bunny, blocks, 36), (terrain, in_rows, 9)):
        assert bvh.corners.shape[1] == width
        slots = np.flatnonzero(bvh.leaf_face >= 0)
        rows = mesh.positions[mesh.faces[bvh.leaf_face[slots]]]
        assert np.array_equal(layout.slot_corners(bvh.corners, slots), rows)
    assert (in_rows.leaf_face >= 0).all()  # rows: no padding
    padding = np.concatenate([np.flatnonzero(blocks.leaf_face < 0),
                              np.arange(len(blocks.leaf_face), 4 * len(blocks.corners))])
    assert len(padding) and not layout.slot_corners(blocks.corners, padding).any()
    rows = bunny.positions[bunny.faces[blocks.leaf_face]].reshape(-1, 9)
    rows[blocks.leaf_face < 0] = 0.0
    rng = np.random.default_rng(33)
    lo, hi = np.array(bunny.bounds())
    n = 4000
    origins = np.concatenate([rng.uniform(lo, hi, (n, 3)),
                              rng.uniform(2 * lo - hi, 2 * hi - lo, (n, 3)),
                              np.repeat([[0.0, 0.1, 0.4]], n, axis=0)])
    directions = rng.normal(size=(3 * n, 3))
    directions[2 * n:] = rng.uniform(lo, hi, (n, 3)) - origins[2 * n:]
    m = len(origins)
    cam = hsr.Camera.frame(bunny.bounds(), direction=(0, 0, 1))
    rank = window_ranking(cam.projection_matrix(1.0) @ cam.view_matrix, (0.0, 1.0))
    face_offsets = np.zeros(1, np.int64)
    for kernel in (trace_range, trace_packets):
        for mode, raster in ((0, None), (1, None), (2, None), (0, (1, True, True, rank))):
            answers = []
            for corners in (blocks.corners, rows):
                out = (np.full(m, 7.0), np.full(m, 7, np.int32), np.full(m, 7, np.int32),
                       np.full((m, 2), 7.0), np.full((m, 3), 7.0), np.full(m, 7, np.int32))
                kernel(0, m, origins, directions, np.zeros(1), np.full(1, np.inf), mode,
                       raster, corners, blocks.leaf_face, blocks.node_box, blocks.node_link,
                       blocks.root_ref, blocks.root_count, blocks.wide_depth, face_offsets,
                       *out)
                answers.append(out[:2] + out[3:] if mode == 0 else out[5:])
            for a, b in zip(*answers):
                np.testing.assert_array_equal(a, b)
            if mode == 0:
                assert (answers[0][1] >= 0).sum() > m // 4  # many hits compared


def corner_blocks_of(tris):
    """(F, 3, 3) corners as the walks' corner blocks (hsr.algorithms.bvh.layout's
    corner_blocks: slot k's corner j, coordinate a at [k // 4, 4 (3 j + a) + k % 4]),
    written here apart from the build's gather; the lanes past the last face zeros."""
    blocks = np.zeros(((len(tris) + 3) // 4 * 4, 3, 3), dtype=tris.dtype)
    blocks[:len(tris)] = tris
    return np.ascontiguousarray(blocks.reshape(-1, 4, 3, 3).transpose(0, 2, 3, 1)).reshape(
        -1, 36)


def _exact_slabs(lo, hi, o, d):
    """(t_in, t_out) of the ray o + t d against box [lo, hi], in exact rational
    arithmetic, t_in at least 0."""
    from fractions import Fraction

    t_in, t_out = Fraction(0), None
    for a in range(3):
        t0 = (Fraction(float(lo[a])) - Fraction(float(o[a]))) / Fraction(float(d[a]))
        t1 = (Fraction(float(hi[a])) - Fraction(float(o[a]))) / Fraction(float(d[a]))
        t_in = max(t_in, min(t0, t1))
        t_out = max(t0, t1) if t_out is None else min(t_out, max(t0, t1))
    return t_in, t_out


def _tight_box_rays(rng, n, scale_exponents):
    """Rays aimed at corners of boxes whose bounds are exact in float32 (tight: no outward
    rounding to hide behind), from origins near and far, directions short and long."""
    for _ in range(n):
        unit = np.float32(rng.choice([1.0, 0.1, 1 / 3]))
        lo = (rng.integers(-4, 4, 3) * unit).astype(np.float32)
        hi = (lo + rng.integers(1, 4, 3) * unit).astype(np.float32)
        corner = np.where(rng.random(3) < 0.5, lo, hi).astype(np.float64)
        o = rng.uniform(-20, 20, 3) * 10.0 ** rng.integers(*scale_exponents)
        d = (corner - o) * 10.0 ** rng.uniform(-8, 8)
        yield lo, hi, o, d


def test_the_box_test_never_misses_a_box_the_exact_ray_meets():
    """Rays aimed at corners of tight boxes, origins from 0.1 to 1e6 away and directions
    from 1e-8 to 1e8 long: whenever exact rational arithmetic says the ray meets the box,
    the float32 box test, the careful float64 one and the packets' enter it, also with
    the bound at the exact entry (rounded up to float64: a hit found there, with a
    higher face id, must not hide a box holding an equal one), and the walk's pruning
    by that bound keeps each test's key. Without the float32 test's pad 17% of these
    rays miss their box; with the float64 tests' bound unpadded 1% of the boxes at the
    bound were dropped."""
    from fractions import Fraction

    from numba import njit

    from hsr.algorithms.bvh.boxes import box_bound, box_frame, careful_keys8, slack_bound
    from hsr.algorithms.bvh.stack import bound_key, next_box
    from hsr.algorithms.simd import box_keys8, packet_keys8

    @njit
    def box_entered(box, o, inv, reach, bound):
        """What the walk's float32 box test (its ray from box_frame, bound from box_bound),
        the careful float64 test and the packets' test (four copies of the ray) say of
        lane 0 of ``box``, and whether each key survives the walk's pruning by the
        bound (next_box): (entered, careful entered, packet entered, popped, fits)."""
        keys = np.empty(8, dtype=np.int32)  # the single-ray walks' (the packets' int64)
        ox, oy, oz, ix, iy, iz, pad32, pad, fits = box_frame(o[0], o[1], o[2], inv[0], inv[1],
                                                             inv[2], reach)
        fast = box_keys8(box, 0, ox, oy, oz, ix, iy, iz, pad32, box_bound(bound, pad), keys)
        stack = np.zeros((2, 2), dtype=np.int64)
        stack_t = np.zeros(2, dtype=np.int32)
        stack_t[0] = keys[0]
        careful = careful_keys8(box, 0, o[0], o[1], o[2], inv[0], inv[1], inv[2], bound, keys)
        stack_t[1] = keys[0]
        rays = np.empty((6, 4))
        for a in range(3):
            rays[a, :], rays[3 + a, :] = o[a], inv[a]
        entries = np.empty((4, 8))
        packet = packet_keys8(box, 0, rays, np.full(4, bound), 15, entries,
                              np.empty(8, dtype=np.int64))
        popped = 0
        for j in range(2):
            popped += next_box(stack[0], stack[1], stack_t[j:j + 1], 1, bound_key(bound),
                               0)[3] << j
        # The packet walk's pop keeps a ray's entry within the slack of its bound.
        popped += (entries[0, 0] <= slack_bound(bound)) << 2
        return fast & 1, careful & 1, packet & 1, popped, fits

    rng = np.random.default_rng(7)
    met = 0
    for lo, hi, o, d in _tight_box_rays(rng, 3000, (-1, 6)):
        t_in, t_out = _exact_slabs(lo, hi, o, d)
        if t_in > t_out:
            continue
        met += 1
        box = np.full((1, 64), np.inf, dtype=np.float32)
        box[0, 0:24:8], box[0, 24:48:8] = lo, hi  # lane 0; lanes 1-7 empty
        reach = float(np.abs(np.r_[lo, hi]).max())
        bound = float(t_in)
        if Fraction(bound) < t_in:
            bound = float(np.nextafter(bound, np.inf))
        for b in (1.7976931348623157e308, bound):
            fast, careful, packet, popped, fits = box_entered(box, o, 1.0 / d, reach, b)
            assert fits
            assert (fast, careful, packet, popped) == (1, 1, 1, 7), (lo, hi, o, d, b)
    assert met > 1000


def test_rays_float32_cannot_hold_take_the_careful_box_test():
    """The float32 box test's bound is finite and padded. Rays whose box distances
    would leave float32's range (an origin 1e35 away, a direction component of 1e-120
    whose inverse is 1e120) are not fitted (box_frame) and take the careful float64
    test; the walk answers them as the brute-force reference does, and so does a scene
    whose coordinates are beyond float32's range."""
    from hsr.algorithms.bvh.boxes import box_bound, box_frame

    # The walk's largest bound stays a finite float32: a missed box (entered at +inf)
    # must fail it.
    assert box_bound(1.7976931348623157e308, 1.0) == np.finfo(np.float32).max
    assert box_bound(2.0, 1e-3) >= 2.0 + 1e-3
    assert not box_frame(1e35, 0.0, 0.0, -1e-35, 1.0, 1.0, 1.0)[-1]
    assert not box_frame(0.0, 0.0, 5.0, 1e120, 1.0, -1.0, 1.0)[-1]
    assert box_frame(0.0, 0.0, 5.0, 1.0, 1.0, -1.0, 1.0)[-1]
    mesh = hsr.scenes.cube()
    rays = hsr.RayScene(mesh)
    origins = np.array([[1e35, 0.2, 0.1], [0.3, 0.2, 5.0], [0.3, 0.2, 5.0], [-4.0, 0.1, 0.2]])
    directions = np.array([[-1.0, 0.0, 0.0], [1e-120, -1e-121, -1.0], [0.0, 1e-300, -1.0],
                           [1.0, 1e-130, 1e-125]])
    tris = mesh.positions[mesh.faces]
    want_t = brute_force(tris, origins, directions)[0]
    hits = rays.cast(origins, directions)
    np.testing.assert_array_equal(hits.face_id >= 0, np.isfinite(want_t))
    np.testing.assert_allclose(hits.t, want_t, rtol=1e-12)
    far = hsr.Mesh(mesh.positions * 1e36, mesh.faces)
    far_hits = hsr.RayScene(far).cast(origins[1:3] * [1e36, 1e36, 1e36], directions[1:3])
    np.testing.assert_allclose(far_hits.t, want_t[1:3] * 1e36, rtol=1e-12)


def test_node_records_are_read_where_they_are_written():
    """The box tests and ``child`` find a record by a constant (simd.NODE_BYTES) instead
    of the array's stride: it must be the records' size, and each lane's reference and
    count read back as ``set_child`` wrote them, in every record."""
    from numba import njit

    from hsr.algorithms.bvh.layout import LANES, NODE_WORDS, child, node_records, set_child
    from hsr.algorithms.simd import NODE_BYTES

    @njit
    def write_then_read(link):
        for w in range(link.shape[0]):
            for lane in range(LANES):
                set_child(link, w, lane, 1000 * w + lane, lane - 1)
        out = np.empty((link.shape[0], LANES, 2), dtype=np.int64)
        for w in range(link.shape[0]):
            for lane in range(LANES):
                out[w, lane, 0], out[w, lane, 1] = child(link, w, lane)
        return out

    box, link = node_records(6)
    assert NODE_BYTES == NODE_WORDS * 4 == box.strides[0] == link.strides[0]
    got = write_then_read(link)
    w, lane = np.meshgrid(np.arange(6), np.arange(LANES), indexing="ij")
    np.testing.assert_array_equal(got[..., 0], 1000 * w + lane)
    np.testing.assert_array_equal(got[..., 1], lane - 1)


@pytest.mark.parametrize("width", [32, 64])
def test_the_lane_keys_sort_like_python_and_round_entries_down(width):
    """Keys of entries (their IEEE bits, the lane in the three low bits: float32 in
    int32, as box_keys8 writes them for the single-ray walks, and float64 in int64, the
    packets') sorted by sort_keys8 (a vector sorting network on the keys; min_key8 gives
    the first) against Python's sort of (entry rounded down to eight units in the last
    place, lane) pairs, the rounding done here on NumPy's view of the bits: equal
    entries, zeros, +inf (missed lanes), tiny and huge values; each key's lane is in its
    three low bits and its entry, read back, lies at most seven units in the last place
    below the true one (never above it: the walk's pruning compares it with the
    bound)."""
    from numba import njit

    from hsr.algorithms.simd import float_bits, min_key8, sort_keys8

    real, whole = (np.float32, np.int32) if width == 32 else (np.float64, np.int64)

    @njit
    def keys(e, out):
        for lane in range(8):
            out[lane] = float_bits(e[lane]) & ~7 | lane  # (e's width: 32 or 64 bits)
        least = min_key8(out)  # (the walk takes its next box from it before sorting)
        sort_keys8(out)
        if least != out[0]:
            out[:] = -1
        return out

    rng = np.random.default_rng(11)
    pool = np.array([0.0, 0.0, 1.0, 1.0, 1e-45, 1e-40, 0.5, 2.0, 3e38, np.inf, np.inf]
                    if width == 32 else
                    [0.0, 0.0, 1.0, 1.0, 5e-324, 1e-300, 0.5, 2.0, 1e300, np.inf, np.inf])
    for trial in range(3000):
        e = (rng.choice(pool, 8) if trial % 2 else rng.exponential(1.0, 8)
             * (rng.random(8) > 0.2) + np.where(rng.random(8) < 0.3, np.inf, 0.0))
        e = e.astype(real)
        got = keys(e, np.empty(8, dtype=whole))
        coarse = e.view(whole) >> 3
        assert [k & 7 for k in got] == [lane for _, lane in sorted(zip(coarse, range(8)))]
        if len(set(coarse)) == 8:  # no near-ties: the order of the values themselves
            assert [k & 7 for k in got] == list(np.argsort(e, kind="stable"))
        for k in got:
            true = e[k & 7]
            back = whole(k & ~7).view(real)
            assert back <= true and true.view(whole) - (k & ~7) <= 7


@functools.cache
def _pruning_rule():
    """A kernel of the single-ray walks' pruning rule, compiled once: (below32(entry),
    above32(bound), the key of below32(entry) in ``lane``, bound_key(bound),
    bound_key(-0.0), the bits of below32(+inf) and of below32(1e300) with the lane bits
    set)."""
    from numba import njit

    from hsr.algorithms.bvh.boxes import above32, below32
    from hsr.algorithms.bvh.stack import bound_key
    from hsr.algorithms.simd import float_bits

    @njit
    def rule(entry, bound, lane):
        low = below32(entry)
        return (low, above32(bound), float_bits(low) & ~7 | lane, bound_key(bound),
                bound_key(-0.0), float_bits(below32(np.inf)),
                float_bits(below32(1e300)) | 7)

    return rule


@settings(max_examples=300, deadline=None)
@given(st.floats(0.0, 1e39), st.floats(0.0, 1e39), st.integers(0, 7),
       st.sampled_from([1.0, 1e-30, 1e-40, 1e-44, 1e-300]))
def test_a_key_at_or_before_the_bound_is_never_pruned(entry, above, lane, scale):
    """The single-ray walks' pruning (stack.next_box) keeps a box whose exact entry is at
    most the bound, whatever its lane: below32 gives a float32 at most the entry (the
    careful test's key), above32 one at least the bound, and a key built from the first
    passes bound_key of the second; in float32's normal range, its subnormal range (the
    absolute rounding there), beyond its largest value, at 0 and -0.0 (a hit at t = 0)."""
    from hsr.algorithms.bvh.boxes import FLOAT32_MAX

    entry *= scale
    bound = entry + above * scale
    low, high, key, limit, limit_at_zero, missed, largest = _pruning_rule()(entry, bound,
                                                                            lane)
    assert np.float64(low) <= entry and 0.0 <= low
    assert np.float64(high) >= bound or high == np.float32(FLOAT32_MAX)
    assert key <= limit
    assert key <= limit_at_zero or entry > 0.0
    # A missed lane (+inf) stays after every entered one, however far.
    assert missed == np.float32(np.inf).view(np.int32) and largest < missed


def test_packets_give_the_one_ray_answers_bit_for_bit(bunny):
    """The packet walk against the one-ray walk (two traversals that share only the
    box and triangle tests) on every query, with per-ray intervals, rays from the near
    plane, rays from the eye (packets from one origin, whose box and leaf tests share
    their first steps), rays parallel to axes (the packet's careful box test) and a
    last packet of three rays."""
    from hsr.algorithms.bvh.packets import trace_packets
    from hsr.algorithms.bvh.walk import trace_range

    rays = hsr.RayScene(bunny)
    bvh = rays.bvh
    camera = hsr.Camera.frame(bunny.bounds())
    origins, directions = pixel_rays(camera, 60, 50)
    eye = np.broadcast_to(np.asarray(camera.eye, dtype=np.float64), origins.shape)
    lo, hi = bunny.bounds()
    grid = np.stack(np.meshgrid(np.linspace(lo[0], hi[0], 24), np.linspace(lo[1], hi[1], 24),
                                [hi[2] + 1.0]), -1).reshape(-1, 3)
    directions = np.concatenate([directions, origins + directions - eye,
                                 np.tile([0.0, 0.0, -1.0], (len(grid), 1))])
    origins = np.concatenate([origins, eye, grid])
    origins, directions = origins[:-1], directions[:-1]  # 6,575 rays
    n = len(origins)
    rng = np.random.default_rng(4)
    t_min = rng.uniform(0, 0.3, n) * (rng.random(n) < 0.5)
    t_max = np.where(rng.random(n) < 0.5, np.inf, t_min + rng.uniform(0, 2, n))
    for mode in (0, 1, 2):
        answers = []
        # Each ray walked alone (ranges of one ray), the packets, the interleaved walk.
        for kernel, rows in ((trace_range, [(i, i + 1) for i in range(n)]),
                             (trace_packets, [(0, n)]), (trace_range, [(0, n)])):
            out = (np.full(n, 7.0), np.full(n, 7, np.int32), np.full(n, 7, np.int32),
                   np.full((n, 2), 7.0), np.full((n, 3), 7.0), np.full(n, 7, np.int32))
            for r_lo, r_hi in rows:
                kernel(r_lo, r_hi, origins, directions, t_min, t_max, mode, None,
                       bvh.corners, bvh.leaf_face, bvh.node_box, bvh.node_link,
                       bvh.root_ref, bvh.root_count, bvh.wide_depth, rays.face_offsets,
                       *out)
            answers.append(out if mode == 0 else out[5:])
        for single, packet, interleaved in zip(*answers):
            np.testing.assert_array_equal(single, packet)
            np.testing.assert_array_equal(single, interleaved)
        assert (answers[0][0 if mode == 0 else 0] != 7).all()  # every ray written


def test_rays_from_a_vertex_name_the_lowest_face_around_it(walk_model):
    """A ray from a mesh vertex (t_min 0) meets every face around it at t = 0, a tie
    the lowest face id must win whichever boxes hold those faces, in both single-ray
    walks (the bunny's, the terrain's interleaved one) and in packets (four rays from
    each vertex, one origin). Reference: Moller-Trumbore over every face, each face
    around the vertex turned so that the vertex is its first corner (its t is then
    exactly 0). Before the fix, a hit at t = 0 made the walk's pruning bound the bits of
    0.0, below the keys of the other boxes entered at 0 (their lane in the low bits),
    so their faces were dropped: half of the bunny's rays named a higher face."""
    from hsr.algorithms.bvh.packets import trace_packets

    mesh, rays = walk_model
    bvh = rays.bvh
    rng = np.random.default_rng(21)
    vertex = np.repeat(rng.choice(np.unique(mesh.faces), 50, replace=False), 4)
    origins = mesh.positions[vertex]
    directions = rng.normal(size=(len(origins), 3))
    hits = rays.cast(origins, directions)
    n = len(origins)
    out = (np.empty(n), np.empty(n, np.int32), np.empty(n, np.int32), np.empty((n, 2)),
           np.empty((n, 3)), np.empty(n, np.int32))
    trace_packets(0, n, origins, directions, np.zeros(1), np.full(1, np.inf), 0, None,
                  bvh.corners, bvh.leaf_face, bvh.node_box, bvh.node_link, bvh.root_ref,
                  bvh.root_count, bvh.wide_depth, rays.face_offsets, *out)
    for i, v in enumerate(vertex):
        faces = mesh.faces.copy()
        for turn in (1, 2):  # v first, the winding kept
            at = faces[:, turn] == v
            faces[at] = np.roll(faces[at], -turn, axis=1)
        want_t, want_f = brute_force(mesh.positions[faces], origins[i:i + 1],
                                     directions[i:i + 1])[:2]
        assert want_t[0] == 0.0
        assert (hits.t[i], hits.face_id[i]) == (0.0, want_f[0]), i
        assert (out[0][i], out[1][i]) == (0.0, want_f[0]), i


def test_interleaved_walks_answer_each_ray_as_if_walked_alone(walk_model):
    """trace_range walks SLOTS rays in turn in a scene above INTERLEAVE_BYTES (a
    120k-face terrain), switching at leaves and at wide nodes past HOT_NODES (its tree
    has more): every ray of a long chunk (slots refilled thousands of times, a last
    round part-full) gets, in all three queries, exactly what it gets walked alone (a
    range of one ray), with random and axis-parallel rays (the careful box test) mixed
    and per-ray intervals; a sample's any-hit answers equal brute force. A 30k-face
    terrain, below INTERLEAVE_BYTES, walks each ray to its end: the same holds."""
    from hsr.algorithms.bvh.layout import HOT_NODES
    from hsr.algorithms.bvh.walk import SLOTS, trace_range

    mesh, rays = walk_model
    bvh = rays.bvh
    assert bvh.n_wide_nodes > HOT_NODES
    rng = np.random.default_rng(12)
    origins, directions = random_rays(mesh.bounds(), 2500, rng)
    lo, hi = mesh.bounds()
    grid = np.column_stack([rng.uniform(lo[0], hi[0], 300), rng.uniform(lo[1], hi[1], 300),
                            np.full(300, hi[2] + 1.0)])
    origins = np.concatenate([origins, grid])
    directions = np.concatenate([directions, np.tile([0.0, 0.0, -1.0], (300, 1))])
    order = rng.permutation(len(origins))[:-3]  # 2,797 rays: not a multiple of SLOTS
    origins, directions = origins[order], directions[order]
    n = len(origins)
    assert n % SLOTS != 0
    t_min = rng.uniform(0, 0.3, n) * (rng.random(n) < 0.5)
    t_max = np.where(rng.random(n) < 0.5, np.inf, t_min + rng.uniform(0, 2, n))
    sample = rng.choice(n, 150, replace=False)

    def walk(mode, rows):
        # Garbage no answer can be (a terrain's ray may cross it seven times).
        out = (np.full(n, -7.0), np.full(n, -7, np.int32), np.full(n, -7, np.int32),
               np.full((n, 2), -7.0), np.full((n, 3), -7.0), np.full(n, -7, np.int32))
        for r_lo, r_hi in rows:
            trace_range(r_lo, r_hi, origins, directions, t_min, t_max, mode, None,
                        bvh.corners, bvh.leaf_face, bvh.node_box, bvh.node_link,
                        bvh.root_ref, bvh.root_count, bvh.wide_depth, rays.face_offsets,
                        *out)
        return out if mode == 0 else out[5:]

    for mode in (0, 1, 2):
        together = walk(mode, [(0, n)])
        alone = walk(mode, [(i, i + 1) for i in range(n)])
        assert (together[0] != -7).all()  # every ray written
        for a, b in zip(together, alone):
            np.testing.assert_array_equal(a, b)
        if mode == 1:
            counts = [brute_force(mesh.positions[mesh.faces], origins[i:i + 1],
                                  directions[i:i + 1], t_min[i], t_max[i])[3][0]
                      for i in sample]
            np.testing.assert_array_equal(together[0][sample], np.array(counts) > 0)
            assert 20 < np.count_nonzero(counts) < 130  # hits and misses both tested


def test_rays_that_miss_the_root_are_answered_as_misses_between_walking_rays(walk_model):
    """trace_range answers a ray that enters none of the root's boxes as it reads it,
    without a slot: in a long chunk where runs of such rays (pointing away from the
    model, or towards it but stopped short by t_max) sit between rays that walk, every
    output of every ray is written (outputs start as garbage) and equals the packet
    walk's, which has no such shortcut; the rays stopped short answer as misses, and
    the nearest hits of a sample equal brute force. A 30k-face terrain is walked a ray
    at a time, a 120k-face terrain (above INTERLEAVE_BYTES) eight rays in turn."""
    from hsr.algorithms.bvh.packets import trace_packets
    from hsr.algorithms.bvh.walk import trace_range

    mesh, rays = walk_model
    bvh = rays.bvh
    rng = np.random.default_rng(21)
    lo, hi = np.array(mesh.bounds())
    center, size = (lo + hi) / 2, np.linalg.norm(hi - lo)
    n = 3001
    away = rng.normal(size=(n, 3))
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    origins = center + 2 * size * away
    kind = rng.integers(0, 3, n)  # 0: away, 1: towards but short, 2: into the box
    targets = rng.uniform(lo, hi, (n, 3))
    directions = np.where((kind == 0)[:, None], away, targets - origins)
    t_max = np.where(kind == 1, 0.2, np.inf)
    t_min = np.zeros(1)
    answers = []
    for kernel in (trace_range, trace_packets):
        out = (np.full(n, 7.0), np.full(n, 7, np.int32), np.full(n, 7, np.int32),
               np.full((n, 2), 7.0), np.full((n, 3), 7.0), np.full(n, 7, np.int32))
        kernel(0, n, origins, directions, t_min, t_max, 0, None, bvh.corners,
               bvh.leaf_face, bvh.node_box, bvh.node_link, bvh.root_ref, bvh.root_count,
               bvh.wide_depth, rays.face_offsets, *out)
        counts = np.full(n, 7, np.int32)
        kernel(0, n, origins, directions, t_min, t_max, 2, None, bvh.corners,
               bvh.leaf_face, bvh.node_box, bvh.node_link, bvh.root_ref, bvh.root_count,
               bvh.wide_depth, rays.face_offsets, *out[:5], counts)
        answers.append((*out[:5], counts))
    for mine, packets in zip(*answers):
        np.testing.assert_array_equal(mine, packets)
    t, face, object_id, uv, normal, count = answers[0]
    missed = kind < 2
    assert np.isinf(t[missed]).all() and (face[missed] == -1).all()
    assert (object_id[missed] == -1).all() and (count[missed] == 0).all()
    assert (uv[missed] == 0).all() and (normal[missed] == 0).all()
    assert 0.2 < (face[kind == 2] >= 0).mean() < 1.0  # some walk to a hit, some do not
    sample = rng.choice(np.flatnonzero(kind == 2), 40, replace=False)
    want_t, want_f, _, _ = brute_force(mesh.positions[mesh.faces], origins[sample],
                                       directions[sample])
    np.testing.assert_array_equal(face[sample], want_f)
    np.testing.assert_allclose(t[sample][want_f >= 0], want_t[want_f >= 0], rtol=1e-9)

def test_camera_rays_cut_short_answer_occluded_as_brute_force(bunny):
    """Camera rays, coherent and as many as four a triangle (so RayScene walks them in
    packets), a third of them stopped around where they meet the model: rays of one
    packet stop at different depths, and one ray's hit must not answer its neighbour.
    ``occluded`` equals the one-ray walk on all and brute force on a sample."""
    from hsr.algorithms.bvh.hits import ANY
    from hsr.algorithms.bvh.walk import trace_range
    from hsr.visibility.rays import _coherent

    rays = hsr.RayScene(bunny)
    bvh = rays.bvh
    cam = hsr.Camera.frame(bunny.bounds())
    view_proj = cam.projection_matrix(1.0) @ cam.view_matrix
    inv = np.linalg.inv(view_proj)
    # A 560 x 560 crop at the middle of a 1000 x 1000 view: pixels smaller than the
    # triangles, so neighbouring rays often meet the same one.
    xs = (np.arange(220, 780) + 0.5) / 1000 * 2 - 1
    gx, gy = np.meshgrid(xs, -xs)
    far = np.c_[gx.ravel(), gy.ravel(), np.ones(gx.size), np.ones(gx.size)] @ inv.T
    directions = far[:, :3] / far[:, 3:] - np.asarray(cam.eye)
    n = len(directions)
    origins = np.tile(np.asarray(cam.eye, dtype=np.float64), (n, 1))
    assert n >= 4 * len(bunny.faces) and _coherent(origins, directions, rays.scene_size)
    rng = np.random.default_rng(3)
    # The hit distance is about 0.3-0.5 of the way to the far plane: stop a third of
    # the rays around there.
    t_max = np.where(rng.random(n) < 0.3, rng.uniform(0.2, 0.6, n), np.inf)
    plain = np.full(n, 7, np.int32)
    trace_range(0, n, origins, directions, np.zeros(1), t_max, ANY, None, bvh.corners,
                bvh.leaf_face, bvh.node_box, bvh.node_link, bvh.root_ref, bvh.root_count,
                bvh.wide_depth, rays.face_offsets, np.empty(0), np.empty(0, np.int32),
                np.empty(0, np.int32), np.empty((0, 2)), np.empty((0, 3)), plain)
    sample = rng.choice(n, 200, replace=False)
    hit = [brute_force(bunny.positions[bunny.faces], origins[i:i + 1], directions[i:i + 1],
                       0.0, t_max[i])[3][0] > 0 for i in sample]
    np.testing.assert_array_equal(plain[sample], hit)
    cut = np.isfinite(t_max)
    assert 0 < plain[cut].sum() < cut.sum()  # cut rays both hit and stop short
    np.testing.assert_array_equal(rays.occluded(origins, directions, t_max=t_max), plain)


@pytest.mark.parametrize("name", ["cube", "octahedron", "icosphere"])
def test_axis_parallel_packets_count_and_hit_like_brute_force(name):
    """Rays along -z (coherent, so walked in packets, and parallel to two axes, so
    through the careful box test) through closed meshes: counts and nearest hits equal
    a brute-force test."""
    mesh = _closed_meshes()[name]
    rays = hsr.RayScene(mesh)
    # Runs of four rays 1/1000 apart (a packet each) from a 21 x 21 grid whose points
    # on the diagonal x = y lie exactly on the cube's face diagonals.
    base = np.stack(np.meshgrid(np.linspace(-1.5, 1.5, 21), np.linspace(-1.5, 1.5, 21)),
                    -1).reshape(-1, 1, 2)
    xy = (base + np.array([[0, 0], [1e-3, 0], [2e-3, 0], [3e-3, 0]])).reshape(-1, 2)
    origins = np.hstack([xy, np.full((len(xy), 1), 3.0)])
    directions = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
    assert _coherent(origins, directions, rays.scene_size)
    t, face, _, count = brute_force(mesh.positions[mesh.faces], origins, directions)
    # Rays in the plane of a side face graze it: ambiguous, left out (the brute force
    # counts each triangle there).
    inside = (np.abs(xy) < 1.0 - 1e-9).all(axis=1) if name == "cube" else np.ones(len(xy), bool)
    got = rays.count(origins, directions)
    np.testing.assert_array_equal(got[inside] % 2, 0)
    hits = rays.cast(origins, directions)
    np.testing.assert_array_equal(hits.hit[inside], np.isfinite(t[inside]))
    np.testing.assert_allclose(hits.t[inside], t[inside], rtol=1e-12)
    assert (count[inside & hits.hit] >= 1).all()


def test_huge_finite_rays_are_not_refused():
    """The rays' quick check sums coordinates: one that overflows to inf is a false
    alarm the exact check clears (a bug here refused good rays as 'not finite')."""
    rays = hsr.RayScene(hsr.scenes.cube())
    origins = np.array([[1e308, 1e308, 0.0], [0.0, 0.0, 5.0]])
    directions = np.array([[-1.0, -1e308, 0.0], [0.0, 0.0, -1.0]])
    hits = rays.cast(origins, directions, t_max=1e300)
    assert hits.face_id[0] == -1 and hits.face_id[1] >= 0
    assert rays.count(origins, directions).tolist() == [0, 2]


def test_bad_rays_in_a_coherent_query_raise_only_the_error():
    """Camera-like rays with a zero direction and a NaN origin among them: the check for
    packets meets them first and must stay quiet (no NumPy warning), the walk refuses."""
    import warnings

    rays = hsr.RayScene(hsr.scenes.cube())
    origins = np.tile([0.0, 0.0, 5.0], (4000, 1))
    directions = np.tile([0.0, 0.0, -1.0], (4000, 1)) + np.linspace(0, 1e-3, 4000)[:, None]
    directions[8] = 0.0
    origins[12] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(RayError, match="ray 8 is \\(0, 0, 0\\)"):
            rays.cast(origins, directions)


def test_coherent_rays_that_miss_along_an_axis_warn_nothing(models_dir):
    """Camera-like rays from one point, half of them missing with a zero direction
    component: the footprint estimate that chooses their walk (which casts a sample of
    them) must not multiply a miss's infinite distance by that zero (NumPy's "invalid
    value" warning reached the user), and the answers equal the brute force's."""
    import warnings

    cow = hsr.load(os.path.join(models_dir, "cow.obj"))
    rays = hsr.RayScene(cow)
    n = 4096
    origins = np.tile([0.0, 0.0, 10.0], (n, 1))
    directions = np.zeros((n, 3))
    directions[:, 0] = np.linspace(-0.02, 0.02, n)
    directions[:, 2] = -1.0
    directions[n // 2:, 0] = 0.0  # along the axis past the model: they miss
    directions[n // 2:, 1] = np.linspace(1.0, 1.01, n - n // 2)
    directions[n // 2:, 2] = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hits = rays.cast(origins, directions)
    expected_t, expected_face, _, _ = brute_force(cow.positions[cow.faces], origins,
                                                  directions)
    assert (hits.face_id[n // 2:] == -1).all() and (hits.face_id[:n // 2] >= 0).any()
    np.testing.assert_array_equal(hits.face_id, expected_face)
    np.testing.assert_allclose(hits.t, expected_t, rtol=1e-9)


def test_float32_vertices_keep_float32_corners_and_every_answer(bunny):
    """A scene whose vertices are all float32 values (as binary PLY, STL and glTF give
    them) keeps its BVH corners in float32; every query and the ray caster (with back
    faces culled, whose facing test reads the corners) answer bit for bit as with the
    same corners in float64, on random rays, camera rays and rays through vertices."""
    from hsr.algorithms.bvh.sah import build

    mesh32 = hsr.Mesh(bunny.positions.astype(np.float32).astype(np.float64), bunny.faces)
    rays32 = hsr.RayScene(mesh32)
    assert rays32.bvh.corners.dtype == np.float32
    assert hsr.RayScene(bunny).bvh.corners.dtype == np.float64  # OBJ text: not float32
    rays64 = hsr.RayScene(mesh32)
    rays64.bvh.corners = rays64.bvh.corners.astype(np.float64)
    rng = np.random.default_rng(21)
    o_rand, d_rand = random_rays(mesh32.bounds(), 20_000, rng)
    o_cam, d_cam = pixel_rays(hsr.Camera.frame(mesh32.bounds()), 120, 90)
    corner = mesh32.positions[rng.choice(len(mesh32.positions), 500)]
    o_vtx = corner + rng.normal(size=(500, 3))
    for o, d in ((o_rand, d_rand), (o_cam, d_cam), (o_vtx, corner - o_vtx)):
        a, b = rays32.cast(o, d), rays64.cast(o, d)
        for field in ("t", "face_id", "object_id", "barycentric", "normal"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
        np.testing.assert_array_equal(rays32.count(o, d), rays64.count(o, d))
        np.testing.assert_array_equal(rays32.occluded(o, d), rays64.occluded(o, d))
        assert a.hit.any()
    cam = hsr.Camera.frame(mesh32.bounds())
    tree32, tree64 = build(mesh32), build(mesh32)
    tree64.corners = tree64.corners.astype(np.float64)
    state = hsr.RenderState(cull="back")
    f32 = hsr.render(mesh32, cam, 160, 120, algorithm="raycast", state=state,
                     options={"bvh": tree32})
    f64 = hsr.render(mesh32, cam, 160, 120, algorithm="raycast", state=state,
                     options={"bvh": tree64})
    np.testing.assert_array_equal(f32.face_id, f64.face_id)
    np.testing.assert_array_equal(f32.depth, f64.depth)
    assert (f32.face_id >= 0).any()


def test_the_facing_test_reads_float32_corners_in_float64():
    """The triangle test's facing (culling) on rays grazing their triangles, where the
    sign of n . d rests on the last bits of the cross product: float32 corners give
    exactly the float64 corners' answers, so the arithmetic is float64 in both."""
    from numba import njit

    from hsr.algorithms.bvh.triangle import intersect as _intersect
    from hsr.algorithms.bvh.triangle import ray_frame

    def test_all(tris, origins, directions, cull_code):
        # (The corners as the walks keep them: rows of nine values.)
        return test_rows(np.ascontiguousarray(tris).reshape(len(tris), 9), origins,
                         directions, cull_code)

    @njit
    def test_rows(tris, origins, directions, cull_code):
        out = np.empty((len(origins), 4))
        for i in range(len(origins)):
            ox, oy, oz = origins[i, 0], origins[i, 1], origins[i, 2]
            dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
            kx, ky, kz, sx, sy, sz, okx, oky, okz = ray_frame(ox, oy, oz, dx, dy, dz)
            out[i, 0], out[i, 1], out[i, 2], out[i, 3] = _intersect(
                tris, i, okx, oky, okz, kx, ky, kz, sx, sy, sz, cull_code, True, dx, dy, dz)
        return out

    rng = np.random.default_rng(8)
    n = 4000
    tris = rng.normal(size=(n, 3, 3)).astype(np.float32)
    a, b, c = (tris[:, k].astype(np.float64) for k in range(3))
    normal = np.cross(b - a, c - a)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    tangent = np.cross(normal, rng.normal(size=(n, 3)))
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    tilt = 10.0 ** rng.uniform(-10, -5, n) * rng.choice([-1.0, 1.0], n)
    directions = tangent + tilt[:, None] * normal
    origins = (a + b + c) / 3 - directions
    # Independently: a culled test answers as the unculled one (every ray meets its
    # triangle, at t = 1) where numpy's float64 facing keeps the face, and misses
    # where it culls it (rays whose facing is too close to 0 to call are left out).
    unculled = test_all(tris.astype(np.float64), origins, directions, 0)
    assert (unculled[:, 0] >= 0).all()
    facing = np.einsum("ij,ij->i", np.cross(b - a, c - a), directions)
    clear = np.abs(facing) > 1e-9 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    for cull_code in (1, 2):
        got32 = test_all(tris, origins, directions, cull_code)
        got64 = test_all(tris.astype(np.float64), origins, directions, cull_code)
        np.testing.assert_array_equal(got32, got64)
        # Front (the normal opposing the ray) is kept when back faces are culled (1).
        kept = (facing < 0) == (cull_code == 1)
        np.testing.assert_array_equal(got64[clear & kept], unculled[clear & kept])
        assert (got64[clear & ~kept, 0] == -1.0).all()
        hit = got64[:, 0] >= 0
        assert 0.2 < hit.mean() < 0.8  # both facings met, culled and kept
