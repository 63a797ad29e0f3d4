"""Sort-last rendering of a partitioned scene on 1, 2 and 4 local Dask workers, against one
process rendering the whole scene.

    pip install -e ".[bench,dask]"
    python benchmarks/bench_sortlast.py [--faces 20000000,100000000] [--parts 8]
        [--size 1920x1080] [--views 8] [--workers 1,2,4] [--streamed] [--no-whole]

For each generated terrain (``hsr.scenes.terrain_mesh``; with ``--streamed`` the same
terrain written to a binary PLY a row of cells at a time and partitioned streaming, so
no process ever holds it): the partition's time, then the whole scene rendered by
``hsr.render`` in this process (views per second; skipped with ``--no-whole`` and with
``--streamed``), then ``hsr.batch.render_partitioned`` on a LocalCluster of N
single-threaded worker processes (views per second, the share of the workers' task time
spent compositing, the tasks' time by kind, each worker's peak resident memory (VmHWM,
reset before the timed views). Each cluster renders two views first (loading its parts,
compiling), which are not timed. Runs on demand, never in the test suite.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

import numpy as np

import hsr
from hsr.batch import render_partitioned


def reset_peak() -> None:
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


def peak_mb() -> float:
    with open("/proc/self/status") as f:
        return int(next(r for r in f if r.startswith("VmHWM:")).split()[1]) / 1024


def terrain_ply(path: str, n_triangles: int) -> np.ndarray:
    """``hsr.scenes.terrain_mesh(n_triangles)`` written to a binary PLY a few rows at a
    time (vertices as float32, as PLY files usually hold them); returns its (2, 3) box."""
    import math

    n = max(2, int(round(math.sqrt(n_triangles / 2.0))) + 1)
    u = np.linspace(-1.0, 1.0, n)
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {n * n}\n"
              f"property float x\nproperty float y\nproperty float z\n"
              f"element face {2 * (n - 1) ** 2}\nproperty list uchar int vertex_indices\n"
              f"end_header\n").encode()
    face = np.dtype([("count", "u1"), ("v", "<i4", (3,))])
    rows = max(1, (1 << 22) // n)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    with open(path, "wb") as f:
        f.write(header)
        for r0 in range(0, n, rows):
            gx, gz = np.meshgrid(u, u[r0:r0 + rows])
            height = (0.12 * np.sin(5.0 * gx) * np.cos(4.0 * gz)
                      + 0.05 * np.sin(17.0 * gx + 3.0 * gz) + 0.02 * np.cos(31.0 * gz - 7.0 * gx))
            block = np.stack([gx.ravel(), height.ravel(), gz.ravel()], 1).astype("<f4")
            lo, hi = np.minimum(lo, block.min(0)), np.maximum(hi, block.max(0))
            block.tofile(f)
        for r0 in range(0, n - 1, rows):
            i, j = np.meshgrid(np.arange(n - 1), np.arange(r0, min(r0 + rows, n - 1)))
            a = (j * n + i).ravel()
            records = np.empty(2 * len(a), dtype=face)
            records["count"] = 3
            records["v"][0::2] = np.stack([a, a + n, a + n + 1], 1)
            records["v"][1::2] = np.stack([a, a + n + 1, a + 1], 1)
            records.tofile(f)
    return np.stack([lo, hi]).astype(np.float64)


def cameras(bounds, n: int, aspect: float) -> list:
    return [hsr.views.framed(bounds, d, aspect)
            for d in hsr.views.directions("hemisphere", n)]


def on_cluster(store, cams, width, height, workers: int) -> dict:
    import distributed

    with distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                  silence_logs=50) as cluster, \
            distributed.Client(cluster) as client:
        render_partitioned(store, cams[:2], width, height, client=client, views_per_task=1,
                           outputs=())
        client.run(reset_peak)
        with distributed.get_task_stream(client) as stream:
            start = time.perf_counter()
            render_partitioned(store, cams, width, height, client=client, views_per_task=1,
                               outputs=())
            seconds = time.perf_counter() - start
        kinds: dict = {}
        for task in stream.data:
            kind = task["key"].split("-")[0]
            busy = sum(s["stop"] - s["start"] for s in task["startstops"]
                       if s["action"] == "compute")
            kinds[kind] = kinds.get(kind, 0.0) + busy
        peaks = client.run(peak_mb)
    total = sum(kinds.values()) or 1.0
    return {"views_s": len(cams) / seconds, "composite": kinds.get("_merge", 0.0) / total,
            "kinds": kinds, "peak": max(peaks.values())}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--faces", default="20000000,100000000")
    parser.add_argument("--parts", type=int, default=8)
    parser.add_argument("--size", default="1920x1080")
    parser.add_argument("--views", type=int, default=8)
    parser.add_argument("--workers", default="1,2,4")
    parser.add_argument("--no-whole", action="store_true", help="skip the one-process render")
    parser.add_argument("--streamed", action="store_true", help="write the terrain to a PLY "
                        "in pieces and partition it streaming (no process holds it)")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    rows = []
    for n in (int(v) for v in args.faces.split(",")):
        folder = tempfile.mkdtemp(prefix="hsr-sortlast-")
        try:
            whole = None
            if args.streamed:
                ply = os.path.join(folder, "t.ply")
                bounds = terrain_ply(ply, n)
                start = time.perf_counter()
                store = hsr.partition(ply, args.parts, os.path.join(folder, "t.zarr"))
                part_s = time.perf_counter() - start
                os.remove(ply)
                cams = cameras(bounds, args.views, width / height)
            else:
                mesh = hsr.scenes.terrain_mesh(n)
                start = time.perf_counter()
                store = hsr.partition(mesh, args.parts, os.path.join(folder, "t.zarr"))
                part_s = time.perf_counter() - start
                cams = cameras(mesh.bounds(), args.views, width / height)
                if not args.no_whole:
                    hsr.render(mesh, cams[0], width, height)
                    start = time.perf_counter()
                    for cam in cams:
                        hsr.render(mesh, cam, width, height)
                    whole = len(cams) / (time.perf_counter() - start)
                del mesh
            faces = store.n_faces
            for w in (int(v) for v in args.workers.split(",")):
                r = on_cluster(store, cams, width, height, w)
                rows.append((faces, w, part_s, whole, r))
                print(f"{faces:,} faces, {w} workers: {r['views_s']:.2f} views/s, "
                      f"compositing {100 * r['composite']:.0f}% of task time, "
                      f"peak {r['peak']:.0f} MB per worker; tasks {r['kinds']}",
                      file=sys.stderr)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
    print("\n| faces | parts | partition s | one process, views/s | workers | sort-last "
          "views/s | compositing share | peak MB per worker |")
    print("|---|---|---|---|---|---|---|---|")
    for faces, w, part_s, whole, r in rows:
        print(f"| {faces:,} | {args.parts} | {part_s:.1f} | "
              f"{'-' if whole is None else f'{whole:.2f}'} | {w} | {r['views_s']:.2f} | "
              f"{100 * r['composite']:.0f}% | {r['peak']:.0f} |")
    return 0


if __name__ == "__main__":
    np.seterr(all="ignore")
    sys.exit(main())
