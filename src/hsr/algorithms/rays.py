"""Arbitrary rays against a scene's BVH (:mod:`hsr.algorithms.bvh`): the nearest hit, any
hit, or every hit, for rays ``origin + t * direction`` with ``t`` in ``[t_min, t_max]``
(units of the direction's length, as Embree and Open3D count them).

The triangle test is the ray caster's watertight one (Woop, Benthin & Wald 2013): an edge
shared by two triangles gives exactly opposite edge values in both, so no ray slips
through a closed mesh. A ray exactly on a shared edge or vertex meets every triangle
there; the nearest-hit and any-hit queries keep that (a hit is a hit), but counting must
see the surface once, so :func:`_owns` breaks the tie as a rasterizer's top-left rule
does: on a zero edge value, the triangle owns the point only when that edge, in the
ray's own 2-D frame and with the triangle's winding made counter-clockwise there, points
one way (up, or right when level). The neighbour across the edge walks it the other way,
so exactly one of the two owns it; at a vertex, exactly one triangle of a fan around it.
A ray that grazes a silhouette edge meets two triangles of opposite facing, which then
walk the edge the same way: both or neither count, and parity is kept.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .bvh import LANES, _intersect, careful_entries4, descend, next_box, ray_frame, sheared_corners
from .simd import box_entries4

__all__ = ["trace_range", "check_rays", "NEAREST", "ANY", "COUNT"]

NEAREST, ANY, COUNT = 0, 1, 2


@njit(cache=True, nogil=True, inline="always")
def _edge_owned(px, py, qx, qy, flip):
    """Whether the triangle owns the points on its edge P -> Q: walked counter-clockwise
    in the ray's 2-D frame (Q -> P when ``flip``, the triangle being wound the other way
    there), the edge goes up, or right when level."""
    if flip:
        px, py, qx, qy = qx, qy, px, py
    return qy > py or (qy == py and qx > px)


@njit(cache=True, nogil=True)
def _owns(tris, f, okx, oky, okz, kx, ky, kz, sx, sy):
    """With one or two zero edge values (the ray through an edge or a vertex of
    triangle ``f``): whether ``f`` counts the hit (see the module notes). The corners
    are :func:`hsr.algorithms.bvh.sheared_corners`, as the hit test saw them, so the
    zero tests see the same numbers."""
    ax, ay, _, bx, by, _, cx, cy, _ = sheared_corners(tris, f, okx, oky, okz, kx, ky, kz,
                                                      sx, sy)
    u = cx * by - cy * bx  # edge B -> C
    v = ax * cy - ay * cx  # edge C -> A
    w = bx * ay - by * ax  # edge A -> B
    flip = u + v + w < 0.0
    return not ((u == 0.0 and not _edge_owned(bx, by, cx, cy, flip))
                or (v == 0.0 and not _edge_owned(cx, cy, ax, ay, flip))
                or (w == 0.0 and not _edge_owned(ax, ay, bx, by, flip)))


@njit(cache=True, nogil=True)
def trace_range(lo, hi, origins, directions, t_min, t_max, mode, tris, leaf_face, node_box,
                node_link, root_ref, root_count, wide_depth, face_offsets, out_t, out_face,
                out_object, out_uv, out_normal, out_count):
    """Rays ``lo .. hi - 1`` through the 4-wide BVH of :func:`hsr.algorithms.bvh.widen`
    in the layout of :func:`hsr.algorithms.bvh.pack_nodes` (the root a wide node when
    ``root_count`` is 0, else a leaf of ``root_count`` slots from ``root_ref``).
    ``mode`` :data:`NEAREST` writes ``out_t`` (+inf on a miss), ``out_face`` (-1),
    ``out_object`` (the instance whose faces start at or before the face in
    ``face_offsets``; -1), ``out_uv`` (the weights of corners 1 and 2) and
    ``out_normal`` (the unit geometric normal as wound; 0); :data:`ANY` writes
    ``out_count`` 1 or 0, stopping at the first hit; :data:`COUNT` writes the number of
    hits in ``out_count``. ``t_min`` / ``t_max``: one value per ray, or one
    for all (length 1). Equal nearest distances go to the lower face id, so the answer
    does not depend on the walk (nor on how rays are split between threads).

    The chunk's rays are checked first (:func:`check_rays`; their data is then in
    cache for the walk); returns ``(tests, problem, ray)``: the triangle tests made, or
    the first bad ray's problem and index with nothing traced.

    The walk is the ordered one of :func:`hsr.algorithms.bvh.descend` and
    :func:`hsr.algorithms.bvh.next_box`, pruned by the nearest hit so far (``mode``
    NEAREST), by ``t_max`` otherwise."""
    problem, bad = check_rays(lo, hi, origins, directions, t_min, t_max)
    if problem:
        return 0, problem, bad
    size = (LANES - 1) * wide_depth + 2 * LANES
    stack_ref = np.empty(size, dtype=np.int64)
    stack_count = np.empty(size, dtype=np.int64)
    stack_t = np.empty(size)
    per_ray = t_min.shape[0] > 1, t_max.shape[0] > 1
    tests = 0
    for i in range(lo, hi):
        ox, oy, oz = origins[i, 0], origins[i, 1], origins[i, 2]
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        t0 = t_min[i if per_ray[0] else 0]
        t1 = t_max[i if per_ray[1] else 0]
        kx, ky, kz, sx, sy, sz, okx, oky, okz = ray_frame(ox, oy, oz, dx, dy, dz)
        inv_dx = 1.0 / dx if dx != 0.0 else np.inf
        inv_dy = 1.0 / dy if dy != 0.0 else np.inf
        inv_dz = 1.0 / dz if dz != 0.0 else np.inf
        # A ray parallel to an axis needs the slab test's NaN care (see open_slabs).
        careful = dx == 0.0 or dy == 0.0 or dz == 0.0
        best_t, best_f, best_k, bu, bv = np.inf, -1, -1, 0.0, 0.0
        count = 0
        # No box entered beyond the bound can hold a hit that matters; a finite bound,
        # so that a missed box (entered at +inf) always fails the test.
        bound = min(t1, 1.7976931348623157e308)
        top = 0
        ref, n = np.int64(root_ref), np.int64(root_count)
        walking = leaf_face.shape[0] > 0
        while walking:
            if n == 0:  # a wide node: walk on into its nearest entered box
                if careful:
                    k0, k1, k2, k3, mask = careful_entries4(node_box, ref, ox, oy, oz, inv_dx,
                                                            inv_dy, inv_dz, bound)
                else:
                    k0, k1, k2, k3, mask = box_entries4(node_box, ref, ox, oy, oz, inv_dx,
                                                        inv_dy, inv_dz, bound)
                ref, n, top, entered = descend(k0, k1, k2, k3, mask, ref, node_link, stack_ref,
                                               stack_count, stack_t, top)
                if entered:
                    continue
            else:  # a leaf: slots ref .. ref + n - 1
                found = False
                for k in range(ref, ref + n):
                    tests += 1
                    t, u, v, w = _intersect(tris, k, okx, oky, okz, kx, ky, kz, sx, sy,
                                            sz, 0, True, dx, dy, dz)
                    if not ((t0 <= t) & (t <= t1)):
                        continue
                    if mode == 1:
                        found = True
                        break
                    if mode == 2:
                        if (u != 0.0 and v != 0.0 and w != 0.0) or _owns(
                                tris, k, okx, oky, okz, kx, ky, kz, sx, sy):
                            count += 1
                        continue
                    f = leaf_face[k]
                    if t < best_t or (t == best_t and f < best_f):
                        best_t, best_f, best_k, bu, bv = t, f, k, v, w
                        bound = t
                if found:
                    count = 1
                    break
            ref, n, top, walking = next_box(stack_ref, stack_count, stack_t, top, bound)
        if mode == 0:
            out_t[i] = best_t
            out_face[i] = best_f
            out_uv[i, 0] = bu
            out_uv[i, 1] = bv
            _hit_record(tris, best_k, best_f, face_offsets, out_object, out_normal, i)
        else:
            out_count[i] = count
    return tests, 0, -1


@njit(cache=True, nogil=True, inline="always")
def _hit_record(tris, k, f, face_offsets, out_object, out_normal, i):
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
    e1x = tris[k, 1, 0] - tris[k, 0, 0]
    e1y = tris[k, 1, 1] - tris[k, 0, 1]
    e1z = tris[k, 1, 2] - tris[k, 0, 2]
    e2x = tris[k, 2, 0] - tris[k, 0, 0]
    e2y = tris[k, 2, 1] - tris[k, 0, 1]
    e2z = tris[k, 2, 2] - tris[k, 0, 2]
    nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    out_normal[i, 0], out_normal[i, 1], out_normal[i, 2] = nx / norm, ny / norm, nz / norm


@njit(cache=True, nogil=True)
def check_rays(lo, hi, origins, directions, t_min, t_max):
    """(problem, ray) of the first bad ray of ``lo .. hi - 1``, (0, -1) when all are
    good (``t_min`` / ``t_max`` per ray, or length 1 for all). Problems: 1 an origin
    not finite, 2 a direction not finite, 3 a zero direction, 4 t_min NaN or infinite,
    5 t_max NaN, 6 t_min < 0, 7 t_min > t_max."""
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
