"""Convex pieces of one polygon merged back into rings: where two pieces share an edge
(the same two vertices, walked in opposite directions), the edge is inside the union and
goes; the edges left are chained into closed rings (outer boundaries and holes, as a
nonzero-winding fill draws them). Vertices are compared on a grid of 2^-20 px (cuts of two
triangles of one polygon by the same line meet their shared edge at points computed from
either side, equal only to rounding); zero-length edges are dropped. Where the edges do
not chain (a vertex of one piece in the middle of another's edge), the group is kept as
its pieces.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _next_in_piece(piece_start, p0, p1, e0, nxt):
    """Into ``nxt``: for each vertex of pieces p0..p1 (numbered from e0), the index of the
    next one."""
    for p in range(p0, p1):
        a, b = piece_start[p], piece_start[p + 1]
        for i in range(a, b):
            nxt[i - e0] = (i + 1 if i + 1 < b else a) - e0


SNAP = 2.0 ** 20  # grid steps per pixel for matching vertices


def pieces_in_order(vertices, piece_start, order) -> tuple:
    """The pieces' (or rings') vertices reordered as ``order`` lists them (some or all of
    them), and their starts."""
    size = np.diff(piece_start)[order]
    start = np.r_[0, np.cumsum(size)].astype(np.int64)
    src = np.repeat(piece_start[:-1][order] - start[:-1], size) + np.arange(start[-1])
    return np.ascontiguousarray(vertices[src]), start


def merge_pieces(vertices, piece_start, group_start):
    """Rings of each group of pieces (group g: pieces group_start[g] .. group_start[g + 1]):
    ``(ring_vertices (V', 2), ring_start (R + 1,), group_ring_start (G + 1,))``."""
    return _merge(np.ascontiguousarray(vertices, dtype=np.float64),
                  np.round(vertices * SNAP).astype(np.int64),
                  np.asarray(piece_start, np.int64), np.asarray(group_start, np.int64))


@njit(cache=True, nogil=True)
def _group_edges(key, piece_start, p0, p1, nxt, e0, out, ts, idx):
    """Into ``out``: the directed edges (start x, y, end x, y on the snap grid) of the
    group's pieces, each split at every group vertex lying inside it (T-junctions),
    zero-length ones dropped; returns their count. ``ts``, ``idx``: scratch."""
    n_e = piece_start[p1] - e0
    m = 0
    for i in range(n_e):
        ax, ay = key[e0 + i, 0], key[e0 + i, 1]
        bx, by = key[e0 + nxt[i], 0], key[e0 + nxt[i], 1]
        dx, dy = float(bx - ax), float(by - ay)
        length2 = dx * dx + dy * dy
        if length2 == 0.0:
            continue
        k = 0
        for j in range(n_e):
            vx, vy = float(key[e0 + j, 0] - ax), float(key[e0 + j, 1] - ay)
            t = (vx * dx + vy * dy) / length2
            if t <= 0.0 or t >= 1.0:
                continue
            cross = vx * dy - vy * dx
            if cross * cross > 4.0 * length2:  # more than 2 grid steps off the line
                continue
            ts[k], idx[k] = t, j
            k += 1
        # Along the edge (insertion sort, stable as argsort's: a handful of points).
        for r in range(1, k):
            t, j = ts[r], idx[r]
            q = r
            while q > 0 and ts[q - 1] > t:
                ts[q], idx[q] = ts[q - 1], idx[q - 1]
                q -= 1
            ts[q], idx[q] = t, j
        cx, cy = ax, ay
        for r in range(k):
            j = idx[r]
            vx, vy = key[e0 + j, 0], key[e0 + j, 1]
            if vx != cx or vy != cy:
                out[m, 0], out[m, 1], out[m, 2], out[m, 3] = cx, cy, vx, vy
                m += 1
                cx, cy = vx, vy
        if bx != cx or by != cy:
            out[m, 0], out[m, 1], out[m, 2], out[m, 3] = cx, cy, bx, by
            m += 1
    return m


@njit(cache=True, nogil=True)
def _merge(vertices, key, piece_start, group_start):
    n_groups = group_start.shape[0] - 1
    cap = 2 * vertices.shape[0] + 16
    out = np.empty((cap, 2))
    ring_start = np.empty(cap + 1, dtype=np.int64)
    group_ring = np.empty(n_groups + 1, dtype=np.int64)
    nv, nr = 0, 0
    ring_start[0] = 0
    # Scratch for the largest group, allocated once (a figure has thousands of groups).
    most = 1
    for g in range(n_groups):
        most = max(most, piece_start[group_start[g + 1]] - piece_start[group_start[g]])
    nxt = np.empty(most, dtype=np.int64)
    edges = np.empty((4 * most * most + 1, 4), dtype=np.int64)
    used = np.empty(4 * most * most + 1, dtype=np.bool_)
    ts = np.empty(most)
    idx = np.empty(most, dtype=np.int64)
    keep = np.empty(4 * most * most + 1, dtype=np.bool_)
    for g in range(n_groups):
        group_ring[g] = nr
        p0, p1 = group_start[g], group_start[g + 1]
        e0 = piece_start[p0]
        ok = p1 - p0 > 1
        nv0, nr0 = nv, nr
        if ok:
            _next_in_piece(piece_start, p0, p1, e0, nxt)
            n_m = _group_edges(key, piece_start, p0, p1, nxt, e0, edges, ts, idx)
            used[:n_m] = False
            for i in range(n_m):
                if used[i]:
                    continue
                for j in range(i + 1, n_m):
                    if (not used[j] and edges[j, 0] == edges[i, 2] and edges[j, 1] == edges[i, 3]
                            and edges[j, 2] == edges[i, 0] and edges[j, 3] == edges[i, 1]):
                        used[i] = True
                        used[j] = True
                        break
            if n_m > cap - nv:
                ok = False
            for i in range(n_m):
                if not ok:
                    break
                if used[i]:
                    continue
                first = nv
                cur = i
                while True:
                    used[cur] = True
                    out[nv, 0], out[nv, 1] = edges[cur, 0] / SNAP, edges[cur, 1] / SNAP
                    nv += 1
                    if edges[cur, 2] == edges[i, 0] and edges[cur, 3] == edges[i, 1]:
                        break
                    found = -1
                    for j in range(n_m):
                        if (not used[j] and edges[j, 0] == edges[cur, 2]
                                and edges[j, 1] == edges[cur, 3]):
                            found = j
                            break
                    if found < 0:
                        ok = False
                        break
                    cur = found
                if not ok:
                    break
                nv = first + _drop_collinear(out, first, nv, keep)
                nr += 1
                ring_start[nr] = nv
        if not ok:  # one piece, or edges that do not chain: the pieces as they are
            nv, nr = nv0, nr0
            for p in range(p0, p1):
                for i in range(piece_start[p], piece_start[p + 1]):
                    out[nv, 0], out[nv, 1] = vertices[i, 0], vertices[i, 1]
                    nv += 1
                nr += 1
                ring_start[nr] = nv
    group_ring[n_groups] = nr
    return out[:nv].copy(), ring_start[:nr + 1].copy(), group_ring


@njit(cache=True, nogil=True)
def _drop_collinear(out, first, end, keep):
    """Remove ring vertices out[first:end] on the line through their neighbours (twice
    the triangle's area under 1e-9 px^2); returns the ring's new length. ``keep``:
    scratch."""
    n = end - first
    for i in range(n):
        px, py = out[first + (i - 1) % n, 0], out[first + (i - 1) % n, 1]
        cx, cy = out[first + i, 0], out[first + i, 1]
        qx, qy = out[first + (i + 1) % n, 0], out[first + (i + 1) % n, 1]
        keep[i] = abs((cx - px) * (qy - py) - (cy - py) * (qx - px)) > 1e-9
    if keep[:n].sum() < 3:
        return n
    k = 0
    for i in range(n):
        if keep[i]:
            out[first + k, 0], out[first + k, 1] = out[first + i, 0], out[first + i, 1]
            k += 1
    return k
