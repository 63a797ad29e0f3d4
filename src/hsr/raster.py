"""The shared triangle fill, compiled with Numba.

Coverage: window x, y snapped to 1/256 pixel, edge functions (Pineda 1988) evaluated in
exact int64 arithmetic with the top-left fill rule (see :mod:`hsr.conventions`), so a
pixel centre on an edge shared by two triangles goes to exactly one of them.

Depth: a plane through the *unsnapped* window-space corners, evaluated at the pixel centre
in float64, clamped to the depth range and rounded to float32 (the buffer format).

Parallelism: the viewport is cut into horizontal bands of about equal work; bands are
filled in parallel (:mod:`hsr.parallel`), each thread owning whole bands and walking the triangles
in submission order, so there are no races and the result does not depend on the number
of threads. (Square tiles with per-tile triangle lists were measured 2.5x slower on meshes
of small triangles: the binning and per-tile set-up cost more than they save.)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .conventions import SUBPIXEL_BITS

__all__ = ["setup_triangles", "band_split", "fill_bands", "depth_passes", "FIRST_WINS",
           "rasterize"]

_ONE = 1 << SUBPIXEL_BITS
# Pseudo depth function for front-to-back filling with a coverage mask: a pixel takes the
# first fragment that reaches it (BSP front-to-back traversal).
FIRST_WINS = 8
_HALF = _ONE >> 1


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
    zplane : (N, 5) float64, (x0, y0, z0, dz/dx, dz/dy) of the unsnapped depth plane.
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


def setup_records(n: int):
    """Empty set-up records for ``n`` triangles: (vert_fixed, edge_bias, bbox, zplane) as
    :func:`setup_triangles` describes them."""
    # Compact records (fixed-point coordinates stay below 2**28 thanks to the guard band):
    # memory traffic, not arithmetic, is what set-up costs on large meshes.
    return (np.empty((n, 6), dtype=np.int32), np.empty((n, 3), dtype=np.int8),
            np.empty((n, 4), dtype=np.int32), np.empty((n, 5)))


def estimate_row_work(delta: np.ndarray, widest) -> np.ndarray:
    """(H,) estimated fill work per row from the set-up parts' per-row deltas
    ((parts, H + 1)) and widest rows: the box widths of the triangles on a row plus a
    share for clearing it."""
    return np.cumsum(delta.sum(axis=0)[:-1]) + 0.05 * max(widest)


def covers_pixels(bbox: np.ndarray) -> np.ndarray:
    """(N,) bool: set-up boxes that hold at least one pixel centre."""
    return (bbox[:, 0] <= bbox[:, 1]) & (bbox[:, 2] <= bbox[:, 3])


def fill_targets(width, height, state, depth_buffer=None, counts=False):
    """The buffers a fill draws into: ``(depth, face, clear, count_tested,
    count_written)``. Fresh buffers are cleared by the fill itself (``clear`` = the
    state's clear depth); over ``depth_buffer`` nothing is cleared (``clear`` = NaN) and
    ``face`` starts at -1. The count arrays are (H, W) with ``counts``, else (1, 1)."""
    if depth_buffer is None:
        depth = np.empty((height, width), dtype=np.float32)
        face = np.empty((height, width), dtype=np.int32)
        clear = state.clear_depth
    else:
        depth, clear = depth_buffer, np.nan
        face = np.full((height, width), -1, dtype=np.int32)
    shape = (height, width) if counts else (1, 1)
    return (depth, face, clear, np.zeros(shape, dtype=np.int32),
            np.zeros(shape, dtype=np.int32))


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
    x0 = np.int64(math.floor(fx0 * _ONE + 0.5))
    y0 = np.int64(math.floor(fy0 * _ONE + 0.5))
    x1 = np.int64(math.floor(fx1 * _ONE + 0.5))
    y1 = np.int64(math.floor(fy1 * _ONE + 0.5))
    x2 = np.int64(math.floor(fx2 * _ONE + 0.5))
    y2 = np.int64(math.floor(fy2 * _ONE + 0.5))
    area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    if area < 0:  # make the corner order counter-clockwise
        x1, x2 = x2, x1
        y1, y2 = y2, y1
    vert_fixed[t, 0], vert_fixed[t, 1] = x0, y0
    vert_fixed[t, 2], vert_fixed[t, 3] = x1, y1
    vert_fixed[t, 4], vert_fixed[t, 5] = x2, y2
    edge_bias[t, 0] = _bias(x1 - x0, y1 - y0)
    edge_bias[t, 1] = _bias(x2 - x1, y2 - y1)
    edge_bias[t, 2] = _bias(x0 - x2, y0 - y2)
    zplane[t, 0], zplane[t, 1], zplane[t, 2], zplane[t, 3], zplane[t, 4] = \
        fx0, fy0, fz0, 0.0, 0.0
    # Pixel i is a candidate when its centre 256*i + 128 lies within the box.
    bx0 = max(-((-(min(x0, x1, x2) - _HALF)) // _ONE), 0)
    bx1 = min((max(x0, x1, x2) - _HALF) // _ONE, width - 1)
    by0 = max(-((-(min(y0, y1, y2) - _HALF)) // _ONE), 0)
    by1 = min((max(y0, y1, y2) - _HALF) // _ONE, height - 1)
    if area == 0 or bx0 > bx1 or by0 > by1:  # covers no pixel centre
        bbox[t, 0], bbox[t, 1], bbox[t, 2], bbox[t, 3] = 0, -1, 0, -1
        return 0
    bbox[t, 0], bbox[t, 1], bbox[t, 2], bbox[t, 3] = bx0, bx1, by0, by1
    delta[by0] += bx1 - bx0 + 1
    delta[by1 + 1] -= bx1 - bx0 + 1
    # Depth plane from the unsnapped positions.
    ax, ay = fx1 - fx0, fy1 - fy0
    bx, by = fx2 - fx0, fy2 - fy0
    az, bz = fz1 - fz0, fz2 - fz0
    det = ax * by - bx * ay
    if det != 0.0:
        zplane[t, 3] = (az * by - bz * ay) / det
        zplane[t, 4] = (ax * bz - bx * az) / det
    if offset_factor != 0.0 or offset_units != 0.0:
        zplane[t, 2] += polygon_offset(zplane[t, 3], zplane[t, 4], fz0, fz1, fz2,
                                       offset_factor, offset_units)
    return bx1 + 1


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


def band_split(row_work: np.ndarray, n_bands: int) -> np.ndarray:
    """Row boundaries (n_bands + 1,) of horizontal bands (window rows, y up) holding about
    equal work (``row_work`` from :func:`setup_triangles`)."""
    height = len(row_work)
    if n_bands <= 1:
        return np.array([0, height], dtype=np.int64)
    total = np.cumsum(row_work)
    cuts = np.searchsorted(total, total[-1] * np.arange(1, n_bands) / n_bands)
    return np.concatenate([[0], cuts, [height]]).astype(np.int64)


@njit(cache=True, nogil=True, inline="always")
def depth_passes(func, z, stored):
    """glDepthFunc comparison ``z OP stored``; codes in DepthFunc order."""
    if func == 1:
        return z < stored
    if func == 3:
        return z <= stored
    if func == 0:
        return False
    if func == 2:
        return z == stored
    if func == 4:
        return z > stored
    if func == 5:
        return z != stored
    if func == 6:
        return z >= stored
    return True


def fill_bands(workers, bands, vert_fixed, edge_bias, bbox, zplane, tri_face, width, height,
               depth_test, depth_func, depth_write, z_lo, z_hi, clear_depth, depth_buf,
               face_buf, count_tested, count_written, want_counts, tie_by_face=False,
               pieces=None):
    """Fill on ``workers``, one call of :func:`fill_band` per band; returns the fragments
    tested, fragments written and (triangle, band) pairs filled, summed over the bands. ``pieces`` = (face_base, clip_at,
    piece_off) for records laid out by face (see :func:`fill_band`); by default record t
    is triangle t of face ``tri_face[t]``."""
    face_base, clip_at, piece_off = pieces if pieces is not None else (0, _NO_CLIP, _NO_PIECES)
    counts = workers.run(fill_band, bands, vert_fixed, edge_bias, bbox, zplane, tri_face,
                         face_base, clip_at, piece_off, width, height, depth_test,
                         depth_func, depth_write, z_lo, z_hi, clear_depth, depth_buf,
                         face_buf, count_tested, count_written, want_counts, tie_by_face)
    return tuple(sum(c[k] for c in counts) for k in range(3))


_NO_CLIP = np.zeros(0, dtype=np.int64)
_NO_PIECES = np.zeros(1, dtype=np.int64)


@njit(cache=True, nogil=True)
def fill_band(b_lo, b_end, vert_fixed, edge_bias, bbox, zplane, tri_face, face_base, clip_at,
              piece_off, width, height, depth_test, depth_func, depth_write, z_lo, z_hi,
              clear_depth, depth_buf, face_buf, count_tested, count_written, want_counts,
              tie_by_face):
    """Fill triangles, in submission order, into ``depth_buf`` / ``face_buf`` (image rows,
    row 0 = top); ``face_buf`` receives the face of the triangle that passes.

    Records: the first ``n_main = len(bbox) - piece_off[-1]`` are one per slot f, of face
    ``tri_face[f]`` (or ``face_base + f`` when ``tri_face`` is empty: records laid out by
    face). Slot ``clip_at[k]`` (ascending) is replaced by the clipped pieces
    ``n_main + piece_off[k] .. n_main + piece_off[k + 1]`` of the same face, so clipped
    faces keep their place in submission order without reordering the records.

    This call fills window rows ``b_lo <= y < b_end`` (y up) only: a thread owns whole
    bands and walks every triangle overlapping them in order, so no two threads touch a
    pixel and the result does not depend on the band layout or the number of threads.
    Unless ``clear_depth`` is NaN the band first clears its rows: ``face_buf`` to -1 and
    ``depth_buf`` to ``clear_depth`` (cleared where it is filled, in parallel).
    ``depth_write`` is the depth mask (ignored when the test is off: OpenGL does not write
    depth then). With ``tie_by_face`` (LESS / LEQUAL only) equal depths are decided by
    face id as submission order would decide them (LESS: the lower id wins, LEQUAL: the
    higher), which makes the result independent of the drawing order (occlusion culling
    draws objects front to back). Returns (fragments tested, fragments written, triangles
    that overlap the band: the band's share of the binning).
    """
    n = bbox.shape[0]
    write_depth = depth_test and depth_write
    do_clear_depth = not np.isnan(clear_depth)
    clear_value = np.float32(clear_depth)
    b_hi = b_end - 1
    if do_clear_depth:
        for j in range(b_lo, b_hi + 1):
            row = height - 1 - j
            for i in range(width):
                face_buf[row, i] = -1
                depth_buf[row, i] = clear_value
    n_tested = 0
    n_written = 0
    n_binned = 0
    n_main = n - piece_off[-1]
    by_face = tri_face.shape[0] == 0
    k = 0
    for f in range(n_main):
        t_lo, t_hi = f, f + 1
        if k < clip_at.shape[0] and clip_at[k] == f:
            t_lo, t_hi = n_main + piece_off[k], n_main + piece_off[k + 1]
            k += 1
        face = face_base + f if by_face else tri_face[f]
        for t in range(t_lo, t_hi):
            y0, y1 = max(np.int64(bbox[t, 2]), b_lo), min(np.int64(bbox[t, 3]), b_hi)
            x0, x1 = np.int64(bbox[t, 0]), np.int64(bbox[t, 1])
            if y0 > y1 or x0 > x1:
                continue
            n_binned += 1
            X0, Y0 = np.int64(vert_fixed[t, 0]), np.int64(vert_fixed[t, 1])
            X1, Y1 = np.int64(vert_fixed[t, 2]), np.int64(vert_fixed[t, 3])
            X2, Y2 = np.int64(vert_fixed[t, 4]), np.int64(vert_fixed[t, 5])
            px = x0 * _ONE + _HALF
            py = y0 * _ONE + _HALF
            # E_k(p) = (Xb - Xa) (py - Ya) - (Yb - Ya) (px - Xa) for edge a -> b; biased so
            # that "inside" is E >= 0 for every edge, and (e0 | e1 | e2) >= 0 tests all three.
            e0_row = (X1 - X0) * (py - Y0) - (Y1 - Y0) * (px - X0) + np.int64(edge_bias[t, 0])
            e1_row = (X2 - X1) * (py - Y1) - (Y2 - Y1) * (px - X1) + np.int64(edge_bias[t, 1])
            e2_row = (X0 - X2) * (py - Y2) - (Y0 - Y2) * (px - X2) + np.int64(edge_bias[t, 2])
            step_x0, step_y0 = -(Y1 - Y0) * _ONE, (X1 - X0) * _ONE
            step_x1, step_y1 = -(Y2 - Y1) * _ONE, (X2 - X1) * _ONE
            step_x2, step_y2 = -(Y0 - Y2) * _ONE, (X0 - X2) * _ONE
            zx0, zy0, zz0 = zplane[t, 0], zplane[t, 1], zplane[t, 2]
            dzdx, dzdy = zplane[t, 3], zplane[t, 4]
            for j in range(y0, y1 + 1):
                e0, e1, e2 = e0_row, e1_row, e2_row
                row = height - 1 - j
                z_row = zz0 + dzdy * (j + 0.5 - zy0)
                for i in range(x0, x1 + 1):
                    if (e0 | e1 | e2) >= 0:
                        z = z_row + dzdx * (i + 0.5 - zx0)
                        z = min(max(z, z_lo), z_hi)
                        zf = np.float32(z)
                        n_tested += 1
                        if want_counts:
                            count_tested[row, i] += 1
                        if depth_func == FIRST_WINS:
                            passed = face_buf[row, i] < 0
                        elif tie_by_face:
                            stored = depth_buf[row, i]
                            passed = zf < stored or (zf == stored and (
                                face < face_buf[row, i] if depth_func == 1 else
                                face > face_buf[row, i]))
                        else:
                            passed = (not depth_test) or depth_passes(depth_func, zf,
                                                                      depth_buf[row, i])
                        if passed:
                            face_buf[row, i] = face
                            if write_depth:
                                depth_buf[row, i] = zf
                            n_written += 1
                            if want_counts:
                                count_written[row, i] += 1
                    e0 += step_x0
                    e1 += step_x1
                    e2 += step_x2
                e0_row += step_y0
                e1_row += step_y1
                e2_row += step_y2
    return n_tested, n_written, n_binned


def rasterize(xy_window, depth_window, tri_face, width, height, state, workers, *,
              depth_test=None, depth_func=None, depth_write=None, counts=False,
              depth_buffer=None):
    """Set up and fill triangles in array order into fresh buffers: the one sequence every
    raster-based algorithm runs. ``depth_test`` / ``depth_func`` (a code, see
    :class:`hsr.state.DepthFunc`, or :data:`FIRST_WINS`) / ``depth_write`` default to
    ``state``'s. With ``depth_buffer`` the draw goes over it (no clear).

    Returns ``(face, depth, bbox, tested, written, count_tested, count_written)``; the
    counts are (H, W) arrays when ``counts`` else None.
    """
    depth_test = state.depth_test if depth_test is None else depth_test
    depth_func = state.depth_func.code if depth_func is None else depth_func
    depth_write = state.depth_mask if depth_write is None else depth_write
    depth, face, clear, count_tested, count_written = fill_targets(
        width, height, state, depth_buffer, counts)
    vert_fixed, edge_bias, bbox, zplane, row_work = setup_triangles(
        np.ascontiguousarray(xy_window), np.ascontiguousarray(depth_window), width, height,
        workers, state.polygon_offset)
    # One band per thread: the split balances estimated work, and every extra band costs
    # a walk over all triangles.
    bands = band_split(row_work, workers.threads)
    z_lo, z_hi = min(state.depth_range), max(state.depth_range)
    tested, written, _ = fill_bands(
        workers, bands, vert_fixed, edge_bias, bbox, zplane, tri_face, width, height,
        depth_test, depth_func, depth_write, z_lo, z_hi, clear, depth, face, count_tested,
        count_written, counts)
    return (face, depth, bbox, tested, written, count_tested if counts else None,
            count_written if counts else None)
