"""The bounding volume hierarchy the ray caster (:mod:`hsr.algorithms.raycast`) and the
ray queries (:class:`hsr.visibility.RayScene`) walk: :func:`build` bins the faces by the
surface-area heuristic into a binary tree (flat arrays, built once per scene and reused
across views), collapses it into the 8-wide tree of :mod:`.layout`
(:func:`hsr.algorithms.bvh.collapse.widen`) and stores the triangles in leaf order (a
leaf's corners are one run of memory)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ...parallel import Workers
from ...scene.mesh import Scene, SceneLike, as_scene, corner_cross
from ..simd import grow_box, prefetch
from .collapse import widen
from .layout import (
    COUNT_AT,
    REF,
    corner_blocks,
    corner_layout,
    corner_rows,
    node_records,
    pack_leaves,
    set_corner,
)

__all__ = ["LEAF_SIZE", "N_BINS", "world_triangles", "BVH", "build", "binary_tree", "AHEAD"]

LEAF_SIZE = 4

N_BINS = 16


def world_triangles(scene: Scene) -> np.ndarray:
    """(F, 3, 3) float64 world-space corners in submission order."""
    return as_scene(scene).world_triangles()


@dataclass
class BVH:
    """A bounding volume hierarchy over a scene's world-space triangles, as the walks
    read it (the binary tree the build goes through is not kept: no walk reads it).

    - tri_index : (T,) int32 the face id in each slot (degenerate faces are left out),
      in leaf order, -1 in the padding slots of packed blocks
      (:func:`hsr.algorithms.bvh.layout.pack_leaves`; no leaf holds them); leaf_face is
      the walks' name for it (the same array);
    - corners : the world-space corners of each slot's face, slots in leaf order (a
      leaf's triangles are one run of memory): (T, 9) rows, or for a scene that fits in
      :data:`hsr.algorithms.bvh.layout.BLOCKS_BYTES` the blocks of four slots of
      :func:`hsr.algorithms.bvh.layout.corner_blocks` ((ceil(T / 4), 36); either as
      (T, 3, 3): :func:`hsr.algorithms.bvh.layout.slot_corners`); float32 when every
      vertex is exactly a float32 value, else float64 (the tests compute in float64
      either way);
    - n_faces : the scene's face count;
    - node_box (W, 64) float32 and node_link (W, 64) int32: the 8-wide tree of
      :func:`hsr.algorithms.bvh.collapse.widen` in the records of
      :func:`hsr.algorithms.bvh.layout.node_records`; the root a wide node when
      root_count is 0, else a leaf of root_count slots from root_ref; wide_depth the
      deepest wide level (it sizes the walk's stack);
    - bounds (2, 3) float64: the scene's box (lower, upper corner; +inf / -inf for no
      faces).
    """

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
    def n_wide_nodes(self) -> int:
        """Nodes of the walked 8-wide tree."""
        return len(self.node_box)

    @property
    def walked(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, int, int]:
        """The arguments the walks of :mod:`hsr.algorithms.bvh.walk` take for the tree, in
        their order: ``(corners, leaf_face, node_box, node_link, root_ref, root_count,
        wide_depth)``."""
        return (self.corners, self.leaf_face, self.node_box, self.node_link, self.root_ref,
                self.root_count, self.wide_depth)


def build(scene: SceneLike, threads: int | None = None) -> BVH:
    """Build the BVH of ``scene`` (a Scene, Mesh, ...) in world space, on ``threads``
    threads (default: numba's thread count; the tree does not depend on it).

    Raises :class:`~hsr.errors.MeshError` for something that is not a scene or mesh,
    or one of 2**31 faces or more.
    """
    import time

    from ...errors import MeshError

    t0 = time.perf_counter()
    positions, faces = _world_mesh(as_scene(scene))
    n_faces = len(faces)
    if n_faces >= 2**31:  # the walk's references are int32
        raise MeshError(f"a BVH takes fewer than 2**31 faces, got {n_faces:,}")
    # Each array is let go once the build is past it: the peak is the largest phase's.
    # (Measurements: docs/history.md, "Ray core".)
    with Workers(threads) as workers:
        arrays = binary_tree(positions, faces, workers)
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
        del node_min, node_max, node_left, node_start, node_count
        # A scene whose vertices are all float32 values (as binary PLY, STL and glTF
        # files give them) keeps its corners in float32: half the bytes, and every
        # test reads them back as the same float64 values, so no answer changes.
        dtype = np.dtype(np.float32 if _float32_exact(positions) else np.float64)
        if not corner_layout(len(tri_index), dtype.itemsize, len(node_box)):
            corners = corner_rows(len(tri_index), dtype)
        else:
            if root == (0, 0):  # each leaf in as few blocks as it can take
                moved, n_slots = pack_leaves(node_link)
                packed = np.full(n_slots, -1, dtype=np.int32)
                packed[moved] = tri_index
                tri_index = packed
            corners = corner_blocks(len(tri_index), dtype)
        workers.run_range(_gather_corners, len(tri_index), positions, faces, tri_index,
                          corners)
    return BVH(tri_index, corners=corners, n_faces=n_faces, node_box=node_box,
               node_link=node_link, root_ref=root[0], root_count=root[1], wide_depth=depth,
               leaf_face=tri_index, bounds=bounds,
               build_ms=1e3 * (time.perf_counter() - t0))


def binary_tree(positions, faces, workers):
    """The binary SAH tree of the faces with an area (:func:`_flag_area`) of the mesh
    ``positions``, ``faces`` (as :func:`_world_mesh` gives them), on ``workers``: (node_min,
    node_max, node_left, node_start, node_count, leaf order of the faces, number of
    nodes), as :func:`_build` makes it."""
    n_faces = len(faces)
    # The passes over every face on all threads; each writes its own rows.
    with_area = np.empty(n_faces, dtype=np.bool_)
    workers.run_range(_flag_area, n_faces, positions, faces, with_area)
    slots = np.flatnonzero(with_area).astype(np.int32)  # fewer than 2**31 faces
    del with_area
    prim = np.empty((len(slots), 9))
    workers.run_range(_fill_prims, len(slots), positions, faces, slots, prim)
    return _build(prim, slots, workers)  # (slots becomes the leaf order)


def _world_mesh(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Scene.world_mesh` as the build's passes read it: contiguous, float64, and
    its faces checked again. A Mesh checks its faces when made, but the passes index
    without bounds checks and a mesh's arrays can be changed after."""
    from ...errors import MeshError

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
    """Slots ``lo .. hi - 1`` of the walks' corners (rows or blocks,
    :mod:`hsr.algorithms.bvh.layout`): face ``order[k]``'s, in leaf order (-1: a
    padding slot, left as it is)."""
    for k in range(lo, hi):
        f = order[k]
        if f < 0:
            continue
        for j in range(3):
            v = faces[f, j]
            for a in range(3):
                set_corner(corners, k, j, a, positions[v, a])


def _build(prim, slots, workers):
    """The binary SAH tree over the records ``prim`` of faces ``slots``
    (:func:`_fill_prims`): (node_min, node_max, node_left, node_start, node_count, leaf
    order of the faces, number of nodes). ``prim`` and ``slots`` are partitioned in
    place: ``slots`` becomes the leaf order.

    In parallel (``workers``, :class:`hsr.parallel.Workers`): the top of the tree is split
    on one thread until every open node holds at most 1 / (4 threads) of the faces; those
    subtrees are then built on all threads at once (each in its own range of faces and of
    node numbers, so no two threads write the same place); the arrays keep the unused
    numbers between subtrees, which no link reaches, for
    :func:`hsr.algorithms.bvh.collapse.widen` to walk from the root. The tree is the same
    as on one thread, node numbering aside.
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
    return (*(a[:ends[-1]] for a in nodes), order, n_nodes)


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
        # Binned SAH over all three axes (_best_split); an axis along which the centroids do
        # not spread puts every face in bin 0 and is not swept. A node of fewer faces than
        # N_BINS gets as many bins as faces.
        # (Measurements: docs/history.md, "Ray core".)
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
