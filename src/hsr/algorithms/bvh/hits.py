"""What both walks share about rays and hits: the queries (:data:`NEAREST`, :data:`ANY`,
:data:`COUNT`, :data:`ALL`, :data:`FIRST`) and their hit rules, written once here for both walks
(:func:`in_interval`, :func:`nearer`, :func:`counted`, :func:`listed`), the checks of a
ray (:func:`check_rays`, :func:`plausible_ray`), the record of a hit (:func:`hit_record`,
:func:`list_records`) and the prefetch of a leaf (:func:`fetch_box`).

A query's walk is the same for all of them; what a hit does is the rule's. NEAREST keeps
the hit :func:`nearer` than the best so far, ANY stops at the first hit in the interval,
COUNT adds the hits :func:`counted` (each crossing of the surface once), ALL lists those
same hits (:func:`listed`) into a list as long as the ray's count (so its walk ends when
the list is full), FIRST the nearest of them into a shorter list."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import prefetch
from .layout import NODE_WORDS, ROW_VALUES, nowrap, slot_row
from .triangle import face_normal, owns

__all__ = ["NEAREST", "ANY", "COUNT", "ALL", "FIRST", "LARGEST", "RECORD_AHEAD",
           "in_interval", "nearer", "counted", "listed", "finish_list", "sort_listed", "hit_record",
           "list_records", "check_rays", "plausible_ray", "fetch_slot", "fetch_box",
           "surface_area"]

# The queries. ALL's and FIRST's walk is COUNT's (every box within the interval, in any
# order); ALL's stops when its list is full, FIRST's keeps the nearest that fit.
NEAREST, ANY, COUNT, ALL, FIRST = 0, 1, 2, 3, 4

# How many hits ahead a pass over hits fetches a hit's corners: far enough for a
# miss to memory to be over when the pass gets there.
# (Measurements: docs/history.md, "Ray core".)
RECORD_AHEAD = 64

# A list this short is sorted in place by insertion; a longer one by np.argsort.
SHORT_LIST = 16

# A walk's bound starts at t_max made finite, so that a missed box (entered at +inf)
# always fails the test against it.
LARGEST = 1.7976931348623157e308


@njit(cache=True, nogil=True, inline="always")
def in_interval(t, t0, t1):
    """Every query's first rule: a hit counts only with ``t`` in ``[t0, t1]`` (a miss,
    t = -1, never does). Bitwise, one branch fewer."""
    return (t0 <= t) & (t <= t1)


@njit(cache=True, nogil=True, inline="always")
def nearer(t, f, best_t, best_f):
    """NEAREST's rule: hit (t, face f) goes before (best_t, best_f); equal distances to
    the lower face id, so the answer does not depend on the walk's order."""
    return t < best_t or (t == best_t and f < best_f)


@njit(cache=True, nogil=True, inline="always")
def counted(u, v, w, tris, k, okx, oky, okz, kx, ky, kz, sx, sy):
    """COUNT's, ALL's and FIRST's rule: a hit inside triangle slot ``k`` (barycentrics u, v, w all
    non-zero) counts; one on an edge or a vertex counts for the one triangle there that
    :func:`hsr.algorithms.bvh.triangle.owns` it, so a crossing is counted once."""
    return (u != 0.0 and v != 0.0 and w != 0.0) or owns(tris, k, okx, oky, okz, kx, ky,
                                                        kz, sx, sy)


@njit(cache=True, nogil=True, inline="always")
def _move(hit_t, hit_face, hit_uv, hit_slot, to, frm):
    hit_t[to], hit_face[to], hit_slot[to] = hit_t[frm], hit_face[frm], hit_slot[frm]
    hit_uv[to, 0], hit_uv[to, 1] = hit_uv[frm, 0], hit_uv[frm, 1]


@njit(cache=True, nogil=True, inline="always")
def _insert(t, f, u, v, k, start, j, hit_t, hit_face, hit_uv, hit_slot):
    """Put hit (t, f, u, v, k) into the sorted run ``start .. j - 1`` in its place, the
    hits after it moved one up (into ``j`` at the end, whatever was there)."""
    while j > start and nearer(t, f, hit_t[j - 1], hit_face[j - 1]):
        _move(hit_t, hit_face, hit_uv, hit_slot, j, j - 1)
        j -= 1
    hit_t[j], hit_face[j], hit_slot[j] = t, f, k
    hit_uv[j, 0], hit_uv[j, 1] = u, v


@njit(cache=True, nogil=True)
def sort_listed(start, n, hit_t, hit_face, hit_uv, hit_slot):
    """Sort a ray's list ``start .. start + n - 1`` nearest first, equal distances by face
    id (:func:`nearer`): by insertion up to :data:`SHORT_LIST` hits, else by a stable
    argsort of the distances whose runs of equal ones are then put in face order."""
    if n <= SHORT_LIST:
        for a in range(start + 1, start + n):
            _insert(hit_t[a], hit_face[a], hit_uv[a, 0], hit_uv[a, 1], hit_slot[a], start, a,
                    hit_t, hit_face, hit_uv, hit_slot)
        return
    order = start + np.argsort(hit_t[start:start + n], kind="mergesort")
    # Runs of equal distances (stable: in list order) by face id, by insertion.
    a = 0
    while a < n:
        b = a + 1
        while b < n and hit_t[order[b]] == hit_t[order[a]]:
            b += 1
        for c in range(a + 1, b):
            o = order[c]
            d = c
            while d > a and hit_face[o] < hit_face[order[d - 1]]:
                order[d] = order[d - 1]
                d -= 1
            order[d] = o
        a = b
    # (Indexing by an array makes a new one: the run is read whole before it is written.)
    hit_t[start:start + n], hit_face[start:start + n] = hit_t[order], hit_face[order]
    hit_uv[start:start + n], hit_slot[start:start + n] = hit_uv[order], hit_slot[order]


@njit(cache=True, nogil=True)
def listed(mode, t, f, u, v, k, i, lists, filled, bound, hit_t, hit_face, hit_uv, hit_slot):
    """ALL's and FIRST's rule, for a hit that :func:`counted` (t, face f, weights u and v
    of corners 1 and 2, slot k) on ray ``i``, whose list is ``lists[i] .. lists[i + 1] -
    1`` with ``filled`` hits so far and whose walk is bounded by ``bound``. Returns the
    new ``(filled, bound)``; a bound of -1 ends the ray's walk.

    Until the list is full a hit goes at its end (sorted once the walk ends,
    :func:`finish_list`). ALL's list is as long as the ray's count, so once it is full
    every hit is in it and the walk ends. FIRST's ray may have more hits than its list
    holds (``max_hits``) and keeps the nearest: when the list first overflows it is
    sorted and ``filled`` becomes ``cap + 1`` (full and sorted); from then on a hit nearer
    than the last takes its place in order, and the last kept distance bounds the walk
    (no farther hit can be kept)."""
    start = lists[i]
    cap = lists[i + 1] - start
    if filled < cap:
        j = start + filled
        hit_t[j], hit_face[j], hit_slot[j] = t, f, k
        hit_uv[j, 0], hit_uv[j, 1] = u, v
        filled += 1
        if mode == ALL and filled == cap:
            return filled, -1.0
        return filled, bound
    if cap == 0:
        return filled, bound
    if filled == cap:
        sort_listed(start, cap, hit_t, hit_face, hit_uv, hit_slot)
        filled = cap + 1
    last = start + cap - 1
    if nearer(t, f, hit_t[last], hit_face[last]):  # the last is dropped
        _insert(t, f, u, v, k, start, last, hit_t, hit_face, hit_uv, hit_slot)
    return filled, hit_t[last]


@njit(cache=True, nogil=True, inline="always")
def finish_list(i, lists, filled, hit_t, hit_face, hit_uv, hit_slot):
    """Ray ``i``'s list, its walk over, nearest first: sorted here unless FIRST already
    keeps it so (``filled`` past its length) or it holds one hit or none."""
    if 1 < filled <= lists[i + 1] - lists[i]:
        sort_listed(lists[i], filled, hit_t, hit_face, hit_uv, hit_slot)


@njit(cache=True, nogil=True)
def list_records(first, last, tris, face_offsets, hit_face, hit_object, hit_normal):
    """The objects and normals of listed hits ``first .. last - 1`` (their slots in
    ``hit_object`` until now), as the nearest hits get theirs (:func:`hit_record`), the
    corners of the hit :data:`RECORD_AHEAD` on fetched meanwhile."""
    for j in range(first, last):
        if j + RECORD_AHEAD < last:
            fetch_slot(tris, hit_object[j + RECORD_AHEAD])
        hit_record(tris, hit_object[j], hit_face[j], face_offsets, hit_object, hit_normal, j)


@njit(cache=True, nogil=True, inline="always")
def hit_record(tris, k, f, face_offsets, out_object, out_normal, i):
    """The object and the unit normal (as wound) of the hit in slot ``k`` (face ``f``),
    or -1 and 0 for a miss (k < 0)."""
    at = nowrap(i)  # (no negative-index wraparound)
    if k < 0:
        out_object[at] = -1
        out_normal[at, 0] = out_normal[at, 1] = out_normal[at, 2] = 0.0
        return
    # The instance: the last offset at or below f (binary search).
    a, b = 0, face_offsets.shape[0] - 1
    while b - a > 1:
        m = (a + b) // 2
        if face_offsets[nowrap(m)] <= f:
            a = m
        else:
            b = m
    out_object[at] = a
    nx, ny, nz = face_normal(tris, k)
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    out_normal[at, 0], out_normal[at, 1], out_normal[at, 2] = nx / norm, ny / norm, nz / norm


@njit(cache=True, nogil=True)
def check_rays(lo, hi, origins, directions, t_min, t_max):
    """(problem, ray) of the first bad ray of ``lo .. hi - 1``, (0, -1) when all are
    good (``t_min`` / ``t_max`` per ray, or length 1 for all). Problems: 1 an origin
    not finite, 2 a direction not finite, 3 a zero direction, 4 t_min NaN or infinite,
    5 t_max NaN, 6 t_min < 0, 7 t_min > t_max. A test with a branch per check, so the
    walks call it only for rays :func:`plausible_ray` flags (measurements:
    docs/history.md, "Ray core")."""
    per_ray = t_min.shape[0] > 1, t_max.shape[0] > 1
    for i in range(lo, hi):
        for a in range(3):
            if not np.isfinite(origins[i, a]):
                return 1, i
            if not np.isfinite(directions[i, a]):
                return 2, i
        if directions[i, 0] == 0.0 and directions[i, 1] == 0.0 and directions[i, 2] == 0.0:
            return 3, i
        t0 = t_min[i if per_ray[0] else 0]
        t1 = t_max[i if per_ray[1] else 0]
        if not np.isfinite(t0):
            return 4, i
        if t1 != t1:
            return 5, i
        if t0 < 0.0:
            return 6, i
        if t0 > t1:
            return 7, i
    return 0, -1


@njit(cache=True, nogil=True, inline="always")
def plausible_ray(origins, directions, t_min, t_max, i, per_ray):
    """Whether ray ``i`` cannot be bad, without branches: a sum of the six coordinates
    is NaN or infinite when one of them is (x - x is then NaN); a sum that overflows is
    a false alarm, which :func:`check_rays`' exact tests then clear."""
    at = nowrap(i)  # (no negative-index wraparound)
    s = (origins[at, 0] + origins[at, 1] + origins[at, 2] + directions[at, 0]
         + directions[at, 1] + directions[at, 2])
    zero = (directions[at, 0] == 0.0) & (directions[at, 1] == 0.0) & (directions[at, 2] == 0.0)
    t0 = t_min[nowrap(i if per_ray[0] else 0)]
    t1 = t_max[nowrap(i if per_ray[1] else 0)]
    return not (((s - s) != 0.0) | zero | ((t0 - t0) != 0.0) | (t0 < 0.0) | (t1 != t1)
                | (t0 > t1))


@njit(cache=True, nogil=True, inline="always")
def fetch_slot(tris, k):
    """Prefetch the corners of slot ``k``: every line of its row, or of its block (in
    blocks a slot's nine values are spread across the block)."""
    row = slot_row(tris, k)
    prefetch(tris, row, 0)
    for offset in range(64, tris.strides[0], 64):
        prefetch(tris, row, offset)
    prefetch(tris, row, tris.strides[0] - 1)


@njit(cache=True, nogil=True, inline="always")
def fetch_box(node_box, tris, leaf_face, ref, n, faces):
    """Prefetch the memory of the walk's box (ref, n): a wide node's 256-byte record
    (n == 0), or a leaf's n triangles' corners from slot ref, and their face ids if
    ``faces`` (the nearest hit's walk reads the id of each hit it finds)."""
    if n == 0:
        for offset in range(0, 4 * NODE_WORDS, 64):
            prefetch(node_box, ref, offset)
    else:  # the rows or blocks of slots ref .. ref + n - 1
        row = slot_row(tris, ref)
        for offset in range(0, (slot_row(tris, ref + n - 1) + 1 - row) * tris.strides[0],
                            64):
            prefetch(tris, row, offset)
        if faces:
            # Fetched with the corners: read after them it missed on its own.
            # (Measurements: docs/history.md, "Ray core".)
            prefetch(leaf_face, ref, 0)


def surface_area(tris, samples, n=None) -> float:
    """The summed area of the triangles ``tris``: (F, 3, 3) corners, or the first ``n``
    slots of the walks' corners (rows or blocks, :mod:`hsr.algorithms.bvh.layout`);
    float32 or float64. Estimated from about ``samples`` of them evenly spread over the
    slots (all of them when there are no more): their mean area times the slots."""
    if tris.ndim == 3:
        tris, n = np.ascontiguousarray(tris).reshape(len(tris), ROW_VALUES), len(tris)
    return _surface_area(tris, samples, len(tris) if n is None else n)


@njit(cache=True, nogil=True)
def _surface_area(tris, samples, n):
    step = max(1, n // max(1, samples))
    total, counted = 0.0, 0
    for k in range(0, n, step):
        cx, cy, cz = face_normal(tris, k)  # (B - A) x (C - A), twice the area
        total += 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)
        counted += 1
    return total * n / counted if counted else 0.0
