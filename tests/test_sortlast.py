"""Partitioned scenes and sort-last rendering (hsr.partition, hsr.batch.render_partitioned):
the composited frames must equal hsr.render of the whole scene bit for bit, in every
buffer, for any number of parts, every cull mode and the depth functions that order
fragments, including exact depth ties between faces in different parts and parts whose
boxes overlap; the reference is the single-process render, an independent path through
the same z-buffer (no compositing)."""

import math
import os
import re

import numpy as np
import pytest

import hsr
from conftest import CASES_DIR, MODELS_DIR, coplanar_soup
from hsr.batch import composite, render_partitioned
from hsr.errors import CameraError, MeshError
from hsr.scene.partitioned import PartitionError, open_partitioned

pytest.importorskip("zarr")

BUFFERS = ("face_id", "depth", "object_id", "color", "eye_depth", "distance", "normals")
OUTPUTS = ("color", "eye_depth", "distance", "normals")


def assert_same(frames, scene, cameras, width, height, **options):
    for frame, cam in zip(frames, cameras, strict=True):
        whole = hsr.render(scene, cam, width, height, **options)
        for name in BUFFERS:
            got, want = getattr(frame, name), getattr(whole, name)
            assert got.dtype == want.dtype, name
            assert np.array_equal(got, want, equal_nan=True), \
                f"{name}: {np.count_nonzero(got != want)} pixels differ"


def tie_scene() -> hsr.Scene:
    """Instances with model matrices (rotated, scaled, moved), a coplanar soup whose faces
    overlap at exactly equal depths, and two copies of one cube at the same place (every
    fragment of one ties with the other's), so that ties fall between parts."""
    soup, _ = coplanar_soup(60, seed=7)
    scene = hsr.Scene()
    scene.add(soup, np.diag([2.0, 2.0, 1.0, 1.0]) @ hsr.scenes.translate(0, 0, 3.0))
    cube = hsr.scenes.cube()
    turn = hsr.scenes.rotate_y(30) @ hsr.scenes.scale(0.7)
    scene.add(cube, hsr.scenes.translate(0.3, 0.2, -1.0) @ turn)
    scene.add(cube, hsr.scenes.translate(0.3, 0.2, -1.0) @ turn)
    scene.add(hsr.scenes.uv_sphere(0.6), hsr.scenes.translate(-0.8, -0.3, -0.5))
    return scene


@pytest.fixture(scope="module")
def tie_stores(tmp_path_factory):
    scene = tie_scene()
    folder = tmp_path_factory.mktemp("stores")
    return scene, {k: hsr.partition(scene, k, folder / f"ties{k}.zarr") for k in (1, 2, 3, 7)}


def tie_cameras():
    return [hsr.Camera.look_at((0.4, 0.3, 6.0), (0, 0, -1), fov_y=40, near=0.5, far=20),
            hsr.Camera.look_at((-3.0, 2.0, 4.0), (0, 0, -1), fov_y=50, near=0.5, far=20)]


@pytest.mark.parametrize("parts", [1, 2, 3, 7])
@pytest.mark.parametrize("cull", ["none", "back", "front", "front_and_back"])
@pytest.mark.parametrize("depth_func", ["less", "lequal"])
def test_sort_last_equals_one_render(tie_stores, parts, cull, depth_func):
    scene, stores = tie_stores
    cams = tie_cameras()
    frames = render_partitioned(stores[parts], cams, 96, 72, outputs=OUTPUTS, cull=cull,
                                depth_func=depth_func, light="studio")
    assert_same(frames, scene, cams, 96, 72, cull=cull, depth_func=depth_func,
                light="studio")


def test_the_scene_has_ties_across_parts_and_overlapping_parts(tie_stores):
    """The fixture does what the tests above need: with 7 parts, some pixel is covered by
    faces of two parts at exactly the same window depth (a tie only the global face order
    can break), and some parts' boxes overlap."""
    from hsr.batch.sortlast import render_part

    _, stores = tie_stores
    store = stores[7]
    partial = [render_part(store, p, tie_cameras(), 96, 72, (), {})["frames"]
               for p in range(store.parts)]
    ties = sum(int(np.count_nonzero((a["face_id"] >= 0) & (b["face_id"] >= 0)
                                    & (a["depth"] == b["depth"])))
               for i, a in enumerate(partial) for b in partial[i + 1:])
    assert ties > 50
    boxes = [store.part_bounds(p) for p in range(store.parts)]
    assert any(np.all(a[0] < b[1]) and np.all(b[0] < a[1])
               for i, a in enumerate(boxes) for b in boxes[i + 1:])


@pytest.mark.parametrize("depth_func,clear", [("greater", 0.0), ("gequal", 0.0),
                                              ("always", 1.0)])
def test_other_ordering_depth_functions(tie_stores, depth_func, clear):
    scene, stores = tie_stores
    cams = tie_cameras()
    frames = render_partitioned(stores[3], cams, 64, 48, outputs=("color",),
                                depth_func=depth_func, clear_depth=clear)
    for frame, cam in zip(frames, cams, strict=True):
        whole = hsr.render(scene, cam, 64, 48, depth_func=depth_func, clear_depth=clear)
        assert np.array_equal(frame.face_id, whole.face_id)
        assert np.array_equal(frame.depth, whole.depth)
        assert np.array_equal(frame.color, whole.color)


def test_a_shared_model_in_parts(models_dir, tmp_path):
    mesh = hsr.load(os.path.join(models_dir, "spot.obj"))
    store = hsr.partition(os.path.join(models_dir, "spot.obj"), 5, tmp_path / "spot.zarr")
    assert isinstance(hsr.load_scene(tmp_path / "spot.zarr"), hsr.PartitionedScene)
    cams = hsr.views.sphere(mesh.bounds(), 3, aspect=4 / 3)
    frames = render_partitioned(store, cams, 120, 90, outputs=OUTPUTS, views_per_task=2,
                                light="studio", cull="back")
    assert_same(frames, mesh, cams, 120, 90, light="studio", cull="back")
    loaded = sorted((s["part"], s["faces_loaded"]) for s in frames[0].stats)
    assert loaded == list(enumerate(store.part_faces))  # each part once, only its faces
    assert sum(store.part_faces) == mesh.n_faces


def test_parts_are_compact(models_dir, tmp_path):
    """Morton order makes each part a small region: the parts' boxes of the bunny in 8
    parts hold far less volume than 8 parts of randomly drawn faces."""
    mesh = hsr.load(os.path.join(models_dir, "stanford-bunny.obj"))
    store = hsr.partition(mesh, 8, tmp_path / "bunny.zarr")

    def volume(box):
        return float(np.prod(box[1] - box[0]))

    morton = sum(volume(store.part_bounds(p)) for p in range(8))
    tris = mesh.positions[mesh.faces]
    shuffled = np.random.default_rng(0).permutation(mesh.n_faces)
    random = sum(volume(np.stack([tris[ids].reshape(-1, 3).min(0),
                                  tris[ids].reshape(-1, 3).max(0)]))
                 for ids in np.array_split(shuffled, 8))
    assert morton < 0.3 * random


def test_composite_is_associative_and_commutative(tie_stores):
    """Any reduction tree gives the same frame: ((a b) c) = (a (b c)) = (c (b a))."""
    from hsr.batch.sortlast import render_part

    _, stores = tie_stores
    store = stores[3]
    cams = tie_cameras()
    a, b, c = (render_part(store, p, cams, 64, 48, ("color",), {})["frames"]
               for p in range(3))
    for func in ("less", "lequal", "always"):
        left = composite(composite(a, b, func), c, func)
        right = composite(a, composite(b, c, func), func)
        turned = composite(c, composite(b, a, func), func)
        for name in left:
            assert np.array_equal(left[name], right[name]), (func, name)
            assert np.array_equal(left[name], turned[name]), (func, name)


def test_on_a_dask_cluster(tie_stores, tmp_path):
    distributed = pytest.importorskip("distributed")
    scene, stores = tie_stores
    store = stores[7]
    cams = tie_cameras() * 3
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                  silence_logs=50) as cluster, \
            distributed.Client(cluster) as client:
        frames = render_partitioned(store, cams, 80, 60, outputs=OUTPUTS, client=client,
                                    views_per_task=2, depth_func="lequal", cull="back")
        counts = hsr.visibility.face_visibility(store, cams, (80, 60), client=client,
                                                depth_func="lequal", cull="back")
    assert_same(frames, scene, cams, 80, 60, depth_func="lequal", cull="back")
    assert np.array_equal(counts, hsr.visibility.face_visibility(
        scene, cams, (80, 60), depth_func="lequal", cull="back"))
    for frame in frames:
        loaded = sorted((s["part"], s["faces_loaded"]) for s in frame.stats)
        assert loaded == list(enumerate(store.part_faces))


def test_writing_is_all_or_nothing(tmp_path, monkeypatch):
    """A failure part way leaves nothing under the output name and no temporary folder."""
    from hsr.scene import partition as writer

    calls = []
    real = writer._part_arrays

    def failing(*args):
        calls.append(1)
        if len(calls) == 3:
            raise OSError("disk full")
        return real(*args)

    monkeypatch.setattr(writer, "_part_arrays", failing)
    with pytest.raises(OSError):
        hsr.partition(tie_scene(), 5, tmp_path / "s.zarr")
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("parts", [0, -1, True, 2.0, 10 ** 9])
def test_bad_part_counts_are_refused(tmp_path, parts):
    with pytest.raises(PartitionError, match="parts must be"):
        hsr.partition(hsr.scenes.cube(), parts, tmp_path / "s.zarr")
    assert os.listdir(tmp_path) == []


def test_bad_outputs_are_refused(tmp_path):
    (tmp_path / "taken.zarr").mkdir()
    (tmp_path / "taken.zarr" / "mine.txt").write_text("a user's file")
    with pytest.raises(PartitionError, match="holds other files"):
        hsr.partition(hsr.scenes.cube(), 2, tmp_path / "taken.zarr")
    with pytest.raises(PartitionError, match="does not exist"):
        hsr.partition(hsr.scenes.cube(), 2, tmp_path / "no" / "s.zarr")
    with pytest.raises(PartitionError, match="not a store hsr wrote"):
        hsr.partition(hsr.scenes.cube(), 2, tmp_path / "taken.zarr", overwrite=True)
    with pytest.raises(PartitionError, match="not a partitioned scene"):
        open_partitioned(tmp_path / "taken.zarr")
    assert (tmp_path / "taken.zarr" / "mine.txt").read_text() == "a user's file"
    (tmp_path / "empty.zarr").mkdir()  # an empty folder is a place to write
    assert hsr.partition(hsr.scenes.cube(), 2, tmp_path / "empty.zarr").parts == 2


@pytest.mark.parametrize("options,match", [
    ({"depth_func": "notequal"}, "depth function"),
    ({"depth_func": "equal"}, "depth function"),
    ({"depth_mask": False}, "depth_mask"),
    ({"depth_test": False}, "depth_test"),
    ({"polygon_mode": "line"}, "filled"),
    ({"counts": True}, "counts"),
    ({"hidden_line": True}, "hidden_line"),
    ({"algorithm": "raycast"}, "algorithm must be zbuffer"),
    ({"shading": "depth"}, "whole image"),
    ({"shading": "random"}, "face ids"),
])
def test_options_compositing_cannot_honour_are_refused(tie_stores, options, match):
    _, stores = tie_stores
    with pytest.raises(PartitionError, match=match):
        render_partitioned(stores[2], tie_cameras(), 32, 24, **options)


def test_other_bad_requests_are_refused(tie_stores, tmp_path):
    scene, stores = tie_stores
    store = stores[2]
    with pytest.raises(PartitionError, match="unknown output"):
        render_partitioned(store, tie_cameras(), 32, 24, outputs=("texture",))
    with pytest.raises(CameraError):
        render_partitioned(store, [], 32, 24)
    with pytest.raises(CameraError):
        render_partitioned(store, ["camera"], 32, 24)
    with pytest.raises(PartitionError, match="views_per_task"):
        render_partitioned(store, tie_cameras(), 32, 24, views_per_task=0)
    with pytest.raises(hsr.RenderError):
        render_partitioned(store, tie_cameras(), 0, 24)
    with pytest.raises(PartitionError, match="part must be"):
        store.part(2)
    with pytest.raises(MeshError, match="partitioned"):
        hsr.render(store, tie_cameras()[0], 32, 24)
    glass = hsr.Scene().add(hsr.scenes.cube(), opacity=0.5)
    see_through = hsr.partition(glass, 2, tmp_path / "glass.zarr")
    with pytest.raises(PartitionError, match="transparent"):
        render_partitioned(see_through, tie_cameras(), 32, 24)
    assert math.isfinite(store.bounds().sum())


def test_the_command_line(models_dir, tmp_path, monkeypatch):
    """hsr partition, then hsr batch STORE: the files equal hsr.render of the model from
    the same cameras; the manifest names each view's parts and the faces they loaded."""
    import json

    from PIL import Image

    from conftest import run_cli
    from hsr.batch.tasks import place_cameras

    monkeypatch.chdir(tmp_path)
    model = os.path.join(models_dir, "spot.obj")
    code, err = run_cli(["partition", model, "--parts", "3", "--out", "spot.zarr", "--quiet"])
    assert code == 0, err
    code, err = run_cli(["batch", "spot.zarr", "--views", "sphere:4", "--size", "96x72",
                         "--outputs", "color,ids,window_depth,eye_depth,normals",
                         "--out", "out", "--cull", "back", "--quiet"])
    assert code == 0, err
    mesh = hsr.load(model)
    store = hsr.load_scene("spot.zarr")
    cams = place_cameras(store, ("set", "sphere", 4, 20.0), (96, 72))
    for view, cam in enumerate(cams):
        want = hsr.render(mesh, cam, 96, 72, cull="back", light="studio")
        folder = os.path.join("out", "spot")
        assert np.array_equal(np.asarray(Image.open(f"{folder}/color/{view:04d}.png")),
                              want.color)
        assert np.array_equal(np.load(f"{folder}/ids/{view:04d}.npy"), want.face_id)
        assert np.array_equal(np.load(f"{folder}/window_depth/{view:04d}.npy"), want.depth)
        assert np.array_equal(np.load(f"{folder}/eye_depth/{view:04d}.npy"), want.eye_depth)
        assert np.array_equal(np.load(f"{folder}/normals/{view:04d}.npy"), want.normals)
    rows = json.load(open("out/manifest.json"))["tasks"]
    assert [r["status"] for r in rows] == ["ok"] * 4
    assert all(r["parts"] == [0, 1, 2] and r["faces_loaded"] == store.part_faces for r in rows)


@pytest.mark.parametrize("args,message", [
    (["--parts", "0"], "parts must be"),
    (["--parts", "2", "--out", "missing/s.zarr"], "does not exist"),
    (["--parts", "two"], "invalid int value"),
])
def test_the_command_line_refuses_bad_input(models_dir, tmp_path, monkeypatch, args,
                                             message):
    from conftest import run_cli

    monkeypatch.chdir(tmp_path)
    argv = ["partition", os.path.join(models_dir, "spot.obj")] + args
    if "--out" not in args:
        argv += ["--out", "s.zarr"]
    code, err = run_cli(argv)
    assert code == 2 and len(err) == 1 and err[0].startswith("hsr: error:"), err
    assert message in err[0]
    assert os.listdir(tmp_path) == []


def test_stores_are_only_for_batch(models_dir, tmp_path, monkeypatch):
    from conftest import run_cli

    monkeypatch.chdir(tmp_path)
    model = os.path.join(models_dir, "spot.obj")
    assert run_cli(["partition", model, "--parts", "2", "--out", "s.zarr", "--quiet"])[0] == 0
    for argv in (["render", "s.zarr", "-o", "x.png"], ["partition", model, "--parts", "2",
                                                       "--out", "s.zarr"],
                 ["batch", "s.zarr", model], ["visibility", "s.zarr", "--views", "sphere:2",
                                              "-o", "v.npz"]):
        code, err = run_cli(argv)
        assert code == 2 and len(err) == 1 and err[0].startswith("hsr: error:"), (argv, err)
    assert sorted(os.listdir(tmp_path)) == ["s.zarr"]


def test_a_killed_worker_is_recovered(tmp_path):
    """SIGKILL one worker while the sort-last job runs: Dask loads its parts again and
    reruns its tasks elsewhere; every frame is still the whole scene's render."""
    import signal
    import threading
    import time

    distributed = pytest.importorskip("distributed")
    scene = hsr.Scene().add(hsr.scenes.terrain_mesh(60_000))
    store = hsr.partition(scene, 6, tmp_path / "t.zarr")
    cams = hsr.views.sphere(store.bounds(), 80, aspect=4 / 3)
    outcome = {}
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                  silence_logs=50) as cluster, \
            distributed.Client(cluster) as client:

        def job():
            outcome["frames"] = render_partitioned(store, cams, 96, 72, client=client,
                                                   views_per_task=2)

        thread = threading.Thread(target=job)
        thread.start()
        deadline = time.time() + 60
        while time.time() < deadline and sum(len(keys) for keys in
                                             client.has_what().values()) < 12:
            time.sleep(0.01)
        pids = client.run(os.getpid)
        killed_mid_job = thread.is_alive()
        os.kill(sorted(pids.values())[0], signal.SIGKILL)
        thread.join(180)
    assert killed_mid_job, "the job ended before the kill: make it longer"
    assert not thread.is_alive()
    frames = outcome["frames"]
    assert len(frames) == 80
    for k in range(0, 80, 11):
        whole = hsr.render(scene, cams[k], 96, 72)
        assert np.array_equal(frames[k].face_id, whole.face_id)
        assert np.array_equal(frames[k].color, whole.color)


def reset_peak_rss() -> None:
    """Linux: reset this process's peak resident set size (VmHWM) to its current size."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


def peak_rss_mb() -> float:
    """Linux: this process's peak resident set size (VmHWM) in MB."""
    with open("/proc/self/status") as f:
        line = next(row for row in f if row.startswith("VmHWM:"))
    return int(line.split()[1]) / 1024


def test_workers_under_a_memory_limit_render_a_scene_none_of_them_could_hold(tmp_path):
    """A 4M-face terrain: one process that loads and renders it peaks above 450 MB
    (measured here in a fresh process); in 8 parts on two workers limited to 450 MB each,
    every worker's peak stays under the limit and the frames are the whole render's."""
    import subprocess
    import sys

    distributed = pytest.importorskip("distributed")
    mesh = hsr.scenes.terrain_mesh(4_000_000)
    np.save(tmp_path / "p.npy", mesh.positions)
    np.save(tmp_path / "f.npy", mesh.faces)
    limit_mb = 450
    whole = subprocess.run([sys.executable, "-c", f"""
import resource, numpy as np, hsr
m = hsr.Mesh(np.load({str(tmp_path / 'p.npy')!r}), np.load({str(tmp_path / 'f.npy')!r}))
hsr.render(m, hsr.views.default(m.bounds(), 4 / 3), 256, 192)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""], capture_output=True, text=True, timeout=300)
    assert whole.returncode == 0, whole.stderr[-2000:]
    whole_mb = float(whole.stdout.split()[-1])
    assert whole_mb > limit_mb
    store = hsr.partition(mesh, 8, tmp_path / "terrain.zarr")
    cams = [hsr.views.default(mesh.bounds(), 4 / 3), hsr.views.default(
        mesh.bounds(), 4 / 3, view=(-60, 40))]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  memory_limit=f"{limit_mb}MB", host="127.0.0.1",
                                  dashboard_address="127.0.0.1:0",
                                  silence_logs=50) as cluster, \
            distributed.Client(cluster) as client:
        client.run(reset_peak_rss)  # a worker may start as a copy of this big process
        frames = render_partitioned(store, cams, 256, 192, client=client)
        peaks = client.run(peak_rss_mb)
    print(f"whole scene in one process: peak {whole_mb:.0f} MB; workers' peaks: "
          f"{', '.join(f'{v:.0f}' for v in peaks.values())} MB (limit {limit_mb} MB)")
    assert len(peaks) == 2 and max(peaks.values()) < limit_mb, peaks
    for frame, cam in zip(frames, cams, strict=True):
        want = hsr.render(mesh, cam, 256, 192)
        assert np.array_equal(frame.face_id, want.face_id)
        assert np.array_equal(frame.depth, want.depth)
        assert np.array_equal(frame.color, want.color)


def test_visibility_of_a_partitioned_scene_equals_the_whole_scenes(tie_stores, tmp_path):
    """face_visibility and visibility_matrix take a store (or its path) and count after
    compositing: the same counts, cosines and distances as for the scene in memory."""
    from hsr.visibility import VisibilityError, face_visibility

    scene, stores = tie_stores
    store = stores[3]
    cams = tie_cameras()
    whole = face_visibility(scene, cams, (96, 72), cull="back")
    assert np.array_equal(face_visibility(store, cams, (96, 72), cull="back"), whole)
    assert np.array_equal(face_visibility(store.path, cams, (96, 72), cull="back"), whole)
    assert whole.sum() > 0
    want = hsr.visibility_matrix(scene, cams, (96, 72), quality=True)
    got = hsr.visibility_matrix(store, cams, (96, 72), quality=True)
    for name in ("counts", "cosine", "distance"):
        a, b = getattr(want, name), getattr(got, name)
        assert (a != b).nnz == 0 and a.shape == b.shape, name
    with pytest.raises(VisibilityError, match="partitioned"):
        hsr.visible_faces(store.path, cams[0], 32, 24)
    with pytest.raises(PartitionError, match="algorithm must be zbuffer"):
        face_visibility(store, cams, 32, algorithm="raycast")


def test_a_ply_larger_than_the_address_space_allows_still_partitions(tmp_path):
    """A binary PLY of 3M faces: under a 950 MB address-space cap (RLIMIT_AS) loading it
    and partitioning in memory fails, hsr partition streams it and succeeds; the store
    has the same parts as the in-memory path, and its sort-last frames are hsr.render's
    of the loaded mesh."""
    import resource
    import subprocess
    import sys

    ply = tmp_path / "big.ply"
    hsr.write_mesh(hsr.scenes.terrain_mesh(3_000_000), ply)
    cap = 950 * 2 ** 20

    def capped(code: str):
        def limit():
            resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

        env = dict(os.environ, MALLOC_ARENA_MAX="2")
        return subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                              preexec_fn=limit, capture_output=True, text=True, timeout=600)

    in_memory = capped("import hsr; hsr.partition(hsr.load('big.ply'), 8, 'memory.zarr')")
    assert in_memory.returncode != 0 and not (tmp_path / "memory.zarr").exists()
    streamed = capped("import sys; from hsr.cli import main; "
                      "sys.exit(main(['partition', 'big.ply', '--parts', '8', '--out', "
                      "'big.zarr', '--quiet']))")
    assert streamed.returncode == 0, streamed.stderr[-2000:]
    store = hsr.load_scene(tmp_path / "big.zarr")
    mesh = hsr.load(ply)
    assert store.n_faces == mesh.n_faces and store.parts == 8
    reference = hsr.partition(mesh, 8, tmp_path / "reference.zarr")
    for p in (0, 5):
        assert np.array_equal(store.part(p)[1], reference.part(p)[1])
    cams = hsr.views.sphere(mesh.bounds(), 2, aspect=4 / 3)
    for frame, cam in zip(render_partitioned(store, cams, 96, 72), cams, strict=True):
        whole = hsr.render(mesh, cam, 96, 72)
        assert np.array_equal(frame.face_id, whole.face_id)
        assert np.array_equal(frame.color, whole.color)


def test_streaming_refuses_what_it_cannot_read(tmp_path):
    from hsr.scene.partition import partition_streamed

    quads = tmp_path / "quads.ply"
    header = (b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n"
              b"property float y\nproperty float z\nelement face 1\n"
              b"property list uchar int vertex_indices\nend_header\n")
    body = np.zeros((4, 3), "<f4").tobytes() + bytes([4]) + np.arange(4, dtype="<i4").tobytes()
    quads.write_bytes(header + body)
    with pytest.raises(MeshError):
        partition_streamed(quads, 1, tmp_path / "q.zarr")
    outside = tmp_path / "outside.ply"
    outside.write_bytes(header.replace(b"face 1", b"face 1") + np.zeros((4, 3), "<f4").tobytes()
                        + bytes([3]) + np.array([0, 1, 9], "<i4").tobytes())
    with pytest.raises(MeshError, match="outside"):
        partition_streamed(outside, 1, tmp_path / "o.zarr")
    truncated = tmp_path / "truncated.ply"
    truncated.write_bytes(header + body[:20])
    with pytest.raises(MeshError, match="shorter"):
        partition_streamed(truncated, 1, tmp_path / "t.zarr")
    with pytest.raises(MeshError):
        partition_streamed(tmp_path, 1, tmp_path / "d.zarr")  # a folder, not a file
    assert sorted(os.listdir(tmp_path)) == ["outside.ply", "quads.ply", "truncated.ply"]


def test_a_store_assembles_into_the_scene_it_came_from(tie_stores):
    scene, stores = tie_stores
    assembled = stores[7].assemble()
    assert len(assembled.instances) == len(scene.instances)
    for got, want in zip(assembled.instances, scene.instances, strict=True):
        a, b = got.mesh, want.mesh
        assert np.array_equal(a.positions[a.faces], b.positions[b.faces])
        assert np.array_equal(got.model, want.model) and got.name == want.name
        for name in ("face_colors", "corner_colors", "corner_uv", "corner_normals"):
            x, y = getattr(a, name), getattr(b, name)
            assert (x is None and y is None) or np.array_equal(x, y), name


def test_prune_of_a_store_equals_prune_of_the_scene(models_dir, tmp_path, monkeypatch):
    """hsr.prune and hsr prune take a store: counted part by part, cut in memory; the same
    kept faces and the same pruned geometry as pruning the scene itself."""
    from conftest import run_cli

    housing = hsr.Scene()
    housing.add(hsr.scenes.tessellated_cube(6), hsr.scenes.scale(2.0))
    housing.add(hsr.scenes.uv_sphere(0.5), hsr.scenes.translate(0.2, 0.1, 0.0))  # hidden
    housing.add(hsr.scenes.uv_sphere(0.4), hsr.scenes.translate(3.5, 0.0, 0.0))  # outside
    store = hsr.partition(housing, 4, tmp_path / "housing.zarr")
    views = ["sphere:24"]
    pruned, kept = hsr.prune(housing, views, 128, keep_neighbors=1)
    pruned_store, kept_store = hsr.prune(store, views, 128, keep_neighbors=1)
    assert np.array_equal(kept, kept_store) and 0 < len(kept) < housing.n_faces
    for got, want in zip(pruned_store.instances, pruned.instances, strict=True):
        a, b = got.mesh, want.mesh
        assert np.array_equal(a.positions[a.faces], b.positions[b.faces])
    monkeypatch.chdir(tmp_path)
    code, err = run_cli(["prune", "housing.zarr", "-o", "kept.ply", "--views", "sphere:24",
                         "--size", "128", "--keep-neighbors", "1", "--quiet"])
    assert code == 0, err
    written = hsr.load(tmp_path / "kept.ply")
    assert written.n_faces == len(kept)


def test_long_work_shows_progress_only_when_asked_or_on_a_terminal(tie_stores, tmp_path,
                                                                   capsys):
    from hsr.scene.partition import partition_streamed

    _, stores = tie_stores
    render_partitioned(stores[2], tie_cameras(), 32, 24)
    assert capsys.readouterr().err == ""  # piped: quiet
    render_partitioned(stores[2], tie_cameras(), 32, 24, progress=True)
    assert "sort-last" in capsys.readouterr().err
    hsr.write_mesh(hsr.scenes.terrain_mesh(5000), tmp_path / "t.ply")
    partition_streamed(tmp_path / "t.ply", 2, tmp_path / "a.zarr")
    assert capsys.readouterr().err == ""
    partition_streamed(tmp_path / "t.ply", 2, tmp_path / "b.zarr", progress=True)
    assert "partition" in capsys.readouterr().err


def test_batch_of_a_store_on_local_worker_processes(tie_stores, tmp_path):
    """hsr.batch.render_views(STORE, workers=2): a local cluster of two processes shares
    the parts; the ids equal hsr.render's."""
    pytest.importorskip("distributed")
    from hsr.batch import render_views
    from hsr.batch.tasks import place_cameras

    scene, stores = tie_stores
    result = render_views(stores[3].path, "sphere:3", (64, 48), ("ids",), tmp_path / "out",
                          workers=2)
    assert result.rendered == 3 and result.failed == 0
    cams = place_cameras(stores[3], ("set", "sphere", 3, 20.0), (64, 48))
    stem = os.path.splitext(os.path.basename(stores[3].path))[0]
    for view, cam in enumerate(cams):
        got = np.load(tmp_path / "out" / stem / "ids" / f"{view:04d}.npy")
        assert np.array_equal(got, hsr.render(scene, cam, 64, 48).face_id)


def _shared_obj_files() -> list:
    """The shared OBJ models and failure cases; without ../shared one placeholder, so
    that the test skips through the models_dir fixture (fails in CI) instead of breaking
    the collection."""
    names = []
    for kind, folder in (("models", MODELS_DIR), ("cases", CASES_DIR)):
        if os.path.isdir(folder):
            names += [os.path.join(kind, n) for n in os.listdir(folder) if n.endswith(".obj")]
    return sorted(names) or ["models/(shared models not found)"]


OBJ_FILES = _shared_obj_files()


@pytest.mark.parametrize("name", OBJ_FILES)
def test_obj_read_in_chunks_gives_the_faces_hsr_load_gives(models_dir, name, tmp_path):
    """Every shared model and every OBJ behind a known failure, read in chunks of 37
    bytes (lines, continuations and CR LF pairs across every boundary) and partitioned
    streaming: the same positions and faces as hsr.load, or a MeshError wherever
    hsr.load refuses the geometry (a refused material or texture does not stop it:
    streaming keeps geometry only)."""
    from hsr.scene.obj_stream import ObjStream
    from hsr.scene.partition import partition_streamed

    path = os.path.join(os.path.dirname(models_dir), name)
    try:
        mesh, refused = hsr.load(path), None
    except MeshError as exc:
        mesh, refused = None, str(exc)
    try:
        stream = ObjStream(path, str(tmp_path), chunk_bytes=37)
        store = partition_streamed(path, 1, tmp_path / "s.zarr")
    except MeshError:
        assert mesh is None, "streaming refused what hsr.load reads"
        return
    if mesh is None:
        assert re.search(r"\.mtl|material|texture|Kd|image|pixels", refused), refused
        return
    faces = np.concatenate([c for _, c in stream.face_chunks(1000)])
    assert np.array_equal(stream.positions, mesh.positions)
    assert np.array_equal(faces, mesh.faces)
    whole = store.assemble().instances[0].mesh
    assert np.array_equal(whole.positions[whole.faces], mesh.positions[mesh.faces])


def test_an_obj_partitions_streaming_from_the_command_line(models_dir, tmp_path,
                                                          monkeypatch):
    from conftest import run_cli

    monkeypatch.chdir(tmp_path)
    model = os.path.join(models_dir, "stanford-bunny.obj")
    code, err = run_cli(["partition", model, "--parts", "4", "--out", "s.zarr", "--stream",
                         "--quiet"])
    assert code == 0, err
    streamed = hsr.load_scene("s.zarr")
    loaded = hsr.partition(hsr.load(model), 4, tmp_path / "m.zarr")
    for p in range(4):
        assert np.array_equal(streamed.part(p)[1], loaded.part(p)[1])
    code, err = run_cli(["partition", model, model, "--parts", "2", "--out", "t.zarr",
                         "--stream"])
    assert code == 2 and "one MODEL" in err[0]
    glb = glb_cases(tmp_path)[0]
    code, err = run_cli(["partition", str(glb), "--parts", "2", "--out", "g.zarr",
                         "--stream", "--quiet"])
    assert code == 0, err
    assert [i["name"] for i in hsr.load_scene("g.zarr").instances] == ["left", "ball",
                                                                       "right"]


def test_groups_come_as_they_are_composited(tie_stores):
    """each_partitioned yields each group once, with its first view's index; together
    they are render_partitioned's frames. Bad requests fail before any work."""
    from hsr.batch import each_partitioned

    _, stores = tie_stores
    cams = tie_cameras() * 3
    whole = render_partitioned(stores[3], cams, 48, 36, views_per_task=4)
    groups = sorted(each_partitioned(stores[3], cams, 48, 36, views_per_task=4),
                    key=lambda g: g[0])
    assert [first for first, _ in groups] == [0, 4]
    frames = [f for _, fs in groups for f in fs]
    assert len(frames) == 6
    for a, b in zip(frames, whole, strict=True):
        assert np.array_equal(a.face_id, b.face_id) and np.array_equal(a.color, b.color)
    with pytest.raises(PartitionError):
        each_partitioned(stores[3], cams, 48, 36, depth_func="never")


def test_a_damaged_store_is_refused_in_one_line(tmp_path):
    """A store is read from disk: damaged metadata or parts are a PartitionError naming
    what is wrong, never an IndexError or a wrong frame."""
    import json
    import shutil

    good = hsr.partition(tie_scene(), 3, tmp_path / "good.zarr")
    cams = tie_cameras()[:1]

    def damaged(name, change_meta=None, change_part=None):
        path = tmp_path / name
        shutil.copytree(good.path, path)
        if change_meta:
            doc = json.loads((path / "zarr.json").read_text())
            change_meta(doc["attributes"]["hsr"])
            (path / "zarr.json").write_text(json.dumps(doc))
        if change_part:
            import zarr

            change_part(zarr.open_group(str(path / "part_0001"), mode="r+"))
        return path

    for name, change, match in (
            ("parts.zarr", lambda m: m.update(parts=5), "part_faces"),
            ("faces.zarr", lambda m: m.update(n_faces=-1), "positive"),
            ("model.zarr", lambda m: m["instances"][0].update(model=[1, 2]), "16 finite"),
            ("offsets.zarr", lambda m: m["instances"][1].update(face_offset=10 ** 9),
             "offsets"),
            ("attrs.zarr", lambda m: m["instances"][0].update(attributes=["evil"]),
             "attributes")):
        with pytest.raises(PartitionError, match=match):
            open_partitioned(damaged(name, change_meta=change))

    def out_of_range(group):
        faces = group["faces"][...]
        faces[0, 0] = 10 ** 6
        group["faces"][...] = faces

    def unsorted(group):
        ids = group["face_id"][...]
        group["face_id"][...] = ids[::-1]

    def removed(group):
        del group["positions"]

    for name, change, match in (("range.zarr", out_of_range, "outside"),
                                ("order.zarr", unsorted, "part 1, array face_id: face ids "
                                 "must ascend"),
                                ("missing.zarr", removed, "part 1, array positions")):
        with pytest.raises(PartitionError, match=match):
            render_partitioned(damaged(name, change_part=change), cams, 32, 24)
    shutil.rmtree(tmp_path / "good.zarr" / "part_0002")
    with pytest.raises(PartitionError, match="part 2"):
        render_partitioned(open_partitioned(tmp_path / "good.zarr", check_parts=False),
                           cams, 32, 24)
    with pytest.raises(PartitionError, match="part 2"):
        open_partitioned(tmp_path / "good.zarr")


def test_batch_of_a_store_to_zarr_and_resumed(tie_stores, tmp_path, monkeypatch):
    """--format zarr writes the composited views into a store of their own (ids equal to
    hsr.render's); --resume skips every view already done, and redoes one whose mark is
    cleared; the input store is never the output."""
    pytest.importorskip("distributed")
    import zarr

    from hsr.batch import BatchError, render_views
    from hsr.batch.tasks import place_cameras

    scene, stores = tie_stores
    store = stores[2]
    stem = os.path.splitext(os.path.basename(store.path))[0]
    out = tmp_path / "out"
    first = render_views(store.path, "sphere:4", (48, 36), ("ids", "color"), out,
                         format="zarr")
    assert first.rendered == 4
    group = zarr.open_group(str(out / f"{stem}.zarr"), mode="r")
    cams = place_cameras(store, ("set", "sphere", 4, 20.0), (48, 36))
    for view, cam in enumerate(cams):
        want = hsr.render(scene, cam, 48, 36)
        assert np.array_equal(group["ids"][view], want.face_id)
        assert np.array_equal(group["color"][view], want.color)
    again = render_views(store.path, "sphere:4", (48, 36), ("ids", "color"), out,
                         format="zarr", resume=True)
    assert again.skipped == 4 and again.rendered == 0
    zarr.open_group(str(out / f"{stem}.zarr"), mode="r+")["done"][2] = 0
    redo = render_views(store.path, "sphere:4", (48, 36), ("ids", "color"), out,
                        format="zarr", resume=True)
    assert redo.rendered == 1 and [r["view"] for r in redo.rows if r["status"] == "ok"] == [2]
    files = render_views(store.path, "sphere:4", (48, 36), ("ids",), tmp_path / "files")
    assert files.rendered == 4
    assert render_views(store.path, "sphere:4", (48, 36), ("ids",), tmp_path / "files",
                        resume=True).skipped == 4
    monkeypatch.chdir(os.path.dirname(store.path))
    with pytest.raises(BatchError, match="the partitioned scene itself"):
        render_views(os.path.basename(store.path), "sphere:2", (32, 24), ("ids",), ".",
                     format="zarr")


def glb_cases(tmp_path) -> list:
    """GLB files as trimesh writes them and as tests/test_scenes_gltf.py edits them: three
    transformed nodes, a shared mesh in a reordered tree, two primitives in one mesh, and
    a model hsr writes with its materials."""
    from test_scenes_gltf import glb_bytes, rewrite_glb, shared_tree, three_nodes, two_primitives

    scene, _, _ = three_nodes()
    paths = [tmp_path / "three.glb", tmp_path / "tree.glb", tmp_path / "prims.glb",
             tmp_path / "written.glb"]
    paths[0].write_bytes(glb_bytes(scene))
    paths[1].write_bytes(rewrite_glb(glb_bytes(scene), shared_tree))
    paths[2].write_bytes(rewrite_glb(glb_bytes(scene), two_primitives))
    hsr.write_mesh(tie_scene(), paths[3])
    return paths


def test_a_glb_partitions_streaming_into_the_instances_load_scene_makes(tmp_path):
    """Streamed: the same instances (names, meshes, matrices to the bit), faces, parts,
    part boxes and scene box as partitioning hsr.load_scene's scene, and sort-last ids
    and depth equal to hsr.render of it (colours aside: streaming keeps geometry)."""
    from hsr.scene.partition import partition_streamed

    for k, path in enumerate(glb_cases(tmp_path)):
        loaded = hsr.load_scene(path)
        geometry = hsr.Scene([hsr.Instance(hsr.Mesh(i.mesh.positions, i.mesh.faces,
                                                    name=i.mesh.name), i.model, i.opacity,
                                           i.name) for i in loaded.instances])
        parts = min(3, geometry.n_faces)
        streamed = partition_streamed(path, parts, tmp_path / f"s{k}.zarr", chunk=7)
        reference = hsr.partition(geometry, parts, tmp_path / f"m{k}.zarr")
        assert streamed.instances == reference.instances, path.name
        assert streamed.meta["bounds"] == reference.meta["bounds"]
        for p in range(parts):
            a, b = streamed._arrays(p), reference._arrays(p)
            for name in ("positions", "faces", "face_id", "vertex_start", "vertex_id"):
                assert np.array_equal(a[name], b[name]), (path.name, p, name)
            assert streamed.part_bounds(p).tolist() == reference.part_bounds(p).tolist()
        cam = hsr.views.default(loaded, 4 / 3)
        frame = render_partitioned(streamed, [cam], 96, 72, outputs=("eye_depth",))[0]
        whole = hsr.render(loaded, cam, 96, 72)
        assert np.array_equal(frame.face_id, whole.face_id)
        assert np.array_equal(frame.depth, whole.depth)
        assert np.array_equal(frame.eye_depth, whole.eye_depth)


def test_a_glb_streaming_cannot_read_is_refused(tmp_path):
    from test_scenes_gltf import glb_bytes, rewrite_glb, three_nodes

    from hsr.scene.partition import partition_streamed

    scene, _, _ = three_nodes()

    def strips(h):
        for mesh in h["meshes"]:
            for prim in mesh["primitives"]:
                prim["mode"] = 5

    def outside(h):
        h["bufferViews"][0]["byteLength"] = 10 ** 9

    for name, edit, match in (("strips.glb", strips, "not plain triangles"),
                              ("outside.glb", outside, "runs past the end of buffer 0")):
        path = tmp_path / name
        path.write_bytes(rewrite_glb(glb_bytes(scene), edit))
        with pytest.raises(MeshError, match=match):
            partition_streamed(path, 1, tmp_path / "x.zarr")
    assert not (tmp_path / "x.zarr").exists()


def test_hsr_batch_of_a_store_with_a_scheduler_address(tie_stores, tmp_path):
    """The command line against a running scheduler (a LocalCluster's address, as
    `dask scheduler` would give): the files equal hsr.render's."""
    distributed = pytest.importorskip("distributed")
    from conftest import run_cli
    from hsr.batch.tasks import place_cameras

    scene, stores = tie_stores
    store = stores[3]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                  silence_logs=50) as cluster:
        code, err = run_cli(["batch", store.path, "--views", "orbit:3", "--size", "64x48",
                             "--outputs", "ids,window_depth", "--out", str(tmp_path / "o"),
                             "--scheduler", cluster.scheduler_address, "--quiet"])
    assert code == 0, err
    stem = os.path.splitext(os.path.basename(store.path))[0]
    cams = place_cameras(store, ("set", "orbit", 3, 20.0), (64, 48))
    for view, cam in enumerate(cams):
        want = hsr.render(scene, cam, 64, 48, light="studio")
        folder = tmp_path / "o" / stem
        assert np.array_equal(np.load(folder / "ids" / f"{view:04d}.npy"), want.face_id)
        assert np.array_equal(np.load(folder / "window_depth" / f"{view:04d}.npy"),
                              want.depth)
