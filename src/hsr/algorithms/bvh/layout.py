"""The walked tree's layout. An 8-wide node is one 256-byte record (four cache lines),
its eight child boxes as float32 bounds rounded outwards, then eight references and
eight counts (:func:`node_records`). Nodes are numbered in level order, so the first
:data:`HOT_NODES` are the top of the tree.

A leaf's triangles are a run of slots of the corners, one 2-D array in one of two
layouts (:func:`corner_layout` chooses; the array's width tells them apart): rows, (T,
9), a slot's nine values together (corner j's coordinate a at 3 j + a); or blocks of
four slots (:func:`corner_blocks`), (ceil(T / 4), 36), each coordinate of a block's four
corners one run of memory, so the four-triangle test reads it as one vector; in blocks,
the leaves are packed so that each is read in as few blocks as its size allows
(:func:`pack_leaves`).
:func:`corner`, :func:`leaf_base` and :func:`slot_row` read either. One array type for
both: the walks are compiled once, not once a layout."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import next_float32, prefetch, record_words

__all__ = ["LANES", "NODE_WORDS", "REF", "COUNT_AT", "HOT_NODES", "QUAD", "ROW_VALUES",
           "BLOCK_VALUES", "BLOCKS_BYTES", "node_records", "child", "fetch_links", "set_child",
           "nowrap", "corner_layout", "corner_rows", "corner_blocks", "slot_corners", "corner",
           "set_corner", "leaf_base", "slot_row", "quad_lanes", "pack_leaves", "down32",
           "up32"]

# Children per node: the eight-box test is one AVX-512 vector, and fewer nodes are walked.
# (Measurements: docs/history.md, "Ray core".)
LANES = 8

# A walked node is one 256-byte record, four cache lines: 6 LANES float32 box bounds,
# then LANES int32 references and LANES int32 counts (see node_records).
NODE_WORDS = 8 * LANES

REF, COUNT_AT = 6 * LANES, 7 * LANES

# Wide nodes numbered below HOT_NODES (the top of the tree in level order, 128 KB of
# records) are taken to be in a core's cache: walking into one goes on with the same ray.
# (Measurements: docs/history.md, "Ray core".)
HOT_NODES = 512


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
def child(node_link, w, lane):
    """What lane ``lane`` of wide node ``w`` holds, ``(ref, count)``: a wide node's number
    and 0, a leaf's first slot and its triangle count (> 0), or an empty lane (count -1)."""
    return record_words(node_link, w, REF + lane, COUNT_AT + lane)


@njit(cache=True, nogil=True, inline="always")
def fetch_links(node_link, w):
    """Prefetch the cache line of wide node ``w``'s references and counts: a walk reads
    it only once the node's box test is done, so fetched as the test starts, its wait
    overlaps the test's instead of following it."""
    prefetch(node_link, w, 4 * REF)


@njit(cache=True, nogil=True, inline="always")
def set_child(node_link, w, lane, ref, count):
    """Make lane ``lane`` of wide node ``w`` hold ``(ref, count)`` (see :func:`child`)."""
    node_link[w, REF + lane], node_link[w, COUNT_AT + lane] = ref, count


# Slots a corner block holds: the four-triangle test's lanes (simd.leaf_filter4).
QUAD = 4

# A row's values (a slot's three corners), a block's (four slots').
ROW_VALUES, BLOCK_VALUES = 9, 9 * QUAD

# A scene whose corners and nodes fit in this keeps its corners in blocks: its walks
# are bound by their instructions, which the blocks' vector reads cut. A larger one
# keeps rows: its walks wait on memory, and a leaf of rows spans fewer cache lines (a
# leaf's blocks hold other leaves' slots too). (Measurements: docs/history.md, "Ray
# core".) The interleaved walk's threshold (walk.INTERLEAVE_BYTES) is the same on an AMD
# CPU, half of it on an Intel one.
BLOCKS_BYTES = 8 << 20


def corner_layout(n_slots: int, itemsize: int, n_nodes: int) -> bool:
    """Whether a tree of ``n_nodes`` wide nodes over ``n_slots`` slots of corners of
    ``itemsize`` bytes keeps them in blocks (see :data:`BLOCKS_BYTES`)."""
    return n_slots * ROW_VALUES * itemsize + n_nodes * NODE_WORDS * 4 <= BLOCKS_BYTES


def corner_rows(n: int, dtype) -> np.ndarray:
    """Room for ``n`` slots' corners in rows, uninitialised: ``(n, 9)``, slot k's corner
    j, coordinate a at ``[k, 3 j + a]``."""
    return np.empty((n, ROW_VALUES), dtype=dtype)


def corner_blocks(n: int, dtype) -> np.ndarray:
    """Room for ``n`` slots' corners in blocks: ``(ceil(n / 4), 36)``, zeros; slot k's
    corner j, coordinate a at ``[k // 4, 4 (3 j + a) + k % 4]`` (:func:`corner`). A block
    holds the four slots' corner j, coordinate a side by side: the four-triangle test
    reads each as one vector load (and the triangle test's permutation of the axes is an
    offset), where rows take a load and an insert per value. The lanes past slot n - 1
    stay zeros; no walk tests them (a leaf's lanes are masked: :func:`quad_lanes`)."""
    return np.zeros(((n + QUAD - 1) // QUAD, BLOCK_VALUES), dtype=dtype)


def slot_corners(tris: np.ndarray, slots) -> np.ndarray:
    """The corners of ``slots`` of ``tris`` (rows or blocks) as (..., 3, 3):
    ``[slot, corner, coordinate]``."""
    slots = np.asarray(slots)
    if tris.shape[1] == ROW_VALUES:
        return tris[slots].reshape(slots.shape + (3, 3))
    blocks = tris.reshape(len(tris), 3, 3, QUAD)
    return blocks[slots // QUAD, :, :, slots % QUAD]


@njit(cache=True, nogil=True, inline="always")
def nowrap(i):
    """Index ``i`` (>= 0) as unsigned: Numba then reads ``a[i]`` without the wraparound
    of a negative index (two instructions a read; the walks' indices are never
    negative)."""
    return np.uint64(i)


@njit(cache=True, nogil=True, inline="always")
def _shift(tris):
    """log2 of the slots a row of ``tris`` holds: 2 in blocks, 0 in rows (read from the
    array's width, without a branch)."""
    return (tris.shape[1] == BLOCK_VALUES) << 1


@njit(cache=True, nogil=True, inline="always")
def _at(tris, k, j, a):
    """Where coordinate ``a`` of corner ``j`` of slot ``k`` lies in ``tris``: (row,
    column), in either layout (:func:`nowrap`)."""
    shift = _shift(tris)
    return nowrap(k >> shift), nowrap(((3 * j + a) << shift) + (k & ((1 << shift) - 1)))


@njit(cache=True, nogil=True, inline="always")
def corner(tris, k, j, a):
    """Coordinate ``a`` of corner ``j`` of slot ``k`` of ``tris``, rows or blocks."""
    row, column = _at(tris, k, j, a)
    return tris[row, column]


@njit(cache=True, nogil=True, inline="always")
def set_corner(tris, k, j, a, value):
    """Make coordinate ``a`` of corner ``j`` of slot ``k`` of ``tris`` ``value``."""
    row, column = _at(tris, k, j, a)
    tris[row, column] = value


@njit(cache=True, nogil=True, inline="always")
def leaf_base(tris, ref):
    """The first slot of the first four-slot group the leaf test reads for a leaf from
    slot ``ref``: ``ref`` itself in rows, the start of its block in blocks (the test then
    reads groups ``base``, ``base + 4``, ... with :func:`quad_lanes`' masks)."""
    shift = _shift(tris)
    return (ref >> shift) << shift


@njit(cache=True, nogil=True, inline="always")
def slot_row(tris, k):
    """The row of ``tris`` (its first index) where slot ``k``'s corners start."""
    return k >> _shift(tris)


@njit(cache=True, nogil=True, inline="always")
def quad_lanes(first, end, base):
    """The lanes of the four slots from ``base`` that hold slots ``first .. end - 1``
    (a leaf): a mask of four bits, lane i for slot base + i."""
    lo = max(first - base, 0)
    hi = min(end - base, QUAD)
    return (1 << hi) - (1 << lo)


@njit(cache=True, nogil=True)
def pack_leaves(node_link):
    """Pack the leaves of the wide nodes ``node_link`` into blocks of :data:`QUAD`
    slots, so that each is read in ceil(count / 4) four-slot groups, the fewest (the leaf
    test reads the blocks a leaf's slots touch, :func:`leaf_base`): a leaf of at most
    four slots in one block, a longer one from a block's start or from where a block's
    tail left room enough. Their references in ``node_link`` are rewritten in place.
    Returns (``moved``, n): slot k's new number ``moved[k]``, and the slots in all
    (a multiple of 4); the others are padding, which no leaf holds.

    Best fit, in the order of the nodes' lanes (a node's leaves stay near each other): a
    leaf of at most three slots goes into the smallest room left in a block that holds
    it, a longer one into the room at the end (a leaf runs on in the next block), or
    each starts a new block. In blocks as written the bunny's leaves (4.4 slots on
    average) took 1.87 groups a leaf; packed, 1.33, for 3.9% of padding slots."""
    n_wide = node_link.shape[0]
    n_slots = 0
    for w in range(n_wide):
        for lane in range(LANES):
            if node_link[w, COUNT_AT + lane] > 0:  # a leaf (0: a wide node, -1: empty)
                n_slots = max(n_slots, node_link[w, REF + lane] + node_link[w, COUNT_AT + lane])
    moved = np.empty(n_slots, dtype=np.int64)
    # Room left inside the blocks written so far, by size (1 .. 3 slots): where it starts.
    room = np.empty((QUAD, n_slots + 1), dtype=np.int64)
    rooms = np.zeros(QUAD, dtype=np.int64)
    end = 0  # the slots written so far; the room after it is the end's, kept apart
    for w in range(n_wide):
        for lane in range(LANES):
            count = node_link[w, COUNT_AT + lane]
            if count <= 0:
                continue
            tail = -end % QUAD
            start = -1
            if count < QUAD:
                for size in range(count, QUAD):
                    if rooms[size] > 0:
                        rooms[size] -= 1
                        start = room[size, rooms[size]]
                        if size > count:
                            room[size - count, rooms[size - count]] = start + count
                            rooms[size - count] += 1
                        break
            if start < 0 and tail > 0 and tail >= count % QUAD > 0:
                start = end  # into the end's room, running on into new blocks
            if start < 0 and tail > 0:  # the end's room stays for a short leaf
                room[tail, rooms[tail]] = end
                rooms[tail] += 1
            if start < 0:
                start = end + tail
            if start >= end:
                end = start + count
            ref = node_link[w, REF + lane]
            for k in range(count):
                moved[ref + k] = start + k
            node_link[w, REF + lane] = start
    return moved, end + (-end % QUAD)


@njit(cache=True, nogil=True, inline="always")
def down32(x):
    """The largest float32 <= x."""
    f = np.float32(x)
    if np.float64(f) > x:
        f = next_float32(f, False)
    return f


@njit(cache=True, nogil=True, inline="always")
def up32(x):
    """The smallest float32 >= x."""
    f = np.float32(x)
    if np.float64(f) < x:
        f = next_float32(f, True)
    return f
