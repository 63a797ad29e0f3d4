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
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..geometry.clip import grow, split_triangle
from ..geometry.state import DepthFunc, RenderState
from ..parallel import Workers
from ..raster.fill import rasterize
from .fragments import Fragments
from .support import Needs, refuse_unsupported

NAME = "newell"
OPTIONS = ()  # accepted keys of render(..., options=...)
DESCRIPTION = "Newell-Newell-Sancha: depth sort + 5 tests, reorder, split cycles"


def check(state: RenderState, needs: Needs) -> None:
    """Raise :class:`RenderError` for a request newell cannot honour exactly."""
    refuse_unsupported(NAME, state, needs, allowed=("counts", "subset", "offset"))


def resolve(screen, state, workers: Workers | None = None, counts: bool = False,
            **_) -> Fragments:
    workers = workers or Workers()
    xy, z, face, stats = newell_order(screen.xy_window, screen.depth_window, screen.face_id)
    fc, depth, _, tested, written, c_tested, c_written = rasterize(
        xy, z, face, screen.width, screen.height, state, workers, depth_test=True,
        depth_func=DepthFunc.ALWAYS.code, depth_write=True, counts=counts)
    stats.update(fragments_tested=int(tested), fragments_written=int(written))
    fragments = Fragments(fc, depth, screen, stats, c_tested, c_written)
    fragments.buffers["polygons"] = (xy, face, "back_to_front")
    return fragments


def newell_order(xy_window, depth_window, face_id):
    """Painting order: (xy (M, 3, 2), depth (M, 3), face (M,), stats)."""
    out = _newell(np.ascontiguousarray(xy_window, dtype=np.float64),
                  np.ascontiguousarray(depth_window, dtype=np.float64),
                  np.ascontiguousarray(face_id, dtype=np.int64))
    xy, z, face, n_moves, n_splits, n_unresolved, n_tests = out
    stats = {"moves": int(n_moves), "splits": int(n_splits), "unresolved": int(n_unresolved),
             "pair_tests": int(n_tests), "polygons_painted": len(face)}
    return xy, z, face, stats


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


@njit(cache=True, nogil=True)
def _newell(xy_in, z_in, face_in):
    n0 = xy_in.shape[0]
    cap = max(8, 2 * n0)
    xy = np.empty((cap, 3, 2))
    z = np.empty((cap, 3))
    face = np.empty(cap, dtype=np.int64)
    xy[:n0], z[:n0], face[:n0] = xy_in, z_in, face_in
    n_poly = n0
    scale = 1.0
    for p in range(n0):
        for k in range(3):
            scale = max(scale, abs(xy[p, k, 0]), abs(xy[p, k, 1]))
    eps_xy = 1e-9 * scale
    eps_z = 1e-12
    zmax = np.empty(cap)
    for p in range(n0):
        zmax[p] = max(z[p, 0], z[p, 1], z[p, 2])
    # The list, farthest first (stable: equal depths keep submission order).
    lst = np.argsort(-zmax[:n0], kind="mergesort").astype(np.int64)
    lst = grow(lst, cap)
    head, n_lst = 0, n0
    marked = np.zeros(cap, dtype=np.bool_)
    out = np.empty(cap, dtype=np.int64)
    n_out = 0
    n_moves = n_splits = n_unresolved = n_tests = 0
    budget = 20 * n0 + 1000  # moves + splits before giving up on a polygon
    victim_tri = np.empty((3, 3))
    part_front = np.empty((2, 3, 3))
    part_back = np.empty((2, 3, 3))
    while head < n_lst:
        p = lst[head]
        pa, pb, pc, p_ok = _plane(xy, z, p)
        action = 0  # 0 paint P, 1 move Q to front, 2 split
        target = -1
        j = head + 1
        # An edge-on P covers no area: paint it without tests.
        p_zmin = min(z[p, 0], z[p, 1], z[p, 2])
        p_x0 = min(xy[p, 0, 0], xy[p, 1, 0], xy[p, 2, 0])
        p_x1 = max(xy[p, 0, 0], xy[p, 1, 0], xy[p, 2, 0])
        p_y0 = min(xy[p, 0, 1], xy[p, 1, 1], xy[p, 2, 1])
        p_y1 = max(xy[p, 0, 1], xy[p, 1, 1], xy[p, 2, 1])
        while p_ok and j < n_lst:
            q = lst[j]
            if zmax[q] <= p_zmin:
                break  # sorted: no later Q overlaps P in depth
            j += 1
            n_tests += 1
            # 1, 2: x and y extents.
            if (max(xy[q, 0, 0], xy[q, 1, 0], xy[q, 2, 0]) <= p_x0 + eps_xy
                    or min(xy[q, 0, 0], xy[q, 1, 0], xy[q, 2, 0]) >= p_x1 - eps_xy
                    or max(xy[q, 0, 1], xy[q, 1, 1], xy[q, 2, 1]) <= p_y0 + eps_xy
                    or min(xy[q, 0, 1], xy[q, 1, 1], xy[q, 2, 1]) >= p_y1 - eps_xy):
                continue
            qa, qb, qc, q_ok = _plane(xy, z, q)
            if not q_ok:
                continue
            p_vs_q = _side_of(xy, z, p, qa, qb, qc, eps_z)
            q_vs_p = _side_of(xy, z, q, pa, pb, pc, eps_z)
            if p_vs_q == 0 and q_vs_p == 0:
                # Coplanar: paint the later-submitted first so the first one wins.
                if face[p] >= face[q]:
                    continue
            else:
                # 3: P entirely behind Q's plane; 4: Q entirely in front of P's plane.
                if p_vs_q == 1 or p_vs_q == 0 or q_vs_p == -1 or q_vs_p == 0:
                    continue
            # 5: projections.
            if not _projections_overlap(xy, p, q, eps_xy):
                continue
            # Q may be hidden by P: Q must go first, if it can (3', 4').
            can_swap = (q_vs_p == 1 or p_vs_q == -1 or (p_vs_q == 0 and q_vs_p == 0))
            action = 1 if can_swap and not marked[q] else 2
            target = j - 1
            break
        victim = -1
        if action == 2 and budget > 0:
            # A cycle or a penetration: split whichever straddles the other's plane.
            q = lst[target]
            qa, qb, qc, _ = _plane(xy, z, q)
            if _side_of(xy, z, p, qa, qb, qc, eps_z) == 2:
                victim, va, vb, vc, pos = p, qa, qb, qc, head
            elif _side_of(xy, z, q, pa, pb, pc, eps_z) == 2:
                victim, va, vb, vc, pos = q, pa, pb, pc, target
        if action != 0 and (budget <= 0 or (action == 2 and victim < 0)):
            # Out of budget, or no straddling pair (impossible for planar triangles):
            # never loop, paint P and count it.
            n_unresolved += 1
            action = 0
        if action == 0:
            out = grow(out, n_out + 1)
            out[n_out] = p
            n_out += 1
            head += 1
            continue
        budget -= 1
        if action == 1:
            # Move Q to the head of the list (before P) and mark it.
            q = lst[target]
            for k in range(target, head, -1):
                lst[k] = lst[k - 1]
            lst[head] = q
            marked[q] = True
            n_moves += 1
            continue
        n_splits += 1
        # Remove the victim from the list.
        for k in range(pos, n_lst - 1):
            lst[k] = lst[k + 1]
        n_lst -= 1
        # Cut it by the plane z = va x + vb y + vc, i.e. n . (x, y, z) + d = 0 with
        # n = (-va, -vb, 1), d = -vc (the same Sutherland-Hodgman cut the BSP uses).
        for k in range(3):
            victim_tri[k, 0], victim_tri[k, 1], victim_tri[k, 2] = (
                xy[victim, k, 0], xy[victim, k, 1], z[victim, k])
        n_front, n_back = split_triangle(victim_tri, -va, -vb, 1.0, -vc, eps_z, part_front,
                                         part_back)
        for k in range(n_front + n_back):
            part = part_front[k] if k < n_front else part_back[k - n_front]
            xy = grow(xy, n_poly + 1)
            z = grow(z, n_poly + 1)
            face = grow(face, n_poly + 1)
            zmax = grow(zmax, n_poly + 1)
            marked = grow(marked, n_poly + 1)
            for c in range(3):
                xy[n_poly, c, 0] = part[c, 0]
                xy[n_poly, c, 1] = part[c, 1]
                z[n_poly, c] = part[c, 2]
            face[n_poly] = face[victim]
            zmax[n_poly] = max(z[n_poly, 0], z[n_poly, 1], z[n_poly, 2])
            marked[n_poly] = False
            # Insert in depth order (after equal keys), at or after the head.
            lst = grow(lst, n_lst + 1)
            at = head
            while at < n_lst and zmax[lst[at]] >= zmax[n_poly]:
                at += 1
            for r in range(n_lst, at, -1):
                lst[r] = lst[r - 1]
            lst[at] = n_poly
            n_lst += 1
            n_poly += 1
        # Marks belonged to the old list's order; start fresh for the new pieces.
        for k in range(head, n_lst):
            marked[lst[k]] = False
    order = out[:n_out]
    return (xy[order].copy(), z[order].copy(), face[order].copy(), n_moves, n_splits,
            n_unresolved, n_tests)
