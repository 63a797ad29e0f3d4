"""Convex polygons in the plane, for the exact visible regions: clipping by a half-plane
(Sutherland & Hodgman 1974, one plane at a time) and the difference of two convex
polygons as disjoint convex pieces (each edge line of the subtracted polygon splits off
the part outside it, the rest goes on to the next edge).

A polygon is ``n`` vertices in the first rows of a (MAX_VERTICES, 2) float64 array, in
either orientation: the functions that need it take it from the polygon itself.
"""

from __future__ import annotations

import math

from numba import njit

MAX_VERTICES = 64  # a triangle cut by every edge of many hiders stays far below this


@njit(cache=True, nogil=True)
def clip_half_plane(src, n, a, b, c, dst) -> int:
    """Write into ``dst`` the part of polygon ``src[:n]`` where ``a x + b y + c >= 0``
    (closed: a vertex on the line is kept, an edge is cut only where the sign strictly
    changes, so no vertex is emitted twice); returns its vertex count, 0 when less than a
    triangle is left. The parts of one polygon on either side of a line share the
    points on it and no area."""
    m = 0
    if n == 0:
        return 0
    px, py = src[n - 1, 0], src[n - 1, 1]
    dp = a * px + b * py + c
    for k in range(n):
        qx, qy = src[k, 0], src[k, 1]
        dq = a * qx + b * qy + c
        if (dp > 0.0 and dq < 0.0) or (dp < 0.0 and dq > 0.0):
            t = dp / (dp - dq)
            m = _emit(dst, m, px + t * (qx - px), py + t * (qy - py))
        if dq >= 0.0:
            m = _emit(dst, m, qx, qy)
        px, py, dp = qx, qy, dq
    if m >= 2 and dst[m - 1, 0] == dst[0, 0] and dst[m - 1, 1] == dst[0, 1]:
        m -= 1
    return m if m >= 3 else 0


@njit(cache=True, nogil=True, inline="always")
def side_of_line(poly, n, a, b, c) -> int:
    """1 when every vertex of ``poly[:n]`` has ``a x + b y + c > 0``, -1 when every one has
    it < 0, else 0: a polygon strictly on one side, which :func:`clip_half_plane` would
    keep whole or drop whole (its arithmetic, so the answers agree)."""
    lo, hi = math.inf, -math.inf
    for k in range(n):
        d = a * poly[k, 0] + b * poly[k, 1] + c
        lo, hi = min(lo, d), max(hi, d)
    return 1 if lo > 0.0 else (-1 if hi < 0.0 else 0)


@njit(cache=True, nogil=True, inline="always")
def _emit(dst, m, x, y) -> int:
    """Append (x, y) unless it repeats the last vertex (or there is no room)."""
    if m >= MAX_VERTICES or (m > 0 and dst[m - 1, 0] == x and dst[m - 1, 1] == y):
        return m
    dst[m, 0] = x
    dst[m, 1] = y
    return m + 1


@njit(cache=True, nogil=True)
def clip_to_view(poly, n, width, height, scratch) -> int:
    """Clip ``poly[:n]`` in place to the view [0, width] x [0, height] (``scratch``: a
    buffer of the same shape); returns the vertex count left."""
    n = clip_half_plane(poly, n, 1.0, 0.0, 0.0, scratch)
    n = clip_half_plane(scratch, n, -1.0, 0.0, width, poly)
    n = clip_half_plane(poly, n, 0.0, 1.0, 0.0, scratch)
    return clip_half_plane(scratch, n, 0.0, -1.0, height, poly)


@njit(cache=True, nogil=True)
def signed_area(poly, n) -> float:
    """Shoelace area of ``poly[:n]`` (positive counter-clockwise in the x-right y-up
    sense)."""
    s = 0.0
    for k in range(n):
        j = k + 1 if k + 1 < n else 0
        s += poly[k, 0] * poly[j, 1] - poly[j, 0] * poly[k, 1]
    return 0.5 * s


@njit(cache=True, nogil=True, inline="always")
def _box(p, n):
    """(min x, min y, max x, max y) of ``p[:n]``."""
    x0 = x1 = p[0, 0]
    y0 = y1 = p[0, 1]
    for k in range(1, n):
        x0, x1 = min(x0, p[k, 0]), max(x1, p[k, 0])
        y0, y1 = min(y0, p[k, 1]), max(y1, p[k, 1])
    return x0, y0, x1, y1


@njit(cache=True, nogil=True)
def bounds_overlap(p, n, q, m) -> bool:
    """True unless the boxes of ``p[:n]`` and ``q[:m]`` are apart."""
    px0, py0, px1, py1 = _box(p, n)
    qx0, qy0, qx1, qy1 = _box(q, m)
    return not (px1 <= qx0 or qx1 <= px0 or py1 <= qy0 or qy1 <= py0)


@njit(cache=True, nogil=True, inline="always")
def _beyond_edge(t, k, u, sign) -> float:
    """How far triangle u reaches inside edge k of triangle t, wound ``sign``: the largest
    of its corners' signed cross products (<= 0 when u lies wholly outside or on the
    edge's line). Without branches: the separating-axis test below takes all six."""
    ax, ay = t[k, 0], t[k, 1]
    k1 = k + 1 if k < 2 else 0
    ex, ey = sign * (t[k1, 0] - ax), sign * (t[k1, 1] - ay)
    return max(ex * (u[0, 1] - ay) - ey * (u[0, 0] - ax),
               ex * (u[1, 1] - ay) - ey * (u[1, 0] - ax),
               ex * (u[2, 1] - ay) - ey * (u[2, 0] - ax))


@njit(cache=True, nogil=True)
def triangles_apart(t, u) -> bool:
    """True when triangles ``t`` and ``u`` (3, 2) overlap in no area: an edge of one has
    the other wholly on its outer side or on its line (separating axes; a shared edge or
    vertex counts as apart). Degenerate triangles are never apart (left to the caller)."""
    st = (t[1, 0] - t[0, 0]) * (t[2, 1] - t[0, 1]) - (t[2, 0] - t[0, 0]) * (t[1, 1] - t[0, 1])
    su = (u[1, 0] - u[0, 0]) * (u[2, 1] - u[0, 1]) - (u[2, 0] - u[0, 0]) * (u[1, 1] - u[0, 1])
    if st == 0.0 or su == 0.0:
        return False
    sign_t = 1.0 if st > 0.0 else -1.0
    sign_u = 1.0 if su > 0.0 else -1.0
    reach = min(_beyond_edge(t, 0, u, sign_t), _beyond_edge(t, 1, u, sign_t),
                _beyond_edge(t, 2, u, sign_t), _beyond_edge(u, 0, t, sign_u),
                _beyond_edge(u, 1, t, sign_u), _beyond_edge(u, 2, t, sign_u))
    return reach <= 0.0


@njit(cache=True, nogil=True)
def edge_lines(poly, n, lines) -> int:
    """``lines[k] = (a, b, c)``, (a, b) a unit vector, with ``a x + b y + c > 0`` outside
    edge k of the convex polygon ``poly[:n]`` (whatever its orientation). First merges
    vertices that rounding left within 1e-12 of the polygon's size of the one before (a
    cut at a corner repeats it): an edge that short has no direction. Returns the number
    of edges, 0 when the polygon is a sliver (under three vertices left, or a vertex
    outside another edge's line by more than 1e-9 of its size: not convex to rounding),
    which then bounds nothing."""
    extent = 0.0
    for k in range(n):
        extent = max(extent, abs(poly[k, 0] - poly[0, 0]), abs(poly[k, 1] - poly[0, 1]))
    if extent == 0.0:
        return 0
    m = 0
    for k in range(n):
        if m > 0 and (abs(poly[k, 0] - poly[m - 1, 0]) <= 1e-12 * extent
                      and abs(poly[k, 1] - poly[m - 1, 1]) <= 1e-12 * extent):
            continue
        poly[m, 0] = poly[k, 0]
        poly[m, 1] = poly[k, 1]
        m += 1
    while m > 1 and (abs(poly[m - 1, 0] - poly[0, 0]) <= 1e-12 * extent
                     and abs(poly[m - 1, 1] - poly[0, 1]) <= 1e-12 * extent):
        m -= 1
    if m < 3:
        return 0
    sign = 1.0 if signed_area(poly, m) > 0.0 else -1.0
    for k in range(m):
        j = k + 1 if k + 1 < m else 0
        ex, ey = poly[j, 0] - poly[k, 0], poly[j, 1] - poly[k, 1]
        length = math.sqrt(ex * ex + ey * ey)
        # Inside a counter-clockwise polygon is left of each edge: outside is (ey, -ex).
        a, b = ey * sign / length, -ex * sign / length
        c = -(a * poly[k, 0] + b * poly[k, 1])
        for v in range(m):
            if a * poly[v, 0] + b * poly[v, 1] + c > 1e-9 * extent:
                return 0
        lines[k, 0] = a
        lines[k, 1] = b
        lines[k, 2] = c
    return m
