"""Time ``hsr.RayScene`` against Open3D's RaycastingScene and Embree (embreex) on the
same rays, in one run; and ``hsr.visible_vertices`` of the bunny.

    pip install -e ".[bench]"
    python benchmarks/bench_rays.py [MODEL ...] [--rays 1000000] [--repeat 3] [--rounds 3]

MODEL is a mesh file or ``terrain:N`` (default: the bunny and a 1M-face terrain). Four
ray sets per model (``--sets`` picks some): ``random``, origins uniform in the box grown
by half its size on each side and directions uniform on the sphere; ``inside``, the same
with origins uniform inside the box itself (a sensor inside a scan, the inside/outside
test); ``primary``, one ray per pixel centre of a framed 1000 x 1000 view (from the eye,
directions to the far plane; the terrain is seen edge-on, a strip across the view);
``filling``, the same for a view along the box's shortest axis that the box fills
(``bench_raycast.py``'s ``fill`` view: the terrain from above, about a triangle a
pixel). Timed: the plain public calls with their defaults, the inputs prepared outside
the timer: hsr ``RayScene.cast`` / ``occluded`` / ``count`` / ``all_hits`` (float64 in,
every output), Open3D ``cast_rays`` / ``test_occlusions`` / ``count_intersections`` /
``list_intersections`` and Embree ``run``
(INTERSECT with output, OCCLUDED) on float32. Builds: hsr's ``RayScene(mesh)`` (after a
first one that compiles), Open3D's ``add_triangles`` plus the first query (it commits
its scene lazily), Embree's likewise, alternating, ``--rounds`` x ``--repeat`` each (min
/ median). Each query runs in blocks of ``--repeat`` that alternate over ``--rounds``;
printed: min / median ms and the ratios hsr / peer of both (below 1: hsr is faster).
Last, views per second of ``hsr batch`` of the bunny (``sphere:128`` at 512 x 512, ids +
eye depth) against a loop of Open3D ``cast_rays``, ``--batch-rounds`` alternating runs
each (``--only-batch`` runs just that). ``--memory`` prints instead the resident memory
a ray scene adds per face, held once built and at the peak while building, hsr's and
Open3D's, each built in a fresh process (the median of three). Runs on demand, never in
the test suite; a missing peer is left out. """

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from bench_raycast import view_camera
from bench_regions import cpu_name

import hsr
from common import load_model, peak_gb, timings

MODELS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "models")


RAY_SETS = ("random", "inside", "primary", "filling")


def ray_sets(mesh, n, rng, chosen=RAY_SETS):
    lo, hi = mesh.bounds()
    pad = (hi - lo) / 2
    origins = rng.uniform(lo - pad, hi + pad, (n, 3))
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    sets = {"random": lambda: (origins, directions),
            "inside": lambda: inside_rays(lo, hi, n),
            "primary": lambda: camera_rays(hsr.Camera.frame(mesh.bounds()), n),
            "filling": lambda: camera_rays(view_camera(mesh, "fill"), n)}
    return {name: sets[name]() for name in chosen}


def inside_rays(lo, hi, n):
    """Origins uniform inside the box, directions uniform; from a generator of their own,
    so the other sets' rays are those they were before this set was added."""
    own = np.random.default_rng(1)
    origins = own.uniform(lo, hi, (n, 3))
    directions = own.normal(size=(n, 3))
    return origins, directions / np.linalg.norm(directions, axis=1, keepdims=True)


def camera_rays(cam, n):
    """One ray per pixel centre of a square view of about n pixels: from the eye, the
    directions to the far plane."""
    side = int(round(np.sqrt(n)))
    view_proj = cam.projection_matrix(1.0) @ cam.view_matrix
    inv = np.linalg.inv(view_proj)
    xs = (np.arange(side) + 0.5) / side * 2 - 1
    gx, gy = np.meshgrid(xs, -xs)
    far = np.c_[gx.ravel(), gy.ravel(), np.ones(side * side), np.ones(side * side)] @ inv.T
    far = far[:, :3] / far[:, 3:]
    eye = np.broadcast_to(np.asarray(cam.eye, dtype=np.float64), far.shape).copy()
    return eye, far - eye


def open3d_peer(mesh):
    try:
        import open3d as o3d
    except ImportError:
        return None
    t0 = time.perf_counter()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.positions.astype(np.float32)),
                        o3d.core.Tensor(mesh.faces.astype(np.uint32)))
    scene.cast_rays(o3d.core.Tensor(np.zeros((1, 6), np.float32)))  # commits the scene
    build = 1e3 * (time.perf_counter() - t0)

    def queries(o, d):
        rays = o3d.core.Tensor(np.concatenate([o, d], 1).astype(np.float32))
        return {"cast": lambda: scene.cast_rays(rays),
                "occluded": lambda: scene.test_occlusions(rays),
                "count": lambda: scene.count_intersections(rays),
                "all_hits": lambda: scene.list_intersections(rays)}
    return build, queries


def embree_peer(mesh):
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        return None
    t0 = time.perf_counter()
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, mesh.positions[mesh.faces].astype(np.float32))
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    build = 1e3 * (time.perf_counter() - t0)

    def queries(o, d):
        o32, d32 = o.astype(np.float32), d.astype(np.float32)
        return {"cast": lambda: scene.run(o32, d32, output=1),
                "occluded": lambda: scene.run(o32, d32, query="OCCLUDED")}
    return build, queries


def batch_vs_open3d(views: int, size: int, rounds: int) -> None:
    """Views per second of ``hsr batch`` (``render_views`` with its defaults: a local
    cluster of this machine's cores, started and closed by each run) of the bunny from
    ``sphere:VIEWS`` at SIZE x SIZE, face ids + eye depth written as .npy, against a
    loop of Open3D ``cast_rays`` (scene built once, one pinhole ray set per view, the
    same two buffers written), same cameras, same cores. Both warm (a first run of each
    is not timed), then ``rounds`` runs of each, alternating; printed: views per second
    at the fastest and the median run of each, and their ratios."""
    import tempfile

    try:
        import open3d as o3d
    except ImportError:
        print("\nbatch vs Open3D: open3d not installed")
        return
    from hsr.batch import render_views

    path = os.path.join(MODELS, "stanford-bunny.obj")
    bunny = hsr.load(path)
    cams = hsr.views.sphere(bunny.bounds(), views, 1.0)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(bunny.positions.astype(np.float32)),
                        o3d.core.Tensor(bunny.faces.astype(np.uint32)))

    def open3d_loop(out):
        os.makedirs(out, exist_ok=True)
        for k, cam in enumerate(cams):
            K, R, t = cam.to_opencv(size, size)
            extrinsic = np.eye(4)
            extrinsic[:3, :3], extrinsic[:3, 3] = R, t
            rays = scene.create_rays_pinhole(o3d.core.Tensor(K), o3d.core.Tensor(extrinsic),
                                             size, size)
            hit = scene.cast_rays(rays)
            ids = hit["primitive_ids"].numpy().astype(np.int32)
            t_hit = hit["t_hit"].numpy()
            dirs = rays.numpy()[..., 3:]
            forward = np.asarray(cam.forward)
            eye_depth = (t_hit * (dirs @ forward)).astype(np.float32)  # along the view axis
            ids[~np.isfinite(t_hit)] = -1
            np.save(os.path.join(out, f"ids_{k:04d}.npy"), ids)
            np.save(os.path.join(out, f"eye_{k:04d}.npy"), eye_depth)

    runs = {"hsr batch": lambda out: render_views(
        [path], f"sphere:{views}", (size, size), ("ids", "eye_depth"), out, progress=False),
        "Open3D loop": open3d_loop}
    seconds: dict[str, list] = {name: [] for name in runs}
    with tempfile.TemporaryDirectory() as tmp:
        for name, run in runs.items():
            run(os.path.join(tmp, name.replace(" ", "_") + "_warm"))
        for r in range(rounds):
            for name, run in runs.items():
                t0 = time.perf_counter()
                run(os.path.join(tmp, f"{name.replace(' ', '_')}_{r}"))
                seconds[name].append(time.perf_counter() - t0)
    (mine_lo, mine_med), (theirs_lo, theirs_med) = (
        (min(s), float(np.median(s))) for s in seconds.values())
    print(f"\nbunny, sphere:{views} at {size}x{size}, ids + eye depth written, {rounds} "
          f"alternating runs each, views/s fastest / median run: hsr batch "
          f"{views / mine_lo:.1f} / {views / mine_med:.1f}, Open3D cast_rays loop "
          f"{views / theirs_lo:.1f} / {views / theirs_med:.1f}; hsr / Open3D views/s "
          f"{theirs_lo / mine_lo:.2f} / {theirs_med / mine_med:.2f}")
    print("runs (s): " + "; ".join(f"{name} " + " ".join(f"{x:.2f}" for x in s)
                                  for name, s in seconds.items()))


def scene_memory(spec: str, peer: str) -> tuple[float, float] | None:
    """Bytes per face that building a ray scene of ``spec`` adds to a fresh process's
    resident memory (hsr's ``RayScene``, or Open3D's ``RaycastingScene`` after its
    first query commits it), ``(held, peak)``: held once built, and the peak while
    building (the kernel's high-water mark, VmHWM, reset before the build through
    ``/proc/self/clear_refs``), both above the resident memory before it. The model is
    loaded and the code compiled before the first reading, freed memory handed back
    (``malloc_trim``) before both; None without the peer."""
    import subprocess

    code = f"""
import gc, os, sys
import numpy as np
sys.path.insert(0, {os.path.dirname(os.path.abspath(__file__))!r})
from common import load_model
import hsr
import ctypes
libc = ctypes.CDLL("libc.so.6")
def rss():
    gc.collect()
    libc.malloc_trim(0)  # freed scratch back to the system: count what is held
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
def peak():
    with open("/proc/self/status") as fh:
        return next(int(l.split()[1]) * 1024 for l in fh if l.startswith("VmHWM:"))
def reset_peak():
    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")
mesh, _ = load_model({spec!r})
if {peer!r} == "hsr":
    hsr.RayScene(load_model("terrain:20000")[0])  # compiled code is not the scene's
    before = rss()
    reset_peak()
    scene = hsr.RayScene(mesh)
else:
    import open3d as o3d
    before = rss()
    reset_peak()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.positions.astype(np.float32)),
                        o3d.core.Tensor(mesh.faces.astype(np.uint32)))
    scene.cast_rays(o3d.core.Tensor(np.zeros((1, 6), np.float32)))
top = peak()
print((rss() - before) / mesh.n_faces, (top - before) / mesh.n_faces)
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if done.returncode != 0:
        return None
    held, top = done.stdout.split()[-2:]
    return float(held), float(top)


MEMORY_RUNS = 3


def _median(values):
    """The median of each reading, None if any is missing."""
    return None if None in values else tuple(float(x) for x in np.median(values, axis=0))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", default=[
        os.path.join(MODELS, "stanford-bunny.obj"), "terrain:1000000"])
    parser.add_argument("--rays", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--batch-views", type=int, default=128,
                        help="views of the batch comparison (0: skip it)")
    parser.add_argument("--batch-size", type=int, default=512)
    parser.add_argument("--batch-rounds", type=int, default=5,
                        help="timed runs of each side of the batch comparison, alternating")
    parser.add_argument("--only-batch", action="store_true", help="just the batch comparison")
    parser.add_argument("--sets", default=",".join(RAY_SETS),
                        help=f"ray sets, comma-separated (default {','.join(RAY_SETS)})")
    parser.add_argument("--memory", action="store_true",
                        help="just the memory a ray scene adds per face, hsr and Open3D")
    args = parser.parse_args(argv)
    if args.only_batch:
        batch_vs_open3d(args.batch_views, args.batch_size, args.batch_rounds)
        return 0
    if args.memory:
        print("| model | held bytes per face: hsr RayScene | Open3D | hsr / Open3D "
              "| peak while building: hsr | Open3D | hsr / Open3D |")
        print("|---|---|---|---|---|---|---|")
        for spec in args.models:
            # The median of three fresh processes each: one reading of a small scene
            # moves by a tenth (allocator and thread arenas, a megabyte either way).
            mine, theirs = (_median([scene_memory(spec, peer) for _ in range(MEMORY_RUNS)])
                            for peer in ("hsr", "open3d"))
            cells = []
            for k in range(2):  # held, peak
                a, b = (None if x is None else x[k] for x in (mine, theirs))
                cells += ["-" if a is None else f"{a:.0f}", "-" if b is None else f"{b:.0f}",
                          f"{a / b:.2f}" if a and b else "-"]
            print(f"| {os.path.basename(spec)} | {' | '.join(cells)} |")
        return 0
    chosen = tuple(args.sets.split(","))
    if not set(chosen) <= set(RAY_SETS):
        parser.error(f"--sets: choose from {', '.join(RAY_SETS)}")
    rng = np.random.default_rng(0)
    cpu = cpu_name()
    print("| model | faces | rays | query | hsr ms (min / median) | Open3D ms | hsr / Open3D "
          "| Embree ms | hsr / Embree | CPU |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    builds = []
    for spec in args.models:
        mesh, label = load_model(spec)
        hsr.RayScene(mesh)  # compiles
        # Builds alternate, hsr then each peer, `rounds x repeat` times (a build pays
        # for fresh memory's page faults, which vary from one to the next).
        build_ms: dict[str, list] = {"hsr": [], "Open3D": [], "Embree": []}
        for _ in range(args.rounds * args.repeat):
            rays = peers = None  # the last round's are kept, for the queries
            t0 = time.perf_counter()
            rays = hsr.RayScene(mesh)
            build_ms["hsr"].append(1e3 * (time.perf_counter() - t0))
            peers = {"Open3D": open3d_peer(mesh), "Embree": embree_peer(mesh)}
            for name, peer in peers.items():
                if peer:
                    build_ms[name].append(peer[0])
        cells = [f"{min(ms):.0f} / {np.median(ms):.0f}" if ms else "-"
                 for ms in build_ms.values()]
        mine_ms, o3d_ms = build_ms["hsr"], build_ms["Open3D"]
        cells.append(f"{min(mine_ms) / min(o3d_ms):.2f} / "
                     f"{np.median(mine_ms) / np.median(o3d_ms):.2f}" if o3d_ms else "-")
        builds.append((label, mesh.n_faces, *cells))
        for kind, (o, d) in ray_sets(mesh, args.rays, rng, chosen).items():
            mine = {"cast": lambda: rays.cast(o, d), "occluded": lambda: rays.occluded(o, d),
                    "count": lambda: rays.count(o, d),
                    "all_hits": lambda: rays.all_hits(o, d)}
            theirs = {name: p[1](o, d) if p else {} for name, p in peers.items()}
            for query, fn in mine.items():
                fns = [fn] + [q[query] for q in theirs.values() if query in q]
                measured = iter(timings(fns, args.repeat, args.rounds))
                lo, med = next(measured)
                cells = []
                for name in peers:
                    if query not in theirs[name]:
                        cells += ["-", "-"]
                        continue
                    plo, pmed = next(measured)
                    cells += [f"{plo:.1f} / {pmed:.1f}", f"{lo / plo:.2f} / {med / pmed:.2f}"]
                print(f"| {label} | {mesh.n_faces:,} | {len(o):,} {kind} | {query} | "
                      f"{lo:.1f} / {med:.1f} | {' | '.join(cells)} | {cpu} |", flush=True)
    print()
    print("| model | faces | build ms (min / median): hsr | Open3D | Embree | hsr / Open3D |")
    print("|---|---|---|---|---|---|")
    for label, faces, *cells in builds:
        print(f"| {label} | {faces:,} | {' | '.join(cells)} |")
    # visible_vertices of the bunny: 35k vertices, warm, the RayScene built beforehand.
    bunny = hsr.load(os.path.join(MODELS, "stanford-bunny.obj"))
    rays = hsr.RayScene(bunny)
    cam = hsr.views.default(bunny, 4 / 3)
    (lo, med), = timings([lambda: hsr.visible_vertices(rays, cam, 800, 600)], args.repeat,
                         args.rounds)
    print(f"\nvisible_vertices, bunny ({len(bunny.positions):,} vertices, RayScene reused): "
          f"{lo:.1f} / {med:.1f} ms (min / median); peak RSS {peak_gb():.2f} GB")
    if args.batch_views:
        batch_vs_open3d(args.batch_views, args.batch_size, args.batch_rounds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
