"""Time hsr's ray caster against Embree (embreex) and Open3D's RaycastingScene for
primary visibility, measured in the same run.

    pip install embreex open3d-cpu
    python benchmarks/bench_raycast.py [MODEL ...] [--sizes 1024x1024,1920x1080]
                                       [--views frame,fill] [--repeat 5] [--rounds 3]

MODEL is a mesh file or ``terrain:N`` (the generated grid of N triangles). Views:
``frame``, the model framed by ``Camera.frame`` (the terrain is then seen edge-on, a
strip across the image); ``fill``, looking along the axis of the model's box that is
shortest, close enough that the box fills the image (the terrain from above, a triangle
or so a pixel): hsr's ray caster casts no ray where the BVH's top boxes do not project,
which the peers, given a list of rays, cannot know, so ``frame`` measures that too and
``fill`` the walk alone. hsr: ``hsr.render(..., algorithm="raycast", options={"bvh": tree})``
with the BVH built beforehand (ray generation, traversal, depth/face/distance buffers).
Embree and Open3D: one call on the same rays (origins and directions prepared outside
the timer); their acceleration structures are built on first use, which is timed as
their build. Casts run in blocks of ``--repeat`` that alternate over ``--rounds``, so
all three see the same machine load; min and median per cast are printed, the ratios
hsr / peer of both, the build times (hsr's second build: the first compiles) and the
share of covered pixels on which each peer agrees with hsr about the visible face.
Runs on demand, never in the test suite. A peer that is not installed is left out.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

import hsr
from common import agreement_percent, load_model, timings
from hsr.algorithms.bvh import sah

MODELS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "models")


def rays(camera, width, height):
    """(origins, directions) of the pixel-centre rays from the near to the far plane,
    row 0 at the top, as hsr casts them."""
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    inv = np.linalg.inv(view_proj)
    xs = (np.arange(width) + 0.5) / width * 2 - 1
    ys = 1 - (np.arange(height) + 0.5) / height * 2
    gx, gy = np.meshgrid(xs, ys)
    ndc = np.stack([gx.ravel(), gy.ravel()], axis=1)
    ones = np.ones(len(ndc))
    near = np.c_[ndc, -ones, ones] @ inv.T
    far = np.c_[ndc, ones, ones] @ inv.T
    origin = near[:, :3] / near[:, 3:]
    return origin, far[:, :3] / far[:, 3:] - origin


def view_camera(mesh, view):
    """The camera of ``view`` (see the module's docstring)."""
    if view == "frame":
        return hsr.Camera.frame(mesh.bounds())
    lo, hi = (np.asarray(b, dtype=np.float64) for b in mesh.bounds())
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    axis = int(np.argmin(half))
    up = np.eye(3)[(axis + 1) % 3]
    # The box's cross-section fills a 45-degree view (tan 22.5 = 0.414) from just
    # outside the box.
    reach = min(half[(axis + 1) % 3], half[(axis + 2) % 3]) / np.tan(np.radians(22.5))
    eye = centre + np.eye(3)[axis] * (half[axis] + reach)
    return hsr.Camera(eye=tuple(eye), target=tuple(centre), up=tuple(up), fov_y=45.0,
                      near=0.5 * reach, far=reach + 3 * half[axis])


def embree_peer(tris, origin, direction):
    """(build ms, cast function, face ids of one cast) or None without embreex."""
    try:
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        return None
    t0 = time.perf_counter()
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, tris)
    scene.run(origin[:1], direction[:1])  # Embree builds its BVH lazily on first use
    build = 1e3 * (time.perf_counter() - t0)
    res = scene.run(origin, direction, output=1)
    face = np.where(res["geomID"] >= 0, res["primID"], -1)
    return build, lambda: scene.run(origin, direction, output=1), face


def open3d_peer(tris, origin, direction):
    """(build ms, cast function, face ids of one cast) or None without open3d."""
    try:
        import open3d as o3d
    except ImportError:
        return None
    vertices = np.ascontiguousarray(tris.reshape(-1, 3), dtype=np.float32)
    triangles = np.arange(len(vertices), dtype=np.uint32).reshape(-1, 3)
    ray_tensor = o3d.core.Tensor(np.ascontiguousarray(
        np.concatenate([origin, direction], axis=1), dtype=np.float32))
    t0 = time.perf_counter()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(triangles))
    scene.cast_rays(ray_tensor[:1])  # the structure is built on first use
    build = 1e3 * (time.perf_counter() - t0)
    res = scene.cast_rays(ray_tensor)
    t_hit = res["t_hit"].numpy()
    ids = res["primitive_ids"].numpy().astype(np.int64)
    face = np.where(np.isfinite(t_hit) & (t_hit <= 1.0), ids, -1)
    return build, lambda: scene.cast_rays(ray_tensor), face


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*",
                        default=[os.path.join(MODELS, "stanford-bunny.obj")])
    parser.add_argument("--sizes", default="1024x1024")
    parser.add_argument("--views", default="frame,fill")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args(argv)
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]
    views = args.views.split(",")
    if not set(views) <= {"frame", "fill"}:
        parser.error("--views takes frame and/or fill")
    print("| model | triangles | view | size | rays cast | hsr ms (min / median) | Embree ms | "
          "hsr / Embree | Open3D ms | hsr / Open3D | builds ms: hsr / Embree / Open3D | "
          "agree % Embree / Open3D |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for spec in args.models:
        mesh, label = load_model(spec)
        sah.build(mesh)  # compiles
        tree = sah.build(mesh)
        tris = hsr.Scene([mesh]).world_triangles().astype(np.float32)
        for view, (width, height) in ((v, s) for v in views for s in sizes):
            cam = view_camera(mesh, view)
            origin, direction = (a.astype(np.float32) for a in rays(cam, width, height))
            peers = [embree_peer(tris, origin, direction),
                     open3d_peer(tris, origin, direction)]
            fns = [lambda: hsr.render(mesh, cam, width, height, algorithm="raycast",
                                      options={"bvh": tree})]
            fns += [p[1] for p in peers if p is not None]
            measured = iter(timings(fns, args.repeat, args.rounds))
            mine_ms = next(measured)
            frame = hsr.render(mesh, cam, width, height, algorithm="raycast",
                               options={"bvh": tree})
            mine = frame.face_id.ravel()
            cast_share = f"{100 * frame.stats['rays_cast'] / (width * height):.0f}%"
            cells, builds, agree = [], [f"{tree.build_ms:.0f}"], []
            for peer in peers:
                if peer is None:
                    cells += ["-", "-"]
                    builds.append("-")
                    agree.append("-")
                    continue
                lo, med = next(measured)
                cells += [f"{lo:.1f} / {med:.1f}",
                          f"{mine_ms[0] / lo:.2f} / {mine_ms[1] / med:.2f}"]
                builds.append(f"{peer[0]:.0f}")
                agree.append(f"{agreement_percent(peer[2], mine):.3f}")
            print(f"| {label} | {mesh.n_faces:,} | {view} | {width}x{height} | {cast_share} | "
                  f"{mine_ms[0]:.1f} / {mine_ms[1]:.1f} | {' | '.join(cells)} | "
                  f"{' / '.join(builds)} | {' / '.join(agree)} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
