"""``hsr batch`` on a real Dask cluster (issue #15): a LocalCluster of two worker processes on
the loopback interface, and a scheduler and a worker started as separate processes for the
CLI's --scheduler. Every output is compared with ``hsr.render`` run here, view by view."""

import json
import math
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

import hsr
from hsr.batch import BatchError, render_views
from hsr.cli import main

distributed = pytest.importorskip("distributed")

SIZE = (96, 72)


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                       silence_logs=50)
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture(scope="module")
def models(models_dir):
    return [os.path.join(models_dir, "spot.obj"), os.path.join(models_dir, "african_head.obj")]


def expected(model, cam, size=SIZE, **options):
    return hsr.render(hsr.load_scene(model), cam, *size, **options)


def test_batch_matches_render_view_by_view(client, models, tmp_path):
    bad = tmp_path / "corrupt.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    out = tmp_path / "out"
    result = render_views(models + [str(bad)], "orbit:8", SIZE,
                          ("color", "eye_depth", "ids", "normals", "window_depth"), out, client,
                          shading="gouraud", cull="back", light="studio")
    rows = json.loads((out / "manifest.json").read_text())["tasks"]
    assert len(rows) == 24 and rows == result.rows
    assert [(r["model"], r["view"]) for r in rows] == [(m, v) for m in models + [str(bad)]
                                                        for v in range(8)]
    # The corrupt model fails alone, each of its views with the reader's one-line error.
    assert all(r["status"] == "ok" for r in rows[:16])
    assert all(r["status"] == "failed" and "vertex index 7" in r["error"] for r in rows[16:])
    for model in models:
        stem = os.path.splitext(os.path.basename(model))[0]
        scene = hsr.load_scene(model)
        cams = hsr.views.orbit(scene.bounds(), 8, 20.0, SIZE[0] / SIZE[1])
        # transforms.json reads back into the same cameras (a NeRF file has no near and
        # far planes: the rows of the projection that place pixels must agree).
        read, files, size = hsr.read_transforms(out / stem / "transforms.json")
        assert size == SIZE and files[5] == "color/0005.png"
        for cam, back in zip(cams, read):
            assert np.allclose(cam.view_matrix, back.view_matrix, atol=1e-9)
            assert np.allclose(cam.projection_matrix(4 / 3)[[0, 1, 3]],
                               back.projection_matrix(4 / 3)[[0, 1, 3]], atol=1e-9)
        for v in (0, 3, 7):
            want = hsr.render(scene, cams[v], *SIZE, shading="gouraud", cull="back",
                              light="studio")
            got = np.asarray(Image.open(out / stem / "color" / f"{v:04d}.png"))
            assert np.array_equal(got, want.color)
            for name, buffer in (("eye_depth", want.eye_depth), ("ids", want.face_id),
                                 ("normals", want.normals), ("window_depth", want.depth)):
                array = np.load(out / stem / name / f"{v:04d}.npy")
                assert array.dtype == buffer.dtype and np.array_equal(array, buffer), name
    assert "2 of" not in result.summary() and "8 of 24 views failed" in result.summary()


def test_a_killed_worker_loses_nothing(client, models_dir, tmp_path):
    """SIGKILL one worker process while the job runs: Dask reruns its tasks on the other
    (and the restarted) worker; every view is done once in the manifest and right."""
    model = os.path.join(models_dir, "stanford-bunny.obj")
    out = tmp_path / "out"
    outcome = {}

    def job():
        outcome["result"] = render_views([model], "sphere:48", (160, 120), ("ids",), out,
                                         client)

    thread = threading.Thread(target=job)
    thread.start()
    folder = out / "stanford-bunny" / "ids"
    deadline = time.time() + 60
    while time.time() < deadline and not (folder.is_dir() and len(os.listdir(folder)) >= 3):
        time.sleep(0.02)
    pids = client.run(os.getpid)
    victim = sorted(pids.values())[0]
    os.kill(victim, signal.SIGKILL)
    thread.join(180)
    assert not thread.is_alive()
    rows = outcome["result"].rows
    assert [r["view"] for r in rows] == list(range(48))
    assert all(r["status"] == "ok" for r in rows), [r for r in rows if r["status"] != "ok"]
    scene = hsr.load_scene(model)
    cams = hsr.views.sphere(scene.bounds(), 48, 160 / 120)
    for v in range(0, 48, 7):
        assert np.array_equal(np.load(folder / f"{v:04d}.npy"),
                              hsr.render(scene, cams[v], 160, 120).face_id)
    assert not [n for n in os.listdir(folder) if n.endswith(".tmp")]


def test_resume_after_a_killed_run_redoes_nothing_finished(models_dir, tmp_path):
    """The CLI is killed (SIGKILL, no clean-up) part way; --resume renders exactly the
    views without all their outputs and leaves finished files untouched."""
    model = os.path.join(models_dir, "stanford-bunny.obj")
    out = tmp_path / "out"
    args = [sys.executable, "-m", "hsr", "batch", model, "--views", "orbit:40", "--size",
            "192x144", "--outputs", "color,ids", "--out", str(out), "--workers", "2",
            "--quiet"]
    proc = subprocess.Popen(args, start_new_session=True)
    color = out / "stanford-bunny" / "color"
    deadline = time.time() + 120
    while time.time() < deadline and not (color.is_dir() and len(os.listdir(color)) >= 4):
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)  # the client and its local cluster
    proc.wait()
    finished = {v for v in range(40)
                if (color / f"{v:04d}.png").exists()
                and (out / "stanford-bunny" / "ids" / f"{v:04d}.npy").exists()}
    assert 0 < len(finished) < 40, "the kill came too late or too early to test resume"
    stamps = {v: os.stat(color / f"{v:04d}.png").st_mtime_ns for v in finished}
    # What a worker killed while writing leaves behind (the kill above may leave some).
    (color / ".0000.png.0123456789abcdef.tmp").write_bytes(b"half a PNG")
    assert main(["batch", model, "--views", "orbit:40", "--size", "192x144", "--outputs",
                 "color,ids", "--out", str(out), "--workers", "2", "--resume", "--quiet"]) == 0
    rows = json.loads((out / "manifest.json").read_text())["tasks"]
    assert {r["view"] for r in rows if r["status"] == "skipped"} == finished
    assert {r["view"] for r in rows if r["status"] == "ok"} == set(range(40)) - finished
    assert all(os.stat(color / f"{v:04d}.png").st_mtime_ns == stamps[v] for v in finished)
    assert not [n for n in os.listdir(color) if n.endswith(".tmp")]  # stale ones removed
    scene = hsr.load_scene(model)
    cams = hsr.views.orbit(scene.bounds(), 40, 20.0, 192 / 144)
    for v in (min(finished), max(set(range(40)) - finished)):
        assert np.array_equal(np.asarray(Image.open(color / f"{v:04d}.png")),
                              hsr.render(scene, cams[v], 192, 144, light="studio").color)


def test_zarr_store_and_resume(client, models, tmp_path):
    import zarr

    out = tmp_path / "z"
    render_views(models[:1], "hemisphere:5", SIZE, ("color", "eye_depth", "ids"), out, client,
                 format="zarr")
    group = zarr.open_group(out / "spot.zarr", mode="r")
    assert group["color"].shape == (5, 72, 96, 3) and group["color"].chunks == (1, 72, 96, 3)
    assert group["done"][:].tolist() == [1] * 5
    scene = hsr.load_scene(models[0])
    cams = hsr.views.hemisphere(scene.bounds(), 5, 96 / 72)
    for v in range(5):
        want = hsr.render(scene, cams[v], *SIZE)
        assert np.array_equal(group["ids"][v], want.face_id)
        assert np.array_equal(group["eye_depth"][v], want.eye_depth)
        assert np.allclose(group.attrs["cameras"][v]["view_matrix"], cams[v].view_matrix)
    result = render_views(models[:1], "hemisphere:5", SIZE, ("color", "eye_depth", "ids"),
                          out, client, format="zarr", resume=True)
    assert result.skipped == 5 and result.rendered == 0


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_cli_against_a_separately_started_cluster(models, tmp_path, capsys):
    """`dask scheduler` and `dask worker` as their own processes, as on a real cluster."""
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    bin_dir = os.path.dirname(sys.executable)
    scheduler = subprocess.Popen([os.path.join(bin_dir, "dask"), "scheduler", "--host",
                                  "127.0.0.1", "--port", str(port), "--no-dashboard"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    worker = subprocess.Popen([os.path.join(bin_dir, "dask"), "worker", address, "--nthreads",
                               "1", "--host", "127.0.0.1", "--no-dashboard"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with distributed.Client(address, timeout="30s") as c:
            c.wait_for_workers(1, timeout=60)
        out = tmp_path / "remote"
        assert main(["batch", *models, "--views", "orbit:4:30", "--size", "96x72",
                     "--outputs", "ids", "--out", str(out), "--scheduler", address,
                     "--views-per-task", "3"]) == 0
        printed = capsys.readouterr().out
        assert "8 of 8 views rendered" in printed
        scene = hsr.load_scene(models[1])
        cam = hsr.views.orbit(scene.bounds(), 4, 30.0, 96 / 72)[2]
        assert np.array_equal(np.load(out / "african_head" / "ids" / "0002.npy"),
                              hsr.render(scene, cam, *SIZE).face_id)
    finally:
        for proc in (worker, scheduler):
            proc.terminate()
            proc.wait(30)


@pytest.mark.parametrize("kwargs,error,message", [
    ({"views": "orbit:0"}, BatchError, "1..1000000"),
    ({"views": "orbit:4:95"}, BatchError, "ELEVATION"),
    ({"views": "cube:4"}, BatchError, "not orbit"),
    ({"outputs": ("color", "colour")}, BatchError, "outputs must be"),
    ({"outputs": ("ids", "ids")}, BatchError, "outputs must be"),
    ({"format": "hdf5"}, BatchError, "format"),
    ({"views_per_task": 0}, BatchError, "views_per_task"),
    ({"size": (0, 10)}, hsr.RenderError, "width"),
    ({"cul": "back"}, hsr.RenderError, "no argument cul"),
    ({"algorithm": "painter", "depth_func": "greater"}, hsr.RenderError, "greater"),
    ({"workspace": None}, hsr.RenderError, "workspace is not a batch render option"),
    ({"near": 2.0, "far": 1.0}, hsr.CameraError, "greater than near"),
    ({"near": float("nan")}, hsr.CameraError, "near"),
])
def test_bad_jobs_are_refused_before_any_work(models, tmp_path, kwargs, error, message):
    args = {"views": "orbit:2", "size": SIZE, "outputs": ("color",), "out": tmp_path / "o"}
    args.update(kwargs)
    with pytest.raises(error, match=message):
        render_views(models, **args)
    assert not (tmp_path / "o").exists()


def test_cli_bad_job_is_one_line(models, tmp_path, capsys):
    twin = tmp_path / "spot.obj"
    twin.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    code = main(["batch", models[0], str(twin), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "rename one" in err
    code = main(["batch", models[0], "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"])
    assert code == 2 and "does not combine" in capsys.readouterr().err


def test_views_per_task():
    from hsr.batch.plan import group_views

    # 512 x 512: 16 views make 4 M pixels; 128 views on 2 workers: 16 a task, 8 tasks.
    assert [len(g) for g in group_views(range(128), 512, 512, 2)] == [16] * 8
    # Few views: still four tasks per worker.
    assert [len(g) for g in group_views(range(8), 64, 64, 2)] == [1] * 8
    # Many small models in one job: each model's 16 tiny views in one task.
    assert group_views(range(16), 128, 128, 2, job_views=16_000) == [list(range(16))]
    # Large views: one 4K view a task.
    assert len(group_views(range(10), 3840, 2160, 2)) == 10
    # Set by hand (a large cluster: fewer, longer tasks).
    assert [len(g) for g in group_views(range(10), 64, 64, 2, per_task=4)] == [4, 4, 2]


def test_tasks_amortise_the_model_load(models_dir):
    """On a large cluster a model's tasks land on different workers, each loading the
    model: 1,000 bunny-sized OBJs x 256 views at 1024 x 1024 on 100 workers. By pixels
    alone that is 4 views a task, 64 loads of each model (as much time as rendering);
    amortised, the loads stay near a tenth of the model's views, and the job still has
    four tasks per worker. A single model on the same cluster still spreads."""
    from hsr.batch import plan

    bunny = os.path.getsize(os.path.join(models_dir, "stanford-bunny.obj"))
    groups = plan.group_views(range(256), 1024, 1024, 100, job_views=256_000,
                              model_bytes=bunny)
    load_s = bunny * plan.LOAD_SECONDS_PER_BYTE
    view_s = 1024 * 1024 * plan.VIEW_SECONDS_PER_PIXEL
    assert len(groups[0]) * view_s * 0.1 >= load_s  # a full task amortises its load
    assert len(groups) <= 4  # against 64 by pixels alone
    assert len(groups) * 1000 >= 4 * 100
    assert len(plan.group_views(range(256), 1024, 1024, 100, model_bytes=bunny)) == 256


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 500), st.integers(1, 4096), st.integers(1, 4096), st.integers(1, 400),
       st.integers(0, 10_000), st.integers(0, 50_000_000))
def test_grouping_keeps_order_and_its_rules(count, width, height, workers, more, model_bytes):
    """Every view once, in order, in equal groups but the last; a group is either large
    enough to amortise the load (and covers 4 M pixels or 64 views), or as large as the
    job's spread over the workers allows."""
    from hsr.batch import plan

    job = count + more
    groups = plan.group_views(range(count), width, height, workers, job, None, model_bytes)
    assert [v for g in groups for v in g] == list(range(count))
    size = len(groups[0])
    assert all(len(g) == size for g in groups[:-1]) and len(groups[-1]) <= size
    if len(groups) > 1:
        view_s = width * height * plan.VIEW_SECONDS_PER_PIXEL
        amortised = model_bytes * plan.LOAD_SECONDS_PER_BYTE <= 0.1 * size * view_s + 1e-12
        fills = size >= 64 or size * width * height >= (4 << 20) - width * height
        assert (amortised and fills) or size == math.ceil(job / (4 * workers))


def test_per_model_cameras_and_camera_lists(client, models, tmp_path):
    """per-model:FILE gives each model its own camera file; a Python list of cameras is
    used for every model."""
    scenes = [hsr.load_scene(m) for m in models]
    own = [hsr.views.hemisphere(s.bounds(), 2 + k, 4 / 3) for k, s in enumerate(scenes)]
    for k, cams in enumerate(own):
        hsr.write_transforms(tmp_path / f"cams{k}.json", cams, *SIZE)
    (tmp_path / "views.json").write_text(json.dumps(
        {os.path.basename(models[0]): "cams0.json", models[1]: "cams1.json"}))
    out = tmp_path / "per"
    result = render_views(models, f"per-model:{tmp_path / 'views.json'}", SIZE, ("ids",), out,
                          client)
    assert [r["view"] for r in result.rows] == [0, 1, 0, 1, 2]
    read = hsr.read_transforms(tmp_path / "cams1.json")[0]
    assert np.array_equal(np.load(out / "african_head" / "ids" / "0002.npy"),
                          hsr.render(scenes[1], read[2], *SIZE).face_id)
    # A transforms.json for every model.
    result = render_views(models, str(tmp_path / "cams1.json"), SIZE, ("ids",),
                          tmp_path / "file", client)
    assert [r["view"] for r in result.rows] == [0, 1, 2, 0, 1, 2]
    assert np.array_equal(np.load(tmp_path / "file" / "spot" / "ids" / "0001.npy"),
                          hsr.render(scenes[0], read[1], *SIZE).face_id)
    shared = own[0]
    result = render_views(models, list(shared), SIZE, ("ids",), tmp_path / "list", client)
    assert result.rendered == 4
    assert np.array_equal(np.load(tmp_path / "list" / "african_head" / "ids" / "0001.npy"),
                          hsr.render(scenes[1], shared[1], *SIZE).face_id)


def test_default_local_cluster_for_large_views(models_dir, tmp_path):
    """Views of 512 x 512 pixels and more run on threads of one worker in this process (no
    client given): the same bits as hsr.render, the mesh cache shared by both threads."""
    model = os.path.join(models_dir, "spot.obj")
    result = render_views([model], "orbit:4", (512, 512), ("ids", "eye_depth"),
                          tmp_path / "big", workers=2)
    assert result.rendered == 4
    scene = hsr.load_scene(model)
    for v, cam in enumerate(hsr.views.orbit(scene.bounds(), 4, 20.0, 1.0)):
        frame = hsr.render(scene, cam, 512, 512)
        assert np.array_equal(np.load(tmp_path / "big" / "spot" / "ids" / f"{v:04d}.npy"),
                              frame.face_id)
        assert np.array_equal(np.load(tmp_path / "big" / "spot" / "eye_depth" /
                                      f"{v:04d}.npy"), frame.eye_depth)


def test_a_worker_with_several_threads_shares_its_cache(models, tmp_path):
    """Two threads in one worker ask the mesh cache at once (the cache's dict was once
    changed while another thread walked it: the whole job stopped)."""
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                       dashboard_address="127.0.0.1:0", silence_logs=50)
    paths = []
    for k in range(8):
        path = tmp_path / f"tri{k}.obj"
        path.write_text(f"v 0 0 0\nv 1 0 {k}\nv 0 1 0\nv 1 1 1\nf 1 2 3\nf 2 4 3\n")
        paths.append(str(path))
    with distributed.Client(cluster) as c:
        result = render_views(paths + models, "orbit:3", (32, 24), ("ids",), tmp_path / "o", c)
    cluster.close()
    assert result.failed == 0 and result.rendered == 30


def test_mesh_cache_loads_a_model_once_when_threads_ask_together(models_dir):
    """Four threads ask for the bunny at the same moment: one load, one scene for all
    (without the cache's lock each thread loaded its own copy, and the eviction loop
    could walk the dict while another thread changed it)."""
    from hsr.batch.tasks import MeshCache

    cache = MeshCache()
    barrier = threading.Barrier(4)
    got = []
    path = os.path.join(models_dir, "stanford-bunny.obj")

    def ask():
        barrier.wait()
        got.append(cache.get(path))

    threads = [threading.Thread(target=ask) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(got) == 4 and all(scene is got[0] for scene in got)
    assert len(cache.scenes) == 1


def test_a_camera_file_without_planes_is_fitted_to_each_model(client, models_dir, tmp_path):
    """hsr batch read a transforms.json that names no near/far with 0.1 and 100, and its
    driver never loads the models to fit them: a scan in millimetres came out empty with
    every view 'ok'. Now each worker fits the planes to its model, as --view does; and a
    Z-up model's view set turns about +Z (its STL says so)."""
    import trimesh

    spot = hsr.load(os.path.join(models_dir, "spot.obj"))
    models, scenes = [], []
    for scale in (1e-3, 1e3):
        mesh = hsr.Mesh(spot.positions * scale, spot.faces)
        path = tmp_path / f"spot_{scale:g}.ply"
        hsr.write_mesh(mesh, path)
        models.append(str(path))
        scenes.append(hsr.load_scene(path))
    # Each model's camera, placed at its scale, written without planes.
    cam = hsr.views.default(spot, SIZE[0] / SIZE[1])
    rig = [hsr.Camera.look_at(np.asarray(cam.eye) * scale, np.asarray(cam.target) * scale,
                              cam.up, cam.fov_y, cam.near, cam.far) for scale in (1e-3, 1e3)]
    per_model = {}
    for k, (model, placed) in enumerate(zip(models, rig)):
        path = tmp_path / f"rig_{k}.json"
        hsr.write_transforms(path, [placed], *SIZE)
        doc = json.loads(path.read_text())
        del doc["near"], doc["far"]  # as other tools write them
        path.write_text(json.dumps(doc))
        per_model[os.path.basename(model)] = path.name
    (tmp_path / "per_model.json").write_text(json.dumps(per_model))
    out = tmp_path / "out"
    result = render_views(models, f"per-model:{tmp_path / 'per_model.json'}", SIZE, ("ids",),
                          out, client)
    assert not result.failed
    for model, scene, placed in zip(models, scenes, rig):
        stem = os.path.splitext(os.path.basename(model))[0]
        ids = np.load(out / stem / "ids" / "0000.npy")
        want = hsr.render(scene, placed.fitted(scene.bounds()), *SIZE).face_id
        assert (want >= 0).sum() > 500 and np.array_equal(ids, want)
    # The same through one camera file shared by the models (the 1e3 rig's camera).
    shared = tmp_path / "rig_1.json"
    result = render_views(models[1:], str(shared), SIZE, ("ids",), tmp_path / "one", client)
    ids = np.load(tmp_path / "one" / "spot_1000" / "ids" / "0000.npy")
    assert not result.failed and (ids >= 0).sum() > 500
    # A Z-up tower (STL) orbited: every view stands it up (taller than wide).
    box = trimesh.creation.box(extents=(1.0, 1.0, 4.0))
    box.export(tmp_path / "tower.stl")
    result = render_views([str(tmp_path / "tower.stl")], "orbit:3", (96, 96), ("ids",),
                          tmp_path / "tower", client)
    assert not result.failed
    for v in range(3):
        rows, cols = np.nonzero(np.load(tmp_path / "tower" / "tower" / "ids" / f"{v:04d}.npy")
                                >= 0)
        assert np.ptp(rows) > 1.8 * np.ptp(cols)
    assert main(["batch", str(tmp_path / "tower.stl"), "--views", "orbit:2", "--size", "96",
                 "--up-axis", "y", "--outputs", "ids", "--out", str(tmp_path / "lying"),
                 "--scheduler", client.scheduler.address, "--quiet"]) == 0
    rows, cols = np.nonzero(np.load(tmp_path / "lying" / "tower" / "ids" / "0000.npy") >= 0)
    assert np.ptp(rows) < 1.8 * np.ptp(cols)
