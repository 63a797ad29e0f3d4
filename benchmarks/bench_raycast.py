"""Time hsr's ray caster against Embree (embreex) for primary visibility, same run.

    pip install embreex
    python benchmarks/bench_raycast.py [MODEL ...] [--size 1024x1024] [--repeat 5]

hsr: ``hsr.render(..., algorithm="raycast", options={"bvh": tree})`` with the BVH built
beforehand (ray generation, traversal, depth/face/distance buffers). Embree: one
``EmbreeScene.run`` of the same rays (origins and directions prepared outside the timer).
Prints the median times, the ratio, BVH build times and the share of pixels on which the
two agree about the visible face.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from common import agreement_percent, median_ms

import hsr
import hsr.algorithms.bvh as rc

MODELS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "models")


def rays(camera, width, height):
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


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*",
                        default=[os.path.join(MODELS, "stanford-bunny.obj")])
    parser.add_argument("--size", default="1024x1024")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    try:
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        print("embreex is not installed: pip install embreex", file=sys.stderr)
        return 1
    print(f"{'model':22} {'tris':>7} {'size':>10} {'hsr ms':>8} {'embree ms':>9} {'ratio':>6} "
          f"{'hsr build':>9} {'emb build':>9} {'agree':>8}")
    for path in args.models:
        mesh = hsr.load(path)
        cam = hsr.Camera.frame(mesh.bounds())
        tree = rc.build(mesh)
        tree = rc.build(mesh)  # second build: compiled
        hsr_ms, = median_ms([lambda: hsr.render(mesh, cam, width, height, algorithm="raycast",
                                                options={"bvh": tree})], args.repeat)
        tris = hsr.Scene([mesh]).world_triangles().astype(np.float32)
        t0 = time.perf_counter()
        scene = rtcs.EmbreeScene()
        TriangleMesh(scene, tris)
        origin, direction = rays(cam, width, height)
        origin, direction = origin.astype(np.float32), direction.astype(np.float32)
        scene.run(origin[:1], direction[:1])  # Embree builds its BVH lazily on first use
        emb_build = 1e3 * (time.perf_counter() - t0)
        emb_ms, = median_ms([lambda: scene.run(origin, direction, output=1)], args.repeat)
        res = scene.run(origin, direction, output=1)
        prim = np.where(res["geomID"] >= 0, res["primID"], -1).reshape(height, width)
        mine = hsr.render(mesh, cam, width, height, algorithm="raycast",
                          options={"bvh": tree}).face_id
        agree = agreement_percent(prim, mine)
        print(f"{os.path.basename(path):22} {mesh.n_faces:7d} {width:>4}x{height:<5} "
              f"{hsr_ms:8.1f} {emb_ms:9.1f} {hsr_ms / emb_ms:6.2f} {tree.build_ms:9.1f} "
              f"{emb_build:9.1f} {agree:7.3f}%", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
