"""The z-buffer (Catmull 1974): for every fragment, keep it if it passes the depth test
against what is stored. Follows OpenGL's depth state exactly, in submission order."""

from __future__ import annotations

import numpy as np

from ..fragments import Fragments
from ..parallel import Workers
from ..pipeline import ScreenTriangles
from ..raster import band_split, fill_bands, setup_triangles
from ..state import RenderState

NAME = "zbuffer"
DESCRIPTION = "depth buffer with OpenGL depth state (test, func, mask, clear, range)"


def resolve(screen: ScreenTriangles, state: RenderState, depth_buffer: np.ndarray | None = None,
            counts: bool = False, workers: Workers | None = None) -> Fragments:
    """Z-buffer visibility of ``screen``. The depth buffer starts cleared to
    ``state.clear_depth``, or is ``depth_buffer`` ((H, W) float32, updated in place: draws
    accumulate as in OpenGL without glClear). ``face_id`` marks what this draw wrote."""
    workers = workers or Workers()
    width, height = screen.width, screen.height
    if depth_buffer is None:
        depth = np.empty((height, width), dtype=np.float32)
        clear = state.clear_depth
    else:
        depth = depth_buffer
        clear = np.nan
    face = np.empty((height, width), dtype=np.int32)
    shape = (height, width) if counts else (1, 1)
    count_tested = np.zeros(shape, dtype=np.int32)
    count_written = np.zeros(shape, dtype=np.int32)
    vert_fixed, edge_bias, bbox, zplane = setup_triangles(
        screen.xy_window, screen.depth_window, width, height, workers)
    # One band per thread: the split balances estimated work, and every extra band costs
    # a walk over all triangles.
    bands = band_split(bbox, height, workers.threads)
    z_lo, z_hi = min(state.depth_range), max(state.depth_range)
    tested, written = fill_bands(
        workers, bands, vert_fixed, edge_bias, bbox, zplane, screen.face_id, width, height,
        state.depth_test, state.depth_func.code, state.depth_mask, z_lo, z_hi, clear, depth,
        face, count_tested, count_written, counts)
    stats = {
        "triangles_rasterized": int(np.count_nonzero((bbox[:, 0] <= bbox[:, 1])
                                                     & (bbox[:, 2] <= bbox[:, 3]))),
        "bands": len(bands) - 1,
        "fragments_tested": int(tested),
        "fragments_written": int(written),
    }
    return Fragments(face, depth, screen, stats,
                     count_tested if counts else None, count_written if counts else None)
