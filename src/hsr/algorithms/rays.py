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

from .bvh import _down32, _intersect, _up32, open_slabs, ray_frame, sheared_corners
from .simd import box_entries4

__all__ = ["trace_range", "check_rays", "widen", "pack_nodes", "NEAREST", "ANY", "COUNT"]

NEAREST, ANY, COUNT = 0, 1, 2
# Children per node of the walked tree (the sorting network in trace_range is for four).
LANES = 4
# A walked node is one 128-byte record, two cache lines: 6 LANES float32 box bounds, then
# LANES int32 references and LANES int32 counts (see pack_nodes).
NODE_WORDS = 32
REF, COUNT_AT = 6 * LANES, 7 * LANES


@njit(cache=True, nogil=True)
def widen(node_min, node_max, node_left, node_start, node_count):
    """The binary BVH collapsed into a LANES-wide one (each wide node takes the two
    children of a binary node and, while it has room, replaces the inner child of
    largest surface area by that child's two children: Wald et al. 2008, "Getting rid of
    packets"). Returns (box, ref, count, depth): box (W, 6 LANES) float32, the
    children's boxes as lanes [lo_x.., lo_y.., lo_z.., hi_x.., hi_y.., hi_z..] rounded
    outwards (an empty lane's box lies at +inf, so every ray misses it); ref, count
    (W, LANES) int64: count > 0
    a leaf's first slot and size, 0 a wide node's index, -1 an empty lane; depth the
    deepest wide level. The root must be an inner node."""
    n = node_left.shape[0]
    box = np.full((max(n, 1), 6 * LANES), np.inf, dtype=np.float32)
    ref = np.zeros((max(n, 1), LANES), dtype=np.int64)
    count = np.full((max(n, 1), LANES), -1, dtype=np.int64)
    todo_node = np.empty(n + 1, dtype=np.int64)  # binary node -> its wide node, to fill
    todo_wide = np.empty(n + 1, dtype=np.int64)
    todo_level = np.empty(n + 1, dtype=np.int64)
    todo_node[0], todo_wide[0], todo_level[0] = 0, 0, 0
    top, n_wide, depth = 1, 1, 0
    kids = np.empty(LANES, dtype=np.int64)
    while top > 0:
        top -= 1
        b, w, level = todo_node[top], todo_wide[top], todo_level[top]
        depth = max(depth, level)
        kids[0], kids[1] = node_left[b], node_left[b] + 1
        m = 2
        while m < LANES:
            pick, best = -1, -1.0
            for j in range(m):
                c = kids[j]
                if node_left[c] >= 0:
                    dx = node_max[c, 0] - node_min[c, 0]
                    dy = node_max[c, 1] - node_min[c, 1]
                    dz = node_max[c, 2] - node_min[c, 2]
                    area = dx * dy + dy * dz + dz * dx
                    if area > best:
                        pick, best = j, area
            if pick < 0:
                break
            c = kids[pick]
            kids[pick] = node_left[c]
            kids[m] = node_left[c] + 1
            m += 1
        for lane in range(m):
            c = kids[lane]
            for a in range(3):
                box[w, LANES * a + lane] = _down32(node_min[c, a])
                box[w, LANES * (3 + a) + lane] = _up32(node_max[c, a])
            if node_left[c] < 0:
                ref[w, lane], count[w, lane] = node_start[c], node_count[c]
            else:
                ref[w, lane], count[w, lane] = n_wide, 0
                todo_node[top], todo_wide[top], todo_level[top] = c, n_wide, level + 1
                top += 1
                n_wide += 1
    return box[:n_wide].copy(), ref[:n_wide].copy(), count[:n_wide].copy(), depth


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


def pack_nodes(box, ref, count):
    """The walked layout of :func:`widen`'s tree: ``(node_box, node_link)``, two views
    of one buffer aligned to 64 bytes, each node a 128-byte record (two cache lines, one
    read brings a node's boxes and references together): ``node_box`` (W, 32) float32,
    the boxes in words 0 .. 23; ``node_link`` (W, 32) int32, the references in words
    24 .. 27 and the counts in 28 .. 31 (int32: a scene has fewer than 2**31 faces,
    which :class:`hsr.RayScene` checks). Separate int64 arrays were three records a
    node, and random rays, whose nodes are rarely in cache, paid for each."""
    n = len(box)
    raw = np.empty(n * 4 * NODE_WORDS + 64, dtype=np.uint8)
    start = -raw.ctypes.data % 64
    record = raw[start:start + n * 4 * NODE_WORDS]
    node_box = record.view(np.float32).reshape(n, NODE_WORDS)
    node_link = record.view(np.int32).reshape(n, NODE_WORDS)
    node_box[:, :REF] = box
    node_link[:, REF:COUNT_AT] = ref
    node_link[:, COUNT_AT:] = count
    return node_box, node_link


@njit(cache=True, nogil=True)
def trace_range(lo, hi, origins, directions, t_min, t_max, mode, tris, leaf_face, node_box,
                node_link, root_ref, root_count, wide_depth, face_offsets, out_t, out_face,
                out_object, out_uv, out_normal, out_count):
    """Rays ``lo .. hi - 1`` through the 4-wide BVH of :func:`widen` in the layout of
    :func:`pack_nodes` (the root a wide node when ``root_count`` is 0, else a leaf of
    ``root_count`` slots from ``root_ref``). ``mode`` :data:`NEAREST` writes ``out_t``
    (+inf on a miss), ``out_face`` (-1), ``out_object`` (the instance whose faces start
    at or before the face in ``face_offsets``; -1), ``out_uv`` (the weights of corners
    1 and 2) and ``out_normal`` (the unit geometric normal as wound; 0); :data:`ANY`
    writes ``out_count`` 1 or 0, stopping at the first hit; :data:`COUNT` writes the
    number of hits in ``out_count``. ``t_min`` / ``t_max``: one value per ray, or one
    for all (length 1). Equal nearest distances go to the lower face id, so the answer
    does not depend on the walk (nor on how rays are split between threads).

    The chunk's rays are checked first (:func:`check_rays`; their data is then in
    cache for the walk); returns ``(tests, problem, ray)``: the triangle tests made, or
    the first bad ray's problem and index with nothing traced.

    The walk is ordered: at a wide node the four boxes are tested at once
    (:func:`hsr.algorithms.simd.box_entries4`); boxes the ray misses or enters beyond
    the current bound are dropped, the nearest entered one is walked next and the
    others pushed farthest first with their entry distances, each dropped when popped
    if a hit nearer than it has been found meanwhile."""
    problem, bad = check_rays(lo, hi, origins, directions, t_min, t_max)
    if problem:
        return 0, problem, bad
    size = (LANES - 1) * wide_depth + 2 * LANES
    stack_ref = np.empty(size, dtype=np.int64)
    stack_count = np.empty(size, dtype=np.int64)
    stack_t = np.empty(size)
    sorted_t = np.empty(LANES)
    order = np.empty(LANES, dtype=np.int64)
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
        # A ray parallel to an axis needs the slab test's NaN care (see _box_entry).
        careful = dx == 0.0 or dy == 0.0 or dz == 0.0
        best_t, best_f, best_k, bu, bv = np.inf, -1, -1, 0.0, 0.0
        count = 0
        # No box entered beyond the bound can hold a hit that matters; a finite bound,
        # so that a missed box (entered at +inf) always fails the test.
        bound = min(t1, 1.7976931348623157e308)
        top = 0
        ref, n = root_ref, root_count
        walking = leaf_face.shape[0] > 0
        while walking:
            if n == 0:  # a wide node: its four children's boxes are in its record
                if careful:
                    k0 = _careful_entry(node_box, ref, 0, ox, oy, oz, inv_dx, inv_dy,
                                        inv_dz, bound)
                    k1 = _careful_entry(node_box, ref, 1, ox, oy, oz, inv_dx, inv_dy,
                                        inv_dz, bound)
                    k2 = _careful_entry(node_box, ref, 2, ox, oy, oz, inv_dx, inv_dy,
                                        inv_dz, bound)
                    k3 = _careful_entry(node_box, ref, 3, ox, oy, oz, inv_dx, inv_dy,
                                        inv_dz, bound)
                    mask = ((k0 < np.inf) | (k1 < np.inf) << 1 | (k2 < np.inf) << 2
                            | (k3 < np.inf) << 3)
                else:
                    k0, k1, k2, k3, mask = box_entries4(node_box, ref, ox, oy, oz, inv_dx,
                                                        inv_dy, inv_dz, bound)
                # Three of four nodes a ray visits enter none or one of their boxes
                # (random rays at the bunny); those need no ordering.
                if mask != 0 and mask & (mask - 1) == 0:  # one box: walk it, push nothing
                    lane = (mask >> 1) - (mask >> 3)  # the set bit's index
                    ref, n = node_link[ref, REF + lane], node_link[ref, COUNT_AT + lane]
                    continue
                if mask != 0:
                    # The entered lanes nearest first by a sorting network on (entry,
                    # lane) pairs (Knuth's five comparators for four keys) made of
                    # selects, not branches. The m entered lanes lead (a missed lane
                    # sorts last at +inf); the nearest is walked next and the others
                    # pushed farthest first. All three pushes are written and the top
                    # moves by m - 1, so the pushes need no branch either (the stack has
                    # LANES slots spare).
                    k0, l0, k1, l1 = _sorted_pair(k0, 0, k1, 1)
                    k2, l2, k3, l3 = _sorted_pair(k2, 2, k3, 3)
                    k0, l0, k2, l2 = _sorted_pair(k0, l0, k2, l2)
                    k1, l1, k3, l3 = _sorted_pair(k1, l1, k3, l3)
                    k1, l1, k2, l2 = _sorted_pair(k1, l1, k2, l2)
                    m = (k0 < np.inf) + (k1 < np.inf) + (k2 < np.inf) + (k3 < np.inf)
                    sorted_t[0], sorted_t[1], sorted_t[2], sorted_t[3] = k0, k1, k2, k3
                    order[0], order[1], order[2], order[3] = l0, l1, l2, l3
                    for j in range(LANES - 1):
                        s = max(m - 1 - j, 0)
                        lane = order[s]
                        stack_ref[top + j] = node_link[ref, REF + lane]
                        stack_count[top + j] = node_link[ref, COUNT_AT + lane]
                        stack_t[top + j] = sorted_t[s]
                    top += m - 1
                    ref, n = node_link[ref, REF + l0], node_link[ref, COUNT_AT + l0]
                    continue
            else:  # a leaf: slots ref .. ref + n - 1
                for k in range(ref, ref + n):
                    tests += 1
                    t, u, v, w = _intersect(tris, k, okx, oky, okz, kx, ky, kz, sx, sy,
                                            sz, 0, True, dx, dy, dz)
                    if not ((t0 <= t) & (t <= t1)):
                        continue
                    if mode == 1:
                        count = 1
                        walking = False
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
                if not walking:
                    break
            # The next box still worth entering, from the stack.
            walking = False
            while top > 0:
                top -= 1
                if stack_t[top] <= bound:
                    ref, n = stack_ref[top], stack_count[top]
                    walking = True
                    break
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
def _sorted_pair(ka, la, kb, lb):
    """One comparator of a sorting network: the pairs (ka, la), (kb, lb) in order of
    their keys, by selects (equal keys keep their order)."""
    swap = kb < ka
    return (kb if swap else ka), (lb if swap else la), (ka if swap else kb), (la if swap else lb)


@njit(cache=True, nogil=True, inline="always")
def _lane_slabs(box, w, lane, ox, oy, oz, inv_dx, inv_dy, inv_dz):
    """The ray parameters (t0x, t1x, t0y, t1y, t0z, t1z) where the ray crosses the low
    and high planes of lane ``lane``'s box of wide node ``w``, in float64."""
    return ((np.float64(box[w, lane]) - ox) * inv_dx,
            (np.float64(box[w, 3 * LANES + lane]) - ox) * inv_dx,
            (np.float64(box[w, LANES + lane]) - oy) * inv_dy,
            (np.float64(box[w, 4 * LANES + lane]) - oy) * inv_dy,
            (np.float64(box[w, 2 * LANES + lane]) - oz) * inv_dz,
            (np.float64(box[w, 5 * LANES + lane]) - oz) * inv_dz)


@njit(cache=True, nogil=True, inline="always")
def _careful_entry(box, w, lane, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound):
    """Where the ray enters lane ``lane``'s box of wide node ``w`` (+inf: missed, or
    entered beyond ``bound``), for a ray with a zero direction component: 0 * inf (the
    ray in a slab's plane) is NaN, and the closed slab holds such a ray for every t
    (see _box_entry)."""
    t0x, t1x, t0y, t1y, t0z, t1z = _lane_slabs(box, w, lane, ox, oy, oz, inv_dx, inv_dy,
                                               inv_dz)
    t0x, t1x, t0y, t1y, t0z, t1z = open_slabs(t0x, t1x, t0y, t1y, t0z, t1z)
    t_in = max(min(t0x, t1x), min(t0y, t1y), min(t0z, t1z), 0.0)
    t_out = min(max(t0x, t1x), max(t0y, t1y), max(t0z, t1z))
    return t_in if t_in <= t_out * (1.0 + 4e-16) + 1e-300 and t_in <= bound else np.inf


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
