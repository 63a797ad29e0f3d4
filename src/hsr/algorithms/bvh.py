"""The bounding volume hierarchy the ray caster (:mod:`hsr.algorithms.raycast`, seed 004)
and the ray queries (:mod:`hsr.algorithms.rays`) walk, and the ray/triangle test.

- :func:`build` makes a bounding volume hierarchy (binned surface-area heuristic, flat
  arrays, built once per scene and reused across views), collapsed into a 4-wide tree
  for the walk (:func:`widen`, :func:`pack_nodes`: a node's four child boxes in one
  128-byte record, tested at once by :func:`hsr.algorithms.simd.box_entries4`);
  traversal is a stack walk, nearest entered box first, pruned by the best hit so far
  (:func:`descend`, :func:`next_box`; the walks themselves are in
  :mod:`hsr.algorithms.rays`). The triangles are stored in leaf order (a leaf's corners
  are one run of memory).

Intersection is the watertight test of Woop, Benthin & Wald (2013): the ray is made the
+z axis by a permutation and a shear, and the three 2-D edge functions are evaluated so
that an edge shared by two triangles gives exactly opposite values in both, so no ray
slips between them. The ray caster's rays run from the near plane to the far plane (the
parameter t in [0, 1]), which is exactly the depth range the rasterizer's clipping keeps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..parallel import Workers
from ..scene.mesh import Scene, SceneLike, as_scene
from .simd import SLACK, SLACK_ABS, float_bits, sorted_keys4

__all__ = ["BVH", "build", "world_triangles", "widen", "pack_nodes",
           "inverse_direction", "careful_entries4", "descend", "next_box",
           "careful_packet_entries", "stack_size", "walk_stack"]

LEAF_SIZE = 4
N_BINS = 16
# Children per node of the walked tree (the sorting network in descend is for four).
LANES = 4
# A walked node is one 128-byte record, two cache lines: 6 LANES float32 box bounds, then
# LANES int32 references and LANES int32 counts (see pack_nodes).
NODE_WORDS = 32
REF, COUNT_AT = 6 * LANES, 7 * LANES


def world_triangles(scene: Scene) -> np.ndarray:
    """(F, 3, 3) float64 world-space corners in submission order."""
    return as_scene(scene).world_triangles()


@dataclass
class BVH:
    """A bounding volume hierarchy over a scene's world-space triangles.

    As built (binary, binned SAH): node_min, node_max : (N, 3) float32 boxes (rounded
    outwards from the float64 ones the build used); node_left : (N,) int32 first child
    (the second is ``node_left + 1``) or -1 for a leaf; node_start, node_count : (N,)
    int32 a leaf's range of slots; tri_index : (T,) int32 the face id in each slot
    (degenerate faces are left out); corners : (T, 3, 3) float64 world-space corners of
    each slot's face (stored in leaf order, so a leaf's triangles are read in one run of
    memory); n_faces : the scene's face count.

    As walked: node_box (W, 32) float32 and node_link (W, 32) int32, the 4-wide tree of
    :func:`widen` in the records of :func:`pack_nodes`; the root a wide node when
    root_count is 0, else a leaf of root_count slots from root_ref; wide_depth the
    deepest wide level (it sizes the walk's stack); leaf_face, the walk's name for
    tri_index (the same array); bounds (2, 3) float64, the scene's box (lower, upper
    corner; +inf / -inf for no faces).

    Built with ``keep_tree=False`` (as :class:`hsr.RayScene` builds it), the binary
    arrays node_min .. node_count are empty: the walks read only the wide tree.
    """

    node_min: np.ndarray
    node_max: np.ndarray
    node_left: np.ndarray
    node_start: np.ndarray
    node_count: np.ndarray
    tri_index: np.ndarray
    corners: np.ndarray
    n_faces: int
    node_box: np.ndarray
    node_link: np.ndarray
    root_ref: int
    root_count: int
    wide_depth: int
    leaf_face: np.ndarray
    bounds: np.ndarray
    build_ms: float = 0.0

    @property
    def n_nodes(self) -> int:
        """Nodes of the binary tree (0 when it was not kept)."""
        return len(self.node_left)

    @property
    def n_wide_nodes(self) -> int:
        """Nodes of the walked 4-wide tree."""
        return len(self.node_box)


def build(scene: SceneLike, threads: int | None = None, keep_tree: bool = True) -> BVH:
    """Build the BVH of ``scene`` (a Scene, Mesh, ...) in world space, on ``threads``
    threads (default: numba's thread count; the tree does not depend on it).
    ``keep_tree=False`` drops the binary tree once the walked 4-wide one is made (21
    bytes a face that no walk reads).

    Raises :class:`~hsr.errors.MeshError` for something that is not a scene or mesh,
    or one of 2**31 faces or more.
    """
    import time

    from ..errors import MeshError

    t0 = time.perf_counter()
    tris = np.ascontiguousarray(world_triangles(scene))
    if len(tris) >= 2**31:  # the walk's references are int32
        raise MeshError(f"a BVH takes fewer than 2**31 faces, got {len(tris):,}")
    with Workers(threads) as workers:
        arrays = _build(tris, _with_area(tris), workers)
    node_min, node_max, node_left, node_start, node_count, tri_index = arrays
    corners = tris[tri_index]
    if node_left[0] >= 0:
        box, ref, count, depth = widen(node_min, node_max, node_left, node_start,
                                       node_count)
        root = (0, 0)
    else:  # one leaf (or none): it is the root
        box = np.full((1, 6 * LANES), np.inf, np.float32)
        ref, count, depth = np.zeros((1, LANES)), np.full((1, LANES), -1), 0
        root = (int(node_start[0]), int(node_count[0]))
    node_box, node_link = pack_nodes(box, ref, count)
    bounds = np.array([node_min[0], node_max[0]])
    # The binary tree is kept for reading, in half the bytes: its boxes in float32
    # rounded outwards (still holding what they bound), its indices in int32.
    tri_index = tri_index.astype(np.int32)
    kept = slice(None) if keep_tree else slice(0, 0)
    return BVH(_outwards32(node_min[kept], -np.inf), _outwards32(node_max[kept], np.inf),
               node_left[kept].astype(np.int32), node_start[kept].astype(np.int32),
               node_count[kept].astype(np.int32), tri_index, corners=corners,
               n_faces=len(tris), node_box=node_box, node_link=node_link, root_ref=root[0],
               root_count=root[1], wide_depth=depth, leaf_face=tri_index, bounds=bounds,
               build_ms=1e3 * (time.perf_counter() - t0))


def _outwards32(values: np.ndarray, towards: float) -> np.ndarray:
    """``values`` in float32, each rounded towards ``towards`` (-inf: down, +inf: up)
    where float32 cannot hold it exactly (beyond float32's range: to +-inf, or the
    largest float32 on the inner side)."""
    with np.errstate(over="ignore"):
        rounded = values.astype(np.float32)
    moved = rounded < values if towards > 0 else rounded > values
    rounded[moved] = np.nextafter(rounded[moved], np.float32(towards))
    return rounded


@njit(cache=True, nogil=True)
def _with_area(tris):
    """The faces whose corners span a non-zero area (the cross product of two edges is
    not the zero vector): the others cannot be hit."""
    keep = np.empty(tris.shape[0], dtype=np.int64)
    n = 0
    for f in range(tris.shape[0]):
        e1x, e1y, e1z = (tris[f, 1, 0] - tris[f, 0, 0], tris[f, 1, 1] - tris[f, 0, 1],
                         tris[f, 1, 2] - tris[f, 0, 2])
        e2x, e2y, e2z = (tris[f, 2, 0] - tris[f, 0, 0], tris[f, 2, 1] - tris[f, 0, 1],
                         tris[f, 2, 2] - tris[f, 0, 2])
        nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
        if nx * nx + ny * ny + nz * nz > 0.0:
            keep[n] = f
            n += 1
    return keep[:n].copy()


@njit(cache=True, nogil=True, inline="always")
def _down32(x):
    """The largest float32 <= x."""
    f = np.float32(x)
    if np.float64(f) > x:
        f = np.nextafter(f, np.float32(-np.inf))
    return f


@njit(cache=True, nogil=True, inline="always")
def _up32(x):
    """The smallest float32 >= x."""
    f = np.float32(x)
    if np.float64(f) < x:
        f = np.nextafter(f, np.float32(np.inf))
    return f


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
    deepest wide level. The root must be an inner node.

    Wide nodes are numbered in level order (the root, then its children, then theirs),
    a node's wide children next to each other: the first few thousand are the top of
    the tree, which every walk passes through, and :func:`hsr.algorithms.rays.trace_range`
    counts on that (``HOT_NODES``)."""
    n = node_left.shape[0]
    box = np.full((max(n, 1), 6 * LANES), np.inf, dtype=np.float32)
    ref = np.zeros((max(n, 1), LANES), dtype=np.int64)
    count = np.full((max(n, 1), LANES), -1, dtype=np.int64)
    todo_node = np.empty(n + 1, dtype=np.int64)  # binary node -> its wide node, to fill
    todo_wide = np.empty(n + 1, dtype=np.int64)
    todo_level = np.empty(n + 1, dtype=np.int64)
    todo_node[0], todo_wide[0], todo_level[0] = 0, 0, 0
    # A queue (first in, first out): level order. Each binary node enters it once.
    head, top, n_wide, depth = 0, 1, 1, 0
    kids = np.empty(LANES, dtype=np.int64)
    while head < top:
        b, w, level = todo_node[head], todo_wide[head], todo_level[head]
        head += 1
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


def pack_nodes(box, ref, count):
    """The walked layout of :func:`widen`'s tree: ``(node_box, node_link)``, two views
    of one buffer aligned to 64 bytes, each node a 128-byte record (two cache lines, one
    read brings a node's boxes and references together): ``node_box`` (W, 32) float32,
    the boxes in words 0 .. 23; ``node_link`` (W, 32) int32, the references in words
    24 .. 27 and the counts in 28 .. 31 (int32: a scene has fewer than 2**31 faces,
    which :func:`build` checks). Separate int64 arrays were three records a
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


@njit(cache=True, nogil=True, inline="always")
def inverse_direction(dx, dy, dz):
    """(1 / dx, 1 / dy, 1 / dz, careful) for the slab tests: +inf for a zero component,
    and ``careful`` when there is one (0 * inf is NaN there; see :func:`open_slabs`)."""
    return (1.0 / dx if dx != 0.0 else np.inf, 1.0 / dy if dy != 0.0 else np.inf,
            1.0 / dz if dz != 0.0 else np.inf, dx == 0.0 or dy == 0.0 or dz == 0.0)


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
    (see :func:`open_slabs`)."""
    t0x, t1x, t0y, t1y, t0z, t1z = _lane_slabs(box, w, lane, ox, oy, oz, inv_dx, inv_dy,
                                               inv_dz)
    t0x, t1x, t0y, t1y, t0z, t1z = open_slabs(t0x, t1x, t0y, t1y, t0z, t1z)
    t_in = max(min(t0x, t1x), min(t0y, t1y), min(t0z, t1z), 0.0)
    t_out = min(max(t0x, t1x), max(t0y, t1y), max(t0z, t1z))
    # The slack is that of hsr.algorithms.simd (see SLACK there).
    return t_in if t_in <= t_out * SLACK + SLACK_ABS and t_in <= bound else np.inf


@njit(cache=True, nogil=True, inline="always")
def careful_entries4(box, w, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound):
    """:func:`hsr.algorithms.simd.box_entries4` lane by lane with the NaN care of
    :func:`_careful_entry`, for rays with a zero direction component."""
    k0 = _careful_entry(box, w, 0, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound)
    k1 = _careful_entry(box, w, 1, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound)
    k2 = _careful_entry(box, w, 2, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound)
    k3 = _careful_entry(box, w, 3, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound)
    return k0, k1, k2, k3, (k0 < np.inf) | (k1 < np.inf) << 1 | (k2 < np.inf) << 2 | (
        k3 < np.inf) << 3


@njit(cache=True, nogil=True, inline="always")
def descend(k0, k1, k2, k3, mask, ref, node_link, stack_ref, stack_count, stack_t, top):
    """One step of the ordered walk at wide node ``ref``, given where the ray enters
    its four boxes (``k0 .. k3``, +inf: not before the bound) and the ``mask`` of the
    entered ones (:func:`hsr.algorithms.simd.box_entries4`, or
    :func:`careful_entries4`): ``(ref, n, top, entered)``, the child to walk next
    (``n`` 0: a wide node, else a leaf of ``n`` slots from ``ref``) and the new stack
    top, or ``entered`` False when the ray enters none of the boxes. Entered boxes
    other than the nearest are pushed farthest first with their entries as keys of
    :func:`hsr.algorithms.simd.sorted_keys4` (:func:`next_box` drops one when a hit
    nearer than it has been found meanwhile).

    (The box test stays in the calling kernel: inlined here, with the node array
    passed in, the walk of random rays at the bunny took 193 ms instead of 118.)"""
    if mask == 0:
        return ref, np.int64(0), top, False
    # Three of four nodes a random ray visits enter one box or none: no ordering.
    if mask & (mask - 1) == 0:
        lane = (mask >> 1) - (mask >> 3)  # the set bit's index
        return (np.int64(node_link[ref, REF + lane]), np.int64(node_link[ref, COUNT_AT + lane]),
                top, True)
    # The lanes nearest first (sorted_keys4: a sorting network without branches, since
    # which lanes a ray enters is what a random ray makes unpredictable). The entered
    # lanes lead (a missed lane sorts last, at +inf); the nearest is walked next and the
    # m others pushed farthest first. All three pushes are written and the top moves by
    # m, so the pushes need no branch either (the stack has LANES slots spare).
    s0, s1, s2, s3 = sorted_keys4(k0, k1, k2, k3)
    m = (mask & 1) + ((mask >> 1) & 1) + ((mask >> 2) & 1) + (mask >> 3) - 1
    # Slots top .. top + m - 1 take the m-th .. first entered lane after the nearest.
    _push(stack_ref, stack_count, stack_t, top, node_link, ref,
          s3 if m == 3 else (s2 if m == 2 else s1))
    _push(stack_ref, stack_count, stack_t, top + 1, node_link, ref, s2 if m == 3 else s1)
    _push(stack_ref, stack_count, stack_t, top + 2, node_link, ref, s1)
    lane = s0 & 3
    return (np.int64(node_link[ref, REF + lane]), np.int64(node_link[ref, COUNT_AT + lane]),
            top + m, True)


@njit(cache=True, nogil=True, inline="always")
def careful_packet_entries(box, w, rays, bound, out):
    """:func:`hsr.algorithms.simd.packet_entries4` ray by ray with the NaN care of
    :func:`_careful_entry`, for a packet holding a ray with a zero direction
    component."""
    mask = 0
    for r in range(4):
        for k in range(LANES):
            e = _careful_entry(box, w, k, rays[0, r], rays[1, r], rays[2, r], rays[3, r],
                               rays[4, r], rays[5, r], bound[r])
            out[k, r] = e
            mask |= (e < np.inf) << (4 * k + r)
    return mask


@njit(cache=True, nogil=True, inline="always")
def stack_size(wide_depth):
    """Slots of one walk's stack: each wide node walked leaves at most three siblings
    behind, plus the spare slots :func:`descend` writes."""
    return (LANES - 1) * wide_depth + 2 * LANES


@njit(cache=True, nogil=True)
def walk_stack(wide_depth, walks):
    """(references, counts, entry keys) of the stacks of ``walks`` walks, each
    :func:`stack_size` slots, one after another. Sized once per walk: an array re-bound
    inside the loop (grown on demand) costs reference counting at every step, more than
    doubling the walk's time."""
    size = walks * stack_size(wide_depth)
    return (np.empty(size, dtype=np.int64), np.empty(size, dtype=np.int64),
            np.empty(size, dtype=np.int64))


@njit(cache=True, nogil=True, inline="always")
def _push(stack_ref, stack_count, stack_t, at, node_link, ref, key):
    """Stack slot ``at``: the lane of wide node ``ref`` and its entry, as ``key`` of
    :func:`hsr.algorithms.simd.sorted_keys4` gives them."""
    lane = key & 3
    stack_ref[at] = node_link[ref, REF + lane]
    stack_count[at] = node_link[ref, COUNT_AT + lane]
    stack_t[at] = key


@njit(cache=True, nogil=True, inline="always")
def next_box(stack_ref, stack_count, stack_t, top, bound, bottom):
    """The next box still worth entering from the stack (slots ``bottom .. top - 1``;
    one array can hold several rays' stacks): ``(ref, n, top, found)``;
    boxes entered beyond ``bound`` (a hit nearer than them has been found since they
    were pushed) are dropped. The stack holds entries as keys of
    :func:`hsr.algorithms.simd.sorted_keys4`, compared with the bound's bits (bound
    + 0.0 makes a bound of -0.0 the +0.0 whose bits are the least)."""
    bound_key = float_bits(bound + 0.0)
    while top > bottom:
        top -= 1
        if stack_t[top] <= bound_key:
            return np.int64(stack_ref[top]), np.int64(stack_count[top]), top, True
    return np.int64(0), np.int64(0), top, False


def _build(tris, tri_index, workers):
    """The binary SAH tree over the slots ``tri_index`` (faces with area): (node_min,
    node_max, node_left, node_start, node_count, leaf order of the faces).

    In parallel (``workers``, :class:`hsr.parallel.Workers`): the top of the tree is
    split on one thread until every open node holds at most 1 / (4 threads) of the
    faces; those subtrees are then built on all threads at once (each in its own range
    of faces and of node numbers, so no two threads write the same place), and the node
    numbers closed up. The tree is the same as on one thread, node numbering aside.
    """
    n = len(tri_index)
    prim, order = _prims(tris, tri_index)
    max_nodes = max(1, 2 * n)
    nodes = (np.empty((max_nodes, 3)), np.empty((max_nodes, 3)),
             np.full(max_nodes, -1, dtype=np.int64), np.zeros(max_nodes, dtype=np.int64),
             np.zeros(max_nodes, dtype=np.int64))
    nodes[4][0] = n  # the root holds every slot
    cutoff = n // (4 * workers.threads) if workers.threads > 1 and n > 4096 else 0
    pending = np.empty(max_nodes, dtype=np.int64)
    # The top, on this thread: nodes of at most `cutoff` faces are left open.
    n_top, n_pending = _grow(prim, order, *nodes, 0, 1, cutoff, pending)
    pending = pending[:n_pending]
    if n_pending == 0:
        return (*(a[:n_top].copy() for a in nodes), order)
    # Subtree k (c faces: at most 2c - 1 nodes, its root already numbered among the
    # top's) numbers its new nodes from base[k].
    base = n_top + np.concatenate([[0], np.cumsum(2 * nodes[4][pending] - 2)[:-1]])
    each = np.stack([pending, base], axis=1).astype(np.int64)
    ends = np.asarray(workers.run(_grow_subtree, np.arange(n_pending + 1), prim, order,
                                  *nodes, each), dtype=np.int64)
    _close_up(nodes[2], n_top, pending, base, ends)
    keep = np.concatenate([np.arange(n_top)] + [np.arange(s, e) for s, e in zip(base, ends)])
    return (*(a[keep] for a in nodes), order)


@njit(cache=True, nogil=True)
def _prims(tris, tri_index):
    """(prim, order): each slot's box and centroid as one record [lo x3, hi x3,
    centroid x3] (partitioned in place with ``order``, so every pass of the build reads
    memory in sequence) and the slots' face ids."""
    n = tri_index.shape[0]
    prim = np.empty((n, 9))
    for k in range(n):
        t = tri_index[k]
        for a in range(3):
            lo = min(tris[t, 0, a], tris[t, 1, a], tris[t, 2, a])
            hi = max(tris[t, 0, a], tris[t, 1, a], tris[t, 2, a])
            prim[k, a], prim[k, 3 + a], prim[k, 6 + a] = lo, hi, 0.5 * (lo + hi)
    return prim, tri_index.copy()


@njit(cache=True, nogil=True)
def _grow_subtree(k, k_end, prim, order, node_min, node_max, node_left, node_start,
                  node_count, each):
    """Subtree ``k`` of :func:`_build`: node ``each[k, 0]`` split down to its leaves,
    new nodes numbered from ``each[k, 1]``. Returns the next free number."""
    root, base = each[k, 0], each[k, 1]
    end, _ = _grow(prim, order, node_min, node_max, node_left, node_start, node_count,
                   root, base, 0, np.empty(0, dtype=np.int64))
    return end


@njit(cache=True, nogil=True)
def _grow(prim, order, node_min, node_max, node_left, node_start, node_count, root,
          next_node, cutoff, pending):
    """Split node ``root`` (its slots node_start .. + node_count) and its descendants
    until leaves of at most LEAF_SIZE faces, numbering new nodes from ``next_node``;
    with ``cutoff`` > 0 a node of at most that many faces is left open and listed in
    ``pending``. Returns (next free node number, number pending)."""
    stack = [root]
    n_pending = 0
    bin_lo = np.empty((N_BINS, 3))
    bin_hi = np.empty((N_BINS, 3))
    bin_n = np.empty(N_BINS, dtype=np.int64)
    left_cost = np.empty(N_BINS)
    right_cost = np.empty(N_BINS)
    while len(stack) > 0:
        node = stack.pop()
        s, c = node_start[node], node_count[node]
        # The node's box and the box of its faces' centroids, in one pass.
        l0 = l1 = l2 = m0 = m1 = m2 = np.inf
        h0 = h1 = h2 = n0 = n1 = n2 = -np.inf
        for k in range(s, s + c):
            l0, l1, l2 = min(l0, prim[k, 0]), min(l1, prim[k, 1]), min(l2, prim[k, 2])
            h0, h1, h2 = max(h0, prim[k, 3]), max(h1, prim[k, 4]), max(h2, prim[k, 5])
            m0, m1, m2 = min(m0, prim[k, 6]), min(m1, prim[k, 7]), min(m2, prim[k, 8])
            n0, n1, n2 = max(n0, prim[k, 6]), max(n1, prim[k, 7]), max(n2, prim[k, 8])
        node_min[node, 0], node_min[node, 1], node_min[node, 2] = l0, l1, l2
        node_max[node, 0], node_max[node, 1], node_max[node, 2] = h0, h1, h2
        if c <= LEAF_SIZE:
            continue
        if c <= cutoff:
            pending[n_pending] = node
            n_pending += 1
            continue
        # Binned SAH over all three axes (Wald 2007): cost = area(L) n(L) + area(R) n(R),
        # the right sides' areas summed in one sweep from the right, the left in one
        # from the left.
        best_axis, best_split, best_cost = -1, -1, np.inf
        for a in range(3):
            c_lo = m0 if a == 0 else (m1 if a == 1 else m2)
            extent = (n0 if a == 0 else (n1 if a == 1 else n2)) - c_lo
            if extent <= 0.0:
                continue
            bin_n[:] = 0
            bin_lo[:] = np.inf
            bin_hi[:] = -np.inf
            for k in range(s, s + c):
                b = _bin_of(prim[k, 6 + a], c_lo, extent)
                bin_n[b] += 1
                for d in range(3):
                    bin_lo[b, d] = min(bin_lo[b, d], prim[k, d])
                    bin_hi[b, d] = max(bin_hi[b, d], prim[k, 3 + d])
            _sweep(bin_lo, bin_hi, bin_n, 0, 1, left_cost, 1)  # bins 0 .. split - 1
            _sweep(bin_lo, bin_hi, bin_n, N_BINS - 1, -1, right_cost, 0)  # split .. last
            for split in range(1, N_BINS):
                cost = left_cost[split] + right_cost[split]
                if cost < best_cost:
                    best_axis, best_split, best_cost = a, split, cost
        mid = s
        if best_axis >= 0:
            a = best_axis
            c_lo = m0 if a == 0 else (m1 if a == 1 else m2)
            extent = (n0 if a == 0 else (n1 if a == 1 else n2)) - c_lo
            j = s + c - 1
            while mid <= j:
                if _bin_of(prim[mid, 6 + a], c_lo, extent) < best_split:
                    mid += 1
                else:
                    order[mid], order[j] = order[j], order[mid]
                    for q in range(9):
                        prim[mid, q], prim[j, q] = prim[j, q], prim[mid, q]
                    j -= 1
        if mid == s or mid == s + c:  # no useful split: halve in index order
            mid = s + c // 2
        left = next_node
        next_node += 2
        node_left[node] = left
        node_start[left], node_count[left] = s, mid - s
        node_start[left + 1], node_count[left + 1] = mid, s + c - mid
        stack.append(left + 1)
        stack.append(left)
    return next_node, n_pending


@njit(cache=True, nogil=True)
def _close_up(node_left, n_top, pending, base, ends):
    """Renumber child references for the node arrays with the gaps between subtrees
    closed (subtree k's nodes base[k] .. ends[k] - 1 move to just after subtree
    k - 1's): those inside subtree k and its root's, ``pending[k]``."""
    start = n_top
    for k in range(base.shape[0]):
        shift = base[k] - start
        node_left[pending[k]] -= shift
        for node in range(base[k], ends[k]):
            if node_left[node] >= 0:
                node_left[node] -= shift
        start += ends[k] - base[k]


@njit(cache=True, nogil=True, inline="always")
def _bin_of(centroid, c_lo, extent):
    """The SAH bin of a centroid (the same expression wherever a bin is assigned, so the
    partition puts each triangle on the side its bin was counted on)."""
    return min(int((centroid - c_lo) / extent * N_BINS), N_BINS - 1)


@njit(cache=True, nogil=True, inline="always")
def _sweep(bin_lo, bin_hi, bin_n, first, step, cost, shift):
    """One sweep of the SAH over the bins from ``first`` by ``step`` (N_BINS - 1 of
    them): after bin b, ``cost[b + shift]`` = area x count of the union so far. From
    the left (0, 1, shift 1) that is each split's left side, from the right
    (N_BINS - 1, -1, shift 0) its right side: O(bins) per axis, not O(bins^2)."""
    count = 0
    lx = ly = lz = np.inf
    hx = hy = hz = -np.inf
    b = first
    for _ in range(N_BINS - 1):
        if bin_n[b] > 0:
            count += bin_n[b]
            lx, ly, lz = min(lx, bin_lo[b, 0]), min(ly, bin_lo[b, 1]), min(lz, bin_lo[b, 2])
            hx, hy, hz = max(hx, bin_hi[b, 0]), max(hy, bin_hi[b, 1]), max(hz, bin_hi[b, 2])
        area = 0.0
        if count > 0:
            dx, dy, dz = hx - lx, hy - ly, hz - lz
            area = (dx * dy + dy * dz + dz * dx) * count
        cost[b + shift] = area
        b += step


@njit(cache=True, nogil=True, inline="always")
def ray_frame(ox, oy, oz, dx, dy, dz):
    """The ray's frame for :func:`_intersect` (Woop, Benthin & Wald 2013): kz the axis
    of the direction's largest component, kx and ky the others (swapped when that
    component is negative, which keeps the winding), the shear (sx, sy, sz) that makes
    the ray the +z axis, and the origin's coordinates on the permuted axes."""
    ad = (abs(dx), abs(dy), abs(dz))
    kz = 0
    if ad[1] > ad[kz]:
        kz = 1
    if ad[2] > ad[kz]:
        kz = 2
    kx, ky = (kz + 1) % 3, (kz + 2) % 3
    dk = (dx, dy, dz)
    if dk[kz] < 0.0:
        kx, ky = ky, kx
    sz = 1.0 / dk[kz]
    sx, sy = dk[kx] * sz, dk[ky] * sz
    ok = (ox, oy, oz)
    return kx, ky, kz, sx, sy, sz, ok[kx], ok[ky], ok[kz]


@njit(cache=True, nogil=True, inline="always")
def open_slabs(t0x, t1x, t0y, t1y, t0z, t1z):
    """The six slab distances with each NaN made the bound that keeps its slab open
    (-inf for a low plane, +inf for a high one). 0 * inf is NaN: a ray parallel to a
    slab (inv = inf) whose origin lies on one of its planes; the box is closed, so the
    ray lies inside that slab for every t, and min and max would pass the NaN on or
    drop it depending on argument order (a box beside the origin of an axis-aligned ray
    was missed)."""
    return (-np.inf if t0x != t0x else t0x, np.inf if t1x != t1x else t1x,
            -np.inf if t0y != t0y else t0y, np.inf if t1y != t1y else t1y,
            -np.inf if t0z != t0z else t0z, np.inf if t1z != t1z else t1z)


@njit(cache=True, nogil=True, inline="always")
def sheared_corners(tris, f, okx, oky, okz, kx, ky, kz, sx, sy):
    """Triangle ``f``'s corners relative to the ray's origin on the permuted axes, sheared
    so the ray is the +z axis (Woop et al.): (ax, ay, az, bx, by, bz, cx, cy, cz). One
    function for every test that must see the same numbers (the hit test and the
    ownership of an edge hit)."""
    az = tris[f, 0, kz] - okz
    bz = tris[f, 1, kz] - okz
    cz = tris[f, 2, kz] - okz
    ax = tris[f, 0, kx] - okx - sx * az
    ay = tris[f, 0, ky] - oky - sy * az
    bx = tris[f, 1, kx] - okx - sx * bz
    by = tris[f, 1, ky] - oky - sy * bz
    cx = tris[f, 2, kx] - okx - sx * cz
    cy = tris[f, 2, ky] - oky - sy * cz
    return ax, ay, az, bx, by, bz, cx, cy, cz


@njit(cache=True, nogil=True, inline="always")
def _intersect(tris, f, okx, oky, okz, kx, ky, kz, sx, sy, sz, cull_code, front_ccw, dx, dy,
               dz):
    """Woop-Benthin-Wald watertight ray/triangle test (``ok*`` are the ray origin's
    coordinates on the permuted axes). Returns (t, u, v, w) with t = -1 for a miss;
    (u, v, w) are barycentrics of corners (0, 1, 2)."""
    ax, ay, az, bx, by, bz, cx, cy, cz = sheared_corners(tris, f, okx, oky, okz, kx, ky,
                                                         kz, sx, sy)
    # 2-D edge functions; the same edge in a neighbour gives exactly the opposite value.
    u = cx * by - cy * bx
    v = ax * cy - ay * cx
    w = bx * ay - by * ax
    det = u + v + w
    # Outside when the edge values have mixed signs. One test of bitwise ands and ors,
    # not short-circuit ones: each of those is a branch, and on incoherent rays their
    # outcomes are coin flips.
    if (((u < 0.0) | (v < 0.0) | (w < 0.0)) & ((u > 0.0) | (v > 0.0) | (w > 0.0))) | (
            det == 0.0):
        return -1.0, 0.0, 0.0, 0.0
    if cull_code != 0:
        # Facing: the ray meets the counter-clockwise (front) side when the normal
        # opposes it.
        e1x, e1y, e1z = (tris[f, 1, 0] - tris[f, 0, 0], tris[f, 1, 1] - tris[f, 0, 1],
                         tris[f, 1, 2] - tris[f, 0, 2])
        e2x, e2y, e2z = (tris[f, 2, 0] - tris[f, 0, 0], tris[f, 2, 1] - tris[f, 0, 1],
                         tris[f, 2, 2] - tris[f, 0, 2])
        facing = (e1y * e2z - e1z * e2y) * dx + (e1z * e2x - e1x * e2z) * dy + (
            e1x * e2y - e1y * e2x) * dz
        front = (facing < 0.0) == front_ccw
        if (cull_code == 1 and not front) or (cull_code == 2 and front) or cull_code == 3:
            return -1.0, 0.0, 0.0, 0.0
    t = (u * (sz * az) + v * (sz * bz) + w * (sz * cz)) / det
    return t, u / det, v / det, w / det
