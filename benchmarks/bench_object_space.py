"""How object-space methods scale: Newell's algorithm and BSP build / render on meshes of
growing size (generated terrain, or the models given), against the z-buffer in the same
run.

    python benchmarks/bench_object_space.py [--sizes 1000,3000,10000,30000,100000] [MODEL ...]
"""

from __future__ import annotations

import argparse
import os
import sys

import hsr
import hsr.algorithms.bsp_tree as bsp
from common import agreement_percent, peak_gb, timed


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*")
    parser.add_argument("--sizes", default="1000,3000,10000,30000,100000")
    parser.add_argument("--size", default="1024x768")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    cases = [(f"terrain {int(n)}", *hsr.scenes.terrain(int(n)))
             for n in args.sizes.split(",") if n] if not args.models else []
    for path in args.models:
        mesh = hsr.load(path)
        cases.append((os.path.basename(path), hsr.Scene([mesh]), hsr.Camera.frame(mesh.bounds())))
    # Compile first, so times are warm.
    warm_scene, warm_cam = hsr.scenes.get("cyclic")
    for name in ("zbuffer", "newell", "bsp"):
        hsr.render(warm_scene, warm_cam, 32, 24, algorithm=name)
    print(f"{'mesh':18} {'tris':>7} {'zbuf ms':>8} {'newell ms':>9} {'tests':>11} {'splits':>7} "
          f"{'agree':>8} {'bsp build ms':>12} {'nodes':>7} {'bsp splits':>10} {'bsp ms':>7} "
          f"{'peak GB':>7}")
    for label, scene, cam in cases:
        z, z_ms = timed(lambda: hsr.render(scene, cam, width, height))
        n, n_ms = timed(lambda: hsr.render(scene, cam, width, height, algorithm="newell"))
        tree, b_ms = timed(lambda: bsp.build(scene))
        _, r_ms = timed(lambda: hsr.render(scene, cam, width, height, algorithm="bsp",
                                           options={"tree": tree}))
        agree = agreement_percent(z.face_id, n.face_id)
        peak = peak_gb()
        print(f"{label:18} {scene.n_faces:7d} {z_ms:8.1f} {n_ms:9.1f} "
              f"{n.stats['pair_tests']:11d} {n.stats['splits']:7d} {agree:7.3f}% {b_ms:12.1f} "
              f"{tree.n_nodes:7d} {tree.splits:10d} {r_ms:7.1f} {peak:7.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
