"""Intersection lines: the segments where faces pass through each other (one mesh folding
through itself, or parts of a scene that interpenetrate), as world-space edges that the
exact hidden-line engine then hides like any other.

Candidate pairs come from a uniform grid over the faces' boxes (candidates only, never
the answer); each pair is cut exactly (Moller 1997: the two triangles' intervals on the
line where their planes meet, intersected). Faces that share a vertex (welded by
position) are neighbours in a mesh, not an intersection, and coplanar faces overlap in
an area, not a line: both are skipped.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..geometry.weld import weld

_CELL_FACES = 2.0  # about this many faces' boxes per grid cell
_MAX_PAIRS = 50_000_000  # candidate pairs before a scene is refused (memory)


@njit(cache=True, nogil=True, inline="always")
def _interval(p0, p1, p2, d0, d1, d2, direction):
    """The parameter interval (along ``direction``) where a triangle whose vertices are at
    signed distances d0, d1, d2 from the other plane crosses that plane; the lone vertex
    is the one on its own side."""
    if d0 * d1 > 0.0:  # p2 alone
        a, b, c, da, db, dc = p2, p0, p1, d2, d0, d1
    elif d0 * d2 > 0.0:  # p1 alone
        a, b, c, da, db, dc = p1, p0, p2, d1, d0, d2
    elif d1 * d2 > 0.0 or d0 != 0.0:  # p0 alone
        a, b, c, da, db, dc = p0, p1, p2, d0, d1, d2
    elif d1 != 0.0:
        a, b, c, da, db, dc = p1, p0, p2, d1, d0, d2
    else:
        a, b, c, da, db, dc = p2, p0, p1, d2, d0, d1
    # The crossing points on edges a-b and a-c.
    q1 = a + (b - a) * (da / (da - db)) if da != db else a
    q2 = a + (c - a) * (da / (da - dc)) if da != dc else a
    t1 = (q1 * direction).sum()
    t2 = (q2 * direction).sum()
    if t1 <= t2:
        return t1, t2, q1, q2
    return t2, t1, q2, q1


@njit(cache=True, nogil=True)
def _cut_pairs(lo, hi, tris, pairs, eps):
    """Intersection segments of candidate pairs ``lo:hi``: (ends (K, 2, 3), pair (K,))."""
    ends = np.empty((hi - lo, 2, 3))
    which = np.empty(hi - lo, np.int64)
    k = 0
    for r in range(lo, hi):
        i, j = pairs[r, 0], pairs[r, 1]
        a0, a1, a2 = tris[i, 0], tris[i, 1], tris[i, 2]
        b0, b1, b2 = tris[j, 0], tris[j, 1], tris[j, 2]
        na = np.cross(a1 - a0, a2 - a0)
        nb = np.cross(b1 - b0, b2 - b0)
        la = math.sqrt((na * na).sum())
        lb = math.sqrt((nb * nb).sum())
        if la == 0.0 or lb == 0.0:
            continue
        na = na / la
        nb = nb / lb
        # Signed distances of each triangle's corners to the other's plane (tiny ones are
        # on it: a corner touching the other face).
        db0, db1, db2 = ((b0 - a0) * na).sum(), ((b1 - a0) * na).sum(), ((b2 - a0) * na).sum()
        sb = eps[i] + eps[j]
        db0 = 0.0 if abs(db0) <= sb else db0
        db1 = 0.0 if abs(db1) <= sb else db1
        db2 = 0.0 if abs(db2) <= sb else db2
        if (db0 > 0 and db1 > 0 and db2 > 0) or (db0 < 0 and db1 < 0 and db2 < 0):
            continue
        da0, da1, da2 = ((a0 - b0) * nb).sum(), ((a1 - b0) * nb).sum(), ((a2 - b0) * nb).sum()
        da0 = 0.0 if abs(da0) <= sb else da0
        da1 = 0.0 if abs(da1) <= sb else da1
        da2 = 0.0 if abs(da2) <= sb else da2
        if (da0 > 0 and da1 > 0 and da2 > 0) or (da0 < 0 and da1 < 0 and da2 < 0):
            continue
        if da0 == 0.0 and da1 == 0.0 and da2 == 0.0:
            continue  # coplanar: an area, not a line
        direction = np.cross(na, nb)
        length = math.sqrt((direction * direction).sum())
        if length < 1e-12:
            continue
        direction = direction / length
        s0, s1, pa0, pa1 = _interval(a0, a1, a2, da0, da1, da2, direction)
        t0, t1, pb0, pb1 = _interval(b0, b1, b2, db0, db1, db2, direction)
        start = max(s0, t0)
        stop = min(s1, t1)
        if stop - start <= 0.0:
            continue
        p = pa0 if s0 >= t0 else pb0
        q = pa1 if s1 <= t1 else pb1
        ends[k, 0] = p
        ends[k, 1] = q
        which[k] = r
        k += 1
    return ends[:k].copy(), which[:k].copy()


def _candidate_pairs(tris: np.ndarray, vertex_key: np.ndarray) -> np.ndarray:
    """(P, 2) pairs i < j of faces whose boxes share a grid cell, sharing no vertex."""
    lo, hi = tris.min(axis=1), tris.max(axis=1)
    extent = float(np.max(hi.max(axis=0) - lo.min(axis=0)))
    if extent == 0.0 or len(tris) < 2:
        return np.zeros((0, 2), np.int64)
    mean_size = float(np.mean(hi - lo)) or extent
    cell = max(mean_size * _CELL_FACES ** (1 / 3), extent * 1e-6)
    origin = lo.min(axis=0)
    c0 = np.floor((lo - origin) / cell).astype(np.int64)
    c1 = np.floor((hi - origin) / cell).astype(np.int64)
    span = c1 - c0 + 1
    count = span.prod(axis=1)
    if count.sum() > _MAX_PAIRS:
        from ..errors import RenderError

        raise RenderError(f"intersection lines: {count.sum():,} grid entries; the scene's "
                          f"faces are too uneven in size for the grid")
    face = np.repeat(np.arange(len(tris)), count)
    k = np.arange(len(face)) - np.repeat(np.cumsum(count) - count, count)
    sx, sy = span[face, 0], span[face, 1]
    cx = c0[face, 0] + k % sx
    cy = c0[face, 1] + (k // sx) % sy
    cz = c0[face, 2] + k // (sx * sy)
    dims = c1.max(axis=0) + 1
    cells = (cz * dims[1] + cy) * dims[0] + cx
    order = np.lexsort((face, cells))
    cells, face = cells[order], face[order]
    starts = np.flatnonzero(np.r_[True, cells[1:] != cells[:-1], True])
    sizes = np.diff(starts)
    found: list = []
    for n in np.unique(sizes[sizes > 1]):
        groups = starts[:-1][sizes == n]
        members = face[groups[:, None] + np.arange(n)]  # (G, n)
        a, b = np.triu_indices(n, 1)
        found.append(np.stack([members[:, a].ravel(), members[:, b].ravel()], axis=1))
        if sum(len(p) for p in found) > _MAX_PAIRS:
            from ..errors import RenderError

            raise RenderError("intersection lines: too many candidate face pairs")
    if not found:
        return np.zeros((0, 2), np.int64)
    pairs = np.unique(np.sort(np.concatenate(found), axis=1), axis=0)
    # Faces sharing a corner (by position) are mesh neighbours.
    keys = vertex_key
    shared = np.zeros(len(pairs), bool)
    for u in range(3):
        for v in range(3):
            shared |= keys[pairs[:, 0], u] == keys[pairs[:, 1], v]
    return pairs[~shared]


def intersection_edges(tris: np.ndarray, workers=None) -> tuple:
    """The segments where the world-space triangles ``tris`` (F, 3, 3) cross each other:
    ``(ends (K, 2, 3), faces (K, 2))``, each segment with the two faces it lies on."""
    from ..parallel import Workers

    tris = np.ascontiguousarray(tris, dtype=np.float64)
    pairs = _candidate_pairs(tris, weld(tris.reshape(-1, 3))[1].reshape(-1, 3))
    if not len(pairs):
        return np.zeros((0, 2, 3)), np.zeros((0, 2), np.int64)
    size = np.abs(tris).max(axis=(1, 2))
    eps = 1e-12 * np.maximum(size, 1.0)  # a corner this close to a plane is on it
    parts = (workers or Workers()).run_range(_cut_pairs, len(pairs), tris, pairs, eps,
                                             min_chunk=4096)
    ends = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 2, 3))
    which = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0, np.int64)
    return ends, pairs[which]
