"""The interleaved walk (:func:`trace_range`): arbitrary rays ``origin + t * direction``
with ``t`` in ``[t_min, t_max]`` (units of the direction's length, as Embree and Open3D
count them) against the 8-wide tree, a few rays per thread in turn so that their waits on
memory overlap. The nearest hit, any hit, or the count of hits (:mod:`.hits`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import (
    bit_count,
    borrowed,
    box_keys8,
    box_mask8,
    leaf_test4,
    lowest_bit,
    min_key8,
    sort_keys8,
)
from .boxes import box_bound, box_frame, box_reach, careful_keys8, inverse_direction
from .hits import (
    ANY,
    COUNT,
    FIRST,
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
from .layout import HOT_NODES, LANES, QUAD, child, fetch_links, leaf_base, nowrap, quad_lanes
from .ranking import clip_zw, depth32, ranks_before, t_bound
from .stack import bound_key, next_box, stack_size, walk_stack
from .triangle import culled, ray_frame

__all__ = ["SLOTS", "INTERLEAVE_BY_VENDOR", "INTERLEAVE_BYTES", "interleave_bytes",
           "trace_range"]

# Rays one thread walks at once (trace_range): a walk is a chain of memory reads, each
# waiting on the one before, and past the cache each costs a trip to the last-level
# cache or memory; with eight walks in turn, eight such trips overlap.
SLOTS = 8

# Scenes whose corners and nodes fit in this are walked a ray at a time, to its end:
# their reads come from the cache, and switching rays costs more than it hides. Where
# that stops holding is the CPU family's (its caches' latency), measured on each; others
# take the first. (Measurements: docs/history.md, "Ray core".)
INTERLEAVE_BY_VENDOR = {"AuthenticAMD": 8 << 20, "GenuineIntel": 4 << 20}


def interleave_bytes(cpuinfo: str = "/proc/cpuinfo") -> int:
    """:data:`INTERLEAVE_BY_VENDOR`'s threshold for this machine's CPU (its ``vendor_id``
    in ``cpuinfo``), the AMD one where the vendor is not listed or cannot be read."""
    try:
        with open(cpuinfo) as fh:
            vendor = next((line.split(":", 1)[1].strip() for line in fh
                           if line.startswith("vendor_id")), "")
    except OSError:
        vendor = ""
    return INTERLEAVE_BY_VENDOR.get(vendor, INTERLEAVE_BY_VENDOR["AuthenticAMD"])


# This machine's (a constant of the compiled walk; Numba's cache is per CPU).
INTERLEAVE_BYTES = interleave_bytes()

# The columns of trace_range's slot state: float64 ...
(_F_OX, _F_OY, _F_OZ, _F_IX, _F_IY, _F_IZ, _F_SX, _F_SY, _F_SZ, _F_OKX, _F_OKY, _F_OKZ,
 _F_BOUND, _F_T, _F_U, _F_V, _F_Z, _F_PAD, _F_COLUMNS) = range(19)

# ... and int64 (_I_SLOT: the BVH slot of the best hit, _I_FACE its face).
(_I_RAY, _I_REF, _I_N, _I_TOP, _I_FACE, _I_SLOT, _I_COUNT, _I_FRAMED, _I_CAREFUL, _I_KX,
 _I_KY, _I_KZ, _I_LIMIT, _I_COLUMNS) = range(14)


# error_model "numpy": IEEE division, without the zero test Numba adds to each division
# under Python's rules (every divisor in the walks is non-zero or checked first).
@njit(cache=True, nogil=True, error_model="numpy")
def trace_range(lo, hi, origins, directions, t_min, t_max, mode, raster, tris, leaf_face,
                node_box, node_link, root_ref, root_count, wide_depth, face_offsets, out_t,
                out_face, out_object, out_uv, out_normal, out_count, lists=None):
    """Rays ``lo .. hi - 1`` through the 8-wide BVH of :func:`hsr.algorithms.bvh.collapse.widen`
    in the layout of :func:`hsr.algorithms.bvh.layout.node_records` (the root a wide node
    when ``root_count`` is 0, else a leaf of ``root_count`` slots from ``root_ref``).
    ``mode`` :data:`~hsr.algorithms.bvh.hits.NEAREST` writes ``out_t`` (+inf on a miss),
    ``out_face`` (-1), ``out_object`` (the instance whose faces start at or before the face
    in ``face_offsets``; -1), ``out_uv`` (the weights of corners 1 and 2) and ``out_normal``
    (the unit geometric normal as wound; 0); :data:`~hsr.algorithms.bvh.hits.ANY` writes
    ``out_count`` 1 or 0, stopping at the first hit; :data:`~hsr.algorithms.bvh.hits.COUNT`
    writes the number of hits in ``out_count``. :data:`~hsr.algorithms.bvh.hits.ALL` lists
    the hits that COUNT counts, nearest first, given ``lists``, the lists' offsets ((N + 1,)
    int64, ray i's list ``lists[i] .. lists[i + 1] - 1``, as long as its count): ``out_t``,
    ``out_face``, ``out_object``, ``out_uv`` and ``out_normal`` then hold one row per
    listed hit; :data:`~hsr.algorithms.bvh.hits.FIRST` the same into shorter lists, each
    ray's nearest hits. (``lists`` is None for the other queries: Numba compiles the two
    kinds apart, as it does ``raster``, and the other queries carry none of the lists'
    code.) ``t_min`` / ``t_max``: one value per ray, or
    one for all (length 1). Equal nearest distances go to the lower face id, so the answer
    does not depend on the walk (nor on how rays are split between threads). ``raster`` is
    None for these queries. The ray caster's walks pass ``(cull_code, front_ccw, lequal,
    rank)`` with mode NEAREST (``out_t``, ``out_face`` and ``out_uv`` written): hits are
    culled by facing as glCullFace does (cull code 0 none, 1 back, 2 front, 3 both) and
    ranked as the z-buffer ranks fragments, by float32 window depth (``rank``:
    :func:`hsr.algorithms.bvh.ranking.window_ranking`), equal depths by submission order
    (the later face under GL_LEQUAL, else the earlier). Numba compiles the two kinds apart
    (``raster is None`` is decided when compiling), so the queries' walks carry none of the
    ray caster's code.

    Each ray is checked as its walk starts (:func:`hsr.algorithms.bvh.hits.check_rays`, in
    ray order); returns ``(tests, problem, ray)``: the triangle tests made, or the first bad
    ray's problem and index, the rays before it traced and none after.

    Each ray's walk is ordered, nearest entered box first (the step at a wide node is
    written out below; :func:`hsr.algorithms.bvh.stack.next_box` pops), pruned by the
    nearest hit so far (``mode`` NEAREST), by ``t_max`` otherwise. :data:`SLOTS` rays are
    walked in turn, each with its own stack and state: when a ray's next step reads a leaf's
    corners or a wide node past the top of the tree
    (:data:`hsr.algorithms.bvh.layout.HOT_NODES`), that memory is prefetched
    (:func:`hsr.algorithms.simd.prefetch`) and the next ray takes a step, so the reads of
    several walks are under way at once instead of one after another (the interleaving of
    independent pointer chases of Kocberber et al. 2015, "Asynchronous memory access
    chaining"). In a scene of at most :data:`INTERLEAVE_BYTES` of corners and nodes, whose
    reads come from the cache, each ray walks to its end before the next one starts. Each
    ray's steps are those of its walk alone (a range of one ray), so are its answers. A ray
    that enters none of the root's boxes is answered as it is read, without taking a slot.
    (Coherent rays that are many for the triangles, a camera's pixels, go through
    :func:`trace_packets` instead, as :func:`hsr.algorithms.bvh.choice.choose_walk`
    decides.)"""
    cull_code, front_ccw = (0, True) if raster is None else (raster[0], raster[1])
    # Views without reference counts, as in trace_packets (none were left in this walk's
    # loop for the queries, in a profile; the ray caster's ranking had them).
    tris, leaf_face = borrowed(tris), borrowed(leaf_face)
    node_box, node_link = borrowed(node_box), borrowed(node_link)
    # (The outputs too: see trace_packets.)
    out_t, out_face, out_object = borrowed(out_t), borrowed(out_face), borrowed(out_object)
    out_uv = borrowed(out_uv)
    interleave = tris.size * tris.itemsize + node_box.size * node_box.itemsize > (
        INTERLEAVE_BYTES)
    per_ray = t_min.shape[0] > 1, t_max.shape[0] > 1
    one_stack = stack_size(wide_depth)
    stack_ref, stack_count, stack_t = walk_stack(wide_depth, SLOTS)
    keys = np.empty(LANES, dtype=np.int32)  # a node's entry keys (box_keys8)
    quad = np.empty((5, QUAD))  # a leaf test's values (leaf_test4)
    # The largest magnitude of the boxes' bounds, for the float32 box test's pad.
    reach = box_reach(node_box, root_ref) if root_count == 0 else 0.0
    # Each slot's state, in two arrays (one per type; columns named by the _F_* and
    # _I_* constants): the ray (-1: none), where its walk stands, its bound, best hit
    # and hit count, its origin and inverse direction for the box tests, and the
    # triangle test's frame (ray_frame), made at its first leaf.
    slot_f = np.empty((SLOTS, _F_COLUMNS))
    slot_i = np.full((SLOTS, _I_COLUMNS), -1, dtype=np.int64)
    # ... and the ray in float32 for the box tests (box_frame): origin x, y, z, inverse
    # direction x, y, z, pad, and the bound as the test takes it (box_bound; _I_LIMIT
    # holds it as the stack's key, bound_key): both change only with the bound, at a
    # hit, so are made once a leaf.
    slot_box = np.empty((SLOTS, 8), dtype=np.float32)
    tests = 0
    # The queries' nearest hits get an object and a normal as their walks end.
    records = mode == NEAREST and raster is None
    next_ray, busy = lo, 0
    if leaf_face.shape[0] == 0:  # no faces: every ray misses
        for i in range(lo, hi):
            at = nowrap(i)
            if mode == NEAREST:
                out_t[at], out_face[at], out_object[at] = np.inf, -1, -1
                out_uv[at, 0], out_uv[at, 1] = 0.0, 0.0
                if records:
                    out_normal[at, 0] = out_normal[at, 1] = out_normal[at, 2] = 0.0
            elif lists is None:  # (a list is empty already)
                out_count[at] = 0
        next_ray = hi
    while True:
        for s in range(SLOTS):
            i = slot_i[s, _I_RAY]
            # The root's boxes the ray this slot just took enters, when the intake tested
            # them (its keys then hold their entries); 0: none pending (a ray that
            # enters none is answered at the intake and takes no slot).
            root_mask = 0
            if i < 0:  # a free slot takes the next ray, if there is one
                while next_ray < hi:
                    i = next_ray
                    at = nowrap(i)
                    # Each ray is checked as its slot takes it: its data is read here anyway.
                    # (Measurements: docs/history.md, "Ray core".)
                    if not plausible_ray(origins, directions, t_min, t_max, i, per_ray):
                        problem, bad = check_rays(i, i + 1, origins, directions, t_min,
                                                  t_max)
                        if problem:
                            return 0, problem, bad
                    next_ray += 1
                    if lists is not None:
                        if lists[i + 1] == lists[at]:
                            i = -1  # nothing to list: the count found no hit
                            continue
                    ox, oy, oz = origins[at, 0], origins[at, 1], origins[at, 2]
                    # A ray parallel to an axis needs the slab test's NaN care (see
                    # open_slabs), one float32 cannot hold the float64 test.
                    inv_dx, inv_dy, inv_dz, careful = inverse_direction(
                        directions[at, 0], directions[at, 1], directions[at, 2])
                    ox32, oy32, oz32, ix32, iy32, iz32, pad32, pad, fits = box_frame(
                        ox, oy, oz, inv_dx, inv_dy, inv_dz, reach)
                    careful = careful or not fits
                    # No box entered beyond the bound can hold a hit that matters.
                    b = min(t_max[nowrap(i if per_ray[1] else 0)], LARGEST)
                    bound32 = box_bound(b, pad)  # (the root's test's, then the slot's)
                    # A ray that enters none of the root's boxes is answered before it takes
                    # a slot; one that enters starts its walk with this test's mask (and
                    # keys) instead of a second test.
                    # (Measurements: docs/history.md, "Ray core".)
                    if root_count != 0 or careful:
                        break
                    if mode == NEAREST:
                        root_mask = box_keys8(node_box, root_ref, ox32, oy32, oz32, ix32,
                                              iy32, iz32, pad32, bound32, keys)
                    else:
                        root_mask = box_mask8(node_box, root_ref, ox32, oy32, oz32, ix32,
                                              iy32, iz32, pad32, bound32)
                    if root_mask != 0:
                        break
                    if mode == NEAREST:
                        out_t[at], out_face[at], out_object[at] = np.inf, -1, -1
                        out_uv[at, 0], out_uv[at, 1] = 0.0, 0.0
                        if records:
                            out_normal[at, 0] = out_normal[at, 1] = out_normal[at, 2] = 0.0
                    elif lists is None:
                        out_count[at] = 0
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
                slot_box[s, 0], slot_box[s, 1], slot_box[s, 2] = ox32, oy32, oz32
                slot_box[s, 3], slot_box[s, 4], slot_box[s, 5] = ix32, iy32, iz32
                slot_box[s, 6], slot_f[s, _F_PAD] = pad32, pad
                slot_f[s, _F_BOUND] = b
                slot_box[s, 7], slot_i[s, _I_LIMIT] = bound32, bound_key(b)
                slot_f[s, _F_T], slot_f[s, _F_U], slot_f[s, _F_V] = np.inf, 0.0, 0.0
                slot_f[s, _F_Z] = np.inf
            at = nowrap(i)  # (its reads then skip the negative-index wraparound)
            ref, n, top = slot_i[s, _I_REF], slot_i[s, _I_N], slot_i[s, _I_TOP]
            b = slot_f[s, _F_BOUND]
            careful = slot_i[s, _I_CAREFUL] != 0
            bound32, limit = slot_box[s, 7], slot_i[s, _I_LIMIT]
            # (The ray's origin, inverse direction and pad are read from the slot where
            # they are used: held in locals, they were spilled and read back at each step.)
            done = False
            while True:
                if n == 0:  # a wide node: walk on into its nearest entered box
                    fetch_links(node_link, ref)
                    if root_mask != 0:
                        mask = root_mask  # (and keys hold its entries)
                        root_mask = 0
                    elif careful:
                        mask = careful_keys8(node_box, ref, slot_f[s, _F_OX],
                                             slot_f[s, _F_OY], slot_f[s, _F_OZ],
                                             slot_f[s, _F_IX], slot_f[s, _F_IY],
                                             slot_f[s, _F_IZ], b, keys)
                    elif mode != NEAREST:  # (the entries unused: see below)
                        mask = box_mask8(node_box, ref, slot_box[s, 0], slot_box[s, 1],
                                         slot_box[s, 2], slot_box[s, 3], slot_box[s, 4],
                                         slot_box[s, 5], slot_box[s, 6], bound32)
                    else:
                        mask = box_keys8(node_box, ref, slot_box[s, 0], slot_box[s, 1],
                                         slot_box[s, 2], slot_box[s, 3], slot_box[s, 4],
                                         slot_box[s, 5], slot_box[s, 6], bound32, keys)
                    # The ordered walk (Wald et al.'s nearest child first), written out here: as an
                    # inlined function taking the arrays, it paid a reference count per step.
                    # (Measurements: docs/history.md, "Ray core".)
                    if mask != 0:
                        if mask & (mask - 1) == 0:
                            # Most nodes a random ray visits enter one box or none.
                            lane = lowest_bit(mask)
                        elif mode != NEAREST:
                            # Any hit ends an `occluded` walk and `count` walks every
                            # entered box: the order does not matter (as in Embree's any-hit
                            # walk), so the lowest lane is walked next, and as their bound
                            # never shrinks every box pushed is walked: no entry key is
                            # kept.
                            # (Measurements: docs/history.md, "Ray core".)
                            lane = lowest_bit(mask)
                            rest = mask & (mask - 1)
                            while rest != 0:
                                other = lowest_bit(rest)
                                rest &= rest - 1
                                up = nowrap(top)
                                stack_ref[up], stack_count[up] = child(node_link, ref, other)
                                top += 1
                        else:
                            # The walk goes on into the nearest entered lane as soon
                            # as it is known; the others' keys are ordered for the
                            # stack meanwhile, nearest first in keys[1 .. m].
                            m = bit_count(mask) - 1  # the entered lanes pushed
                            if m == 1:  # two: one comparison
                                near = keys[nowrap(lowest_bit(mask))]
                                far = keys[nowrap(lowest_bit(mask & (mask - 1)))]
                                keys[1] = max(near, far)
                                lane = min(near, far) & 7
                            else:
                                lane = min_key8(keys) & 7
                                # sort_keys8: a sorting network without branches. The
                                # entered lanes lead (a missed lane sorts last, at +inf).
                                sort_keys8(keys)
                            for j in range(m, 0, -1):
                                up, key = nowrap(top), keys[nowrap(j)]
                                stack_ref[up], stack_count[up] = child(node_link, ref, key & 7)
                                stack_t[up] = key
                                top += 1
                        ref, n = child(node_link, ref, lane)
                        if interleave and (n != 0 or ref >= HOT_NODES):
                            break
                        continue
                else:  # a leaf: slots ref .. ref + n - 1
                    dx, dy, dz = directions[at, 0], directions[at, 1], directions[at, 2]
                    if slot_i[s, _I_FRAMED] == 0:
                        # Made at the first leaf: three of four random rays at the bunny
                        # reach none.
                        (slot_i[s, _I_KX], slot_i[s, _I_KY], slot_i[s, _I_KZ],
                         slot_f[s, _F_SX], slot_f[s, _F_SY], slot_f[s, _F_SZ],
                         slot_f[s, _F_OKX], slot_f[s, _F_OKY], slot_f[s, _F_OKZ]) = ray_frame(
                            slot_f[s, _F_OX], slot_f[s, _F_OY], slot_f[s, _F_OZ], dx, dy, dz)
                        slot_i[s, _I_FRAMED] = 1
                    kx, ky, kz = slot_i[s, _I_KX], slot_i[s, _I_KY], slot_i[s, _I_KZ]
                    sx, sy, sz = slot_f[s, _F_SX], slot_f[s, _F_SY], slot_f[s, _F_SZ]
                    okx, oky, okz = slot_f[s, _F_OKX], slot_f[s, _F_OKY], slot_f[s, _F_OKZ]
                    t0 = t_min[nowrap(i if per_ray[0] else 0)]
                    t1 = t_max[nowrap(i if per_ray[1] else 0)]
                    tests += n
                    end = ref + n
                    for base in range(leaf_base(tris, ref), end, QUAD):
                        # The watertight test on four slots at once (leaf_test4): the
                        # bits of those it does not rule out, and each one's values.
                        left = leaf_test4(tris, base, quad_lanes(ref, end, base), okx, oky,
                                          okz, kx, ky, kz, sx, sy, sz, quad)
                        while left != 0:
                            bit = lowest_bit(left)
                            k, lane = base + bit, nowrap(bit)
                            left &= left - 1
                            if cull_code != 0 and culled(tris, k, cull_code, front_ccw, dx,
                                                         dy, dz):
                                continue
                            det = quad[4, lane]
                            t = quad[0, lane] / det
                            if not in_interval(t, t0, t1):
                                continue
                            u, v, w = quad[1, lane] / det, quad[2, lane] / det, quad[3, lane] / det
                            if mode == ANY:
                                slot_i[s, _I_COUNT] = 1
                                done = True
                                break
                            if mode >= COUNT:  # COUNT, ALL, FIRST: each crossing once
                                if counted(u, v, w, tris, k, okx, oky, okz, kx, ky, kz, sx,
                                           sy):
                                    if lists is None:
                                        slot_i[s, _I_COUNT] += 1
                                        continue
                                    slot_i[s, _I_COUNT], b = listed(
                                        mode, t, leaf_face[nowrap(k)], v, w, k, i, lists,
                                        slot_i[s, _I_COUNT], b, out_t, out_face, out_uv,
                                        out_object)
                                    if b < 0.0:  # every hit the count found
                                        done = True
                                        break
                                continue
                            f = leaf_face[nowrap(k)]
                            if raster is not None:
                                rank = raster[3]
                                zc0, zc1, wc0, wc1 = clip_zw(
                                    rank, slot_f[s, _F_OX], slot_f[s, _F_OY], slot_f[s, _F_OZ],
                                    dx, dy, dz)
                                z = depth32(t, zc0, zc1, wc0, wc1, rank[8], rank[9])
                                if ranks_before(z, f, slot_f[s, _F_Z], slot_i[s, _I_FACE],
                                                 raster[2]):
                                    slot_f[s, _F_T], slot_f[s, _F_U], slot_f[s, _F_V] = t, v, w
                                    slot_f[s, _F_Z] = z
                                    slot_i[s, _I_FACE], slot_i[s, _I_SLOT] = f, k
                                    b = t_bound(t, z, zc0, zc1, wc0, wc1, rank)
                                continue
                            if nearer(t, f, slot_f[s, _F_T], slot_i[s, _I_FACE]):
                                slot_f[s, _F_T], slot_f[s, _F_U], slot_f[s, _F_V] = t, v, w
                                slot_i[s, _I_FACE], slot_i[s, _I_SLOT] = f, k
                                b = t
                        if done:
                            break
                    if done:
                        break
                    if mode == NEAREST or mode == FIRST:  # (a hit may have lowered the bound)
                        bound32, limit = box_bound(b, slot_f[s, _F_PAD]), bound_key(b)
                if mode == NEAREST:
                    ref, n, top, walking = next_box(stack_ref, stack_count, stack_t, top,
                                                    limit, s * one_stack)
                else:
                    walking = top > s * one_stack
                    if walking:
                        top -= 1
                        up = nowrap(top)
                        ref, n = np.int64(stack_ref[up]), np.int64(stack_count[up])
                if not walking:
                    done = True
                    break
                if interleave and (n != 0 or ref >= HOT_NODES):
                    break
            if not done:  # the next step reads memory likely not in cache: fetch it
                slot_i[s, _I_REF], slot_i[s, _I_N], slot_i[s, _I_TOP] = ref, n, top
                slot_f[s, _F_BOUND] = b
                slot_box[s, 7], slot_i[s, _I_LIMIT] = bound32, limit
                fetch_box(node_box, tris, leaf_face, ref, n,
                          mode == NEAREST or lists is not None)
                continue
            # The ray's answer, and a hit's object and normal while its corners are in
            # cache. (Written out here: as a function taking the arrays, even inlined, it
            # took 70 ns a ray. Measurements: docs/history.md, "Ray core".)
            if mode == NEAREST:
                out_t[at] = slot_f[s, _F_T]
                out_face[at] = slot_i[s, _I_FACE]
                out_uv[at, 0], out_uv[at, 1] = slot_f[s, _F_U], slot_f[s, _F_V]
                if records:
                    hit_record(tris, slot_i[s, _I_SLOT], out_face[at], face_offsets,
                               out_object, out_normal, i)
            elif lists is None:
                out_count[at] = slot_i[s, _I_COUNT]
            else:
                finish_list(i, lists, slot_i[s, _I_COUNT], out_t, out_face, out_uv,
                            out_object)
            slot_i[s, _I_RAY] = -1
            busy -= 1
        if busy == 0 and next_ray == hi:
            break
    if lists is not None:
        list_records(lists[lo], lists[hi], tris, face_offsets, out_face, out_object,
                     out_normal)
    return tests, 0, -1
