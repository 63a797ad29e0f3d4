"""The walked tree's node layout: an 8-wide node is one 256-byte record (four cache
lines), its eight child boxes as float32 bounds rounded outwards, then eight references
and eight counts (:func:`node_records`). Nodes are numbered in level order, so the first
:data:`HOT_NODES` are the top of the tree."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import next_float32, record_words

__all__ = ["LANES", "NODE_WORDS", "REF", "COUNT_AT", "HOT_NODES", "node_records", "child",
           "set_child", "down32", "up32"]

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
def set_child(node_link, w, lane, ref, count):
    """Make lane ``lane`` of wide node ``w`` hold ``(ref, count)`` (see :func:`child`)."""
    node_link[w, REF + lane], node_link[w, COUNT_AT + lane] = ref, count


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
