"""The z-buffer (Catmull 1974): for every fragment, keep it if it passes the depth test
against what is stored. Follows OpenGL's depth state exactly, in submission order."""

from __future__ import annotations

import numpy as np

from ..errors import RenderError
from ..fragments import Fragments
from ..occlusion import BLOCK, ObjectBounds, rect_hidden, screen_box, update_hzb
from ..parallel import Workers
from ..pipeline import ScreenTriangles
from ..raster import band_split, fill_bands, rasterize, setup_triangles
from ..state import DepthFunc, RenderState

NAME = "zbuffer"
OPTIONS = ()  # accepted keys of render(..., options=...)
DESCRIPTION = "depth buffer with OpenGL depth state (test, func, mask, clear, range)"
_NO_COUNTS = np.zeros((1, 1), dtype=np.int32)


def resolve(screen: ScreenTriangles, state: RenderState, depth_buffer: np.ndarray | None = None,
            counts: bool = False, workers: Workers | None = None,
            occlusion: ObjectBounds | None = None, **_) -> Fragments:
    """Z-buffer visibility of ``screen``. The depth buffer starts cleared to
    ``state.clear_depth``, or is ``depth_buffer`` ((H, W) float32, updated in place: draws
    accumulate as in OpenGL without glClear). ``face_id`` marks what this draw wrote.
    With ``occlusion`` (the scene's object bounds) objects are drawn front to back and
    those hidden behind what is drawn are skipped (:mod:`hsr.occlusion`)."""
    workers = workers or Workers()
    if occlusion is not None:
        return _resolve_with_occlusion(screen, state, depth_buffer, workers, occlusion)
    face, depth, bbox, tested, written, count_tested, count_written = rasterize(
        screen.xy_window, screen.depth_window, screen.face_id, screen.width, screen.height,
        state, workers, counts=counts, depth_buffer=depth_buffer)
    stats = {
        "triangles_rasterized": int(np.count_nonzero((bbox[:, 0] <= bbox[:, 1])
                                                     & (bbox[:, 2] <= bbox[:, 3]))),
        "fragments_tested": int(tested),
        "fragments_written": int(written),
    }
    return Fragments(face, depth, screen, stats, count_tested, count_written)


def _resolve_with_occlusion(screen, state, depth_buffer, workers, occlusion):
    if not (state.depth_test and state.depth_mask
            and state.depth_func in (DepthFunc.LESS, DepthFunc.LEQUAL)):
        raise RenderError("occlusion culling needs the depth test and depth writes on and "
                          "depth func less or lequal")
    width, height = screen.width, screen.height
    if depth_buffer is None:
        depth = np.full((height, width), state.clear_depth, dtype=np.float32)
    else:
        depth = depth_buffer
    face = np.full((height, width), -1, dtype=np.int32)
    z_lo, z_hi = min(state.depth_range), max(state.depth_range)
    near, far = state.depth_range
    depth_scale, depth_offset = 0.5 * (far - near), 0.5 * (far + near)
    # Screen triangles are in face order, so each object's triangles are one slice.
    tri_start = np.searchsorted(screen.face_id, occlusion.face_offsets)
    hzb = np.empty((-(-height // BLOCK), -(-width // BLOCK)), dtype=np.float32)
    update_hzb(depth, hzb, 0, width - 1, 0, height - 1)
    boxes = [screen_box(c, width, height, depth_scale, depth_offset)
             for c in occlusion.corners_clip]
    order = np.argsort([b[4] for b in boxes], kind="stable")  # nearest first
    tested = written = n_tested = n_culled = n_rasterized = 0
    for obj in order:
        t0, t1 = tri_start[obj], tri_start[obj + 1]
        if t0 == t1:
            continue
        n_tested += 1
        x0, x1, r0, r1, z_min, ok = boxes[obj]
        if ok and rect_hidden(hzb, x0, x1, r0, r1, z_min):
            n_culled += 1
            continue
        # Set up only what is drawn: culled objects cost nothing past the geometry stage.
        vert_fixed, edge_bias, bbox, zplane, row_work = setup_triangles(
            screen.xy_window[t0:t1], screen.depth_window[t0:t1], width, height, workers)
        bands = band_split(row_work, workers.threads)
        t, w = fill_bands(
            workers, bands, vert_fixed, edge_bias, bbox, zplane, screen.face_id[t0:t1], width,
            height, True, state.depth_func.code, True, z_lo, z_hi, np.nan, depth, face,
            _NO_COUNTS, _NO_COUNTS, False, True)
        tested, written = tested + t, written + w
        drawn = bbox[(bbox[:, 0] <= bbox[:, 1]) & (bbox[:, 2] <= bbox[:, 3])]
        n_rasterized += len(drawn)
        if len(drawn):
            update_hzb(depth, hzb, int(drawn[:, 0].min()), int(drawn[:, 1].max()),
                       height - 1 - int(drawn[:, 3].max()), height - 1 - int(drawn[:, 2].min()))
    stats = {
        "triangles_rasterized": n_rasterized,
        "fragments_tested": int(tested),
        "fragments_written": int(written),
        "objects_tested": n_tested,
        "objects_culled": n_culled,
    }
    return Fragments(face, depth, screen, stats)
