"""The bounding volume hierarchy the ray caster (:mod:`hsr.algorithms.raycast`, seed 004)
and the ray queries (:mod:`hsr.algorithms.rays`) walk, and the ray/triangle test.

- :func:`build` makes a bounding volume hierarchy (binned surface-area heuristic, flat
  arrays, built once per scene and reused across views), collapsed into an 8-wide tree
  for the walk (:func:`widen`, :func:`node_records`: a node's eight child boxes in one
  256-byte record, tested at once by :func:`hsr.algorithms.simd.box_keys8`);
  traversal is a stack walk, nearest entered box first, pruned by the best hit so far
  (:func:`next_box`; the walks themselves are in :mod:`hsr.algorithms.rays`). The
  triangles are stored in leaf order (a leaf's corners are one run of memory).

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
from ..scene.mesh import Scene, SceneLike, as_scene, corner_cross
from .simd import (
    SLACK,
    SLACK_ABS,
    float_bits,
    grow_box,
    next_float32,
    prefetch,
)

__all__ = ["BVH", "build", "world_triangles", "widen", "node_records",
           "inverse_direction", "careful_keys8", "next_box",
           "careful_packet_keys8", "stack_size", "walk_stack", "face_normal"]

LEAF_SIZE = 4
N_BINS = 16
# The cost model of the collapse into the walked tree (_collapse_plan): a wide node
# visited costs C_NODE, a triangle tested C_LEAF_TRIANGLE (a leaf's triangles are one
# run of memory tested four at a time, while a node is four cache lines of its own),
# and leaves of the binary tree may be merged into leaves of up to LEAF_MAX triangles.
# Measured against leaves kept as built (at most LEAF_SIZE): one thread, ms min of
# three alternating runs, the walks within 3% either way on the bunny's and a 1M-face
# terrain's random, camera and filling rays, with 0.15 and 0.08 alike; the terrain's
# wide nodes 57,068 -> 32,906 at 0.08 (14.6 -> 8.4 bytes a face), the bunny's 4,136 ->
# 2,455.
C_NODE, C_LEAF_TRIANGLE = 1.0, 0.08
LEAF_MAX = 8
# Children per node of the walked tree (the box test and the sorting network of the walks
# are for eight). Eight against four, the same binary tree collapsed (an AMD EPYC,
# AVX-512: the eight-box test is one vector, as long as four boxes took): the bunny's
# random rays visit 1.91 wide nodes instead of 2.46, a 1M-face terrain's 2.34 instead
# of 3.06; RayScene on two threads, ms min, bunny random cast 52-58 -> 47-51, count
# 70-84 -> 59-65, terrain random count 88-91 -> 74-75, camera rays about the same.
LANES = 8
# A walked node is one 256-byte record, four cache lines: 6 LANES float32 box bounds,
# then LANES int32 references and LANES int32 counts (see node_records).
NODE_WORDS = 8 * LANES
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
    (degenerate faces are left out); corners : (T, 3, 3) world-space corners of each
    slot's face (stored in leaf order, so a leaf's triangles are read in one run of
    memory), float32 when every vertex is exactly a float32 value, else float64 (the
    tests compute in float64 either way); n_faces : the scene's face count.

    As walked: node_box (W, 64) float32 and node_link (W, 64) int32, the 8-wide tree of
    :func:`widen` in the records of :func:`node_records`; the root a wide node when
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
        """Nodes of the walked 8-wide tree."""
        return len(self.node_box)

    @property
    def walked(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, int, int]:
        """The arguments the walks of :mod:`hsr.algorithms.rays` take for the tree, in
        their order: ``(corners, leaf_face, node_box, node_link, root_ref, root_count,
        wide_depth)``."""
        return (self.corners, self.leaf_face, self.node_box, self.node_link, self.root_ref,
                self.root_count, self.wide_depth)


def build(scene: SceneLike, threads: int | None = None, keep_tree: bool = True) -> BVH:
    """Build the BVH of ``scene`` (a Scene, Mesh, ...) in world space, on ``threads``
    threads (default: numba's thread count; the tree does not depend on it).
    ``keep_tree=False`` drops the binary tree once the walked 8-wide one is made (21
    bytes a face that no walk reads).

    Raises :class:`~hsr.errors.MeshError` for something that is not a scene or mesh,
    or one of 2**31 faces or more.
    """
    import time

    from ..errors import MeshError

    t0 = time.perf_counter()
    positions, faces = _world_mesh(as_scene(scene))
    n_faces = len(faces)
    if n_faces >= 2**31:  # the walk's references are int32
        raise MeshError(f"a BVH takes fewer than 2**31 faces, got {n_faces:,}")
    # Each array is let go as soon as the build is past it, and the walk's arrays are
    # made after the build's records are gone: the peak resident memory of a build is
    # that of its largest phase, not of all of them (the 1M-face terrain's 330 bytes a
    # face -> ~130, as Open3D's build peaks at about 140; bench_rays.py --memory).
    with Workers(threads) as workers:
        # The passes over every face on all threads; each writes its own rows.
        with_area = np.empty(n_faces, dtype=np.bool_)
        workers.run_range(_flag_area, n_faces, positions, faces, with_area)
        slots = np.flatnonzero(with_area).astype(np.int32)  # fewer than 2**31 faces
        del with_area
        prim = np.empty((len(slots), 9))
        workers.run_range(_fill_prims, len(slots), positions, faces, slots, prim)
        arrays = _build(prim, slots, workers, keep_tree)
        del prim, slots  # (tri_index is slots, partitioned into leaf order)
        node_min, node_max, node_left, node_start, node_count, tri_index, n_nodes = arrays
        del arrays
        bounds = np.array([node_min[0], node_max[0]])
        if node_left[0] >= 0:
            # A wide node per inner binary node at most: fewer than half the nodes (the
            # leaves are one more than the inner nodes). Records are written once each,
            # as widen makes them; the room past the last is never touched, so never
            # paged in.
            node_box, node_link = node_records(n_nodes // 2 + 1)
            n_wide, depth = widen(node_min, node_max, node_left, node_start, node_count,
                                  node_box, node_link)
            node_box, node_link = node_box[:n_wide], node_link[:n_wide]
            root = (0, 0)
        else:  # one leaf (or none): it is the root
            node_box, node_link = node_records(1)
            node_box[:] = np.inf
            node_link[:, REF:COUNT_AT], node_link[:, COUNT_AT:] = 0, -1
            depth = 0
            root = (int(node_start[0]), int(node_count[0]))
        # The binary tree is kept for reading, in half the bytes: its boxes in float32
        # rounded outwards (still holding what they bound), its indices in int32.
        kept = slice(None) if keep_tree else slice(0, 0)
        tree = (_outwards32(node_min[kept], -np.inf), _outwards32(node_max[kept], np.inf),
                node_left[kept].astype(np.int32), node_start[kept].astype(np.int32),
                node_count[kept].astype(np.int32))
        del node_min, node_max, node_left, node_start, node_count
        # A scene whose vertices are all float32 values (as binary PLY, STL and glTF
        # files give them) keeps its corners in float32: half the bytes, and every
        # test reads them back as the same float64 values, so no answer changes.
        corners = np.empty((len(tri_index), 3, 3),
                           dtype=np.float32 if _float32_exact(positions) else np.float64)
        workers.run_range(_gather_corners, len(tri_index), positions, faces, tri_index,
                          corners)
    return BVH(*tree, tri_index, corners=corners, n_faces=n_faces, node_box=node_box,
               node_link=node_link, root_ref=root[0], root_count=root[1], wide_depth=depth,
               leaf_face=tri_index, bounds=bounds,
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


def _world_mesh(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Scene.world_mesh` as the build's passes read it: contiguous, float64, and
    its faces checked again. A Mesh checks its faces when made, but the passes index
    without bounds checks and a mesh's arrays can be changed after."""
    from ..errors import MeshError

    for inst in scene.instances:
        faces = inst.mesh.faces
        if len(faces) and not (0 <= faces.min() and faces.max() < len(inst.mesh.positions)):
            raise MeshError(f"{inst.mesh.name}: a face indexes a vertex that is not there")
    positions, faces = scene.world_mesh()
    return (np.ascontiguousarray(positions, dtype=np.float64),
            np.ascontiguousarray(faces))


@njit(cache=True, nogil=True)
def _flag_area(lo, hi, positions, faces, with_area):
    """Whether faces ``lo .. hi - 1`` span a non-zero area (the cross product of two
    edges is not the zero vector): the others cannot be hit."""
    for f in range(lo, hi):
        nx, ny, nz = corner_cross(positions, faces[f, 0], faces[f, 1], faces[f, 2])
        with_area[f] = nx * nx + ny * ny + nz * nz > 0.0


@njit(cache=True, nogil=True)
def _fill_prims(lo, hi, positions, faces, slots, prim):
    """Rows ``lo .. hi - 1`` of the build's records: face ``slots[k]``'s box and
    centroid as [lo x3, hi x3, centroid x3] (partitioned in place as the tree is
    split, so each pass of the build reads memory in sequence)."""
    for k in range(lo, hi):
        f = slots[k]
        p, q, r = faces[f, 0], faces[f, 1], faces[f, 2]
        for a in range(3):
            x, y, z = positions[p, a], positions[q, a], positions[r, a]
            low, high = min(x, y, z), max(x, y, z)
            prim[k, a], prim[k, 3 + a], prim[k, 6 + a] = low, high, 0.5 * (low + high)


@njit(cache=True, nogil=True)
def _float32_exact(positions):
    """Whether every coordinate is a float32 value (NaN never is)."""
    flat = positions.reshape(-1)
    exact = True
    for k in range(flat.shape[0]):
        exact &= np.float64(np.float32(flat[k])) == flat[k]
    return exact


@njit(cache=True, nogil=True)
def _gather_corners(lo, hi, positions, faces, order, corners):
    """Rows ``lo .. hi - 1`` of the walks' corners: face ``order[k]``'s, in leaf order."""
    for k in range(lo, hi):
        f = order[k]
        for j in range(3):
            v = faces[f, j]
            corners[k, j, 0] = positions[v, 0]
            corners[k, j, 1] = positions[v, 1]
            corners[k, j, 2] = positions[v, 2]


@njit(cache=True, nogil=True, inline="always")
def _down32(x):
    """The largest float32 <= x."""
    f = np.float32(x)
    if np.float64(f) > x:
        f = next_float32(f, False)
    return f


@njit(cache=True, nogil=True, inline="always")
def _up32(x):
    """The smallest float32 >= x."""
    f = np.float32(x)
    if np.float64(f) < x:
        f = next_float32(f, True)
    return f


@njit(cache=True, nogil=True)
def _collapse_plan(node_min, node_max, node_left, node_count):
    """The 8-wide collapse of the binary tree of least cost (Ylitie, Karras and Laine
    2017, "Efficient incoherent ray traversal on GPUs through compressed wide BVHs",
    sec. 4.1, by dynamic programming from the leaves up).

    Returns (order, second, choice, split): ``order`` the binary nodes reached from the root
    in depth-first order (a node, its first child's subtree, its second's), ``second[p]``
    the position in ``order`` of the second child of ``order[p]`` (the first is at
    p + 1; -1 for a leaf), and ``choice[p, j - 1]`` how the subtree at ``p`` best fills
    at most j lanes: 0 for one lane, the node itself (a leaf, or a wide node of its
    own), -1 for one lane that is a leaf of all its triangles (at most LEAF_MAX), else
    the lanes given to its first child (the rest go to the second); ``split[p]`` the
    lanes given to the first child when the node at ``p`` is a wide node.

    Cost of a collapse (the surface area heuristic, MacDonald and Booth 1990: the rays
    that reach a box in proportion to its area): C_NODE times the area of each wide
    node's box plus C_LEAF_TRIANGLE times each leaf's area and triangles, summed. The
    greedy collapse (expand the child of largest area while a node has room, Wald et
    al. 2008) fills the top of the tree and leaves the bottom, where most nodes are,
    about half empty: 4.2 lanes a node for a 1M-face terrain, 6.1 for this collapse
    without merged leaves."""
    n = node_left.shape[0]
    # Depth-first (pre-)order, the order the build wrote the nodes in, so the reads
    # below run through memory (breadth-first, 65 ms for a 1M-face terrain's plan).
    order = np.empty(n, dtype=np.int64)
    second = np.empty(n, dtype=np.int64)  # position of the second child (-1: a leaf)
    stack = np.empty(n, dtype=np.int64)
    parent = np.empty(n, dtype=np.int64)
    stack[0], parent[0], top, tail = 0, -1, 1, 0
    while top > 0:
        top -= 1
        b, up = stack[top], parent[top]
        if up >= 0:
            second[up] = tail  # (the first child is popped right after its parent)
        order[tail] = b
        second[tail] = -1
        if node_left[b] >= 0:
            stack[top], parent[top] = node_left[b] + 1, tail
            stack[top + 1], parent[top + 1] = node_left[b], -1
            top += 2
        tail += 1
    cost = np.empty((tail, LANES))
    choice = np.zeros((tail, LANES), dtype=np.int8)
    split = np.zeros(tail, dtype=np.int8)  # a wide node's split of its eight lanes
    leaves = np.empty(tail, dtype=np.int64)  # binary leaves in the subtree
    for p in range(tail - 1, -1, -1):
        b_ = order[p]
        dx = node_max[b_, 0] - node_min[b_, 0]
        dy = node_max[b_, 1] - node_min[b_, 1]
        dz = node_max[b_, 2] - node_min[b_, 2]
        area = dx * dy + dy * dz + dz * dx
        as_leaf = area * node_count[b_] * C_LEAF_TRIANGLE
        if second[p] < 0:
            leaves[p] = 1
            cost[p, :] = as_leaf
            continue
        a, b = p + 1, second[p]
        la, lb = leaves[a], leaves[b]
        leaves[p] = la + lb
        # The two subtrees in at most j lanes (a subtree of L leaves uses at most L).
        for j in range(2, LANES + 1):
            best, pick = np.inf, 1
            for k in range(max(1, j - lb), min(j - 1, la) + 1):
                c = cost[a, k - 1] + cost[b, j - k - 1]
                if c < best:
                    best, pick = c, k
            if j > 2 and cost[p, j - 2] <= best:  # fewer lanes do as well
                best, pick = cost[p, j - 2], choice[p, j - 2]
            cost[p, j - 1], choice[p, j - 1] = best, pick
        split[p] = choice[p, LANES - 1]
        # One lane: the node made a wide node of its own, holding its subtree in eight,
        # or a leaf of all its triangles; with fewer lanes to give, that may beat
        # splitting them between the children. (Even in eight lanes a leaf may: a few
        # triangles whose boxes overlap; split keeps the eight-lane split for the
        # node made a wide node anyway, the root.)
        cost[p, 0], choice[p, 0] = area * C_NODE + cost[p, LANES - 1], 0
        if node_count[b_] <= LEAF_MAX and as_leaf < cost[p, 0]:
            cost[p, 0], choice[p, 0] = as_leaf, -1
        for j in range(2, LANES + 1):
            if cost[p, 0] <= cost[p, j - 1]:
                cost[p, j - 1], choice[p, j - 1] = cost[p, 0], choice[p, 0]
    return order[:tail], second[:tail], choice, split


@njit(cache=True, nogil=True)
def widen(node_min, node_max, node_left, node_start, node_count, node_box, node_link):
    """The binary BVH collapsed into a LANES-wide one (the collapse of
    :func:`_collapse_plan`: least cost by the surface area heuristic, binary leaves
    merged into leaves of up to LEAF_MAX triangles where that is cheaper), written into
    the records of :func:`node_records` (``node_box``, ``node_link``, with room for a
    wide node per inner binary node). A wide node's lanes are its children: boxes as
    [lo_x.., lo_y.., lo_z.., hi_x.., hi_y.., hi_z..] rounded outwards to float32 (an
    empty lane's box lies at +inf, so every ray misses it); references a leaf's first
    slot with its count > 0, a wide node's number with count 0, or count -1 for an
    empty lane. Returns (wide nodes, deepest wide level). The root must be an inner node.

    Wide nodes are numbered in level order (the root, then its children, then theirs),
    a node's wide children next to each other: the first few thousand are the top of
    the tree, which every walk passes through, and :func:`hsr.algorithms.rays.trace_range`
    counts on that (``HOT_NODES``). Each record is written once, as its node is made."""
    order, second, choice, split = _collapse_plan(node_min, node_max, node_left, node_count)
    n = node_box.shape[0]
    todo_pos = np.empty(n, dtype=np.int64)  # binary node (its position in order) ->
    todo_wide = np.empty(n, dtype=np.int64)  # its wide node, to fill
    todo_level = np.empty(n, dtype=np.int64)
    todo_pos[0], todo_wide[0], todo_level[0] = 0, 0, 0
    # A queue (first in, first out): level order. Each binary node enters it once.
    head, top, n_wide, depth = 0, 1, 1, 0
    kids = np.empty(LANES, dtype=np.int64)
    split_pos = np.empty(2 * LANES, dtype=np.int64)  # (subtree, lanes) still to split
    split_j = np.empty(2 * LANES, dtype=np.int64)
    while head < top:
        p, w, level = todo_pos[head], todo_wide[head], todo_level[head]
        head += 1
        depth = max(depth, level)
        # The node's two subtrees in eight lanes, split as the plan says.
        k = split[p]
        split_pos[0], split_j[0] = second[p], LANES - k
        split_pos[1], split_j[1] = p + 1, k
        sp, m = 2, 0
        while sp > 0:
            sp -= 1
            q, j = split_pos[sp], split_j[sp]
            c = choice[q, j - 1]
            if c <= 0:  # one lane
                kids[m] = q
                m += 1
            else:
                split_pos[sp], split_j[sp] = second[q], j - c
                split_pos[sp + 1], split_j[sp + 1] = q + 1, c
                sp += 2
        for lane in range(LANES):
            if lane >= m:
                for a in range(6):
                    node_box[w, LANES * a + lane] = np.inf
                node_link[w, REF + lane], node_link[w, COUNT_AT + lane] = 0, -1
                continue
            q = kids[lane]
            c = order[q]
            for a in range(3):
                node_box[w, LANES * a + lane] = _down32(node_min[c, a])
                node_box[w, LANES * (3 + a) + lane] = _up32(node_max[c, a])
            if node_left[c] < 0 or choice[q, 0] < 0:  # a leaf (of the subtree's slots)
                node_link[w, REF + lane] = node_start[c]
                node_link[w, COUNT_AT + lane] = node_count[c]
            else:
                node_link[w, REF + lane], node_link[w, COUNT_AT + lane] = n_wide, 0
                todo_pos[top], todo_wide[top], todo_level[top] = q, n_wide, level + 1
                top += 1
                n_wide += 1
    return n_wide, depth


def node_records(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Room for ``n`` wide nodes in the walked layout, uninitialised: ``(node_box,
    node_link)``, two views of one buffer aligned to 64 bytes, each node a 256-byte
    record (four cache lines, one read brings a node's boxes and references together):
    ``node_box`` (n, 64) float32, the boxes in words 0 .. 47; ``node_link`` (n, 64)
    int32, the references in words 48 .. 55 and the counts in 56 .. 63 (int32: a scene
    has fewer than 2**31 faces, which :func:`build` checks). Separate int64 arrays were
    three records a node, and random rays, whose nodes are rarely in cache, paid for
    each."""
    raw = np.empty(n * 4 * NODE_WORDS + 64, dtype=np.uint8)
    start = -raw.ctypes.data % 64
    record = raw[start:start + n * 4 * NODE_WORDS]
    return (record.view(np.float32).reshape(n, NODE_WORDS),
            record.view(np.int32).reshape(n, NODE_WORDS))


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
def careful_keys8(box, w, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound, keys):
    """:func:`hsr.algorithms.simd.box_keys8` lane by lane with the NaN care of
    :func:`_careful_entry`, for rays with a zero direction component."""
    mask = 0
    for lane in range(LANES):
        e = _careful_entry(box, w, lane, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound)
        keys[lane] = float_bits(e) & ~7 | lane
        mask |= (e < np.inf) << lane
    return mask


@njit(cache=True, nogil=True, inline="always")
def careful_packet_keys8(box, w, rays, bound, active, out, keys):
    """:func:`hsr.algorithms.simd.packet_keys8` ray by ray with the NaN care of
    :func:`_careful_entry`, for a packet holding a ray with a zero direction
    component."""
    mask = 0
    for k in range(LANES):
        nearest = np.inf
        for r in range(4):
            e = _careful_entry(box, w, k, rays[0, r], rays[1, r], rays[2, r], rays[3, r],
                               rays[4, r], rays[5, r], bound[r])
            out[r, k] = e
            if (active >> r) & 1 and e < np.inf:
                mask |= 1 << (4 * k + r)
                nearest = min(nearest, e)
        keys[k] = float_bits(nearest) & ~7 | k
    return mask


@njit(cache=True, nogil=True, inline="always")
def stack_size(wide_depth):
    """Slots of one walk's stack: each of the ``wide_depth + 1`` wide levels a walk
    passes through leaves at most LANES - 1 siblings behind, which
    ``(LANES - 1) * wide_depth + 2 * LANES`` covers with room to spare."""
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
def next_box(stack_ref, stack_count, stack_t, top, bound, bottom):
    """The next box still worth entering from the stack (slots ``bottom .. top - 1``;
    one array can hold several rays' stacks): ``(ref, n, top, found)``;
    boxes entered beyond ``bound`` (a hit nearer than them has been found since they
    were pushed) are dropped. The stack holds entries as keys of
    :func:`hsr.algorithms.simd.sort_keys8`, compared with the bound's bits (bound
    + 0.0 makes a bound of -0.0 the +0.0 whose bits are the least)."""
    bound_key = float_bits(bound + 0.0)
    while top > bottom:
        top -= 1
        if stack_t[top] <= bound_key:
            return np.int64(stack_ref[top]), np.int64(stack_count[top]), top, True
    return np.int64(0), np.int64(0), top, False


def _build(prim, slots, workers, keep_tree=True):
    """The binary SAH tree over the records ``prim`` of faces ``slots``
    (:func:`_fill_prims`): (node_min, node_max, node_left, node_start, node_count, leaf
    order of the faces, number of nodes). ``prim`` and ``slots`` are partitioned in
    place: ``slots`` becomes the leaf order.

    In parallel (``workers``, :class:`hsr.parallel.Workers`): the top of the tree is
    split on one thread until every open node holds at most 1 / (4 threads) of the
    faces; those subtrees are then built on all threads at once (each in its own range
    of faces and of node numbers, so no two threads write the same place), and, with
    ``keep_tree``, the node numbers closed up (without, the arrays keep the unused
    numbers between subtrees, which no link reaches, for :func:`widen` to walk). The
    tree is the same as on one thread, node numbering aside.
    """
    n = len(slots)
    order = slots
    max_nodes = max(1, 2 * n)
    nodes = _node_arrays(max_nodes)
    nodes[2][0], nodes[3][0], nodes[4][0] = -1, 0, n  # the root holds every slot
    cutoff = n // (4 * workers.threads) if workers.threads > 1 and n > 4096 else 0
    pending = np.empty(max_nodes, dtype=np.int64)
    # The top, on this thread: nodes of at most `cutoff` faces are left open.
    n_top, n_pending = _grow(prim, order, *nodes, 0, 1, cutoff, pending)
    pending = pending[:n_pending]
    if n_pending == 0:
        return (*(a[:n_top] for a in nodes), order, n_top)
    # Subtree k (c faces: at most 2c - 1 nodes, its root already numbered among the
    # top's) numbers its new nodes from base[k].
    base = n_top + np.concatenate([[0], np.cumsum(2 * nodes[4][pending] - 2)[:-1]])
    each = np.stack([pending, base], axis=1).astype(np.int64)
    ends = np.asarray(workers.run(_grow_subtree, np.arange(n_pending + 1), prim, order,
                                  *nodes, each), dtype=np.int64)
    n_nodes = n_top + int((ends - base).sum())
    if not keep_tree:
        return (*(a[:ends[-1]] for a in nodes), order, n_nodes)
    _close_up(nodes[2], n_top, pending, base, ends)
    keep = np.concatenate([np.arange(n_top)] + [np.arange(s, e) for s, e in zip(base, ends)])
    return (*(a[keep] for a in nodes), order, n_nodes)


@njit(cache=True, nogil=True)
def _node_arrays(n):
    """Room for ``n`` nodes of the binary tree as built: (node_min, node_max, node_left,
    node_start, node_count), uninitialised (_grow writes each node as it makes it).
    Made by Numba's allocator, not NumPy's: NumPy asks for transparent huge pages for
    arrays of 4 MB or more (``madvise``), so that writing anywhere pages in 2 MB, and
    the subtrees built in parallel write their nodes in ranges apart from each other,
    with room between them (each subtree may need up to twice its faces): the 1M-face
    terrain's node arrays took 111 bytes a face resident for the 42 written."""
    return (np.empty((n, 3)), np.empty((n, 3)), np.empty(n, dtype=np.int64),
            np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64))


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
def _bounds(prim, s, c):
    """The box of slots ``s .. s + c - 1`` and the box of their centroids: (lo x3, hi x3,
    centroid lo x3, centroid hi x3)."""
    l0 = l1 = l2 = m0 = m1 = m2 = np.inf
    h0 = h1 = h2 = n0 = n1 = n2 = -np.inf
    for k in range(s, s + c):
        l0, l1, l2 = min(l0, prim[k, 0]), min(l1, prim[k, 1]), min(l2, prim[k, 2])
        h0, h1, h2 = max(h0, prim[k, 3]), max(h1, prim[k, 4]), max(h2, prim[k, 5])
        m0, m1, m2 = min(m0, prim[k, 6]), min(m1, prim[k, 7]), min(m2, prim[k, 8])
        n0, n1, n2 = max(n0, prim[k, 6]), max(n1, prim[k, 7]), max(n2, prim[k, 8])
    return l0, l1, l2, h0, h1, h2, m0, m1, m2, n0, n1, n2


# Faces ahead of the one being binned or partitioned whose record is prefetched: a
# node's slots are read in order, but a build's passes over the 1M-face terrain's
# 72 MB of records waited on memory (binning it: 22-25 ns a face without, 8-9 with
# 32 ahead, as fast as from cache).
AHEAD = 32


@njit(cache=True, nogil=True, error_model="numpy")
def _bin_faces(prim, s, c, c_lo, scale, nb, bins, bin_n):
    """Slots ``s .. s + c - 1`` counted into ``bin_n`` and their boxes into ``bins``
    (flat: axis, bin, the 8 words of :func:`hsr.algorithms.simd.grow_box`), on all three
    axes in one pass. (Flat, with unsigned indices: Numba's three-index form with its
    negative-index checks took 30 ns a face where this takes 17, before prefetching and
    grow_box.)"""
    for k in range(s, s + c):
        prefetch(prim, k + AHEAD, 0)
        prefetch(prim, k + AHEAD, 64)
        for a in range(3):
            b = np.uint64(a * N_BINS) + np.uint64(_bin_of(prim[k, 6 + a], c_lo[a], scale[a],
                                                          nb))
            bin_n[b] += 1
            grow_box(bins, b * np.uint64(8), prim, k)


@njit(cache=True, nogil=True)
def _grow(prim, order, node_min, node_max, node_left, node_start, node_count, root,
          next_node, cutoff, pending):
    """Split node ``root`` (its slots node_start .. + node_count) and its descendants
    until leaves of at most LEAF_SIZE faces, numbering new nodes from ``next_node``;
    with ``cutoff`` > 0 a node of at most that many faces is left open and listed in
    ``pending``. Returns (next free node number, number pending).

    Each split reads its node's slots twice: once to bin them on all three axes, once
    to partition them. A child's box is the union of its side's bins, the box of its
    centroids (which places its bins) is gathered while partitioning, and both are
    handed down with it. (A pass per axis to bin, with a division per face, through
    Numba's three-index arrays and without prefetching, and a third pass per node for
    the boxes, made the split 30 ns a face per level where it is now about 20 at the
    terrain; most of that came from prefetching and the flat bins, see
    :func:`_bin_faces`.)"""
    n_pending = 0
    # Per axis and bin: its faces' box (lo x3, a spare word, hi x3, a spare word: 64
    # bytes, two vectors of four for simd.grow_box).
    bins = np.empty((3, N_BINS, 8))
    bin_n = np.empty((3, N_BINS), dtype=np.int64)
    right_cost = np.empty(N_BINS)
    c_lo = np.empty(3)
    scale = np.empty(3)
    box = _bounds(prim, node_start[root], node_count[root])
    for a in range(3):
        node_min[root, a], node_max[root, a] = box[a], box[3 + a]
    # The open nodes and their centroid boxes (lo x3, hi x3).
    stack = [root]
    stack_centroids = [box[6:]]
    while len(stack) > 0:
        node = stack.pop()
        cb = stack_centroids.pop()
        s, c = node_start[node], node_count[node]
        if c <= LEAF_SIZE:
            continue
        if c <= cutoff:
            pending[n_pending] = node
            n_pending += 1
            continue
        # Binned SAH over all three axes (_best_split). An axis along which the
        # centroids do not spread (or spread by so little that N_BINS / extent
        # overflows) puts every face in bin 0 and is not swept.
        # A node of fewer faces than N_BINS gets as many bins as faces, fewer to clear
        # and sweep (the bunny's build on two threads: 14 -> 12-13 ms; trees as good:
        # the wide boxes' areas and the casts through them unchanged).
        nb = min(N_BINS, c)
        for a in range(3):
            extent = cb[3 + a] - cb[a]
            c_lo[a] = cb[a]
            scale[a] = nb / extent if extent > 0.0 else 0.0
            if not scale[a] < np.inf:
                scale[a] = 0.0
        bins[:, :nb, :4] = np.inf
        bins[:, :nb, 4:] = -np.inf
        bin_n[:, :nb] = 0
        _bin_faces(prim, s, c, c_lo, scale, nb, bins.reshape(-1), bin_n.reshape(-1))
        best_axis, best_split = _best_split(bins, bin_n, nb, scale, right_cost)
        mid = s
        if best_axis >= 0:
            a = best_axis
            # The sides' centroid boxes, gathered as each face is placed.
            lm0 = lm1 = lm2 = rm0 = rm1 = rm2 = np.inf
            ln0 = ln1 = ln2 = rn0 = rn1 = rn2 = -np.inf
            j = s + c - 1
            while mid <= j:
                prefetch(prim, mid + AHEAD, 0)
                prefetch(prim, j - AHEAD, 0)
                x, y, z = prim[mid, 6], prim[mid, 7], prim[mid, 8]
                if _bin_of(prim[mid, 6 + a], c_lo[a], scale[a], nb) < best_split:
                    lm0, lm1, lm2 = min(lm0, x), min(lm1, y), min(lm2, z)
                    ln0, ln1, ln2 = max(ln0, x), max(ln1, y), max(ln2, z)
                    mid += 1
                else:
                    rm0, rm1, rm2 = min(rm0, x), min(rm1, y), min(rm2, z)
                    rn0, rn1, rn2 = max(rn0, x), max(rn1, y), max(rn2, z)
                    order[mid], order[j] = order[j], order[mid]
                    for q in range(9):
                        prim[mid, q], prim[j, q] = prim[j, q], prim[mid, q]
                    j -= 1
        left = next_node
        next_node += 2
        node_left[node] = left
        if mid == s or mid == s + c:  # no useful split: halve in index order
            mid = s + c // 2
            lb = _bounds(prim, s, mid - s)
            rb = _bounds(prim, mid, s + c - mid)
            for a in range(3):
                node_min[left, a], node_max[left, a] = lb[a], lb[3 + a]
                node_min[left + 1, a], node_max[left + 1, a] = rb[a], rb[3 + a]
            l_centroids, r_centroids = lb[6:], rb[6:]
        else:
            for a in range(3):
                node_min[left, a] = node_min[left + 1, a] = np.inf
                node_max[left, a] = node_max[left + 1, a] = -np.inf
            for b in range(nb):
                child = left if b < best_split else left + 1
                for a in range(3):
                    node_min[child, a] = min(node_min[child, a], bins[best_axis, b, a])
                    node_max[child, a] = max(node_max[child, a], bins[best_axis, b, 4 + a])
            l_centroids = (lm0, lm1, lm2, ln0, ln1, ln2)
            r_centroids = (rm0, rm1, rm2, rn0, rn1, rn2)
        node_start[left], node_count[left] = s, mid - s
        node_start[left + 1], node_count[left + 1] = mid, s + c - mid
        node_left[left] = node_left[left + 1] = -1
        stack.append(left + 1)
        stack_centroids.append(r_centroids)
        stack.append(left)
        stack_centroids.append(l_centroids)
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
def _bin_of(centroid, c_lo, scale, nb):
    """The SAH bin of a centroid among ``nb``, ``scale`` being nb / the centroids' extent
    (the same expression wherever a bin is assigned, so the partition puts each triangle on
    the side its bin was counted on). A multiplication, not a division: the binning
    loop is most of a build."""
    return min(int((centroid - c_lo) * scale), nb - 1)


@njit(cache=True, nogil=True, inline="always")
def _area_times(lx, ly, lz, hx, hy, hz, count):
    """Surface area (half of it) of a box times a face count; 0 for no faces."""
    dx, dy, dz = hx - lx, hy - ly, hz - lz
    return (dx * dy + dy * dz + dz * dx) * count if count > 0 else 0.0


@njit(cache=True, nogil=True)
def _best_split(bins, bin_n, nb, scale, right_cost):
    """The cheapest split of the binned SAH (Wald 2007: cost = area(L) n(L) +
    area(R) n(R)) over the axes with a non-zero ``scale``: (axis, first bin of the
    right side), (-1, -1) with none. Per axis the right sides' costs are summed in one
    sweep from the right into ``right_cost``, then the left sides' in one from the left,
    each split priced as the left sweep reaches it: O(bins) per axis. Empty bins hold
    the empty box (+inf lows, -inf highs), which leaves a union as it is."""
    best_axis, best_split, best_cost = -1, -1, np.inf
    for a in range(3):
        if scale[a] == 0.0:
            continue
        count = 0
        lx = ly = lz = np.inf
        hx = hy = hz = -np.inf
        for b in range(nb - 1, 0, -1):  # right side of split b: bins b .. nb - 1
            count += bin_n[a, b]
            lx, ly, lz = min(lx, bins[a, b, 0]), min(ly, bins[a, b, 1]), min(lz, bins[a, b, 2])
            hx, hy, hz = max(hx, bins[a, b, 4]), max(hy, bins[a, b, 5]), max(hz, bins[a, b, 6])
            right_cost[b] = _area_times(lx, ly, lz, hx, hy, hz, count)
        count = 0
        lx = ly = lz = np.inf
        hx = hy = hz = -np.inf
        for split in range(1, nb):  # left side: bins 0 .. split - 1
            b = split - 1
            count += bin_n[a, b]
            lx, ly, lz = min(lx, bins[a, b, 0]), min(ly, bins[a, b, 1]), min(lz, bins[a, b, 2])
            hx, hy, hz = max(hx, bins[a, b, 4]), max(hy, bins[a, b, 5]), max(hz, bins[a, b, 6])
            cost = _area_times(lx, ly, lz, hx, hy, hz, count) + right_cost[split]
            if cost < best_cost:
                best_axis, best_split, best_cost = a, split, cost
    return best_axis, best_split


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
def face_normal(tris, f):
    """Slot ``f``'s normal as wound, (B - A) x (C - A), not normalised; in float64
    whether the corners are stored in float32 or float64 (float32 arithmetic would
    round it differently)."""
    p0x, p0y, p0z = np.float64(tris[f, 0, 0]), np.float64(tris[f, 0, 1]), np.float64(tris[f, 0, 2])
    e1x, e1y, e1z = tris[f, 1, 0] - p0x, tris[f, 1, 1] - p0y, tris[f, 1, 2] - p0z
    e2x, e2y, e2z = tris[f, 2, 0] - p0x, tris[f, 2, 1] - p0y, tris[f, 2, 2] - p0z
    return e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x


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
        nx, ny, nz = face_normal(tris, f)
        facing = nx * dx + ny * dy + nz * dz
        front = (facing < 0.0) == front_ccw
        if (cull_code == 1 and not front) or (cull_code == 2 and front) or cull_code == 3:
            return -1.0, 0.0, 0.0, 0.0
    t = (u * (sz * az) + v * (sz * bz) + w * (sz * cz)) / det
    return t, u / det, v / det, w / det
