"""Views per second of ``hsr batch`` against a plain Python loop over ``hsr.render``, in the
same run, writing the same files.

    python benchmarks/bench_batch.py [--views 128] [--size 512] [--meshes 1000] [--mesh-views 16]

Jobs: (1) the Stanford bunny from ``orbit:N`` at SIZE x SIZE, colour PNG + face ids; (2)
``--meshes`` small procedural meshes (perturbed icospheres, 1,280 triangles each, written
as OBJ files) x ``--mesh-views`` views at 128 x 128, to show what a task costs when each
view is tiny. For each job: the plain loop (load each mesh once, ``hsr.render`` with the
default threads, the same files written), ``hsr batch`` on three local clusters (one
single-threaded worker process per core; one process of all the threads; one worker of
all the threads inside this process), each warmed first as the loop's process is; and
from cold, the ``hsr batch`` command (its default cluster) against the loop as a script. The
overhead is the share of the workers' wall time spent outside the tasks (each task
measures itself: its model's load, its cameras, its views' render + write). Runs on demand,
never as part of the test suite.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
from PIL import Image

import hsr
from hsr.batch.run import THREADED_PIXELS, render_views

MODELS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "models")


def plain_loop(models, spec_views, size, out):
    """The loop a user writes by hand: each mesh loaded once, each view rendered and its
    colour PNG and face ids written."""
    count = 0
    for path in models:
        scene = hsr.load_scene(path)
        kind, n = spec_views
        cams = getattr(hsr.views, kind)(scene.bounds(), n, aspect=1.0)
        stem = os.path.splitext(os.path.basename(path))[0]
        os.makedirs(os.path.join(out, stem), exist_ok=True)
        for v, cam in enumerate(cams):
            frame = hsr.render(scene, cam, size, size, light="studio")
            Image.fromarray(frame.color).save(os.path.join(out, stem, f"{v:04d}.png"))
            np.save(os.path.join(out, stem, f"{v:04d}.npy"), frame.face_id)
            count += 1
    return count


def batch(models, spec, size, out, client):
    result = render_views(models, spec, (size, size), ("color", "ids"), out, client,
                          light="studio", progress=False)
    assert result.failed == 0, result.summary()
    return result


def cluster(workers, threads, processes=True):
    from distributed import Client, LocalCluster

    where = {"host": "127.0.0.1"} if processes else {}  # in-process: no sockets at all
    c = LocalCluster(n_workers=workers, threads_per_worker=threads, processes=processes,
                     dashboard_address="127.0.0.1:0", silence_logs=50, **where)
    return c, Client(c)


def warm_worker():
    """Load Numba's cached kernels in a worker, as the loop's warm-up does in this process
    (a built-in scene: no model of the job is cached on a worker beforehand)."""
    scene, camera = hsr.scenes.get("cubes")
    hsr.render(scene, camera, 64, 64, threads=1, light="studio")


def procedural(folder, count):
    import trimesh

    rng = np.random.default_rng(0)
    base = trimesh.creation.icosphere(subdivisions=3)
    paths = []
    for k in range(count):
        v = base.vertices * rng.uniform(0.5, 2.0, 3) + rng.normal(scale=0.03,
                                                                 size=base.vertices.shape)
        path = os.path.join(folder, f"m{k:04d}.obj")
        with open(path, "w") as f:
            f.write("".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in v))
            f.write("".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in base.faces))
        paths.append(path)
    return paths


def run_job(label, models, kind, n, size, scratch, rows):
    spec = f"{kind}:{n}"
    views = len(models) * n
    # Warm the kernels in this process first (the workers load Numba's cache likewise).
    plain_loop(models[:1], (kind, 1), size, os.path.join(scratch, "warm"))
    start = time.perf_counter()
    plain_loop(models, (kind, n), size, os.path.join(scratch, "loop"))
    loop_s = time.perf_counter() - start
    cores = os.cpu_count() or 1
    threaded = size * size >= THREADED_PIXELS  # what the local default picks
    for workers, threads, processes, what in (
            (cores, 1, True, f"batch, {cores} processes x 1 thread"
             + ("" if threaded else " (default)")),
            (1, cores, True, f"batch, 1 process x {cores} threads"),
            (1, cores, False, f"batch, in-process, {cores} threads"
             + (" (default)" if threaded else ""))):
        c, client = cluster(workers, threads, processes)
        try:
            client.run(warm_worker)  # every worker's kernels, as the loop's process
            start = time.perf_counter()
            result = batch(models, spec, size, os.path.join(scratch, f"b{workers}"), client)
            wall = time.perf_counter() - start
        finally:
            client.close()
            c.close()
        # Per-task overhead: the workers' time outside the tasks (Dask's scheduling,
        # transfers, idle), against the time inside them (loads, cameras, views).
        overhead = 1.0 - result.task_seconds / (wall * workers * threads)
        rows.append((label, what, views, wall, views / wall, (views / wall) / (views / loop_s),
                     overhead))
    rows.append((label, "plain loop over hsr.render", views, loop_s, views / loop_s, 1.0,
                 float("nan")))
    # From cold, as a user meets it: a fresh process each (imports, Numba's cache, the
    # local cluster's start for the batch), the loop as a script against the CLI.
    loop_cmd = [sys.executable, "-c", "import sys; sys.path.insert(0, %r); import bench_batch as "
                "b; b.plain_loop(%r, (%r, %d), %d, %r)" % (os.path.dirname(
                    os.path.abspath(__file__)), models, kind, n, size,
                    os.path.join(scratch, "cold_loop"))]
    cli_cmd = [sys.executable, "-m", "hsr", "batch", *models, "--views", spec, "--size",
               f"{size}x{size}", "--outputs", "color,ids", "--light", "studio", "--out",
               os.path.join(scratch, "cold_batch")]
    cold = {}
    for what, cmd in (("loop", loop_cmd), ("batch", cli_cmd)):
        start = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        cold[what] = time.perf_counter() - start
    rows.append((label, "from cold: `hsr batch` vs a loop script", views, cold["batch"],
                 views / cold["batch"], cold["loop"] / cold["batch"], float("nan")))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--views", type=int, default=128)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--meshes", type=int, default=1000)
    parser.add_argument("--mesh-views", type=int, default=16)
    args = parser.parse_args()
    rows = []
    scratch = tempfile.mkdtemp(prefix="hsr-bench-batch-")
    try:
        bunny = [os.path.join(MODELS, "stanford-bunny.obj")]
        run_job(f"bunny, {args.size}x{args.size}", bunny, "orbit", args.views, args.size,
                scratch, rows)
        if args.meshes:
            folder = os.path.join(scratch, "meshes")
            os.makedirs(folder)
            models = procedural(folder, args.meshes)
            run_job(f"{args.meshes} meshes x {args.mesh_views} views, 128x128", models,
                    "sphere", args.mesh_views, 128, scratch, rows)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    print(f"{'job':32} | {'how':36} | views | wall s | views/s | x loop | overhead")
    for label, what, views, wall, vps, ratio, overhead in rows:
        print(f"{label:32} | {what:36} | {views:5d} | {wall:6.2f} | {vps:7.1f} | {ratio:6.2f} | "
              + ("" if overhead != overhead else f"{overhead:.1%}"))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
