"""Window-space triangle set-up shared by every fill, compiled with Numba.

Coverage: window x, y snapped to 1/256 pixel, edge functions (Pineda 1988) evaluated in
exact int64 arithmetic with the top-left fill rule (see :mod:`hsr.geometry.conventions`),
so a pixel centre on an edge shared by two triangles goes to exactly one of them.

Depth: a plane through the *unsnapped* window-space corners, evaluated at the pixel centre
in float64 (by the fill), with glPolygonOffset's offset added here.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .conventions import SUBPIXEL_BITS

__all__ = ["setup_triangles", "setup_one", "setup_records", "estimate_row_work",
           "covers_pixels", "polygon_offset", "depth_bounds", "ONE", "HALF"]

ONE = 1 << SUBPIXEL_BITS  # one pixel in snapped window units
HALF = ONE >> 1


def setup_triangles(xy_window, depth_window, width, height, workers, polygon_offset=(0.0, 0.0)):
    """Per-triangle set-up shared by every fill. ``polygon_offset`` = (factor, units) as
    glPolygonOffset: each triangle's depth moves by ``factor * m + units * r``, with ``m``
    its largest window depth slope and ``r`` the smallest float32 step at its largest
    depth (OpenGL 4.6, 14.6.5, floating-point depth buffers).

    Returns
    -------
    vert_fixed : (N, 6) int32, snapped corners (x0, y0, x1, y1, x2, y2) in 1/256 pixel,
        reordered counter-clockwise (y up); widen to int64 before multiplying.
    edge_bias : (N, 3) int8, 0 where a centre exactly on the edge is inside (left or
        bottom edge in y-up window space), -1 where it is not.
    bbox : (N, 4) int32, inclusive pixel ranges (x_min, x_max, y_min, y_max), clamped to
        the viewport, y counted from the bottom; empty when min > max.
    zplane : (N, 7) float64, (x0, y0, z0, dz/dx, dz/dy) of the unsnapped depth plane and
        (z_min, z_max) the range a fragment's depth is clamped to besides the depth
        range: the corners' depths for slivers, (-inf, inf) otherwise (polygon offset
        included; see :func:`setup_one`).
    row_work : (H,) float64, estimated fill work per window row (for :func:`band_split`),
        gathered during the same pass.
    """
    n = xy_window.shape[0]
    vert_fixed, edge_bias, bbox, zplane = setup_records(n)
    factor, units = (float(v) for v in polygon_offset)
    bounds = workers.split(n)
    delta = np.zeros((len(bounds) - 1, height + 1))  # one per part: they run at once
    widest = workers.run(_setup_range, bounds, xy_window, depth_window, width, height,
                         vert_fixed, edge_bias, bbox, zplane, factor, units, each=delta)
    return vert_fixed, edge_bias, bbox, zplane, estimate_row_work(delta, widest)


def setup_records(n: int, workers=None, slot: int = 0):
    """Empty set-up records for ``n`` triangles: (vert_fixed, edge_bias, bbox, zplane) as
    :func:`setup_triangles` describes them; with ``workers``, its scratch buffers of set
    ``slot`` (kept by a :class:`~hsr.parallel.Workspace`)."""
    # Compact records (fixed-point coordinates stay below 2**28 thanks to the guard band):
    # memory traffic, not arithmetic, is what set-up costs on large meshes.
    layout = (((6,), np.int32), ((3,), np.int8), ((4,), np.int32), ((7,), np.float64))
    if workers is None:
        return tuple(np.empty((n, *shape), dtype=dtype) for shape, dtype in layout)
    return tuple(workers.scratch(("records", slot, i), n, shape, dtype)
                 for i, (shape, dtype) in enumerate(layout))


def estimate_row_work(delta: np.ndarray, widest) -> np.ndarray:
    """(H,) estimated fill work per row from the set-up parts' per-row deltas
    ((parts, H + 1)) and widest rows: the box widths of the triangles on a row plus a
    share for clearing it."""
    return np.cumsum(delta.sum(axis=0)[:-1]) + 0.05 * max(widest)


def covers_pixels(bbox: np.ndarray) -> np.ndarray:
    """(N,) bool: set-up boxes that hold at least one pixel centre."""
    return (bbox[:, 0] <= bbox[:, 1]) & (bbox[:, 2] <= bbox[:, 3])


@njit(cache=True, nogil=True)
def _setup_range(lo, hi, xy_window, depth_window, width, height, vert_fixed, edge_bias,
                 bbox, zplane, offset_factor, offset_units, delta):
    # Per-row work estimate of this chunk in ``delta`` (its own (H + 1,) zeros): + box
    # width at a triangle's first row, - after its last.
    widest = 1
    for t in range(lo, hi):
        widest = max(widest, setup_one(
            t, xy_window[t, 0, 0], xy_window[t, 0, 1], depth_window[t, 0],
            xy_window[t, 1, 0], xy_window[t, 1, 1], depth_window[t, 1],
            xy_window[t, 2, 0], xy_window[t, 2, 1], depth_window[t, 2], width, height,
            vert_fixed, edge_bias, bbox, zplane, offset_factor, offset_units, delta))
    return widest


@njit(cache=True, nogil=True, inline="always")
def setup_one(t, fx0, fy0, fz0, fx1, fy1, fz1, fx2, fy2, fz2, width, height, vert_fixed,
              edge_bias, bbox, zplane, offset_factor, offset_units, delta):
    """Set up one triangle (window corners ``f*``) into record ``t`` of the arrays
    :func:`setup_triangles` describes; adds its box width to ``delta`` (per-row work) and
    returns one past its right-most pixel (0 when it covers no pixel centre)."""
    x0 = np.int64(math.floor(fx0 * ONE + 0.5))
    y0 = np.int64(math.floor(fy0 * ONE + 0.5))
    x1 = np.int64(math.floor(fx1 * ONE + 0.5))
    y1 = np.int64(math.floor(fy1 * ONE + 0.5))
    x2 = np.int64(math.floor(fx2 * ONE + 0.5))
    y2 = np.int64(math.floor(fy2 * ONE + 0.5))
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if area < 0:  # make the corner order counter-clockwise
        x1, x2 = x2, x1
        y1, y2 = y2, y1
    # Every field of the record is computed first and stored once, at the end: a store
    # into one of these arrays in the middle keeps the compiler from holding the others
    # in registers across it (they might alias), which cost a fifth of the set-up.
    # Pixel i is a candidate when its centre 256*i + 128 lies within the box.
    bx0 = max(-((-(min(x0, x1, x2) - HALF)) // ONE), 0)
    bx1 = min((max(x0, x1, x2) - HALF) // ONE, width - 1)
    by0 = max(-((-(min(y0, y1, y2) - HALF)) // ONE), 0)
    by1 = min((max(y0, y1, y2) - HALF) // ONE, height - 1)
    covers = area != 0 and bx0 <= bx1 and by0 <= by1
    dzdx = dzdy = 0.0
    z_min, z_max = -np.inf, np.inf
    z_at = fz0
    if covers:
        # Depth plane from the unsnapped positions.
        ax, ay = fx1 - fx0, fy1 - fy0
        bx, by = fx2 - fx0, fy2 - fy0
        az, bz = fz1 - fz0, fz2 - fz0
        det = ax * by - bx * ay
        if det != 0.0:
            dzdx = (az * by - bz * ay) / det
            dzdy = (ax * bz - bx * az) / det
        # Coverage is decided on the snapped corners, depth on the unsnapped plane, which
        # is extrapolated at a covered centre just outside the unsnapped triangle (OpenGL
        # does the same; at edge pixels the difference is a float32 step or so). But a
        # sliver narrower than the snapping step (1/256 pixel) has a plane whose slope
        # across it is meaningless, and snapping can make it cover centres far from it
        # in that direction: the extrapolated depth is then anything (a face inside a
        # closed box won a pixel with depth 0). Such a triangle's depth is clamped to its
        # corners' range, which holds any weighted mean of them (OpenGL 4.6, 14.6.1).
        cx, cy = fx2 - fx1, fy2 - fy1
        longest = max(ax * ax + ay * ay, bx * bx + by * by, cx * cx + cy * cy)
        if det * det * (ONE * ONE) < longest:  # height |det| / edge below 1/256 pixel
            z_min, z_max = min(fz0, fz1, fz2), max(fz0, fz1, fz2)
        if offset_factor != 0.0 or offset_units != 0.0:
            offset = polygon_offset(dzdx, dzdy, fz0, fz1, fz2, offset_factor, offset_units)
            z_at += offset
            z_min += offset
            z_max += offset
    vert_fixed[t, 0], vert_fixed[t, 1] = x0, y0
    vert_fixed[t, 2], vert_fixed[t, 3] = x1, y1
    vert_fixed[t, 4], vert_fixed[t, 5] = x2, y2
    edge_bias[t, 0] = _bias(x1 - x0, y1 - y0)
    edge_bias[t, 1] = _bias(x2 - x1, y2 - y1)
    edge_bias[t, 2] = _bias(x0 - x2, y0 - y2)
    zplane[t, 0], zplane[t, 1], zplane[t, 2], zplane[t, 3], zplane[t, 4] = \
        fx0, fy0, z_at, dzdx, dzdy
    zplane[t, 5], zplane[t, 6] = z_min, z_max
    if not covers:
        bbox[t, 0], bbox[t, 1], bbox[t, 2], bbox[t, 3] = 0, -1, 0, -1
        return 0
    bbox[t, 0], bbox[t, 1], bbox[t, 2], bbox[t, 3] = bx0, bx1, by0, by1
    delta[by0] += bx1 - bx0 + 1
    delta[by1 + 1] -= bx1 - bx0 + 1
    return bx1 + 1


@njit(cache=True, nogil=True, inline="always")
def depth_bounds(zplane, t, z_lo, z_hi):
    """(low, high): what record ``t``'s fragment depths are clamped to, the depth range
    [z_lo, z_hi] narrowed to a sliver's corners' depths (see :func:`setup_one`). Every
    fill clamps through this, so all draw a sliver at the same depths."""
    return max(z_lo, zplane[t, 5]), min(z_hi, zplane[t, 6])


@njit(cache=True, nogil=True)
def polygon_offset(dzdx, dzdy, z0, z1, z2, factor, units):
    """glPolygonOffset's depth offset ``factor * m + units * r`` of one triangle: ``m`` is
    max(|dz/dx|, |dz/dy|) (the approximation the GL spec allows), ``r`` the float32
    resolution 2**(e - 23) at the triangle's largest depth 2**e * 1.xxx."""
    m = max(abs(dzdx), abs(dzdy))
    z_max = max(abs(z0), abs(z1), abs(z2))
    if z_max > 0.0:
        _, e = math.frexp(z_max)  # z_max = mantissa * 2**e, mantissa in [0.5, 1)
        r = math.ldexp(1.0, e - 24)
    else:
        r = math.ldexp(1.0, -149)
    return factor * m + units * r


@njit(cache=True, nogil=True, inline="always")
def _bias(dx, dy):
    # Top-left rule in image orientation = left or bottom edge in y-up window space.
    return 0 if (dy < 0 or (dy == 0 and dx > 0)) else -1
