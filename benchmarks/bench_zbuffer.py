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
second (median) and hsr's peak resident memory so far. Runs on demand, never as part of
the test suite.

OpenGL runs in a process of its own (started once, fed the same triangles and camera,
timing its own blocks in turn with hsr's), because Mesa in hsr's process changes glibc's
heap: after one llvmpipe draw, every 1M-face render there gave its ~57 MB of scratch back
to the kernel at the end (brk shrinking, M_TRIM_THRESHOLD) and faulted it in again, 4,400-
6,300 page faults (10-40 ms) a render that no hsr user without Mesa pays (1-3 faults; the
same with mallopt raising the trim and mmap thresholds). ``--same-process`` times both in
one process as before. hsr is timed as users call it (``--plain``, the default): plain
``hsr.render`` calls, which keep their scratch in the calling thread's default workspace
from frame to frame, as the GL context keeps its framebuffer; ``--workspace`` renders
through one explicit ``hsr.Workspace``; ``--fresh`` drops the default workspace's scratch
after every frame (the allocation every frame that plain calls paid before).
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
from math import nan

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))

import hsr  # noqa: E402
from common import block_ms, peak_gb, progress, timings  # noqa: E402

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


def _gl_peer(conn):
    """The OpenGL side in its own process: ("upload", triangles) keeps a vertex array,
    ("block", view_proj, width, height, repeat) answers one warm-up draw and then the
    milliseconds of ``repeat`` timed ones, None ends."""
    try:
        from gl_reference import GLRenderer

        gl = GLRenderer()
    except Exception as exc:  # moderngl or Mesa missing
        conn.send(str(exc))
        return
    conn.send(None)
    vao = vbo = None
    while (msg := conn.recv()) is not None:
        if msg[0] == "upload":
            if vao is not None:
                vao.release()
                vbo.release()
            vao, vbo = gl.upload(msg[1])
            conn.send(True)
        else:
            _, view_proj, width, height, repeat = msg
            conn.send(block_ms(lambda: gl.render(None, view_proj, width, height, vao=vao),
                               repeat))


class GLPeer:
    """llvmpipe in a child process (see the module's docstring), timed in blocks."""

    def __init__(self):
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(target=_gl_peer, args=(child,), daemon=True)
        self._proc.start()
        error = self._conn.recv()
        if error is not None:
            self._proc.join()
            raise RuntimeError(error)

    def upload(self, tri_world):
        self._conn.send(("upload", np.asarray(tri_world, dtype=np.float32)))
        self._conn.recv()

    def block(self, view_proj, width, height, repeat):
        self._conn.send(("block", view_proj, width, height, repeat))
        return self._conn.recv()

    def close(self):
        self._conn.send(None)
        self._proc.join()


def alternating(run_hsr, peer, view_proj, width, height, repeat, rounds=3):
    """(min, median) ms of hsr and of the peer, blocks alternating as in timings()."""
    hsr_ms, gl_ms = [], []
    for _ in range(rounds):
        hsr_ms += block_ms(run_hsr, repeat)
        gl_ms += peer.block(view_proj, width, height, repeat)
    return [(min(t), float(np.median(t))) for t in (hsr_ms, gl_ms)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", default=DEFAULT_MODELS)
    parser.add_argument("--sizes", default="1024x1024,1920x1080,3840x2160")
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--no-gl", action="store_true", help="skip the OpenGL peer")
    parser.add_argument("--same-process", action="store_true",
                        help="run OpenGL in hsr's process (Mesa then changes hsr's heap)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--plain", action="store_true",
                      help="plain hsr.render calls, as users write them (the default)")
    mode.add_argument("--workspace", action="store_true",
                      help="render through one explicit hsr.Workspace")
    mode.add_argument("--fresh", action="store_true",
                      help="plain calls with the default workspace's scratch dropped "
                           "after every frame")
    args = parser.parse_args(argv)
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]

    gl = peer = None
    if not args.no_gl:
        try:
            if args.same_process:
                from gl_reference import GLRenderer

                gl = GLRenderer()
            else:
                peer = GLPeer()
        except Exception as exc:  # moderngl or Mesa missing
            print(f"# OpenGL peer unavailable ({exc}); timing hsr alone", file=sys.stderr)

    print(f"{'model':24} {'triangles':>9} {'size':>10} {'hsr ms min/med':>15} "
          f"{'gl ms min/med':>15} {'hsr/gl min/med':>15} {'Mtri/s':>7} {'covered':>7} "
          f"{'peak GB':>8}")
    jobs = [(m, s) for m in args.models for s in sizes]
    meshes = {}
    workspace = hsr.Workspace() if args.workspace else None
    for model, (width, height) in progress(jobs, "bench"):
        if model not in meshes:
            meshes.clear()  # keep one large mesh in memory at a time
            meshes[model] = load_model(model)
            if peer is not None:
                peer.upload(hsr.Scene([meshes[model][0]]).world_triangles())
        mesh, label, cam = meshes[model]
        def run_hsr(mesh=mesh, cam=cam, width=width, height=height):
            frame = hsr.render(mesh, cam, width, height, workspace=workspace)
            if args.fresh:
                hsr.parallel.release_default_workspace()
            return frame

        if peer is not None:
            view_proj = cam.projection_matrix(width / height) @ cam.view_matrix
            hsr_ms, gl_ms = alternating(run_hsr, peer, view_proj, width, height, args.repeat)
        elif gl is None:
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
    if peer is not None:
        peer.close()
    if workspace is not None:
        workspace.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
