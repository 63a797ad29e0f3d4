"""Exact visible regions (hsr.visible_regions) against what a user would otherwise run on
the same view, in the same run: hsr.render (pixels), hidden_lines (the exact edge engine)
and a plain shapely baseline (faces nearest first, each differenced against the running
union: right only where faces do not pass through each other), and the first step of
Gordon & Chen's front-to-back BSP method (building the BSP tree and walking it, before any
coverage clipping): the pieces it cuts are what that method would then clip.

    python benchmarks/bench_regions.py [--baseline-faces 20000] [CASE ...]

CASE: NAME@WxH with NAME a shared model (bunny = stanford-bunny.obj) or terrain:N.
Default: the bunny at 1024x1024, the 1M-face terrain at 1920x1080, and a 20k-face terrain
at 1024x768 (small enough for the shapely baseline).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys

import numpy as np

import hsr
from common import load_model, peak_gb, timed

MODELS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "models")


def case(spec):
    name, _, size = spec.partition("@")
    width, height = (int(v) for v in size.split("x"))
    if name == "bunny":
        name = os.path.join(MODELS, "stanford-bunny.obj")
    mesh, label = load_model(name) if ":" in name else (hsr.load(name),
                                                         os.path.basename(name))
    scene = hsr.Scene([mesh])
    camera = hsr.first_look(scene, width / height)
    return label, scene, camera, width, height


def shapely_baseline(scene, camera, width, height):
    """Faces sorted by nearest window depth, each minus the union so far (shapely)."""
    import shapely

    from hsr.geometry.stage import prepare
    from hsr.geometry.state import RenderState

    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    screen = prepare(scene, view_proj, width, height, RenderState(), {})
    xy = np.array(screen.xy_window)
    xy[..., 1] = height - xy[..., 1]
    order = np.argsort(np.asarray(screen.depth_window).min(axis=1), kind="stable")
    covered = shapely.Polygon()
    regions = 0
    for t in order:
        tri = shapely.Polygon(xy[t])
        if not tri.is_valid or tri.area == 0:
            continue
        seen = tri.difference(covered)
        if not seen.is_empty:
            regions += 1
            covered = covered.union(tri)
    return regions


def bsp_walk(scene, camera):
    """Gordon-Chen's first step: the BSP tree (hsr's, as algorithm="bsp" builds it) and its
    front-to-back order; returns the ordered pieces."""
    from hsr.algorithms import bsp_tree

    return bsp_tree.front_to_back(bsp_tree.build(scene), camera)


def cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="*",
                        default=["bunny@1024x1024", "terrain:1000000@1920x1080",
                                 "terrain:20000@1024x768"])
    parser.add_argument("--baseline-faces", type=int, default=20000,
                        help="run the shapely baseline only on scenes up to this many faces")
    args = parser.parse_args(argv)
    warm, cam = hsr.scenes.get("cubes")
    hsr.visible_regions(warm, cam, 64, 48)
    hsr.render(warm, cam, 64, 48)
    hsr.hidden_lines(warm, cam, 64, 48)
    print(f"CPU: {cpu_name()}, {os.cpu_count()} cores")
    print(f"{'case':28} {'faces':>8} {'regions s':>9} {'visible':>8} {'pieces':>8} "
          f"{'x render':>9} {'x lines':>8} {'x shapely':>9} {'x BSP':>6} {'BSP pieces':>10} "
          f"{'peak GB':>7}")
    print("(peak: the high-water mark of the process after each case's regions)")
    for spec in args.cases:
        label, scene, camera, width, height = case(spec)
        regions, t_regions = timed(lambda: hsr.visible_regions(scene, camera, width, height))
        peak = peak_gb()  # the process's high-water mark so far: the BSP build raises it
        _, t_render = timed(lambda: hsr.render(scene, camera, width, height))
        _, t_lines = timed(lambda: hsr.hidden_lines(scene, camera, width, height))
        tree, t_bsp = timed(lambda: bsp_walk(scene, camera))
        if scene.n_faces <= args.baseline_faces:
            _, t_base = timed(lambda: shapely_baseline(scene, camera, width, height))
            base = f"{t_regions / t_base:9.3f}"
        else:
            base = f"{'-':>9}"
        print(f"{label + f' {width}x{height}':28} {scene.n_faces:8d} {t_regions / 1e3:9.2f} "
              f"{len(regions):8d} {len(regions.piece_row):8d} {t_regions / t_render:9.1f} "
              f"{t_regions / t_lines:8.2f} {base} {t_regions / t_bsp:6.2f} {len(tree):10d} "
              f"{peak:7.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
