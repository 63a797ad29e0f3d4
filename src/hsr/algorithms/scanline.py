"""The scan-line algorithm (Wylie, Romney, Evans & Erdahl 1967; Watkins 1970), seed 001.

For each scan line: an edge table bucketed by starting row feeds an active polygon list;
each active triangle's span on the line is where all three of its edge functions are
non-negative (the same exact integer edge functions and top-left rule as the z-buffer, so
coverage is identical); the span ends, sorted by x, cut the line into segments in which
the set of "in" polygons is constant. A segment with one polygon in is written at once;
where more than one is in, depth is compared pixel by pixel from each polygon's plane,
stepping ``z += dz/dx`` along the line (``dz/dx = -a/c`` for the plane
``ax + by + cz + d = 0``). Working memory is one scan line: no depth buffer.

Visibility follows the z-buffer with depth func LESS (nearest wins, ties to the first
submitted triangle) or LEQUAL (ties to the last), the depth test on.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import RenderError
from ..geometry.setup import HALF as _HALF
from ..geometry.setup import ONE as _ONE
from ..geometry.setup import covers_pixels, depth_bounds, setup_triangles
from ..geometry.stage import ScreenTriangles
from ..geometry.state import DepthFunc, RenderState
from ..parallel import Workers
from ..raster.fill import band_split
from .fragments import Fragments
from .support import Needs, refuse_unless_nearest_wins, refuse_unsupported

NAME = "scanline"
OPTIONS: dict = {}  # accepted keys of render(..., options=...): none
DESCRIPTION = "Watkins scan-line: active edge list, spans, incremental depth along the line"


def check(state: RenderState, needs: Needs) -> None:
    """Raise :class:`RenderError` for a request scanline cannot honour exactly."""
    refuse_unless_nearest_wins(NAME, state)
    if needs.counts:
        raise RenderError("scanline does not record per-pixel fragment counts")
    refuse_unsupported(NAME, state, needs)


def resolve(screen: ScreenTriangles, state: RenderState, workers: Workers | None = None,
            counts: bool = False, **_) -> Fragments:
    workers = workers or Workers()
    width, height = screen.width, screen.height
    vert_fixed, edge_bias, bbox, zplane, row_work = setup_triangles(
        screen.xy_window, screen.depth_window, width, height, workers)
    live = np.flatnonzero(covers_pixels(bbox))
    # Edge table: triangles ordered by the first scan line they touch.
    edge_table = live[np.argsort(bbox[live, 2], kind="stable")]
    face = workers.output((height, width), np.int32)
    depth = workers.output((height, width), np.float32)
    z_lo, z_hi = min(state.depth_range), max(state.depth_range)
    bands = band_split(row_work, workers.threads)
    results = workers.run(_scan_rows, bands, edge_table, vert_fixed, edge_bias, bbox, zplane,
                          screen.face_id, width, height, state.depth_func == DepthFunc.LEQUAL,
                          np.float32(state.clear_depth), z_lo, z_hi, face, depth)
    spans = sum(r[0] for r in results)
    compared = sum(r[1] for r in results)
    max_active = max(r[2] for r in results)
    stats = {"spans": int(spans), "depth_comparisons": int(compared),
             "max_active_triangles": int(max_active), "triangles_rasterized": len(live)}
    return Fragments(face, depth, screen, stats)


@njit(cache=True, nogil=True)
def _span(t, j, vert_fixed, edge_bias, bbox):
    """Inclusive pixel range [x0, x1] of triangle t's coverage on window row j (exact:
    the pixel centres where all three biased edge functions are >= 0)."""
    x0, x1 = np.int64(bbox[t, 0]), np.int64(bbox[t, 1])
    py = np.int64(j) * _ONE + _HALF
    for k in range(3):
        xa, ya = np.int64(vert_fixed[t, 2 * k]), np.int64(vert_fixed[t, 2 * k + 1])
        kb = (k + 1) % 3
        xb, yb = np.int64(vert_fixed[t, 2 * kb]), np.int64(vert_fixed[t, 2 * kb + 1])
        # E(i) = e0 + sx * i at pixel centre x = 256 i + 128.
        sx = -(yb - ya) * _ONE
        e0 = (xb - xa) * (py - ya) - (yb - ya) * (_HALF - xa) + np.int64(edge_bias[t, k])
        if sx > 0:  # E >= 0  <=>  i >= ceil(-e0 / sx)
            x0 = max(x0, -(e0 // sx))
        elif sx < 0:  # E >= 0  <=>  i <= floor(e0 / -sx)
            x1 = min(x1, e0 // (-sx))
        elif e0 < 0:
            return 1, 0
    return x0, x1


@njit(cache=True, nogil=True)
def _scan_rows(b_lo, b_end, edge_table, vert_fixed, edge_bias, bbox, zplane, tri_face, width,
               height, lequal, clear_depth, z_lo, z_hi, face_buf, depth_buf):
    n_live = edge_table.shape[0]
    active = np.empty(n_live, dtype=np.int64)
    n_active = 0
    next_in = 0
    # Skip edge-table entries that end before this band.
    events_x = np.empty(2 * n_live, dtype=np.int64)
    events_t = np.empty(2 * n_live, dtype=np.int64)
    inside = np.empty(n_live, dtype=np.int64)  # triangles "in" at the sweep position
    where = np.full(bbox.shape[0], -1, dtype=np.int64)  # slot of a triangle in `inside`
    z_cur = np.empty(n_live)
    spans = 0
    compared = 0
    max_active = 0
    for j in range(b_lo, b_end):
        row = height - 1 - j
        # Update the active polygon list: add those starting here, drop finished ones.
        while next_in < n_live and bbox[edge_table[next_in], 2] <= j:
            t = edge_table[next_in]
            if bbox[t, 3] >= j:
                active[n_active] = t
                n_active += 1
            next_in += 1
        k = 0
        for a in range(n_active):
            if bbox[active[a], 3] >= j:
                active[k] = active[a]
                k += 1
        n_active = k
        max_active = max(max_active, n_active)
        for i in range(width):
            face_buf[row, i] = -1
            depth_buf[row, i] = clear_depth
        # Span ends of every active triangle on this line, sorted by x.
        n_ev = 0
        for a in range(n_active):
            t = active[a]
            x0, x1 = _span(t, j, vert_fixed, edge_bias, bbox)
            if x0 <= x1:
                events_x[n_ev], events_t[n_ev] = x0, t  # enters at x0
                events_x[n_ev + 1], events_t[n_ev + 1] = x1 + 1, -1 - t  # leaves after x1
                n_ev += 2
        if n_ev == 0:
            continue
        order = np.argsort(events_x[:n_ev], kind="mergesort")
        n_in = 0
        e = 0
        while e < n_ev:
            x = events_x[order[e]]
            while e < n_ev and events_x[order[e]] == x:
                t = events_t[order[e]]
                if t >= 0:
                    where[t] = n_in
                    inside[n_in] = t
                    n_in += 1
                else:
                    t = -1 - t
                    slot = where[t]
                    n_in -= 1
                    inside[slot] = inside[n_in]
                    where[inside[slot]] = slot
                    where[t] = -1
                e += 1
            x_end = events_x[order[e]] if e < n_ev else width
            if n_in == 0 or x >= x_end:
                continue
            spans += 1
            # Depth of each "in" polygon at the segment start, then incremental steps.
            for s in range(n_in):
                t = inside[s]
                z_cur[s] = (zplane[t, 2] + zplane[t, 4] * (j + 0.5 - zplane[t, 1])
                            + zplane[t, 3] * (x + 0.5 - zplane[t, 0]))
            for i in range(x, x_end):
                best = -1
                best_z = np.float32(0.0)
                for s in range(n_in):
                    t = inside[s]
                    z_min, z_max = depth_bounds(zplane, t, z_lo, z_hi)
                    zf = np.float32(min(max(z_cur[s], z_min), z_max))
                    z_cur[s] += zplane[t, 3]
                    # Submission order decides ties: LESS keeps the lowest index,
                    # LEQUAL the highest; the clear depth acts as the first "surface".
                    if lequal:
                        ok = zf <= clear_depth and (best < 0 or zf < best_z
                                                    or (zf == best_z and t > best))
                    else:
                        ok = zf < clear_depth and (best < 0 or zf < best_z
                                                   or (zf == best_z and t < best))
                    if ok:
                        best, best_z = t, zf
                compared += n_in - 1
                if best >= 0:
                    face_buf[row, i] = tri_face[best]
                    depth_buf[row, i] = best_z
    return spans, compared, max_active
