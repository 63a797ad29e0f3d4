"""Visible pieces into plotter paths: collinear overlaps merged (an edge two objects
share is drawn once), pieces joined end to end into polylines, polylines ordered to shorten
the pen-up travel between them."""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["merge_collinear", "merge_runs", "join_polylines", "pen_travel", "order_for_plotter"]


def merge_collinear(segments: np.ndarray, angle_tol=1e-7, offset_tol=1e-5) -> np.ndarray:
    """Merge overlapping collinear segments (S, 2, 3) (e.g. an edge drawn by two objects)
    into one; each merged run lies on, and takes its depth from, its first segment."""
    return merge_runs(segments, angle_tol, offset_tol)[0]


def merge_runs(segments: np.ndarray, angle_tol=1e-7, offset_tol=1e-5) -> tuple:
    """:func:`merge_collinear`'s runs (R, 2, 3) and the run each segment went into (S,)."""
    if len(segments) < 2:
        return segments, np.arange(len(segments))
    xy = segments[:, :, :2]
    d = xy[:, 1] - xy[:, 0]
    theta = np.mod(np.arctan2(d[:, 1], d[:, 0]), np.pi)
    theta = np.where(theta > np.pi - angle_tol, 0.0, theta)
    direction = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    rho = direction[:, 0] * xy[:, 0, 1] - direction[:, 1] * xy[:, 0, 0]
    key = np.stack([np.round(theta / angle_tol), np.round(rho / offset_tol)], axis=1)
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.reshape(-1)
    s = np.einsum("ij,ikj->ik", direction, xy)  # position of both ends along the line
    lo, hi = s.min(axis=1), s.max(axis=1)
    order = np.lexsort((lo, group))
    g, lo, hi = group[order], lo[order], hi[order]
    # Running maximum of hi within each group (groups are contiguous after the sort).
    span = float(np.abs(s).max()) * 4.0 + 1.0
    reach = np.maximum.accumulate(hi + g * span) - g * span
    new_run = np.r_[True, (g[1:] != g[:-1]) | (lo[1:] > reach[:-1] + offset_tol)]
    run_start = np.flatnonzero(new_run)
    run_of = np.empty(len(g), dtype=np.int64)
    run_of[order] = np.cumsum(new_run) - 1
    run_end = np.r_[run_start[1:], len(g)] - 1
    first = order[run_start]
    run_lo, run_hi = lo[run_start], reach[run_end]
    seg = segments[first]
    sa = np.einsum("ij,ij->i", direction[first], seg[:, 0, :2])
    sb = np.einsum("ij,ij->i", direction[first], seg[:, 1, :2])
    length = np.where(sb != sa, sb - sa, 1.0)
    ta = ((run_lo - sa) / length)[:, None]
    tb = ((run_hi - sa) / length)[:, None]
    # Keep each run's orientation along its first segment.
    ta, tb = np.where(sb >= sa, ta[:, 0], tb[:, 0])[:, None], np.where(
        sb >= sa, tb[:, 0], ta[:, 0])[:, None]
    return np.stack([seg[:, 0] + ta * (seg[:, 1] - seg[:, 0]),
                     seg[:, 0] + tb * (seg[:, 1] - seg[:, 0])], axis=1), run_of


# Ends closer than this (pixels) are joined: the slivers dropped between visible pieces
# (1e-3 px) and the hairline gaps where an edge dips behind a face at a shared vertex; a
# hundredth of a pixel is 1/400 of a 0.3 mm pen on A4.
JOIN_PX = 0.01


def _nodes(points: np.ndarray, tol: float) -> np.ndarray:
    """Node id of each point (P, 2): points closer than ``tol`` (chained) are one node."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])),
                       shape=(len(points), len(points)))
    return connected_components(graph, directed=False)[1]


def join_polylines(segments: np.ndarray, height: int, tol=JOIN_PX) -> list:
    """Chain segments whose ends meet (within ``tol`` pixels, :data:`JOIN_PX`) into
    polylines (image coordinates, y down) and drop interior points where the direction
    does not change."""
    if len(segments) == 0:
        return []
    node = _nodes(segments[:, :, :2].reshape(-1, 2), tol).reshape(-1, 2)
    n_nodes = node.max() + 1
    adjacency: list[list[int]] = [[] for _ in range(n_nodes)]
    for s, (a, b) in enumerate(node):
        adjacency[a].append(s)
        adjacency[b].append(s)
    used = np.zeros(len(segments), dtype=bool)
    position = np.zeros((n_nodes, 2))
    position[node[:, 0]] = segments[:, 0, :2]
    position[node[:, 1]] = segments[:, 1, :2]

    def walk(start_node):
        chain = [start_node]
        current = start_node
        while True:
            nxt = None
            for s in adjacency[current]:
                if not used[s]:
                    nxt = s
                    break
            if nxt is None:
                return chain
            used[nxt] = True
            a, b = node[nxt]
            current = b if a == current else a
            chain.append(current)

    # Chains start at odd-degree nodes first (each must end a chain, Euler), then anywhere.
    degree = np.array([len(a) for a in adjacency])
    chains = []
    for start_node in list(np.flatnonzero(degree % 2 == 1)) + list(range(n_nodes)):
        while any(not used[s] for s in adjacency[start_node]):
            chains.append(walk(start_node))
    out = []
    for chain in _joined_at_ends(chains):
        line = _simplify(position[chain])  # a new array (fancy indexing): flipped in place
        line[:, 1] = height - line[:, 1]
        out.append(line)
    return out


def _joined_at_ends(chains: list) -> list:
    """Chains (lists of node ids) with two chains that end at the same node made one."""
    at: dict = {}
    for k, chain in enumerate(chains):
        for end in (chain[0], chain[-1]):
            at.setdefault(end, []).append(k)
    alive = [True] * len(chains)
    for k in range(len(chains)):
        for _ in range(2):  # grow the chain at its end, then (turned round) at its start
            while alive[k] and chains[k][0] != chains[k][-1]:
                chain = chains[k]
                other = next((j for j in at.get(chain[-1], ()) if j != k and alive[j]), None)
                if other is None:
                    break
                tail = chains[other] if chains[other][0] == chain[-1] else chains[other][::-1]
                alive[other] = False
                at[chain[-1]] = [j for j in at[chain[-1]] if j not in (k, other)]
                at[tail[-1]] = [j for j in at.get(tail[-1], ()) if j != other] + [k]
                chains[k] = chain + tail[1:]
            chains[k] = chains[k][::-1]
    return [chain for chain, keep in zip(chains, alive) if keep]


def pen_travel(polylines: list) -> float:
    """Pen-up travel of drawing ``polylines`` in order, from the first one's start: the
    sum of the jumps from each end to the next start (pixels)."""
    if len(polylines) < 2:
        return 0.0
    ends = np.array([line[-1] for line in polylines[:-1]])
    starts = np.array([line[0] for line in polylines[1:]])
    return float(np.linalg.norm(starts - ends, axis=1).sum())


def order_for_plotter(polylines: list, start=(0.0, 0.0)) -> list:
    """The polylines in an order, each possibly reversed, that shortens pen-up travel: from
    ``start``, always the nearest unused end next (greedy, as plotter tools sort; the
    nearest ends found through a k-d tree, so 100k polylines take well under a second),
    then improved by 2-opt moves up to :data:`TWO_OPT_MAX` polylines."""
    greedy = _nearest_next(polylines, start)
    return _two_opt(greedy, start) if len(greedy) <= TWO_OPT_MAX else greedy


# 2-opt checks every pair of cut points: O(n^2) a pass (compiled: ~20 ms a pass at 4,000);
# most of the gain comes in the first passes.
TWO_OPT_MAX = 4000
TWO_OPT_PASSES = 6


def _two_opt(polylines: list, start, max_passes: int = TWO_OPT_PASSES) -> list:
    """Reverse runs of the drawing order (each polyline in the run turned round) while that
    shortens the pen-up travel (2-opt, Croes 1958, on an open path from ``start``)."""
    n = len(polylines)
    if n < 2:
        return list(polylines)
    first = np.array([p[0] for p in polylines], dtype=np.float64)
    last = np.array([p[-1] for p in polylines], dtype=np.float64)
    order, flipped = _two_opt_kernel(first, last, np.asarray(start, dtype=np.float64),
                                     max_passes)
    return [polylines[k][::-1] if f else polylines[k] for k, f in zip(order, flipped)]


@njit(cache=True)
def _two_opt_kernel(first, last, here, max_passes):
    """(order, flipped) of the polylines with ends ``first``/``last`` (n, 2) after 2-opt
    moves: reversing positions i..j replaces the jumps (end before i -> first[i]) and
    (last[j] -> first[j+1]) by (end before i -> last[j]) and (first[i] -> first[j+1])."""
    n = first.shape[0]
    first, last = first.copy(), last.copy()
    order = np.arange(n)
    flipped = np.zeros(n, dtype=np.bool_)
    for _ in range(max_passes):
        improved = False
        for i in range(n):
            bx, by = (last[i - 1, 0], last[i - 1, 1]) if i > 0 else (here[0], here[1])
            into_i = np.hypot(first[i, 0] - bx, first[i, 1] - by)
            best, best_j = 0.0, -1
            for j in range(i, n):
                old = into_i
                new = np.hypot(last[j, 0] - bx, last[j, 1] - by)
                if j + 1 < n:
                    old += np.hypot(first[j + 1, 0] - last[j, 0], first[j + 1, 1] - last[j, 1])
                    new += np.hypot(first[j + 1, 0] - first[i, 0],
                                    first[j + 1, 1] - first[i, 1])
                gain = old - new
                if gain > best and gain > 1e-9 * (1.0 + old):
                    best, best_j = gain, j
            if best_j < 0:
                continue
            lo, hi = i, best_j
            while lo < hi:
                for a in range(2):
                    first[lo, a], first[hi, a] = first[hi, a], first[lo, a]
                    last[lo, a], last[hi, a] = last[hi, a], last[lo, a]
                order[lo], order[hi] = order[hi], order[lo]
                flipped[lo], flipped[hi] = flipped[hi], flipped[lo]
                lo += 1
                hi -= 1
            for k in range(i, best_j + 1):  # each polyline of the run turned round
                for a in range(2):
                    first[k, a], last[k, a] = last[k, a], first[k, a]
                flipped[k] = not flipped[k]
            improved = True
        if not improved:
            break
    return order, flipped


@njit(cache=True)
def _nearest_next_kernel(ends, here):
    """The ends picked in greedy order (each polyline's first end 2k, last end 2k + 1),
    every free end looked at each time: O(n^2), for the sizes 2-opt takes anyway."""
    n = ends.shape[0] // 2
    used = np.zeros(n, dtype=np.bool_)
    picks = np.empty(n, dtype=np.int64)
    hx, hy = here[0], here[1]
    for k in range(n):
        best, pick = np.inf, -1
        for e in range(2 * n):
            if not used[e // 2]:
                d = (ends[e, 0] - hx) ** 2 + (ends[e, 1] - hy) ** 2
                if d < best:
                    best, pick = d, e
        used[pick // 2] = True
        picks[k] = pick
        other = pick + 1 if pick % 2 == 0 else pick - 1
        hx, hy = ends[other, 0], ends[other, 1]
    return picks


def _nearest_next(polylines: list, start) -> list:
    """Greedy order: from ``start``, the polyline with the nearest free end next."""
    from scipy.spatial import cKDTree

    n = len(polylines)
    if n == 0:
        return []
    ends = np.empty((2 * n, 2))
    ends[0::2] = [line[0] for line in polylines]
    ends[1::2] = [line[-1] for line in polylines]
    if n <= TWO_OPT_MAX:
        return [polylines[p // 2] if p % 2 == 0 else polylines[p // 2][::-1]
                for p in _nearest_next_kernel(ends, np.asarray(start, dtype=np.float64))]
    tree = cKDTree(ends)
    used = np.zeros(n, dtype=bool)
    out: list = []
    here = np.asarray(start, dtype=np.float64)
    k = 8
    while len(out) < n:
        _, idx = tree.query(here, k=min(k, 2 * n))
        idx = np.atleast_1d(idx)
        free = idx[~used[idx // 2]]
        if not len(free):  # all nearest ends taken: look further
            k = min(2 * k, 2 * n)
            continue
        pick = int(free[0])
        line = polylines[pick // 2]
        used[pick // 2] = True
        line = line if pick % 2 == 0 else line[::-1]
        out.append(line)
        here = line[-1]
        k = 8
    return out


def _simplify(points: np.ndarray) -> np.ndarray:
    """Drop interior points where a polyline goes straight on (collinear joins)."""
    if len(points) < 3:
        return points
    return points[_straight_on(np.ascontiguousarray(points, dtype=np.float64))]


@njit(cache=True)
def _straight_on(points):
    """Indices of the points to keep: the ends, and each point where the direction from
    the last kept point turns (or goes back)."""
    keep = np.empty(len(points), dtype=np.int64)
    keep[0], n = 0, 1
    for i in range(1, len(points) - 1):
        ux, uy = points[i, 0] - points[keep[n - 1], 0], points[i, 1] - points[keep[n - 1], 1]
        vx, vy = points[i + 1, 0] - points[i, 0], points[i + 1, 1] - points[i, 1]
        cross = ux * vy - uy * vx
        if abs(cross) > 1e-9 * (np.hypot(ux, uy) * np.hypot(vx, vy) + 1e-300) \
                or ux * vx + uy * vy <= 0:
            keep[n] = i
            n += 1
    keep[n] = len(points) - 1
    return keep[:n + 1]
