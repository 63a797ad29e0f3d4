"""``hsr warmup``: compile every Numba kernel ahead (they are cached on disk after), so a
first render does not wait for them; and the one-line note a command prints on a
terminal when the kernels still need compiling."""

from __future__ import annotations

import os
import sys
import time


def add_parser(sub) -> None:
    sub.add_parser("warmup", help="compile hsr's kernels now (first run only)",
                   description="Compile every Numba kernel hsr uses by rendering the "
                   "built-in scene with each algorithm, casting rays, counting "
                   "visibility and computing exact regions and lines at a small size; the "
                   "compiled code is cached on disk, so later commands start at once.")


def run(args) -> int:
    import numpy as np

    from .. import algorithms, render, scenes
    from ..geometry.merge import merge_pieces
    from ..lines.vector import hidden_lines
    from ..visibility import RayScene, visibility_matrix
    from ..visibility.regions import visible_regions

    start = time.perf_counter()
    scene, camera = scenes.get("cubes")
    for name in algorithms.ALGORITHMS:
        render(scene, camera, 32, 24, algorithm=name)
    render(scene, camera, 32, 24, shading="gouraud", polygon_mode="line")
    rays = RayScene(scene)
    origins = np.zeros((4, 3)) + np.asarray(camera.eye)
    rays.cast(origins, np.asarray(camera.target) - origins)
    rays.occluded(origins, np.asarray(camera.target) - origins)
    visibility_matrix(scene, [camera], 16)
    # The exact engines (regions, vector lines) and the rings hsr.mpl merges pieces into.
    regions = visible_regions(scene, camera, 32, 24)
    merge_pieces(regions.vertices, regions.piece_start, np.array([0, len(regions.piece_row)]))
    hidden_lines(scene, camera, 32, 24)
    print(f"hsr: kernels compiled and cached in {time.perf_counter() - start:.1f} s")
    return 0


def kernels_cached() -> bool:
    """Whether Numba's on-disk cache holds hsr's kernels: an index file under
    ``NUMBA_CACHE_DIR`` when it is set (Numba then caches there alone), else beside the
    package's modules."""
    root = os.environ.get("NUMBA_CACHE_DIR") or os.path.dirname(
        os.path.dirname(os.path.abspath(__file__)))
    return any(name.endswith(".nbi") for _, _, files in os.walk(root) for name in files)


def note_first_run(command: str, quiet: bool) -> None:
    """One line on a terminal when ``command`` is about to compile the kernels."""
    if quiet or command in ("warmup", "view") or not sys.stderr.isatty() \
            or kernels_cached():
        return
    # Measured cold on a 2-core machine: ~15 s for a render's, ~160 s for all (warmup).
    print("hsr: compiling kernels, first run only (15 s for a render, minutes for "
          "every kernel; `hsr warmup` compiles them all ahead)", file=sys.stderr)
