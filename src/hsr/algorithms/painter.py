"""The painter's algorithm (seed 000, 001, 003): sort triangles by depth, farthest first,
and paint them in that order with no depth test, so nearer ones cover farther ones.

It is *expected* to be wrong where no back-to-front order of whole triangles exists
(cyclic overlap, penetration) or where the sort key misorders two overlapping triangles;
``stats["pixels_wrong"]`` counts the pixels where it differs from the z-buffer, and
:func:`hsr.compare.difference_map` draws them.
"""

from __future__ import annotations

import numpy as np

from ..errors import RenderError
from ..fragments import Fragments
from ..parallel import Workers
from ..pipeline import ScreenTriangles
from ..raster import band_split, fill_bands, setup_triangles
from ..state import RenderState
from . import zbuffer

NAME = "painter"
DESCRIPTION = "depth sort (max / centroid / min key), paint far to near; fails on cycles"
KEYS = ("max", "centroid", "min")
_NO_COUNTS = np.zeros((1, 1), dtype=np.int32)
ALWAYS = 7  # DepthFunc.ALWAYS.code: paint over whatever is there


def paint_in_order(screen: ScreenTriangles, order: np.ndarray, tri_face: np.ndarray,
                   state: RenderState, workers: Workers, counts: bool = False):
    """Fill the triangles ``order`` (indices into ``screen``) in that order, each one
    over whatever is there; the depth buffer keeps the depth of the last painted
    fragment. Returns (face, depth, tested, written, count_tested, count_written)."""
    width, height = screen.width, screen.height
    face = np.empty((height, width), dtype=np.int32)
    depth = np.empty((height, width), dtype=np.float32)
    shape = (height, width) if counts else (1, 1)
    count_tested = np.zeros(shape, dtype=np.int32)
    count_written = np.zeros(shape, dtype=np.int32)
    vert_fixed, edge_bias, bbox, zplane = setup_triangles(
        np.ascontiguousarray(screen.xy_window[order]),
        np.ascontiguousarray(screen.depth_window[order]), width, height, workers)
    bands = band_split(bbox, height, workers.threads)
    z_lo, z_hi = min(state.depth_range), max(state.depth_range)
    tested, written = fill_bands(
        workers, bands, vert_fixed, edge_bias, bbox, zplane, tri_face, width, height, True,
        ALWAYS, True, z_lo, z_hi, state.clear_depth, depth, face, count_tested,
        count_written, counts)
    return face, depth, tested, written, (count_tested if counts else None), (
        count_written if counts else None)


def sort_far_to_near(depth_window: np.ndarray, key: str) -> np.ndarray:
    """Indices farthest first by the key depth (window depth grows with distance);
    stable, so equal keys keep submission order."""
    if key == "max":
        k = depth_window.max(axis=1)
    elif key == "min":
        k = depth_window.min(axis=1)
    elif key == "centroid":
        k = depth_window.mean(axis=1)
    else:
        raise RenderError(f"painter key must be one of {', '.join(KEYS)}; got {key!r}")
    return np.argsort(-k, kind="stable")


def resolve(screen: ScreenTriangles, state: RenderState, workers: Workers | None = None,
            counts: bool = False, key: str = "max", check: bool = True, **_) -> Fragments:
    """Painter's algorithm. ``key`` picks the sort depth; ``check`` also runs the
    z-buffer to count the pixels where painting got it wrong."""
    workers = workers or Workers()
    order = sort_far_to_near(screen.depth_window, key)
    face, depth, tested, written, c_tested, c_written = paint_in_order(
        screen, order, screen.face_id[order], state, workers, counts)
    stats = {"key": key, "fragments_tested": int(tested), "fragments_written": int(written)}
    fragments = Fragments(face, depth, screen, stats, c_tested, c_written)
    if check:
        truth = zbuffer.resolve(screen, state, workers=workers)
        wrong = face != truth.face_id
        stats["pixels_wrong"] = int(np.count_nonzero(wrong))
        fragments.buffers["wrong"] = wrong
    return fragments
