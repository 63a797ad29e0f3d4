"""Newell, Newell & Sancha (1972): depth sort with the tests that make painting exact.

Works in window space, where every triangle is planar (window depth is an affine function
of window x, y) and the view is orthographic along depth. The list is sorted farthest
first; the farthest polygon P is painted only when no polygon Q whose depth range overlaps
P's might be hidden by it. For each such Q the classic tests run in order, cheapest first:

1. x extents do not overlap;  2. y extents do not overlap;
3. P lies entirely behind Q's plane;  4. Q lies entirely in front of P's plane;
5. the projections of P and Q do not overlap (exact separating-axis test).

If one passes, Q is no obstacle. If all fail, Q may have to be painted before P: when Q is
behind P's plane or P in front of Q's plane, Q moves to the head of the list and is
marked. Meeting a marked Q again means a cycle (or penetration): the polygon that
straddles the other's plane is split by it, the pieces go back into the list, and the
process goes on. Equal depths (coplanar polygons) are painted later-submitted first, so
the first submitted ends on top, as with the z-buffer's LESS.

The list is kept as a stack of moved polygons over a heap of the others ordered by their
farthest depth, and the candidates Q of a P come from a grid over the screen: every
remaining polygon whose box meets P's is tested, whatever its place in the list (the
textbook's "stop at the first Q entirely nearer than P" holds only while the list stays
sorted, which moves and splits break). Moves, splits and pair tests are bounded
(``max_actions``, ``max_pair_tests``); a polygon that cannot be ordered within them (or
a cycle with no polygon straddling another's plane) is *deferred*: it is drawn after the
ordered ones with a depth test, so every pixel is still right, and ``stats`` says how many
polygons (``unresolved``) and pixels (``unresolved_pixels``) this fallback decided.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import RenderError
from ..geometry.clip import grow, split_triangle
from ..geometry.state import DepthFunc, RenderState
from ..parallel import Workers, run_with_progress
from ..raster.fill import rasterize
from .fragments import Fragments
from .support import Needs, apply_clear_depth, refuse_unless_nearest_wins, refuse_unsupported

NAME = "newell"
# Accepted keys of render(..., options=...) and what each takes.
OPTIONS = {"max_actions": int, "max_pair_tests": int, "progress": bool}
DESCRIPTION = "Newell-Newell-Sancha: depth sort + 5 tests, reorder, split cycles"


def check(state: RenderState, needs: Needs) -> None:
    """Raise :class:`RenderError` for a request newell cannot honour exactly."""
    refuse_unless_nearest_wins(NAME, state)
    refuse_unsupported(NAME, state, needs, allowed=("counts", "subset", "offset"))


def resolve(screen, state, workers: Workers | None = None, counts: bool = False,
            max_actions: int | None = None, max_pair_tests: int | None = None,
            progress: bool = False, **_) -> Fragments:
    """Newell's order painted far to near. ``max_actions`` (moves + splits, default
    20 n + 1000) and ``max_pair_tests`` (candidates met, default 1000 n + 10**8)
    bound the work;
    ``progress`` shows a bar on the terminal."""
    workers = workers or Workers()
    xy, z, face, deferred, stats = newell_order(
        screen.xy_window, screen.depth_window, screen.face_id, screen.width, screen.height,
        max_actions, max_pair_tests, progress)
    fc, depth, _, tested, written, c_tested, c_written = rasterize(
        xy, z, face, screen.width, screen.height, state, workers, depth_test=True,
        depth_func=DepthFunc.ALWAYS.code, depth_write=True, counts=counts)
    stats.update(fragments_tested=int(tested), fragments_written=int(written))
    stats["unresolved_pixels"] = 0
    if len(deferred[2]):
        # The fallback: polygons that could not be ordered, drawn with the depth test over
        # the painted ones (whose depth buffer holds the nearest painted surface).
        fd, _, _, t2, w2, ct2, cw2 = rasterize(
            deferred[0], deferred[1], deferred[2], screen.width, screen.height, state,
            workers, depth_test=True, depth_func=DepthFunc.LESS.code, depth_write=True,
            counts=counts, depth_buffer=depth)
        decided = fd >= 0
        fc = np.where(decided, fd, fc).astype(np.int32)
        stats["unresolved_pixels"] = int(np.count_nonzero(decided))
        stats.update(fragments_tested=int(tested + t2), fragments_written=int(written + w2))
        if counts:
            c_tested, c_written = c_tested + ct2, c_written + cw2
    stats["cleared_by_clear_depth"] = apply_clear_depth(fc, depth, state)
    fragments = Fragments(fc, depth, screen, stats, c_tested, c_written)
    if not len(deferred[2]):  # an exact vector picture only when everything was ordered
        fragments.buffers["polygons"] = (xy, face, "back_to_front")
    return fragments


def newell_order(xy_window, depth_window, face_id, width, height, max_actions=None,
                 max_pair_tests=None, progress=False):
    """Painting order: (xy (M, 3, 2), depth (M, 3), face (M,), deferred (xy, depth, face)
    of the polygons left to the depth-tested fallback, stats)."""
    n = len(face_id)
    max_actions = 20 * n + 1000 if max_actions is None else int(max_actions)
    max_pair_tests = 1000 * n + 10 ** 8 if max_pair_tests is None else int(max_pair_tests)
    if max_actions < 0 or max_pair_tests < 0:
        raise RenderError("newell max_actions and max_pair_tests must be >= 0")
    xy_window = np.ascontiguousarray(xy_window, dtype=np.float64)
    depth_window = np.ascontiguousarray(depth_window, dtype=np.float64)
    grid = _grid_shape(xy_window, width, height)
    report = np.zeros(3, dtype=np.int64)  # polygons finished, polygons made, done
    args = (xy_window, depth_window, np.ascontiguousarray(face_id, dtype=np.int64),
            float(width), float(height), *grid, max_actions, max_pair_tests, report)
    if progress and n > 0:
        out = run_with_progress(_newell, args, report, n, "newell")
    else:
        out = _newell(*args)
    order, deferred, xy, z, face, n_moves, n_splits, n_tests = out
    stats = {"moves": int(n_moves), "splits": int(n_splits), "unresolved": len(deferred),
             "pair_tests": int(n_tests), "polygons_painted": len(order),
             "max_actions": max_actions, "max_pair_tests": max_pair_tests}
    return (xy[order].copy(), z[order].copy(), face[order].copy(),
            (xy[deferred].copy(), z[deferred].copy(), face[deferred].copy()), stats)


def _grid_shape(xy_window, width, height):
    """(columns, rows) of the screen grid that indexes polygons by their boxes: about one
    cell per polygon, cells no smaller than the median box, at most 1024 x 1024, and
    entries (box x cells covered, summed) kept within 16 n + 4096."""
    n = len(xy_window)
    if n == 0:
        return 1, 1
    lo = np.clip(xy_window.min(axis=1), 0.0, [width, height])
    hi = np.clip(xy_window.max(axis=1), 0.0, [width, height])
    ext = np.maximum(np.median(hi - lo, axis=0), 1.0)
    side = max(np.sqrt(width * height / n), 1.0)
    gx = int(min(1024, max(1, width / max(side, ext[0]))))
    gy = int(min(1024, max(1, height / max(side, ext[1]))))
    while gx * gy > 1:
        cells = ((np.floor(hi[:, 0] * gx / width) - np.floor(lo[:, 0] * gx / width) + 1)
                 * (np.floor(hi[:, 1] * gy / height) - np.floor(lo[:, 1] * gy / height) + 1))
        if cells.sum() <= 16 * n + 4096:
            break
        gx, gy = max(1, gx // 2), max(1, gy // 2)
    return gx, gy


@njit(cache=True, nogil=True, inline="always")
def _plane(xy, z, p):
    """z = a x + b y + c through polygon p; ok False for an edge-on (zero area) one."""
    ax, ay = xy[p, 1, 0] - xy[p, 0, 0], xy[p, 1, 1] - xy[p, 0, 1]
    bx, by = xy[p, 2, 0] - xy[p, 0, 0], xy[p, 2, 1] - xy[p, 0, 1]
    az, bz = z[p, 1] - z[p, 0], z[p, 2] - z[p, 0]
    det = ax * by - bx * ay
    if det == 0.0:
        return 0.0, 0.0, 0.0, False
    a = (az * by - bz * ay) / det
    b = (ax * bz - bx * az) / det
    return a, b, z[p, 0] - a * xy[p, 0, 0] - b * xy[p, 0, 1], True


@njit(cache=True, nogil=True)
def _side_of(xy, z, p, a, b, c, eps):
    """Where polygon p lies relative to the plane z = a x + b y + c: +1 entirely behind
    (farther, z >= plane), -1 entirely in front, 0 on it, 2 straddling."""
    behind = front = False
    for k in range(3):
        s = z[p, k] - (a * xy[p, k, 0] + b * xy[p, k, 1] + c)
        if s > eps:
            behind = True
        elif s < -eps:
            front = True
    if behind and front:
        return 2
    if behind:
        return 1
    if front:
        return -1
    return 0


@njit(cache=True, nogil=True)
def _projections_overlap(xy, p, q, eps):
    """Separating-axis test on the 2-D triangles; touching counts as not overlapping."""
    for first in range(2):
        s, o = (p, q) if first == 0 else (q, p)
        for k in range(3):
            ex = xy[s, (k + 1) % 3, 0] - xy[s, k, 0]
            ey = xy[s, (k + 1) % 3, 1] - xy[s, k, 1]
            nx, ny = -ey, ex
            s_lo = s_hi = nx * xy[s, 0, 0] + ny * xy[s, 0, 1]
            for m in range(1, 3):
                d = nx * xy[s, m, 0] + ny * xy[s, m, 1]
                s_lo, s_hi = min(s_lo, d), max(s_hi, d)
            o_lo = o_hi = nx * xy[o, 0, 0] + ny * xy[o, 0, 1]
            for m in range(1, 3):
                d = nx * xy[o, m, 0] + ny * xy[o, m, 1]
                o_lo, o_hi = min(o_lo, d), max(o_hi, d)
            tol = eps * (abs(nx) + abs(ny))
            if o_hi <= s_lo + tol or s_hi <= o_lo + tol:
                return False
    return True


@njit(cache=True, nogil=True, inline="always")
def _first(zmax, a, b):
    """Whether polygon a comes before b in the depth-sorted list: farther first, then
    the older polygon (submission order, pieces after their sources)."""
    return zmax[a] > zmax[b] or (zmax[a] == zmax[b] and a < b)


@njit(cache=True, nogil=True)
def _heap_push(heap, n, zmax, p):
    heap = grow(heap, n + 1)
    heap[n] = p
    i = n
    while i > 0:
        up = (i - 1) // 2
        if not _first(zmax, heap[i], heap[up]):
            break
        heap[i], heap[up] = heap[up], heap[i]
        i = up
    return heap, n + 1


@njit(cache=True, nogil=True)
def _heap_pop(heap, n, zmax):
    n -= 1
    heap[0] = heap[n]
    i = 0
    while True:
        a, b, best = 2 * i + 1, 2 * i + 2, i
        if a < n and _first(zmax, heap[a], heap[best]):
            best = a
        if b < n and _first(zmax, heap[b], heap[best]):
            best = b
        if best == i:
            return n
        heap[i], heap[best] = heap[best], heap[i]
        i = best


@njit(cache=True, nogil=True, inline="always")
def _cell_range(lo, hi, size, cells):
    a = int(min(max(lo, 0.0), size) * cells / size)
    b = int(min(max(hi, 0.0), size) * cells / size)
    return min(a, cells - 1), min(b, cells - 1)


@njit(cache=True, nogil=True, inline="always")
def _extents(p, xy, z, zmin, zmax, box):
    """Depth range and screen box (x0, x1, y0, y1) of polygon ``p``."""
    zmin[p] = min(z[p, 0], z[p, 1], z[p, 2])
    zmax[p] = max(z[p, 0], z[p, 1], z[p, 2])
    box[p, 0] = min(xy[p, 0, 0], xy[p, 1, 0], xy[p, 2, 0])
    box[p, 1] = max(xy[p, 0, 0], xy[p, 1, 0], xy[p, 2, 0])
    box[p, 2] = min(xy[p, 0, 1], xy[p, 1, 1], xy[p, 2, 1])
    box[p, 3] = max(xy[p, 0, 1], xy[p, 1, 1], xy[p, 2, 1])


@njit(cache=True, nogil=True)
def _index(p, box, width, height, gx, gy, cell_first, entry_poly, entry_next, n_entries):
    """List polygon ``p`` in every grid cell its box meets (at the head of each cell's
    linked list). Returns the (possibly grown) entry arrays and their length."""
    cx0, cx1 = _cell_range(box[p, 0], box[p, 1], width, gx)
    cy0, cy1 = _cell_range(box[p, 2], box[p, 3], height, gy)
    for cy in range(cy0, cy1 + 1):
        for cx in range(cx0, cx1 + 1):
            entry_poly = grow(entry_poly, n_entries + 1)
            entry_next = grow(entry_next, n_entries + 1)
            c = cy * gx + cx
            entry_poly[n_entries] = p
            entry_next[n_entries] = cell_first[c]
            cell_first[c] = n_entries
            n_entries += 1
    return entry_poly, entry_next, n_entries


@njit(cache=True, nogil=True)
def _newell(xy_in, z_in, face_in, width, height, gx, gy, max_actions, max_tests, report):
    n0 = xy_in.shape[0]
    cap = max(16, 2 * n0)
    xy = np.empty((cap, 3, 2))
    z = np.empty((cap, 3))
    face = np.empty(cap, dtype=np.int64)
    zmin = np.empty(cap)
    zmax = np.empty(cap)
    box = np.empty((cap, 4))  # x0, x1, y0, y1
    xy[:n0], z[:n0], face[:n0] = xy_in, z_in, face_in
    state = np.zeros(cap, dtype=np.int8)  # 0 queued, 1 moved (on the stack), 2 finished
    mark = np.zeros(cap, dtype=np.int64)  # == epoch: moved since the last split
    stamp = np.full(cap, -1, dtype=np.int64)  # last query that met the polygon
    epoch = 1
    # The screen grid: per cell a linked list of the polygons whose box meets it.
    cell_first = np.full(gx * gy, -1, dtype=np.int64)
    entry_poly = np.empty(4 * cap, dtype=np.int64)
    entry_next = np.empty(4 * cap, dtype=np.int64)
    n_entries = 0
    heap = np.empty(cap, dtype=np.int64)
    n_heap = 0
    stack = np.empty(16, dtype=np.int64)
    n_stack = 0
    out = np.empty(cap, dtype=np.int64)
    n_out = 0
    deferred = np.empty(16, dtype=np.int64)
    n_def = 0
    scale = 1.0
    for p in range(n0):
        for k in range(3):
            scale = max(scale, abs(xy[p, k, 0]), abs(xy[p, k, 1]))
    eps_xy = 1e-9 * scale
    eps_z = 1e-12
    for p in range(n0):
        _extents(p, xy, z, zmin, zmax, box)
        heap, n_heap = _heap_push(heap, n_heap, zmax, p)
        entry_poly, entry_next, n_entries = _index(p, box, width, height, gx, gy, cell_first,
                                                   entry_poly, entry_next, n_entries)
    n_poly = n0
    report[1] = n0
    n_moves = n_splits = n_tests = 0
    actions = 0
    query = 0
    victim_tri = np.empty((3, 3))
    part_front = np.empty((2, 3, 3))
    part_back = np.empty((2, 3, 3))
    while True:
        # The head of the list: the most recently moved polygon, else the farthest.
        p = -1
        while n_stack > 0:
            if state[stack[n_stack - 1]] == 1:
                p = stack[n_stack - 1]
                break
            n_stack -= 1
        if p < 0:
            while n_heap > 0:
                if state[heap[0]] == 0:
                    p = heap[0]
                    break
                n_heap = _heap_pop(heap, n_heap, zmax)
        if p < 0:
            break
        report[0] = n_out + n_def
        if actions >= max_actions or n_tests >= max_tests:
            # Out of budget: the rest goes to the depth-tested fallback.
            state[p] = 2
            deferred = grow(deferred, n_def + 1)
            deferred[n_def] = p
            n_def += 1
            continue
        pa, pb, pc, p_ok = _plane(xy, z, p)
        action = 0  # 0 paint P, 1 move Q to the head, 2 split, 3 defer P
        q_hit = -1
        query += 1
        if p_ok:  # an edge-on P covers no area: paint it without tests
            cx0, cx1 = _cell_range(box[p, 0], box[p, 1], width, gx)
            cy0, cy1 = _cell_range(box[p, 2], box[p, 3], height, gy)
            for cy in range(cy0, cy1 + 1):
                for cx in range(cx0, cx1 + 1):
                    c = cy * gx + cx
                    e = cell_first[c]
                    prev = -1
                    while e >= 0:
                        q = entry_poly[e]
                        nxt = entry_next[e]
                        if state[q] == 2:  # finished: unlink, so no query meets it again
                            if prev < 0:
                                cell_first[c] = nxt
                            else:
                                entry_next[prev] = nxt
                            e = nxt
                            continue
                        prev = e
                        e = nxt
                        if q == p or stamp[q] == query:
                            continue
                        stamp[q] = query
                        n_tests += 1
                        if zmax[q] <= zmin[p]:
                            continue  # Q entirely nearer: painted later anyway
                        # 1, 2: x and y extents.
                        if (box[q, 1] <= box[p, 0] + eps_xy or box[q, 0] >= box[p, 1] - eps_xy
                                or box[q, 3] <= box[p, 2] + eps_xy
                                or box[q, 2] >= box[p, 3] - eps_xy):
                            continue
                        qa, qb, qc, q_ok = _plane(xy, z, q)
                        if not q_ok:
                            continue
                        p_vs_q = _side_of(xy, z, p, qa, qb, qc, eps_z)
                        q_vs_p = _side_of(xy, z, q, pa, pb, pc, eps_z)
                        coplanar = p_vs_q == 0 and q_vs_p == 0
                        if coplanar:
                            # Paint the later-submitted first so the first one wins.
                            if face[p] >= face[q]:
                                continue
                        elif p_vs_q == 1 or p_vs_q == 0 or q_vs_p == -1 or q_vs_p == 0:
                            continue  # 3: P behind Q's plane; 4: Q in front of P's plane
                        # 5: projections.
                        if not _projections_overlap(xy, p, q, eps_xy):
                            continue
                        # Q may be hidden by P: Q must go first, if it can (3', 4').
                        can_move = q_vs_p == 1 or p_vs_q == -1 or coplanar
                        if can_move and mark[q] != epoch:
                            action = 1
                        elif coplanar:
                            action = 3
                        else:
                            action = 2
                        q_hit = q
                        break
                    if action != 0:
                        break
                if action != 0:
                    break
        if action == 0:
            out = grow(out, n_out + 1)
            out[n_out] = p
            n_out += 1
            state[p] = 2
            continue
        actions += 1
        if action == 1:
            stack = grow(stack, n_stack + 1)
            stack[n_stack] = q_hit
            n_stack += 1
            state[q_hit] = 1
            mark[q_hit] = epoch
            n_moves += 1
            continue
        victim = -1
        if action == 2:
            # A cycle or a penetration: split whichever straddles the other's plane.
            qa, qb, qc, _ = _plane(xy, z, q_hit)
            if _side_of(xy, z, p, qa, qb, qc, eps_z) == 2:
                victim, va, vb, vc = p, qa, qb, qc
            elif _side_of(xy, z, q_hit, pa, pb, pc, eps_z) == 2:
                victim, va, vb, vc = q_hit, pa, pb, pc
        if victim < 0:
            # No polygon straddles the other's plane (a cycle of whole polygons that
            # no cut by these two planes breaks): the depth-tested fallback draws P.
            state[p] = 2
            deferred = grow(deferred, n_def + 1)
            deferred[n_def] = p
            n_def += 1
            continue
        n_splits += 1
        state[victim] = 2
        # Cut it by the plane z = va x + vb y + vc, i.e. n . (x, y, z) + d = 0 with
        # n = (-va, -vb, 1), d = -vc (the same Sutherland-Hodgman cut the BSP uses).
        for k in range(3):
            victim_tri[k, 0], victim_tri[k, 1], victim_tri[k, 2] = (
                xy[victim, k, 0], xy[victim, k, 1], z[victim, k])
        n_front, n_back = split_triangle(victim_tri, -va, -vb, 1.0, -vc, eps_z, part_front,
                                         part_back)
        for k in range(n_front + n_back):
            part = part_front[k] if k < n_front else part_back[k - n_front]
            m = n_poly
            xy = grow(xy, m + 1)
            z = grow(z, m + 1)
            face = grow(face, m + 1)
            zmin = grow(zmin, m + 1)
            zmax = grow(zmax, m + 1)
            box = grow(box, m + 1)
            state = grow(state, m + 1)
            mark = grow(mark, m + 1)
            stamp = grow(stamp, m + 1)
            for c in range(3):
                xy[m, c, 0] = part[c, 0]
                xy[m, c, 1] = part[c, 1]
                z[m, c] = part[c, 2]
            face[m] = face[victim]
            _extents(m, xy, z, zmin, zmax, box)
            state[m] = 0
            mark[m] = 0
            stamp[m] = -1
            heap, n_heap = _heap_push(heap, n_heap, zmax, m)
            entry_poly, entry_next, n_entries = _index(m, box, width, height, gx, gy,
                                                       cell_first, entry_poly, entry_next,
                                                       n_entries)
            n_poly += 1
        report[1] = n_poly
        # Marks belonged to the old list; start fresh for the new pieces.
        epoch += 1
    report[0] = n_out + n_def
    report[2] = 1
    return (out[:n_out].copy(), deferred[:n_def].copy(), xy[:n_poly].copy(),
            z[:n_poly].copy(), face[:n_poly].copy(), n_moves, n_splits, n_tests)
