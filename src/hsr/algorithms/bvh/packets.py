"""The packet walk (:func:`trace_packets`): four rays that start together (a camera's
neighbouring pixels) walk the tree as one, each box tested for all four at once; the
same queries and hit rules as :func:`hsr.algorithms.bvh.walk.trace_range`."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import (
    bit_count,
    borrowed,
    float_bits,
    leaf_filter4,
    leaf_filter4_rays,
    lowest_bit,
    min_key8,
    packet_keys8,
    packet_keys8_shared,
    prefetch,
    sort_keys8,
)
from .boxes import careful_packet_keys8, inverse_direction, slack_bound
from .hits import (
    ANY,
    COUNT,
    LARGEST,
    NEAREST,
    check_rays,
    counted,
    fetch_box,
    finish_list,
    hit_record,
    in_interval,
    list_records,
    listed,
    nearer,
    plausible_ray,
)
from .layout import HOT_NODES, LANES, QUAD, child, leaf_base, nowrap, quad_lanes, slot_row
from .ranking import clip_zw, depth32, ranks_before, t_bound
from .stack import walk_stack
from .triangle import intersect, ray_frame

__all__ = ["PACKET_FETCH_AROUND", "trace_packets"]

# Corners fetched this many slots either side of a packet's last hit as it ends: the next
# packet's rays (the next pixels of a row) land near it, and leaf order keeps neighbours near.
# (Measurements: docs/history.md, "Ray core".)
PACKET_FETCH_AROUND = 16


@njit(cache=True, nogil=True, error_model="numpy")
def trace_packets(lo, hi, origins, directions, t_min, t_max, mode, raster, tris, leaf_face,
                  node_box, node_link, root_ref, root_count, wide_depth, face_offsets, out_t,
                  out_face, out_object, out_uv, out_normal, out_count, lists=None):
    """:func:`hsr.algorithms.bvh.walk.trace_range` four rays at a time: a packet (Wald,
    Slusallek, Benthin and Wagner 2001) walks the boxes that any of its rays enters, each
    box tested for the four rays at once (:func:`hsr.algorithms.simd.packet_keys8`) and each
    ray carried down only into boxes it enters before its own bound; at a leaf each walking
    ray runs the one-ray triangle test. For coherent rays (from one eye, close directions)
    the four walks are nearly one, and a node read serves four rays.

    The results are those of :func:`hsr.algorithms.bvh.walk.trace_range`, bit for bit: a ray
    walks every box it enters before its bound (the union walk only adds boxes, whose
    triangles it tests to no effect on a result that depends on the set of hits, not their
    order), its entries are the one-ray test's numbers, and ties go to the lower face id.

    Four rays from one origin (a camera's, from its eye) share what their tests share:
    the node's bounds less the origin (:func:`hsr.algorithms.simd.packet_keys8_shared`)
    and, along the same permuted axes, a leaf's corners less it
    (:func:`hsr.algorithms.simd.leaf_filter4_rays`), with the same arithmetic, so the
    same answers (measurements: docs/history.md, "Ray core")."""
    cull_code, front_ccw = (0, True) if raster is None else (raster[0], raster[1])
    # Views without reference counts (the caller holds the arrays): the inlined triangle test
    # otherwise counted one at each hit, two atomic instructions.
    # (Measurements: docs/history.md, "Ray core".)
    tris, leaf_face = borrowed(tris), borrowed(leaf_face)
    node_box, node_link = borrowed(node_box), borrowed(node_link)
    # (The outputs too: handed to listed once a hit, they cost two atomic reference
    # counts a hit, half of all_hits' listing walk.)
    out_t, out_face, out_object = borrowed(out_t), borrowed(out_face), borrowed(out_object)
    out_uv = borrowed(out_uv)
    stack_ref, stack_count, _ = walk_stack(wide_depth, 1)
    stack_rays = np.empty(len(stack_ref), dtype=np.int64)
    stack_t = np.empty((len(stack_ref), 4))  # each ray's entry
    rays = np.empty((6, 4))  # origin x, y, z and inverse direction x, y, z per ray
    frame = np.empty((11, 4))  # sx, sy, sz, okx, oky, okz, dx, dy, dz, t_min, t_max
    axes = np.empty((3, 4), dtype=np.int64)
    bound = np.empty(4)
    entries = np.empty((4, LANES))  # each ray's entry into each box
    keys = np.empty(LANES, dtype=np.int64)  # per box, its rays' nearest entry (sort_keys8)
    best_t, best_z, best_uv = np.empty(4), np.empty(4), np.empty((4, 2))
    best_f, best_k = np.empty(4, dtype=np.int64), np.empty(4, dtype=np.int64)
    count = np.empty(4, dtype=np.int64)
    per_ray = t_min.shape[0] > 1, t_max.shape[0] > 1
    tests = 0
    for first in range(lo, hi, 4):
        careful = framed = one_frame = False
        lefts = np.int64(0)
        # The packet's rays are checked as they are read (see trace_range).
        plausible = True
        for i in range(first, min(first + 4, hi)):
            plausible &= plausible_ray(origins, directions, t_min, t_max, i, per_ray)
        if not plausible:
            problem, bad = check_rays(first, min(first + 4, hi), origins, directions, t_min,
                                      t_max)
            if problem:
                return 0, problem, bad
        for r in range(4):
            i = min(first + r, hi - 1)  # past the end: the last ray again, not walking
            ox, oy, oz = origins[i, 0], origins[i, 1], origins[i, 2]
            dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
            frame[6, r], frame[7, r], frame[8, r] = dx, dy, dz
            frame[9, r] = t_min[i if per_ray[0] else 0]
            frame[10, r] = t_max[i if per_ray[1] else 0]
            rays[0, r], rays[1, r], rays[2, r] = ox, oy, oz
            rays[3, r], rays[4, r], rays[5, r], parallel = inverse_direction(dx, dy, dz)
            careful |= parallel
            # A ray past the end enters nothing (every entry is >= 0), nor one with
            # nothing to list (the count found no hit).
            bound[r] = min(frame[10, r], LARGEST) if first + r < hi else -1.0
            if lists is not None:
                if lists[i + 1] == lists[i]:
                    bound[r] = -1.0
            best_t[r], best_z[r], best_f[r], best_k[r] = np.inf, np.inf, -1, -1
            best_uv[r, 0] = best_uv[r, 1] = 0.0
            count[r] = 0
        # Four rays from one origin (a camera's; the same bits, so a signed zero does
        # not pass for its opposite) share the box test's first step.
        shared = True
        for r in range(1, 4):
            for a in range(3):
                shared &= float_bits(rays[a, r]) == float_bits(rays[a, 0])
        top = 0
        ref, n = np.int64(root_ref), np.int64(root_count)
        active = np.int64((1 << min(4, hi - first)) - 1)
        walking = leaf_face.shape[0] > 0
        while walking:
            if n == 0:  # a wide node: the packet's nearest entered box next
                # Per box the nearest entry of the walking rays, as keys of sort_keys8.
                if careful:
                    mask = careful_packet_keys8(node_box, ref, rays, bound, active, entries,
                                                keys)
                elif shared:
                    mask = packet_keys8_shared(node_box, ref, rays, bound, active, entries,
                                               keys)
                else:
                    mask = packet_keys8(node_box, ref, rays, bound, active, entries, keys)
                # The entered boxes nearest first (the step of trace_range, on the keys
                # of the packet's nearest entries): the nearest walked next by the rays
                # that enter it, the others pushed farthest first with each ray's
                # entry. (Written out here, as in trace_range: an inlined function
                # taking the arrays ran 40% slower.)
                if mask != 0:
                    boxes = (mask | (mask >> 1) | (mask >> 2) | (mask >> 3)) & 0x11111111
                    m = bit_count(boxes) - 1  # the entered boxes pushed
                    if m == 0:
                        lane = lowest_bit(boxes) >> 2
                    else:
                        # The nearest known first (min_key8, see trace_range).
                        if m == 1:  # two: one comparison
                            near = keys[lowest_bit(boxes) >> 2]
                            far = keys[lowest_bit(boxes & (boxes - 1)) >> 2]
                            keys[1] = max(near, far)
                            lane = min(near, far) & 7
                        else:
                            lane = min_key8(keys) & 7
                            sort_keys8(keys)
                        for j in range(m, 0, -1):
                            pushed, up = keys[nowrap(j)] & 7, nowrap(top)
                            stack_ref[up], stack_count[up] = child(node_link, ref, pushed)
                            # A box pushed is often walked next by another of the packet's
                            # rays: fetch it now.
                            # (Measurements: docs/history.md, "Ray core".)
                            if stack_count[up] > 0 or stack_ref[up] >= HOT_NODES:
                                fetch_box(node_box, tris, leaf_face, stack_ref[up],
                                           stack_count[up], mode == NEAREST or lists is not None)
                            stack_rays[up] = (mask >> (4 * pushed)) & 15
                            stack_t[up, 0] = entries[0, pushed]
                            stack_t[up, 1] = entries[1, pushed]
                            stack_t[up, 2] = entries[2, pushed]
                            stack_t[up, 3] = entries[3, pushed]
                            top += 1
                    active = (mask >> (4 * lane)) & 15
                    ref, n = child(node_link, ref, lane)
                    continue
            else:  # a leaf: each walking ray tests its triangles
                if not framed:
                    # The rays' frames, made at the packet's first leaf: rays past an
                    # outline reach none.
                    # (Measurements: docs/history.md, "Ray core".)
                    for r in range(4):
                        (axes[0, r], axes[1, r], axes[2, r], frame[0, r], frame[1, r],
                         frame[2, r], frame[3, r], frame[4, r], frame[5, r]) = ray_frame(
                            rays[0, r], rays[1, r], rays[2, r], frame[6, r], frame[7, r],
                            frame[8, r])
                    framed = True
                    # Rays from one origin along the same permuted axes (most of a
                    # camera's packets) share their leaf tests' first step.
                    one_frame = shared
                    for r in range(1, 4):
                        for a in range(3):
                            one_frame &= axes[a, r] == axes[a, 0]
                # A quad of triangles at a time, each walking ray in turn (a ray's
                # triangles are tested in the same order either way): the watertight
                # test four triangles at once, then the scalar one on the few that pass
                # its first check (leaf_filter4; leaf_filter4_rays for the four rays).
                end = ref + n
                for base in range(leaf_base(tris, ref), end, QUAD):
                    lanes = quad_lanes(ref, end, base)
                    if one_frame:
                        lefts = leaf_filter4_rays(tris, base, lanes, frame, axes)
                    for r in range(4):
                        if not (active >> r) & 1 or (mode == ANY and count[r] != 0):
                            continue
                        if lists is not None:
                            if bound[r] < 0.0:  # its list is full
                                continue
                        kx, ky, kz = axes[0, r], axes[1, r], axes[2, r]
                        sx, sy, sz = frame[0, r], frame[1, r], frame[2, r]
                        okx, oky, okz = frame[3, r], frame[4, r], frame[5, r]
                        t0, t1 = frame[9, r], frame[10, r]
                        tests += bit_count(lanes)
                        if one_frame:
                            left = (lefts >> (4 * r)) & 15
                        else:
                            left = leaf_filter4(tris, base, lanes, okx, oky, okz, kx, ky, kz,
                                                sx, sy)
                        while left != 0:
                            k = base + lowest_bit(left)
                            left &= left - 1
                            t, u, v, w = intersect(tris, k, okx, oky, okz, kx, ky, kz, sx, sy,
                                                    sz, cull_code, front_ccw, frame[6, r],
                                                    frame[7, r], frame[8, r])
                            if not in_interval(t, t0, t1):
                                continue
                            if mode == ANY:  # done: this ray enters no box any more
                                count[r] = 1
                                bound[r] = -1.0
                                best_k[r] = k  # (where the next packet's rays land)
                                break
                            if mode >= COUNT:  # COUNT, ALL, FIRST: each crossing once
                                if counted(u, v, w, tris, k, okx, oky, okz, kx, ky, kz, sx,
                                           sy):
                                    if lists is None:
                                        count[r] += 1
                                        continue
                                    count[r], bound[r] = listed(
                                        mode, t, leaf_face[nowrap(k)], v, w, k, first + r,
                                        lists, count[r], bound[r], out_t, out_face, out_uv,
                                        out_object)
                                    if bound[r] < 0.0:  # every hit: done, as ANY
                                        break
                                continue
                            f = leaf_face[nowrap(k)]
                            if raster is not None:
                                rank = raster[3]
                                zc0, zc1, wc0, wc1 = clip_zw(rank, rays[0, r], rays[1, r],
                                                              rays[2, r], frame[6, r], frame[7, r],
                                                              frame[8, r])
                                z = depth32(t, zc0, zc1, wc0, wc1, rank[8], rank[9])
                                if ranks_before(z, f, best_z[r], best_f[r], raster[2]):
                                    best_t[r], best_z[r], best_f[r], best_k[r] = t, z, f, k
                                    best_uv[r, 0], best_uv[r, 1] = v, w
                                    bound[r] = t_bound(t, z, zc0, zc1, wc0, wc1, rank)
                                continue
                            if nearer(t, f, best_t[r], best_f[r]):
                                best_t[r], best_f[r], best_k[r] = t, f, k
                                best_uv[r, 0], best_uv[r, 1] = v, w
                                bound[r] = t
            # The next box on the stack that one of its rays still enters before that
            # ray's bound, walked by those rays.
            walking = False
            while top > 0:
                top -= 1
                up = nowrap(top)  # (no negative-index wraparound)
                keep = 0
                for r in range(4):
                    # (Entries may lie a few roundings above the exact ones.)
                    if (stack_rays[up] >> r) & 1 and stack_t[up, r] <= slack_bound(
                            bound[r]):
                        keep |= 1 << r
                if keep != 0:
                    ref, n, active = stack_ref[up], stack_count[up], np.int64(keep)
                    walking = True
                    break
        if mode != COUNT and best_k[3] >= 0:  # see PACKET_FETCH_AROUND
            around = slot_row(tris, max(best_k[3] - PACKET_FETCH_AROUND, 0))
            for offset in range(0, 2 * PACKET_FETCH_AROUND * 9 * tris.itemsize, 64):
                prefetch(tris, around, offset)
        for r in range(min(4, hi - first)):
            i = first + r
            if lists is not None:
                finish_list(i, lists, count[r], out_t, out_face, out_uv, out_object)
                continue
            if mode != NEAREST:
                out_count[i] = count[r]
                continue
            out_t[i] = best_t[r]
            out_face[i] = best_f[r]
            out_uv[i, 0], out_uv[i, 1] = best_uv[r, 0], best_uv[r, 1]
            if raster is None:
                hit_record(tris, best_k[r], best_f[r], face_offsets, out_object, out_normal,
                            i)
    if lists is not None:
        list_records(lists[lo], lists[hi], tris, face_offsets, out_face, out_object,
                     out_normal)
    return tests, 0, -1
