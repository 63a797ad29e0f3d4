"""The collapse of the binary SAH tree into the 8-wide tree the walks read
(:func:`widen`), by a cost model of nodes visited and triangles tested
(:func:`_collapse_plan`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from .layout import LANES, down32, set_child, up32

__all__ = ["C_NODE", "C_LEAF_TRIANGLE", "LEAF_MAX", "widen"]

# The collapse's cost model: a wide node visited costs C_NODE, a triangle tested
# C_LEAF_TRIANGLE (a leaf is one run of memory, tested four at a time); binary leaves
# merge into leaves of up to LEAF_MAX triangles where that is cheaper.
# (Measurements: docs/history.md, "Ray core".)
C_NODE, C_LEAF_TRIANGLE = 1.0, 0.08

LEAF_MAX = 8


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
    # Depth-first order, the order the build wrote the nodes in: the reads run through memory.
    # (Measurements: docs/history.md, "Ray core".)
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
    :func:`_collapse_plan`: least cost by the surface area heuristic, binary leaves merged
    into leaves of up to LEAF_MAX triangles where that is cheaper), written into the records
    of :func:`hsr.algorithms.bvh.layout.node_records` (``node_box``, ``node_link``, with
    room for a wide node per inner binary node). A wide node's lanes are its children: boxes
    as [lo_x.., lo_y.., lo_z.., hi_x.., hi_y.., hi_z..] rounded outwards to float32 (an
    empty lane's box lies at +inf, so every ray misses it); references a leaf's first slot
    with its count > 0, a wide node's number with count 0, or count -1 for an empty lane.
    Returns (wide nodes, deepest wide level). The root must be an inner node.

    Wide nodes are numbered in level order (the root, then its children, then theirs),
    a node's wide children next to each other: the first few thousand are the top of
    the tree, which every walk passes through, and :func:`hsr.algorithms.bvh.walk.trace_range`
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
                set_child(node_link, w, lane, 0, -1)
                continue
            q = kids[lane]
            c = order[q]
            for a in range(3):
                node_box[w, LANES * a + lane] = down32(node_min[c, a])
                node_box[w, LANES * (3 + a) + lane] = up32(node_max[c, a])
            if node_left[c] < 0 or choice[q, 0] < 0:  # a leaf (of the subtree's slots)
                set_child(node_link, w, lane, node_start[c], node_count[c])
            else:
                set_child(node_link, w, lane, n_wide, 0)
                todo_pos[top], todo_wide[top], todo_level[top] = q, n_wide, level + 1
                top += 1
                n_wide += 1
    return n_wide, depth
