"""Time hsr's z-buffer against OpenGL on Mesa llvmpipe, measured in the same run.

    python benchmarks/bench_zbuffer.py [MODEL ...] [--sizes 1024x1024,1920x1080] [--repeat 7]

MODEL is a mesh file or ``terrain:N``, a generated displaced grid of N triangles (e.g.
``terrain:1000000``, ``terrain:10000000``) seen from the scene's own low oblique camera
(``terrain-edge:N``: the same grid framed from the side by ``Camera.frame``, nearly edge-on,
so that it covers a thin strip: the per-triangle cost with almost no fill). Mesh files are
framed by ``Camera.frame`` (front view, 45 degrees). For each model and size: hsr.render (warm;
face_id + depth + flat colour) and moderngl (static vertex buffer; clear + draw + finish
+ read back face ids and depth), min and median over three alternating blocks of --repeat
runs each, the ratios hsr / llvmpipe of both (< 1 means hsr is faster), triangles per
second (median) and the process's peak resident memory so far. Runs on demand, never as
part of the test suite.
"""

from __future__ import annotations

import argparse
import os
import sys
from math import nan

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))

from common import peak_gb, progress, timings  # noqa: E402

import hsr  # noqa: E402

MODELS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "models")
DEFAULT_MODELS = [os.path.join(MODELS, name) for name in ("african_head.obj", "spot.obj",
                                                          "stanford-bunny.obj")]


def load_model(spec: str):
    """(mesh, label, camera)."""
    kind, _, count = spec.partition(":")
    if kind in ("terrain", "terrain-edge") and count:
        n = int(float(count))
        scene, camera = hsr.scenes.terrain(n)
        mesh = scene.instances[0].mesh
        if kind == "terrain-edge":
            camera = hsr.Camera.frame(mesh.bounds(), fov_y=45)
        return mesh, f"{kind} {n:.0e}", camera
    mesh = hsr.load(spec)
    return mesh, os.path.basename(spec), hsr.Camera.frame(mesh.bounds(), fov_y=45)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", default=DEFAULT_MODELS)
    parser.add_argument("--sizes", default="1024x1024,1920x1080,3840x2160")
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--no-gl", action="store_true", help="skip the OpenGL peer")
    args = parser.parse_args(argv)
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]

    gl = None
    if not args.no_gl:
        try:
            from gl_reference import GLRenderer

            gl = GLRenderer()
        except Exception as exc:  # moderngl or Mesa missing
            print(f"# OpenGL peer unavailable ({exc}); timing hsr alone", file=sys.stderr)

    print(f"{'model':24} {'triangles':>9} {'size':>10} {'hsr ms min/med':>15} "
          f"{'gl ms min/med':>15} {'hsr/gl min/med':>15} {'Mtri/s':>7} {'covered':>7} "
          f"{'peak GB':>8}")
    jobs = [(m, s) for m in args.models for s in sizes]
    meshes = {}
    for model, (width, height) in progress(jobs, "bench"):
        if model not in meshes:
            meshes.clear()  # keep one large mesh in memory at a time
            meshes[model] = load_model(model)
        mesh, label, cam = meshes[model]
        run_hsr = lambda: hsr.render(mesh, cam, width, height)  # noqa: E731
        if gl is None:
            hsr_ms, gl_ms = timings([run_hsr], args.repeat, rounds=3)[0], (nan, nan)
        else:
            view_proj = cam.projection_matrix(width / height) @ cam.view_matrix
            vao, vbo = gl.upload(hsr.Scene([mesh]).world_triangles())
            hsr_ms, gl_ms = timings(
                [run_hsr, lambda: gl.render(None, view_proj, width, height, vao=vao)],
                args.repeat, rounds=3)
            vao.release()
            vbo.release()
        ratio = (hsr_ms[0] / gl_ms[0], hsr_ms[1] / gl_ms[1])
        covered = run_hsr().stats["pixels_covered"] / (width * height)
        peak = peak_gb()
        print(f"{label:24} {mesh.n_faces:9d} {width:>4}x{height:<5} "
              f"{hsr_ms[0]:7.1f}/{hsr_ms[1]:<7.1f} {gl_ms[0]:7.1f}/{gl_ms[1]:<7.1f} "
              f"{ratio[0]:7.2f}/{ratio[1]:<7.2f} {mesh.n_faces / hsr_ms[1] / 1e3:7.2f} "
              f"{covered:7.1%} {peak:8.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
