"""The shared triangle fill, compiled with Numba: every raster algorithm (z-buffer,
painter's, Newell, BSP, transparency, the scan-line's coverage) fills through this.

Coverage comes from the set-up records of :mod:`hsr.geometry.setup` (snapped corners,
exact int64 edge functions, top-left rule). Depth: the triangle's plane evaluated at the
pixel centre in float64, clamped to the depth range (and, for a sliver thinner than the
snapping step, to its corners' depths: see :func:`hsr.geometry.setup.setup_one`) and
rounded to float32 (the buffer format), then glDepthFunc / glDepthMask as OpenGL applies
them.

Parallelism: the viewport is cut into horizontal bands of about equal work; bands are
filled in parallel (:mod:`hsr.parallel`), each thread owning whole bands and walking the
triangles in submission order, so there are no races and the result does not depend on the
number of threads. (Square tiles with per-tile triangle lists were measured 2.5x slower on
meshes of small triangles: the binning and per-tile set-up cost more than they save.)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..geometry.setup import HALF, ONE, depth_bounds, setup_triangles

__all__ = ["band_split", "fill_bands", "fill_band", "fill_band_less", "fill_kernel",
           "fill_targets", "depth_passes", "FIRST_WINS", "rasterize"]

# Pseudo depth function for front-to-back filling with a coverage mask: a pixel takes the
# first fragment that reaches it (BSP front-to-back traversal).
FIRST_WINS = 8


def fill_targets(width, height, state, workers, depth_buffer=None, counts=False):
    """The buffers a fill draws into: ``(depth, face, clear, count_tested,
    count_written)``. Fresh buffers (``workers.output``: the frame returns them) are
    cleared by the fill itself (``clear`` = the state's clear depth); over
    ``depth_buffer`` nothing is cleared (``clear`` = NaN) and ``face`` starts at -1. The
    count arrays are (H, W) with ``counts``, else (1, 1)."""
    if depth_buffer is None:
        depth = workers.output((height, width), np.float32)
        face = workers.output((height, width), np.int32)
        clear = state.clear_depth
    else:
        depth, clear = depth_buffer, np.nan
        face = workers.output((height, width), np.int32)
        face.fill(-1)
    shape = (height, width) if counts else (1, 1)
    return (depth, face, clear, np.zeros(shape, dtype=np.int32),
            np.zeros(shape, dtype=np.int32))


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
    """Fill on ``workers``, one call of :func:`fill_band` (or :func:`fill_band_less`, for
    the default state) per band; returns the fragments tested, fragments written and
    (triangle, band) pairs filled, summed over the bands. ``pieces`` = (face_base,
    clip_at, piece_off) for records laid out by face (see :func:`fill_band`); by default
    record t is triangle t of face ``tri_face[t]``."""
    face_base, clip_at, piece_off = pieces if pieces is not None else (0, _NO_CLIP, _NO_PIECES)
    kernel = fill_kernel(depth_test, depth_func, want_counts, tie_by_face)
    counts = workers.run(kernel, bands, vert_fixed, edge_bias, bbox, zplane, tri_face,
                         face_base, clip_at, piece_off, width, height, depth_test,
                         depth_func, depth_write, z_lo, z_hi, clear_depth, depth_buf,
                         face_buf, count_tested, count_written, want_counts, tie_by_face)
    return tuple(sum(c[k] for c in counts) for k in range(3))


def fill_kernel(depth_test, depth_func, want_counts, tie_by_face=False):
    """:func:`fill_band_less` for the default state, else :func:`fill_band`."""
    if depth_test and depth_func == 1 and not want_counts and not tie_by_face:
        return fill_band_less
    return fill_band


# Boxes at least this many pixels wide are filled by row spans (:func:`row_span`).
SPAN_MIN_WIDTH = 8


@njit(cache=True, nogil=True, inline="always")
def _edge_span(e, step, n):
    """(first, last) of the pixels k in [0, n) with ``e + k * step >= 0`` (exact int64
    edge function ``e`` at k = 0 and its step per pixel); first > last when none. The
    quotient is estimated in float64 and corrected exactly in integers."""
    if step == 0:
        return (0, n - 1) if e >= 0 else (0, -1)
    q = -e / step  # e + q * step = 0
    if step > 0:  # inside from the crossing on
        if e >= 0:
            return 0, n - 1
        if q >= n + 1.0:
            return 0, -1
        k = np.int64(math.ceil(q))
        while e + k * step < 0:
            k += 1
        while k > 0 and e + (k - 1) * step >= 0:
            k -= 1
        return k, n - 1
    if e < 0:  # inside up to the crossing
        return 0, -1
    if q >= n + 1.0:
        return 0, n - 1
    k = np.int64(math.floor(q))
    while e + k * step < 0:
        k -= 1
    while e + (k + 1) * step >= 0:
        k += 1
    return 0, min(k, n - 1)


@njit(cache=True, nogil=True, inline="always")
def row_span(e0, s0, e1, s1, e2, s2, n):
    """(first, last) of the pixels k in [0, n) of a row where all three edge functions
    (values e at k = 0, steps s per pixel) are >= 0: exactly the pixels the per-pixel test
    ``(e0 | e1 | e2) >= 0`` accepts, found with a division per edge instead of a test per
    pixel (a row of a triangle is one interval: the edges are linear)."""
    f0, l0 = _edge_span(e0, s0, n)
    f1, l1 = _edge_span(e1, s1, n)
    f2, l2 = _edge_span(e2, s2, n)
    return max(f0, f1, f2), min(l0, l1, l2)


_NO_CLIP = np.zeros(0, dtype=np.int64)
_NO_PIECES = np.zeros(1, dtype=np.int64)


@njit(cache=True, nogil=True, inline="always")
def _walk(b_lo, b_end, vert_fixed, edge_bias, bbox, zplane, tri_face, face_base, clip_at,
          piece_off, width, height, depth_test, depth_func, depth_write, z_lo, z_hi,
          clear_depth, depth_buf, face_buf, count_tested, count_written, want_counts,
          tie_by_face):
    # The body of fill_band, inlined at each of its call sites so that state passed as a
    # constant folds away the per-fragment branches it decides.
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
            px = x0 * ONE + HALF
            py = y0 * ONE + HALF
            # E_k(p) = (Xb - Xa) (py - Ya) - (Yb - Ya) (px - Xa) for edge a -> b; biased so
            # that "inside" is E >= 0 for every edge, and (e0 | e1 | e2) >= 0 tests all three.
            e0_row = (X1 - X0) * (py - Y0) - (Y1 - Y0) * (px - X0) + np.int64(edge_bias[t, 0])
            e1_row = (X2 - X1) * (py - Y1) - (Y2 - Y1) * (px - X1) + np.int64(edge_bias[t, 1])
            e2_row = (X0 - X2) * (py - Y2) - (Y0 - Y2) * (px - X2) + np.int64(edge_bias[t, 2])
            step_x0, step_y0 = -(Y1 - Y0) * ONE, (X1 - X0) * ONE
            step_x1, step_y1 = -(Y2 - Y1) * ONE, (X2 - X1) * ONE
            step_x2, step_y2 = -(Y0 - Y2) * ONE, (X0 - X2) * ONE
            zx0, zy0, zz0 = zplane[t, 0], zplane[t, 1], zplane[t, 2]
            dzdx, dzdy = zplane[t, 3], zplane[t, 4]
            z_min, z_max = depth_bounds(zplane, t, z_lo, z_hi)
            # Wide boxes (long thin triangles) scan only each row's span inside all three
            # edges, where the edge test always passes (its steps are zeroed); narrow ones
            # test every pixel of the box, which is cheaper than the divisions that find
            # a span.
            wide = x1 - x0 >= SPAN_MIN_WIDTH
            scan_x0, scan_x1, scan_x2 = (0, 0, 0) if wide else (step_x0, step_x1, step_x2)
            for j in range(y0, y1 + 1):
                row = height - 1 - j
                z_row = zz0 + dzdy * (j + 0.5 - zy0)
                if wide:
                    first, last = row_span(e0_row, step_x0, e1_row, step_x1, e2_row, step_x2,
                                           x1 - x0 + 1)
                    i_lo, i_hi = x0 + first, x0 + last
                    e0 = e1 = e2 = np.int64(0)
                else:
                    i_lo, i_hi = x0, x1
                    e0, e1, e2 = e0_row, e1_row, e2_row
                for i in range(i_lo, i_hi + 1):
                    if (e0 | e1 | e2) >= 0:
                        z = z_row + dzdx * (i + 0.5 - zx0)
                        z = min(max(z, z_min), z_max)
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
                    e0 += scan_x0
                    e1 += scan_x1
                    e2 += scan_x2
                e0_row += step_y0
                e1_row += step_y1
                e2_row += step_y2
    return n_tested, n_written, n_binned


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
    return _walk(b_lo, b_end, vert_fixed, edge_bias, bbox, zplane, tri_face, face_base,
                 clip_at, piece_off, width, height, depth_test, depth_func, depth_write, z_lo,
                 z_hi, clear_depth, depth_buf, face_buf, count_tested, count_written,
                 want_counts, tie_by_face)


@njit(cache=True, nogil=True)
def fill_band_less(b_lo, b_end, vert_fixed, edge_bias, bbox, zplane, tri_face, face_base,
                   clip_at, piece_off, width, height, depth_test, depth_func, depth_write,
                   z_lo, z_hi, clear_depth, depth_buf, face_buf, count_tested, count_written,
                   want_counts, tie_by_face):
    """:func:`fill_band` for the default state, glDepthFunc(GL_LESS) with the test on and
    no counts (the arguments that say so are ignored): the same walk with that state as
    constants, so the fragment loop holds one depth comparison and no dispatch (15-30%
    faster on meshes of small triangles). A kernel of its own, compiled on first use,
    so a first render compiles one fill, not two."""
    return _walk(b_lo, b_end, vert_fixed, edge_bias, bbox, zplane, tri_face, face_base,
                 clip_at, piece_off, width, height, True, 1, depth_write, z_lo, z_hi,
                 clear_depth, depth_buf, face_buf, count_tested, count_written, False, False)

def rasterize(xy_window, depth_window, tri_face, width, height, state, workers, *,
              depth_test=None, depth_func=None, depth_write=None, counts=False,
              depth_buffer=None):
    """Set up and fill triangles in array order into fresh buffers: the one sequence every
    raster-based algorithm runs. ``depth_test`` / ``depth_func`` (a code, see
    :class:`hsr.geometry.state.DepthFunc`, or :data:`FIRST_WINS`) / ``depth_write`` default to
    ``state``'s. With ``depth_buffer`` the draw goes over it (no clear).

    Returns ``(face, depth, bbox, tested, written, count_tested, count_written)``; the
    counts are (H, W) arrays when ``counts`` else None.
    """
    depth_test = state.depth_test if depth_test is None else depth_test
    depth_func = state.depth_func.code if depth_func is None else depth_func
    depth_write = state.depth_mask if depth_write is None else depth_write
    depth, face, clear, count_tested, count_written = fill_targets(
        width, height, state, workers, depth_buffer, counts)
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
