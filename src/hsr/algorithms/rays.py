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

from .bvh import (
    COUNT_AT,
    LANES,
    NODE_WORDS,
    REF,
    _intersect,
    careful_keys8,
    careful_packet_keys8,
    face_normal,
    inverse_direction,
    next_box,
    ray_frame,
    sheared_corners,
    stack_size,
    walk_stack,
)
from .simd import (
    bit_count,
    borrowed,
    box_keys8,
    box_mask8,
    float_bits,
    leaf_filter4,
    leaf_filter4_rays,
    lowest_bit,
    min_key8,
    next_float32,
    packet_keys8,
    packet_keys8_shared,
    prefetch,
    sort_keys8,
)

__all__ = ["trace_range", "trace_packets", "check_rays", "window_ranking", "tie_reach",
           "NEAREST", "ANY", "COUNT"]

NEAREST, ANY, COUNT = 0, 1, 2
# A walk's bound starts at t_max made finite, so that a missed box (entered at +inf)
# always fails the test against it.
LARGEST = 1.7976931348623157e308


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


# Rays one thread walks at once (trace_range): a walk is a chain of memory reads, each
# waiting on the one before, and past the cache each costs a trip to the last-level
# cache or memory; with eight walks in turn, eight such trips overlap.
SLOTS = 8
# Wide nodes numbered below HOT_NODES (the top of the tree in level order, 128 KB of
# records; see hsr.algorithms.bvh.widen) are taken to be in a core's cache: walking into
# one goes on with the same ray. Measured with a first version of this walk at one
# thread, 1M random rays, against the one-ray walk (an Intel Xeon, 2 MB of L2 a core):
# switching rays at leaves only, 0.82x at the bunny but 0.80x at a 1M-face terrain; at
# every node, 1.0x and 0.64x; at leaves and at nodes past the first 512 to 8192,
# 0.82-0.90x and 0.56-0.58x (4096 taken then). On an AMD EPYC (1 MB of L2 a core) with
# the walk as it is now, random rays, one thread, cast / occluded ms: the bunny 105 / 80
# at 4096, 95 / 74 at 1024, 89-92 / 73 at 256 and 0; the terrain 144 / 108 at 4096,
# 133 / 99 at 1024 and 256, whose two threads were slower at 256 (82 / 58 against
# 73 / 54). 1024 was in the range good on both: 128 KB, which the 8-wide tree's
# 256-byte records fill at 512.
HOT_NODES = 512
# Scenes whose walked arrays (corners and nodes) take no more than this are walked a ray
# at a time, each to its end, with no switching: their reads come from the cache, and
# switching (the slot's state saved, the next one's loaded) costs more than it hides. A
# quarter of the last-level cache of the machine it was measured on (an AMD EPYC, 32 MB
# L3, 1 MB L2 a core), random rays, one thread, cast ms min of alternating processes,
# interleaved / not: a 30k-face terrain (2.6 MB) 53.8 / 49.2, a 60k one (5.1 MB) 57.5 /
# 57.6, the bunny (5.6 MB) 50.9 / 49.8 (occluded 44.1 / 41.6), a 100k terrain (8.5 MB)
# 59.6 / 63.6, a 1M one 69 / 148. Two threads, the bunny, averages of the minimums:
# cast 27.0 -> 25.5, occluded 23.5 -> 21.9. (Answers do not depend on it.)
INTERLEAVE_BYTES = 8 << 20
# How many rays ahead trace_range's pass over the hits fetches the hit's corners: far
# enough for a miss to memory to be over when the pass gets there (a ray takes a few
# nanoseconds in the pass, a miss about a hundred). One thread, ms min of 4 alternating
# runs, 16 -> 64: the 1M-face terrain's random cast 110.7 -> 104.4, the bunny's 80.3 ->
# 78.0 (perf had put 3% of the terrain's on the first load of the corners there).
RECORD_AHEAD = 64
# trace_packets fetches the corners of the triangles stored this many slots either side of
# a packet's last hit as it ends: the next packet's rays (the next pixels of a row) land
# next to it, and the leaf order keeps neighbouring triangles near each other in memory.
# Where each ray lands on a triangle of its own, its leaf's corners were a wait on memory
# at every packet. One thread, 1M rays, ms min of alternating processes: a 1M-face terrain
# filling the view, cast 140-154 -> 131-132 (8 either side 129-134, 32 122-130); two
# threads, cast 72.6 -> 67.0, occluded 66.5 -> 61.1 (averages of the minimums); the
# bunny's camera rays within noise.
PACKET_FETCH_AROUND = 16
# The columns of trace_range's slot state: float64 ...
(_F_OX, _F_OY, _F_OZ, _F_IX, _F_IY, _F_IZ, _F_SX, _F_SY, _F_SZ, _F_OKX, _F_OKY, _F_OKZ,
 _F_BOUND, _F_T, _F_U, _F_V, _F_Z, _F_COLUMNS) = range(18)
# ... and int64 (_I_SLOT: the BVH slot of the best hit, _I_FACE its face).
(_I_RAY, _I_REF, _I_N, _I_TOP, _I_FACE, _I_SLOT, _I_COUNT, _I_FRAMED, _I_CAREFUL, _I_KX,
 _I_KY, _I_KZ, _I_COLUMNS) = range(13)


@njit(cache=True, nogil=True, inline="always")
def _fetch_box(node_box, tris, leaf_face, ref, n, faces):
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
            # Read after the corners have come, this load missed on its own at random
            # rays (6% of the bunny's cast in a profile). One thread, ms min of 5
            # alternating runs: the 1M-face terrain's random cast 119.6 -> 106.1, the
            # bunny's 82.8 -> 76.9; packets within noise.
            prefetch(leaf_face, ref, 0)


# error_model "numpy": IEEE division, without the zero test Numba adds to each division
# under Python's rules (every divisor in the walks is non-zero or checked first).
@njit(cache=True, nogil=True, error_model="numpy")
def trace_range(lo, hi, origins, directions, t_min, t_max, mode, raster, tris, leaf_face,
                node_box, node_link, root_ref, root_count, wide_depth, face_offsets, out_t,
                out_face, out_object, out_uv, out_normal, out_count):
    """Rays ``lo .. hi - 1`` through the 8-wide BVH of :func:`hsr.algorithms.bvh.widen`
    in the layout of :func:`hsr.algorithms.bvh.node_records` (the root a wide node when
    ``root_count`` is 0, else a leaf of ``root_count`` slots from ``root_ref``).
    ``mode`` :data:`NEAREST` writes ``out_t`` (+inf on a miss), ``out_face`` (-1),
    ``out_object`` (the instance whose faces start at or before the face in
    ``face_offsets``; -1), ``out_uv`` (the weights of corners 1 and 2) and
    ``out_normal`` (the unit geometric normal as wound; 0); :data:`ANY` writes
    ``out_count`` 1 or 0, stopping at the first hit; :data:`COUNT` writes the number of
    hits in ``out_count``. ``t_min`` / ``t_max``: one value per ray, or one
    for all (length 1). Equal nearest distances go to the lower face id, so the answer
    does not depend on the walk (nor on how rays are split between threads).
    ``raster`` is None for these queries. The ray caster's walks pass
    ``(cull_code, front_ccw, lequal, rank)`` with mode NEAREST (``out_t``, ``out_face``
    and ``out_uv`` written): hits are culled by facing as glCullFace does (cull code 0
    none, 1 back, 2 front, 3 both) and ranked as the z-buffer ranks fragments, by float32
    window depth (``rank``: :func:`window_ranking`), equal depths by submission order
    (the later face under GL_LEQUAL, else the earlier). Numba compiles the two kinds
    apart (``raster is None`` is decided when compiling), so the queries' walks carry
    none of the ray caster's code.

    Each ray is checked as its walk starts (:func:`check_rays`, in ray order);
    returns ``(tests, problem, ray)``: the triangle tests made, or the first bad ray's
    problem and index, the rays before it traced and none after.

    Each ray's walk is ordered, nearest entered box first (the step at a wide node is
    written out below; :func:`hsr.algorithms.bvh.next_box` pops), pruned by the
    nearest hit so far (``mode``
    NEAREST), by ``t_max`` otherwise. :data:`SLOTS` rays are walked in turn, each with
    its own stack and state: when a ray's next step reads a leaf's corners or a wide
    node past the top of the tree (:data:`HOT_NODES`), that memory is prefetched
    (:func:`hsr.algorithms.simd.prefetch`) and the next ray takes a step, so the reads
    of several walks are under way at once instead of one after another (the
    interleaving of independent pointer chases of Kocberber et al. 2015, "Asynchronous
    memory access chaining"). In a scene of at most :data:`INTERLEAVE_BYTES` of corners
    and nodes, whose reads come from the cache, each ray walks to its end before the
    next one starts. Each ray's steps are those of its walk alone (a range of
    one ray), so are its answers. A ray that enters none of the root's boxes is
    answered as it is read, without taking a slot. (Coherent rays that are many for the
    triangles, a camera's pixels, go through :func:`trace_packets` instead: RayScene
    sends them there from four rays a face, the ray caster up to
    :data:`hsr.algorithms.raycast.PACKET_FACES_PER_PIXEL` faces a pixel.)"""
    cull_code, front_ccw = (0, True) if raster is None else (raster[0], raster[1])
    # Views without reference counts, as in trace_packets (none were left in this walk's
    # loop for the queries, in a profile; the ray caster's ranking had them).
    tris, leaf_face = borrowed(tris), borrowed(leaf_face)
    node_box, node_link = borrowed(node_box), borrowed(node_link)
    interleave = tris.size * tris.itemsize + node_box.size * node_box.itemsize > (
        INTERLEAVE_BYTES)
    per_ray = t_min.shape[0] > 1, t_max.shape[0] > 1
    one_stack = stack_size(wide_depth)
    stack_ref, stack_count, stack_t = walk_stack(wide_depth, SLOTS)
    keys = np.empty(LANES, dtype=np.int64)  # a node's entry keys (box_keys8)
    # Each slot's state, in two arrays (one per type; columns named by the _F_* and
    # _I_* constants): the ray (-1: none), where its walk stands, its bound, best hit
    # and hit count, its origin and inverse direction for the box tests, and the
    # triangle test's frame (ray_frame), made at its first leaf.
    slot_f = np.empty((SLOTS, _F_COLUMNS))
    slot_i = np.full((SLOTS, _I_COLUMNS), -1, dtype=np.int64)
    tests = 0
    # The queries' nearest hits get an object and a normal (the pass after the walk):
    # the rays that hit are listed for it.
    records = mode == NEAREST and raster is None
    hit_rays = np.empty(hi - lo if records else 0, dtype=np.int64)
    n_hits = 0
    next_ray, busy = lo, 0
    if leaf_face.shape[0] == 0:  # no faces: every ray misses
        for i in range(lo, hi):
            if mode == NEAREST:
                out_t[i], out_face[i], out_object[i] = np.inf, -1, -1
                out_uv[i, 0], out_uv[i, 1] = 0.0, 0.0
                if records:
                    out_normal[i, 0] = out_normal[i, 1] = out_normal[i, 2] = 0.0
            else:
                out_count[i] = 0
        next_ray = hi
    while True:
        for s in range(SLOTS):
            i = slot_i[s, _I_RAY]
            # The root's mask when this slot's ray was just tested there and entered (a
            # ray answered before it at the intake leaves 0 here, which starts no walk).
            root_mask = -1
            if i < 0:  # a free slot takes the next ray, if there is one
                while next_ray < hi:
                    i = next_ray
                    # Each ray is checked as its slot takes it: its data is read here
                    # anyway, where a pass of its own over the chunk first cost 10 ns a
                    # ray (the bunny's 1M random rays, occluded, one thread: 82 -> 77 ms).
                    if not _plausible(origins, directions, t_min, t_max, i, per_ray):
                        problem, bad = check_rays(i, i + 1, origins, directions, t_min,
                                                  t_max)
                        if problem:
                            return 0, problem, bad
                    next_ray += 1
                    ox, oy, oz = origins[i, 0], origins[i, 1], origins[i, 2]
                    # A ray parallel to an axis needs the slab test's NaN care (see
                    # open_slabs).
                    inv_dx, inv_dy, inv_dz, careful = inverse_direction(
                        directions[i, 0], directions[i, 1], directions[i, 2])
                    # No box entered beyond the bound can hold a hit that matters.
                    b = min(t_max[i if per_ray[1] else 0], LARGEST)
                    # A ray that enters none of the root's boxes is answered here, before
                    # it takes a slot: its walk would be that one test (the root is
                    # always in cache) and the slot's state written and read back for
                    # it. Three of four random rays at the bunny are such rays. One
                    # thread, 1M rays, ms min of three alternating runs: the bunny's
                    # random cast 75.7 -> 69.7, occluded 61.2 -> 58.9, count 102.0 ->
                    # 95.9; the 1M-face terrain's random cast 102.0 -> 94.8, its camera
                    # rays' 42.7 -> 38.8. A ray that enters starts its walk with this
                    # test's mask (and, for the nearest hit, its keys) instead of testing
                    # the root again: bunny's random rays, one thread, ms min of eight
                    # alternating runs averaged, cast 52.0 -> 51.4, occluded (four) 45.0
                    # -> 44.5; the terrain's random cast (three) 70.9 -> 69.1.
                    if root_count != 0 or careful:
                        break
                    if mode == NEAREST:
                        root_mask = box_keys8(node_box, root_ref, ox, oy, oz, inv_dx, inv_dy,
                                              inv_dz, b, keys)
                    else:
                        root_mask = box_mask8(node_box, root_ref, ox, oy, oz, inv_dx, inv_dy,
                                              inv_dz, b)
                    if root_mask != 0:
                        break
                    if mode == NEAREST:
                        out_t[i], out_face[i], out_object[i] = np.inf, -1, -1
                        out_uv[i, 0], out_uv[i, 1] = 0.0, 0.0
                        if records:
                            out_normal[i, 0] = out_normal[i, 1] = out_normal[i, 2] = 0.0
                    else:
                        out_count[i] = 0
                    i = -1
                if i < 0:
                    continue
                busy += 1
                slot_i[s, _I_RAY] = i
                slot_i[s, _I_REF], slot_i[s, _I_N] = root_ref, root_count
                slot_i[s, _I_TOP] = s * one_stack
                slot_i[s, _I_FACE], slot_i[s, _I_SLOT] = -1, -1
                slot_i[s, _I_COUNT], slot_i[s, _I_FRAMED] = 0, 0
                slot_f[s, _F_OX], slot_f[s, _F_OY], slot_f[s, _F_OZ] = ox, oy, oz
                slot_f[s, _F_IX], slot_f[s, _F_IY], slot_f[s, _F_IZ] = inv_dx, inv_dy, inv_dz
                slot_i[s, _I_CAREFUL] = careful
                slot_f[s, _F_BOUND] = b
                slot_f[s, _F_T], slot_f[s, _F_U], slot_f[s, _F_V] = np.inf, 0.0, 0.0
                slot_f[s, _F_Z] = np.inf
            ref, n, top = slot_i[s, _I_REF], slot_i[s, _I_N], slot_i[s, _I_TOP]
            b = slot_f[s, _F_BOUND]
            ox, oy, oz = slot_f[s, _F_OX], slot_f[s, _F_OY], slot_f[s, _F_OZ]
            inv_dx, inv_dy, inv_dz = slot_f[s, _F_IX], slot_f[s, _F_IY], slot_f[s, _F_IZ]
            careful = slot_i[s, _I_CAREFUL] != 0
            done = False
            while True:
                if n == 0:  # a wide node: walk on into its nearest entered box
                    if root_mask > 0:
                        mask = root_mask  # (and keys hold its entries)
                        root_mask = -1
                    elif careful:
                        mask = careful_keys8(node_box, ref, ox, oy, oz, inv_dx, inv_dy,
                                             inv_dz, b, keys)
                    elif mode != NEAREST:  # (the entries unused: see below)
                        mask = box_mask8(node_box, ref, ox, oy, oz, inv_dx, inv_dy, inv_dz, b)
                    else:
                        mask = box_keys8(node_box, ref, ox, oy, oz, inv_dx, inv_dy, inv_dz,
                                         b, keys)
                    # The ordered walk (Wald et al.'s nearest child first): into the
                    # nearest entered box, the others pushed farthest first with their
                    # keys (next_box drops one when a hit nearer than it has been found
                    # meanwhile). Written out here: as an inlined function taking the
                    # arrays, the bunny's camera rays took 88 ms instead of 49 (Numba
                    # counts references to arrays handed to an inlined function).
                    if mask != 0:
                        if mask & (mask - 1) == 0:
                            # Most nodes a random ray visits enter one box or none.
                            lane = lowest_bit(mask)
                        elif mode != NEAREST:
                            # Any hit ends an `occluded` walk, and `count` walks every
                            # entered box: the order does not matter (Embree's any-hit
                            # walk does not sort either). The lowest lane walked next.
                            # One thread, ms min of three alternating runs: count, the
                            # terrain's random rays 147.6 -> 143.4, camera rays 84.8 ->
                            # 79.9, the bunny's 110.8 -> 108.6 and 103.8 -> 101.4;
                            # occluded within 5% either way. (Packets, which fetch what
                            # they push, lost 5-13% on the terrain without their order.)
                            # Their bound never shrinks, so every box pushed is walked:
                            # no entry is kept, nor compared when it is popped.
                            lane = lowest_bit(mask)
                            rest = mask & (mask - 1)
                            while rest != 0:
                                other = lowest_bit(rest)
                                rest &= rest - 1
                                stack_ref[top] = node_link[ref, REF + other]
                                stack_count[top] = node_link[ref, COUNT_AT + other]
                                top += 1
                        else:
                            # The walk goes on into the nearest entered lane as soon
                            # as it is known; the others' keys are ordered for the
                            # stack meanwhile, nearest first in keys[1 .. m].
                            m = bit_count(mask) - 1  # the entered lanes pushed
                            if m == 1:  # two: one comparison
                                near = keys[lowest_bit(mask)]
                                far = keys[lowest_bit(mask & (mask - 1))]
                                keys[1] = max(near, far)
                                lane = min(near, far) & 7
                            else:
                                lane = min_key8(keys) & 7
                                # sort_keys8: a sorting network without branches. The
                                # entered lanes lead (a missed lane sorts last, at +inf).
                                sort_keys8(keys)
                            for j in range(m, 0, -1):
                                stack_ref[top] = node_link[ref, REF + (keys[j] & 7)]
                                stack_count[top] = node_link[ref, COUNT_AT + (keys[j] & 7)]
                                stack_t[top] = keys[j]
                                top += 1
                        ref, n = (np.int64(node_link[ref, REF + lane]),
                                  np.int64(node_link[ref, COUNT_AT + lane]))
                        if interleave and (n != 0 or ref >= HOT_NODES):
                            break
                        continue
                else:  # a leaf: slots ref .. ref + n - 1
                    dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
                    if slot_i[s, _I_FRAMED] == 0:
                        # Made at the first leaf: three of four random rays at the bunny
                        # reach none.
                        (slot_i[s, _I_KX], slot_i[s, _I_KY], slot_i[s, _I_KZ],
                         slot_f[s, _F_SX], slot_f[s, _F_SY], slot_f[s, _F_SZ],
                         slot_f[s, _F_OKX], slot_f[s, _F_OKY], slot_f[s, _F_OKZ]) = ray_frame(
                            ox, oy, oz, dx, dy, dz)
                        slot_i[s, _I_FRAMED] = 1
                    kx, ky, kz = slot_i[s, _I_KX], slot_i[s, _I_KY], slot_i[s, _I_KZ]
                    sx, sy, sz = slot_f[s, _F_SX], slot_f[s, _F_SY], slot_f[s, _F_SZ]
                    okx, oky, okz = slot_f[s, _F_OKX], slot_f[s, _F_OKY], slot_f[s, _F_OKZ]
                    t0 = t_min[i if per_ray[0] else 0]
                    t1 = t_max[i if per_ray[1] else 0]
                    for quad in range(ref, ref + n, 4):
                        # The watertight test four triangles at once, then the scalar one on
                        # the few that pass its first check (leaf_filter4).
                        m = min(4, ref + n - quad)
                        tests += m
                        left = leaf_filter4(tris, quad, m, okx, oky, okz, kx, ky, kz, sx, sy)
                        while left != 0:
                            k = quad + lowest_bit(left)
                            left &= left - 1
                            t, u, v, w = _intersect(tris, k, okx, oky, okz, kx, ky, kz, sx, sy,
                                                    sz, cull_code, front_ccw, dx, dy, dz)
                            if not ((t0 <= t) & (t <= t1)):
                                continue
                            if mode == ANY:
                                slot_i[s, _I_COUNT] = 1
                                done = True
                                break
                            if mode == COUNT:
                                if (u != 0.0 and v != 0.0 and w != 0.0) or _owns(
                                        tris, k, okx, oky, okz, kx, ky, kz, sx, sy):
                                    slot_i[s, _I_COUNT] += 1
                                continue
                            f = leaf_face[k]
                            if raster is not None:
                                rank = raster[3]
                                zc0, zc1, wc0, wc1 = _clip_zw(rank, ox, oy, oz, dx, dy, dz)
                                z = _depth32(t, zc0, zc1, wc0, wc1, rank[8], rank[9])
                                if _ranks_before(z, f, slot_f[s, _F_Z], slot_i[s, _I_FACE],
                                                 raster[2]):
                                    slot_f[s, _F_T], slot_f[s, _F_U], slot_f[s, _F_V] = t, v, w
                                    slot_f[s, _F_Z] = z
                                    slot_i[s, _I_FACE], slot_i[s, _I_SLOT] = f, k
                                    b = _t_bound(t, z, zc0, zc1, wc0, wc1, rank)
                                continue
                            if t < slot_f[s, _F_T] or (t == slot_f[s, _F_T]
                                                       and f < slot_i[s, _I_FACE]):
                                slot_f[s, _F_T], slot_f[s, _F_U], slot_f[s, _F_V] = t, v, w
                                slot_i[s, _I_FACE], slot_i[s, _I_SLOT] = f, k
                                b = t
                        if done:
                            break
                    if done:
                        break
                if mode == NEAREST:
                    ref, n, top, walking = next_box(stack_ref, stack_count, stack_t, top, b,
                                                    s * one_stack)
                else:
                    walking = top > s * one_stack
                    if walking:
                        top -= 1
                        ref, n = np.int64(stack_ref[top]), np.int64(stack_count[top])
                if not walking:
                    done = True
                    break
                if interleave and (n != 0 or ref >= HOT_NODES):
                    break
            if not done:  # the next step reads memory likely not in cache: fetch it
                slot_i[s, _I_REF], slot_i[s, _I_N], slot_i[s, _I_TOP] = ref, n, top
                slot_f[s, _F_BOUND] = b
                _fetch_box(node_box, tris, leaf_face, ref, n, mode == NEAREST)
                continue
            # The ray's answer; out_object holds the hit's slot until the pass below.
            # (Written out here: as a function taking the arrays, even inlined, it took
            # 70 ns a ray.)
            if mode == NEAREST:
                out_t[i] = slot_f[s, _F_T]
                out_face[i] = slot_i[s, _I_FACE]
                out_object[i] = slot_i[s, _I_SLOT]
                out_uv[i, 0], out_uv[i, 1] = slot_f[s, _F_U], slot_f[s, _F_V]
                if records:
                    if slot_i[s, _I_SLOT] >= 0:
                        hit_rays[n_hits] = i
                        n_hits += 1
                    else:
                        out_normal[i, 0] = out_normal[i, 1] = out_normal[i, 2] = 0.0
            else:
                out_count[i] = slot_i[s, _I_COUNT]
            slot_i[s, _I_RAY] = -1
            busy -= 1
        if busy == 0 and next_ray == hi:
            break
    # Each hit's object and normal, in a pass of its own: inside the walk's loop this
    # code made the walk of random rays at the bunny 15% slower. The pass goes over the
    # hits alone (listed as their walks ended; a miss's normal is written there): over
    # every ray, a branch a ray that random rays (one in nine a hit at the bunny)
    # mispredicted, it took 3 of the bunny's 52 ms. One thread, 1M random rays, cast,
    # ms min of alternating runs: the bunny 55.2 -> 53.0, the 1M-face terrain 72.8 ->
    # 69.5 (averages of four).
    if records:
        for j in range(n_hits):
            # The corners of the hit RECORD_AHEAD hits on are fetched meanwhile: rays
            # that each hit a triangle of their own find it out of cache by now.
            if j + RECORD_AHEAD < n_hits:
                ahead = out_object[hit_rays[j + RECORD_AHEAD]]
                prefetch(tris, ahead, 0)
                prefetch(tris, ahead, 9 * tris.itemsize - 1)
            i = hit_rays[j]
            _hit_record(tris, out_object[i], out_face[i], face_offsets, out_object, out_normal,
                        i)
    return tests, 0, -1


@njit(cache=True, nogil=True, error_model="numpy")
def trace_packets(lo, hi, origins, directions, t_min, t_max, mode, raster, tris, leaf_face,
                  node_box, node_link, root_ref, root_count, wide_depth, face_offsets, out_t,
                  out_face, out_object, out_uv, out_normal, out_count):
    """:func:`trace_range` four rays at a time: a packet (Wald, Slusallek, Benthin and
    Wagner 2001) walks the boxes that any of its rays enters, each box tested for the
    four rays at once (:func:`hsr.algorithms.simd.packet_keys8`) and each ray
    carried down only into boxes it enters before its own bound; at a leaf each
    walking ray runs the one-ray triangle test. For coherent rays (from one eye, close
    directions) the four walks are nearly one, and a node read serves four rays.

    The results are those of :func:`trace_range`, bit for bit: a ray walks every box
    it enters before its bound (the union walk only adds boxes, whose triangles it
    tests to no effect on a result that depends on the set of hits, not their order),
    its entries are the one-ray test's numbers, and ties go to the lower face id.

    Four rays from one origin (a camera's, from its eye) share what their tests share:
    the node's bounds less the origin (:func:`hsr.algorithms.simd.packet_keys8_shared`)
    and, along the same permuted axes, a leaf's corners less it
    (:func:`hsr.algorithms.simd.leaf_filter4_rays`), with the same arithmetic, so the
    same answers (one thread, 1M rays, ms min of alternating runs, each step: the
    bunny's filling rays 88 -> 84-85 -> 77-79, its framed view 51 -> 48-49 -> 46-47,
    the 1M terrain's filling rays 181-183 -> 174-177 -> 171-175)."""
    cull_code, front_ccw = (0, True) if raster is None else (raster[0], raster[1])
    # Views without reference counts (the caller holds the arrays): the triangle test,
    # inlined at each hit, took a count of the corners' array each time, two atomic
    # instructions that wait for the reads in flight. One thread, the ray caster's
    # frames, ms min of alternating processes: the 1M terrain filling 1024x1024 205 ->
    # 192, the bunny's close view 80 -> 75 (with the ranking as a tuple of floats,
    # window_ranking); RayScene's packets unchanged (171.5 / 172.9 at the terrain).
    tris, leaf_face = borrowed(tris), borrowed(leaf_face)
    node_box, node_link = borrowed(node_box), borrowed(node_link)
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
            plausible &= _plausible(origins, directions, t_min, t_max, i, per_ray)
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
            # A ray past the end enters nothing (every entry is >= 0).
            bound[r] = min(frame[10, r], LARGEST) if first + r < hi else -1.0
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
                            pushed = keys[j] & 7
                            stack_ref[top] = node_link[ref, REF + pushed]
                            stack_count[top] = node_link[ref, COUNT_AT + pushed]
                            # A box pushed is often walked next by another of the
                            # packet's rays: its memory is fetched now, while the nearest
                            # is walked (one thread, ms min of 4 alternating runs: a 1M
                            # terrain's filling rays 198 -> 186, its camera rays 46.8 ->
                            # 43.3; the bunny's 50.7 -> 49.9; in trace_range, whose rays
                            # walk alone, it lost on the terrain's rays).
                            if stack_count[top] > 0 or stack_ref[top] >= HOT_NODES:
                                _fetch_box(node_box, tris, leaf_face, stack_ref[top],
                                           stack_count[top], mode == NEAREST)
                            stack_rays[top] = (mask >> (4 * pushed)) & 15
                            stack_t[top, 0] = entries[0, pushed]
                            stack_t[top, 1] = entries[1, pushed]
                            stack_t[top, 2] = entries[2, pushed]
                            stack_t[top, 3] = entries[3, pushed]
                            top += 1
                    active = (mask >> (4 * lane)) & 15
                    ref, n = (np.int64(node_link[ref, REF + lane]),
                              np.int64(node_link[ref, COUNT_AT + lane]))
                    continue
            else:  # a leaf: each walking ray tests its triangles
                if not framed:
                    # The rays' frames for the triangle test, made at the packet's first
                    # leaf: a camera's rays past a model's outline mostly reach none (1M
                    # rays that all miss a 1M-face terrain, one thread: 20.3 -> 17.1 ms).
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
                for quad in range(ref, ref + n, 4):
                    m = min(4, ref + n - quad)
                    if one_frame:
                        lefts = leaf_filter4_rays(tris, quad, m, frame, axes)
                    for r in range(4):
                        if not (active >> r) & 1 or (mode == ANY and count[r] != 0):
                            continue
                        kx, ky, kz = axes[0, r], axes[1, r], axes[2, r]
                        sx, sy, sz = frame[0, r], frame[1, r], frame[2, r]
                        okx, oky, okz = frame[3, r], frame[4, r], frame[5, r]
                        t0, t1 = frame[9, r], frame[10, r]
                        tests += m
                        if one_frame:
                            left = (lefts >> (4 * r)) & 15
                        else:
                            left = leaf_filter4(tris, quad, m, okx, oky, okz, kx, ky, kz, sx,
                                                sy)
                        while left != 0:
                            k = quad + lowest_bit(left)
                            left &= left - 1
                            t, u, v, w = _intersect(tris, k, okx, oky, okz, kx, ky, kz, sx, sy,
                                                    sz, cull_code, front_ccw, frame[6, r],
                                                    frame[7, r], frame[8, r])
                            if not ((t0 <= t) & (t <= t1)):
                                continue
                            if mode == ANY:  # done: this ray enters no box any more
                                count[r] = 1
                                bound[r] = -1.0
                                best_k[r] = k  # (where the next packet's rays land)
                                break
                            if mode == COUNT:
                                if (u != 0.0 and v != 0.0 and w != 0.0) or _owns(
                                        tris, k, okx, oky, okz, kx, ky, kz, sx, sy):
                                    count[r] += 1
                                continue
                            f = leaf_face[k]
                            if raster is not None:
                                rank = raster[3]
                                zc0, zc1, wc0, wc1 = _clip_zw(rank, rays[0, r], rays[1, r],
                                                              rays[2, r], frame[6, r], frame[7, r],
                                                              frame[8, r])
                                z = _depth32(t, zc0, zc1, wc0, wc1, rank[8], rank[9])
                                if _ranks_before(z, f, best_z[r], best_f[r], raster[2]):
                                    best_t[r], best_z[r], best_f[r], best_k[r] = t, z, f, k
                                    best_uv[r, 0], best_uv[r, 1] = v, w
                                    bound[r] = _t_bound(t, z, zc0, zc1, wc0, wc1, rank)
                                continue
                            if t < best_t[r] or (t == best_t[r] and f < best_f[r]):
                                best_t[r], best_f[r], best_k[r] = t, f, k
                                best_uv[r, 0], best_uv[r, 1] = v, w
                                bound[r] = t
            # The next box on the stack that one of its rays still enters before that
            # ray's bound, walked by those rays.
            walking = False
            while top > 0:
                top -= 1
                keep = 0
                for r in range(4):
                    if (stack_rays[top] >> r) & 1 and stack_t[top, r] <= bound[r]:
                        keep |= 1 << r
                if keep != 0:
                    ref, n, active = stack_ref[top], stack_count[top], np.int64(keep)
                    walking = True
                    break
        if mode != COUNT and best_k[3] >= 0:  # see PACKET_FETCH_AROUND
            around = max(best_k[3] - PACKET_FETCH_AROUND, 0)
            for offset in range(0, 2 * PACKET_FETCH_AROUND * 9 * tris.itemsize, 64):
                prefetch(tris, around, offset)
        for r in range(min(4, hi - first)):
            i = first + r
            if mode != NEAREST:
                out_count[i] = count[r]
                continue
            out_t[i] = best_t[r]
            out_face[i] = best_f[r]
            out_uv[i, 0], out_uv[i, 1] = best_uv[r, 0], best_uv[r, 1]
            if raster is None:
                _hit_record(tris, best_k[r], best_f[r], face_offsets, out_object, out_normal,
                            i)
    return tests, 0, -1


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


def window_ranking(view_proj, depth_range) -> tuple:
    """The ray caster's ranking (``raster[3]`` of :func:`trace_range`) for the rays of
    pixels (NDC x, y in [-1, 1]) to the far plane (t = 1), from the near plane (t = 0)
    or from the eye (the near plane at t = near / far; :func:`tie_reach` holds for both),
    11 floats: rows 2 and 3 of ``view_proj`` (the ray's clip z and w), the scale and offset that
    take NDC depth to window depth for glDepthRange ``depth_range`` (near, far), and
    the rays' tie reach (:func:`tie_reach`)."""
    near, far = depth_range
    scale = 0.5 * (far - near)
    # A tuple of floats, not an array: a walk that binds an array from its ``raster``
    # tuple, or hands one to an inlined helper, counts a reference to it each time, two
    # atomic instructions; once a hit, they were 5-6% of the 1M-face terrain's filling
    # frame in a profile (one thread).
    return tuple(float(x) for x in np.concatenate([
        np.asarray(view_proj, dtype=np.float64)[2:4].ravel(),
        [scale, 0.5 * (far + near), tie_reach(view_proj, scale)]]))


# Window depths (float32, in [0, 1] between the near and far planes) that round to
# the same float32, or the wrong way round, are less than one float32 step apart (at
# most 2**-23 in [0, 1]) plus the float64 rounding of computing them (~1e-15): four
# steps bound that with room to spare.
DEPTH_TIE = 2.0 ** -21
# The largest tie reach used (far / near beyond about 100): past it, solving for the
# next float32 depth at each hit prunes boxes better.
REACH_MAX = 1e-4


def tie_reach(view_proj, depth_scale) -> float:
    """How far past a hit (in t, on [0, 1]) another hit of the same pixel ray can still
    rank before it or tie (window depths within :data:`DEPTH_TIE`), for every pixel ray
    of ``view_proj``; NaN when that bound does not hold or exceeds :data:`REACH_MAX`
    (then :func:`_t_bound` solves at each hit).

    A pixel ray runs from NDC (x, y, -1) to (x, y, 1): in clip space from l0 (x, y, -1, 1)
    to l1 (x, y, 1, 1), l0 and l1 its clip w at the two planes, so along it clip w is
    W(t) = l0 + t (l1 - l0) and clip z Z(t) = -l0 + t (l1 + l0): two of its points
    differ in window depth ``scale Z / W + offset`` by ``scale (t' - t) K / (W(t)
    W(t'))`` with K = W(0) Z' - Z(0) W' = 2 l0 l1 (Z' and W' the slopes).
    A step D solves to ``t' - t = a W(t) / (1 - a (l1 - l0))``, ``a = D W(t) / (scale
    K)``; with ``a |l1 - l0| <= 1/2`` that is at most ``2 a W(t)``, so at most
    ``D / scale * max(l0, l1) / min(l0, l1)`` (``a |l1 - l0|`` is at most half of that,
    far below 1/2 for any reach kept). The ratio l1 / l0 is a ratio of affine
    functions of (x, y) (1 / l is row 3 of the inverse of ``view_proj`` times the NDC
    point), so its largest value either way is at a corner of the image. A perspective
    ray from the eye instead (the ray caster's) reaches the near plane at t0 = near /
    far, and the point at t above lies at t0 + (1 - t0) t on it: the same depth step
    spans less of it, and the reach holds."""
    if not depth_scale > 0.0:
        return np.nan
    try:
        inverse_w = np.linalg.inv(np.asarray(view_proj, dtype=np.float64))[3]
    except np.linalg.LinAlgError:
        return np.nan
    corners = np.array([[x, y] for x in (-1.0, 1.0) for y in (-1.0, 1.0)])
    near_w = 1.0 / (corners @ inverse_w[:2] - inverse_w[2] + inverse_w[3])
    far_w = 1.0 / (corners @ inverse_w[:2] + inverse_w[2] + inverse_w[3])
    if not (np.all(near_w > 0.0) and np.all(far_w > 0.0) and np.all(np.isfinite(near_w))
            and np.all(np.isfinite(far_w))):
        return np.nan
    ratio = float(np.max(np.maximum(far_w / near_w, near_w / far_w)))
    # (1 + 1e-6): the walk's clip w and z come from the rays as made, to float64 rounding.
    reach = DEPTH_TIE / depth_scale * ratio * (1.0 + 1e-6) + 1e-12
    return reach if reach <= REACH_MAX else np.nan


@njit(cache=True, nogil=True, inline="always")
def _clip_zw(rank, ox, oy, oz, dx, dy, dz):
    """(zc0, zc1, wc0, wc1): clip z and w along the ray are zc0 + t zc1 and wc0 + t wc1
    (both linear in t)."""
    zc0 = rank[0] * ox + rank[1] * oy + rank[2] * oz + rank[3]
    zc1 = rank[0] * dx + rank[1] * dy + rank[2] * dz
    wc0 = rank[4] * ox + rank[5] * oy + rank[6] * oz + rank[7]
    wc1 = rank[4] * dx + rank[5] * dy + rank[6] * dz
    return zc0, zc1, wc0, wc1


@njit(cache=True, nogil=True, inline="always")
def _depth32(t, zc0, zc1, wc0, wc1, depth_scale, depth_offset):
    """float32 window depth of the point at parameter t of the ray."""
    return np.float32((zc0 + t * zc1) / (wc0 + t * wc1) * depth_scale + depth_offset)


@njit(cache=True, nogil=True, inline="always")
def _t_bound(t, z, zc0, zc1, wc0, wc1, rank):
    """The ray parameter past which no hit can rank before the hit at ``t`` (float32
    window depth ``z``) nor tie with it (window depth grows monotonically along the
    ray): ``t`` plus the rays' tie reach (:func:`tie_reach`, ``rank[10]``), else past
    the next float32 above ``z``. With the reach only an add waits on the hit, where
    solving takes two divisions after the depth's own, and the walk's next step waits
    on the bound: the packet walk of the 1M-face terrain filling 1024x1024, one thread,
    208.1 -> 201.1 ms (the median of five alternating runs' minimums; 188 without
    ranking)."""
    reach, depth_scale, depth_offset = rank[10], rank[8], rank[9]
    if reach == reach:
        return min(1.0, t * (1.0 + 1e-9) + reach)
    if depth_scale == 0.0:
        return 1.0
    # next_float32, not np.nextafter, which calls libm (0.7% of a 1M-face terrain's
    # frame in a profile; no change measured in the walk's time): the same float32 for
    # every finite z.
    z_next = next_float32(z, True)
    zn = (np.float64(z_next) - depth_offset) / depth_scale
    denom = zn * wc1 - zc1
    if denom == 0.0:
        return 1.0
    solved = (zc0 - zn * wc0) / denom
    # Past the far plane (z rounded up to the far plane's depth when far / near is
    # large) the solution can cross the pole of the depth map and come out before the
    # hit; NaN for a degenerate ray: no pruning then.
    return min(1.0, solved * (1.0 + 1e-9) + 1e-12) if solved >= t else 1.0


@njit(cache=True, nogil=True, inline="always")
def _ranks_before(z, f, best_z, best_f, lequal):
    """Whether a hit of window depth ``z`` on face ``f`` beats the best so far as the
    z-buffer decides (no best yet: ``best_f`` < 0): nearer, or as near and drawn later
    under GL_LEQUAL (earlier under GL_LESS, where the first drawn stays)."""
    return best_f < 0 or z < best_z or (z == best_z and (f > best_f if lequal else f < best_f))


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
    nx, ny, nz = face_normal(tris, k)
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    out_normal[i, 0], out_normal[i, 1], out_normal[i, 2] = nx / norm, ny / norm, nz / norm


@njit(cache=True, nogil=True)
def check_rays(lo, hi, origins, directions, t_min, t_max):
    """(problem, ray) of the first bad ray of ``lo .. hi - 1``, (0, -1) when all are
    good (``t_min`` / ``t_max`` per ray, or length 1 for all). Problems: 1 an origin
    not finite, 2 a direction not finite, 3 a zero direction, 4 t_min NaN or infinite,
    5 t_max NaN, 6 t_min < 0, 7 t_min > t_max. A test with a branch per check (10 ms a
    million rays): the walks call it only for rays :func:`_plausible` flags."""
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
def _plausible(origins, directions, t_min, t_max, i, per_ray):
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

