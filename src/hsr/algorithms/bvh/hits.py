"""What both walks share about rays and hits: the queries (:data:`NEAREST`, :data:`ANY`,
:data:`COUNT`), the checks of a ray (:func:`check_rays`, :func:`plausible_ray`), the
record of a hit (:func:`hit_record`) and the prefetch of a leaf (:func:`fetch_box`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import prefetch
from .layout import NODE_WORDS
from .triangle import face_normal

__all__ = ["NEAREST", "ANY", "COUNT", "LARGEST", "hit_record", "check_rays", "plausible_ray",
           "fetch_box", "surface_area"]

NEAREST, ANY, COUNT = 0, 1, 2

# A walk's bound starts at t_max made finite, so that a missed box (entered at +inf)
# always fails the test against it.
LARGEST = 1.7976931348623157e308


@njit(cache=True, nogil=True, inline="always")
def hit_record(tris, k, f, face_offsets, out_object, out_normal, i):
    """The object and the unit normal (as wound) of the hit in slot ``k`` (face ``f``),
    or -1 and 0 for a miss (k < 0)."""
    if k < 0:
        out_object[i] = -1
        out_normal[i, 0] = out_normal[i, 1] = out_normal[i, 2] = 0.0
        return
    # The instance: the last offset at or below f (binary search).
    a, b = 0, face_offsets.shape[0] - 1
    while b - a > 1:
        m = (a + b) // 2
        if face_offsets[m] <= f:
            a = m
        else:
            b = m
    out_object[i] = a
    nx, ny, nz = face_normal(tris, k)
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    out_normal[i, 0], out_normal[i, 1], out_normal[i, 2] = nx / norm, ny / norm, nz / norm


@njit(cache=True, nogil=True)
def check_rays(lo, hi, origins, directions, t_min, t_max):
    """(problem, ray) of the first bad ray of ``lo .. hi - 1``, (0, -1) when all are
    good (``t_min`` / ``t_max`` per ray, or length 1 for all). Problems: 1 an origin
    not finite, 2 a direction not finite, 3 a zero direction, 4 t_min NaN or infinite,
    5 t_max NaN, 6 t_min < 0, 7 t_min > t_max. A test with a branch per check (10 ms a
    million rays): the walks call it only for rays :func:`plausible_ray` flags."""
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
    s = (origins[i, 0] + origins[i, 1] + origins[i, 2] + directions[i, 0]
         + directions[i, 1] + directions[i, 2])
    zero = (directions[i, 0] == 0.0) & (directions[i, 1] == 0.0) & (directions[i, 2] == 0.0)
    t0 = t_min[i if per_ray[0] else 0]
    t1 = t_max[i if per_ray[1] else 0]
    return not (((s - s) != 0.0) | zero | ((t0 - t0) != 0.0) | (t0 < 0.0) | (t1 != t1)
                | (t0 > t1))


@njit(cache=True, nogil=True, inline="always")
def fetch_box(node_box, tris, leaf_face, ref, n, faces):
    """Prefetch the memory of the walk's box (ref, n): a wide node's 256-byte record
    (n == 0), or a leaf's n triangles' corners from slot ref, and their face ids if
    ``faces`` (the nearest hit's walk reads the id of each hit it finds)."""
    if n == 0:
        for offset in range(0, 4 * NODE_WORDS, 64):
            prefetch(node_box, ref, offset)
    else:
        for offset in range(0, n * 9 * tris.itemsize, 64):
            prefetch(tris, ref, offset)
        if faces:
            # Fetched with the corners: read after them it missed on its own.
            # (Measurements: docs/history.md, "Ray core".)
            prefetch(leaf_face, ref, 0)


@njit(cache=True, nogil=True)
def surface_area(tris, samples) -> float:
    """The summed area of the triangles ``tris`` ((F, 3, 3) corners, float32 or
    float64), estimated from about ``samples`` of them evenly spread over the array
    (all of them when there are no more): their mean area times F."""
    n = tris.shape[0]
    step = max(1, n // max(1, samples))
    total, counted = 0.0, 0
    for k in range(0, n, step):
        cx, cy, cz = face_normal(tris, k)  # (B - A) x (C - A), twice the area
        total += 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)
        counted += 1
    return total * n / counted if counted else 0.0
