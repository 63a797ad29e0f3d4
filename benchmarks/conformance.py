"""Conformance table: hsr vs OpenGL (Mesa llvmpipe) on the shared models, for the note.

    python benchmarks/conformance.py [--size 1024x768]

Per model and camera: share of covered pixels with equal face ids, and the 99th-percentile
and worst depth difference where they agree.
"""

import argparse
import glob
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))

import hsr  # noqa: E402
from gl_reference import GLRenderer, cameras_for, compare_gl  # noqa: E402

MODELS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "models")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--size", default="1024x768")
    parser.add_argument("--cull", default="none")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    gl = GLRenderer()
    print(f"{'model':28} {'camera':8} {'covered':>8} {'ids equal':>10} {'depth p99':>10} "
          f"{'depth max':>10}")
    for path in sorted(glob.glob(os.path.join(MODELS, "*.obj"))):
        mesh = hsr.load(path)
        for view, cam in cameras_for(mesh).items():
            share, p99, worst, n_cov, _ = compare_gl(gl, mesh, cam, width, height,
                                                     cull=args.cull)
            print(f"{os.path.basename(path):28} {view:8} {n_cov:8d} {100 * share:9.4f}% "
                  f"{p99:10.2e} {worst:10.2e}", flush=True)


if __name__ == "__main__":
    main()
