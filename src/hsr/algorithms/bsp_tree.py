"""Binary space partitioning trees (Fuchs, Kedem & Naylor 1980), seed 001.

The tree is built once per scene in world space: each node takes one polygon's plane as
its splitter; the node keeps the polygons lying in that plane, and every other polygon
goes to the front or back subtree, cut in two by the plane when it straddles it. For any
eye position an in-order walk gives an exact back-to-front order: at each node, first the
subtree on the far side of the plane from the eye, then the node's own polygons, then the
near subtree. No depth test is needed; cyclic overlap and penetration are resolved by the
cuts. Pieces keep their source face id.

Splitter choice (``heuristic``): among up to ``candidates`` polygons of a node, spaced
evenly through it, pick the one minimising ``split_weight * splits + |front - back|``
("balanced", the default, trades splits against balance), ``splits`` alone
("min_splits"), or simply take the first polygon ("first", the textbook version).

Robustness: every polygon carries the plane of its source face, computed once from the
whole face (pieces inherit it, so a thin piece never gets a plane of its own from its
rounded corners); the splitter lies on its own plane by definition, never tested against
it; corners within ``eps`` (scaled to the scene's extent) of a plane count as on it, so a
plane that only grazes a polygon does not cut it. Every polygon is placed in exactly one
node and pieces are cut only by planes of other polygons, so the build ends; it is also
bounded: past ``max_polygons`` (default 64 n + 100,000, at most 20 million) it stops with a
:class:`RenderError` instead of filling the memory.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import RenderError, check_choice
from ..geometry.clip import grow, split_triangle
from ..parallel import run_with_progress
from ..scene.mesh import as_scene

__all__ = ["BSPTree", "build", "back_to_front", "front_to_back", "HEURISTICS"]

HEURISTICS = ("balanced", "min_splits", "first")
_FRONT, _BACK, _ON, _SPAN = 1, 2, 0, 3


@dataclass
class BSPTree:
    """A BSP tree in flat arrays.

    plane : (N, 4) node planes (unit normal n, offset d: n . x + d = 0);
    front, back : (N,) child nodes or -1; poly_start, poly_count : (N,) the node's
    polygons in ``node_polys``; triangles : (P, 3, 3) world-space polygons (source faces
    and the pieces cut from them), ``face_id`` : (P,) their source faces.
    """

    plane: np.ndarray
    front: np.ndarray
    back: np.ndarray
    poly_start: np.ndarray
    poly_count: np.ndarray
    node_polys: np.ndarray
    triangles: np.ndarray
    face_id: np.ndarray
    n_faces: int
    build_ms: float = 0.0
    heuristic: str = "balanced"

    @property
    def n_nodes(self) -> int:
        return len(self.plane)

    @property
    def splits(self) -> int:
        """Polygons created by cutting: pieces beyond the original faces."""
        return len(self.face_id) - len(np.unique(self.face_id))

    def depth(self) -> int:
        """Longest root-to-leaf path (number of nodes); 0 for an empty tree."""
        if self.n_nodes == 0:
            return 0
        best, stack = 0, [(0, 1)]
        while stack:
            node, d = stack.pop()
            best = max(best, d)
            for child in (self.front[node], self.back[node]):
                if child >= 0:
                    stack.append((child, d + 1))
        return best


def default_max_polygons(n_faces: int) -> int:
    """The default bound on the polygons (faces and pieces) a tree may hold."""
    return int(min(64 * n_faces + 100_000, 20_000_000))


def build(scene, heuristic: str = "balanced", candidates: int = 8,
          split_weight: float = 8.0, max_polygons: int | None = None,
          progress: bool = False) -> BSPTree:
    """Build the BSP tree of ``scene``'s world-space triangles (degenerate ones left out).
    Raises :class:`RenderError` for an unknown heuristic or when the tree would hold more
    than ``max_polygons`` polygons (see :func:`default_max_polygons`). ``progress`` shows
    a bar on the terminal."""
    check_choice(heuristic, HEURISTICS, "bsp heuristic")
    t0 = time.perf_counter()
    scene = as_scene(scene)
    tris = scene.world_triangles()
    limit = default_max_polygons(len(tris)) if max_polygons is None else max_polygons
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 1:
        raise RenderError(f"bsp max_polygons must be a positive integer, got {limit!r}")
    if limit < len(tris):
        raise RenderError(f"bsp max_polygons = {limit:,} is less than the scene's "
                          f"{len(tris):,} faces")
    with np.errstate(all="ignore"):  # huge coordinates: their faces are left out below
        normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        length = np.linalg.norm(normal, axis=1)
        scale = np.maximum(np.einsum("ij,ij->i", tris[:, 1] - tris[:, 0],
                                     tris[:, 1] - tris[:, 0]),
                           np.einsum("ij,ij->i", tris[:, 2] - tris[:, 0],
                                     tris[:, 2] - tris[:, 0]))
        keep = np.flatnonzero(np.isfinite(length) & np.isfinite(scale)
                              & (length > 1e-12 * scale))
        unit = normal[keep] / length[keep, None]
        # The plane through the centroid: its corners lie on it to rounding.
        planes = np.concatenate([unit, -np.einsum("ij,ij->i", unit,
                                                  tris[keep].mean(axis=1))[:, None]], axis=1)
    extent = float(np.abs(tris[keep]).max()) if len(keep) else 1.0
    n_cand = 1 if heuristic == "first" else max(1, int(candidates))
    weight = 1.0 if heuristic == "min_splits" else float(split_weight)
    balance = 0.0 if heuristic == "min_splits" else 1.0
    report = np.zeros(3, dtype=np.int64)  # polygons placed, polygons made, done
    args = (np.ascontiguousarray(tris[keep]), keep.astype(np.int64),
            np.ascontiguousarray(planes), n_cand, weight, balance, 1e-9 * max(extent, 1e-300),
            int(limit), report)
    out = run_with_progress(_build, args, report, len(keep), "bsp build") if progress \
        else _build(*args)
    if out[-1] != 0:
        raise RenderError(f"bsp: the tree grew past max_polygons = {limit:,} polygons "
                          f"({len(keep):,} faces cut again and again); raise the limit "
                          f"(--option max_polygons=N) or use another algorithm")
    return BSPTree(*out[:-1], n_faces=len(tris),  # type: ignore[misc]
                   build_ms=1e3 * (time.perf_counter() - t0), heuristic=heuristic)


@njit(cache=True, nogil=True)
def _side(tri, nx, ny, nz, d, eps):
    has_front = has_back = False
    for k in range(3):
        s = nx * tri[k, 0] + ny * tri[k, 1] + nz * tri[k, 2] + d
        if s > eps:
            has_front = True
        elif s < -eps:
            has_back = True
    if has_front and has_back:
        return _SPAN
    if has_front:
        return _FRONT
    if has_back:
        return _BACK
    return _ON


@njit(cache=True, nogil=True, inline="always")
def _append_pieces(pieces, k, src, tris, face, planes, n_poly, idx, count):
    """Store the ``k`` pieces of split polygon ``src`` as new polygons ``n_poly...`` with
    its source face and plane, and list them in ``idx`` from ``count``. Returns
    (n_poly, count)."""
    for j in range(k):
        tris[n_poly] = pieces[j]
        face[n_poly] = face[src]
        planes[n_poly] = planes[src]
        idx[count] = n_poly
        count += 1
        n_poly += 1
    return n_poly, count


@njit(cache=True, nogil=True)
def _build(tris_in, face_in, planes_in, n_cand, split_weight, balance_weight, eps,
           max_polygons, report):
    n0 = tris_in.shape[0]
    tris = np.empty((max(4, 2 * n0), 3, 3))
    tris[:n0] = tris_in
    face = np.empty(max(4, 2 * n0), dtype=np.int64)
    face[:n0] = face_in
    planes = np.empty((max(4, 2 * n0), 4))
    planes[:n0] = planes_in
    report[1] = n0
    n_poly = n0
    cap = max(4, n0)
    plane = np.empty((cap, 4))
    front = np.full(cap, -1, dtype=np.int64)
    back = np.full(cap, -1, dtype=np.int64)
    poly_start = np.zeros(cap, dtype=np.int64)
    poly_count = np.zeros(cap, dtype=np.int64)
    node_polys = np.empty(max(4, n0), dtype=np.int64)
    n_node_polys = 0
    n_nodes = 0
    # Pending work: (node id, polygon indices) pairs kept in one index pool.
    pool = np.arange(n0).astype(np.int64)
    pool_len = n0
    stack_node = np.empty(64, dtype=np.int64)
    stack_lo = np.empty(64, dtype=np.int64)
    stack_n = np.empty(64, dtype=np.int64)
    top = 0
    if n0 == 0:
        return (plane[:0].copy(), front[:0].copy(), back[:0].copy(), poly_start[:0].copy(),
                poly_count[:0].copy(), node_polys[:0].copy(), tris[:0].copy(), face[:0].copy(),
                0)
    n_nodes = 1
    stack_node[0], stack_lo[0], stack_n[0] = 0, 0, n0
    top = 1
    piece_f = np.empty((2, 3, 3))
    piece_b = np.empty((2, 3, 3))
    while top > 0:
        top -= 1
        node, lo, cnt = stack_node[top], stack_lo[top], stack_n[top]
        # Choose the splitter.
        best_i, best_cost = pool[lo], np.inf
        step = max(1, cnt // n_cand)
        if n_cand > 1 and cnt > 1:
            for c in range(0, cnt, step):
                cand = pool[lo + c]
                nx, ny, nz, d = planes[cand, 0], planes[cand, 1], planes[cand, 2], planes[cand, 3]
                n_f = n_b = n_s = 0
                for q in range(cnt):
                    if pool[lo + q] == cand:
                        continue
                    side = _side(tris[pool[lo + q]], nx, ny, nz, d, eps)
                    if side == _FRONT:
                        n_f += 1
                    elif side == _BACK:
                        n_b += 1
                    elif side == _SPAN:
                        n_s += 1
                cost = split_weight * n_s + balance_weight * abs(n_f - n_b)
                if cost < best_cost:
                    best_cost, best_i = cost, cand
        nx, ny, nz, d = planes[best_i, 0], planes[best_i, 1], planes[best_i, 2], planes[best_i, 3]
        plane[node, 0], plane[node, 1], plane[node, 2], plane[node, 3] = nx, ny, nz, d
        # Partition: on-plane polygons stay here; others go front / back (cut if needed).
        front_idx = np.empty(2 * cnt, dtype=np.int64)
        back_idx = np.empty(2 * cnt, dtype=np.int64)
        nf = nb = 0
        poly_start[node] = n_node_polys
        for q in range(cnt):
            p = pool[lo + q]
            # The splitter lies on its own plane by definition: never test it (its rounded
            # corners could seem to straddle it and be cut forever).
            side = _ON if p == best_i else _side(tris[p], nx, ny, nz, d, eps)
            if side == _ON:
                node_polys = grow(node_polys, n_node_polys + 1)
                node_polys[n_node_polys] = p
                n_node_polys += 1
            elif side == _FRONT:
                front_idx[nf] = p
                nf += 1
            elif side == _BACK:
                back_idx[nb] = p
                nb += 1
            else:
                k_f, k_b = split_triangle(tris[p], nx, ny, nz, d, eps, piece_f, piece_b)
                if n_poly + k_f + k_b > max_polygons:
                    return (plane[:0].copy(), front[:0].copy(), back[:0].copy(),
                            poly_start[:0].copy(), poly_count[:0].copy(), node_polys[:0].copy(),
                            tris[:0].copy(), face[:0].copy(), 1)
                tris = grow(tris, n_poly + k_f + k_b)
                face = grow(face, n_poly + k_f + k_b)
                planes = grow(planes, n_poly + k_f + k_b)
                n_poly, nf = _append_pieces(piece_f, k_f, p, tris, face, planes, n_poly,
                                            front_idx, nf)
                n_poly, nb = _append_pieces(piece_b, k_b, p, tris, face, planes, n_poly,
                                            back_idx, nb)
                report[1] = n_poly
        poly_count[node] = n_node_polys - poly_start[node]
        report[0] = n_node_polys
        for child_n, child_idx, is_front in ((nf, front_idx, True), (nb, back_idx, False)):
            if child_n == 0:
                continue
            if n_nodes >= plane.shape[0]:
                plane = grow(plane, n_nodes + 1)
                front = grow(front, n_nodes + 1)
                back = grow(back, n_nodes + 1)
                poly_start = grow(poly_start, n_nodes + 1)
                poly_count = grow(poly_count, n_nodes + 1)
                front[n_nodes:] = -1
                back[n_nodes:] = -1
            child = n_nodes
            n_nodes += 1
            front[child] = -1
            back[child] = -1
            if is_front:
                front[node] = child
            else:
                back[node] = child
            pool = grow(pool, pool_len + child_n)
            pool[pool_len:pool_len + child_n] = child_idx[:child_n]
            if top >= stack_node.shape[0]:
                stack_node = grow(stack_node, top + 1)
                stack_lo = grow(stack_lo, top + 1)
                stack_n = grow(stack_n, top + 1)
            stack_node[top], stack_lo[top], stack_n[top] = child, pool_len, child_n
            top += 1
            pool_len += child_n
    report[2] = 1
    return (plane[:n_nodes].copy(), front[:n_nodes].copy(), back[:n_nodes].copy(),
            poly_start[:n_nodes].copy(), poly_count[:n_nodes].copy(),
            node_polys[:n_node_polys].copy(), tris[:n_poly].copy(), face[:n_poly].copy(), 0)


@njit(cache=True, nogil=True)
def _walk(plane, front, back, poly_start, poly_count, node_polys, face, ex, ey, ez, ew,
          far_first):
    """In-order walk for an eye at homogeneous point (ex, ey, ez, ew) (ew = 0: an eye at
    infinity, orthographic). far_first: back to front, else front to back. Coplanar
    polygons of a node come in reverse submission order back to front (so the first
    submitted is painted last and wins, as with LESS) and in submission order front to
    back (so it is written first)."""
    n_nodes = plane.shape[0]
    order = np.empty(node_polys.shape[0], dtype=np.int64)
    n_out = 0
    if n_nodes == 0:
        return order
    # Explicit stack of (node, stage): stage 0 = descend first child, 1 = emit, 2 = second.
    stack = np.empty(2 * n_nodes + 2, dtype=np.int64)
    stage = np.empty(2 * n_nodes + 2, dtype=np.int64)
    top = 1
    stack[0], stage[0] = 0, 0
    while top > 0:
        node = stack[top - 1]
        st = stage[top - 1]
        side = plane[node, 0] * ex + plane[node, 1] * ey + plane[node, 2] * ez + plane[node, 3] * ew
        eye_front = side >= 0.0
        near_child = front[node] if eye_front else back[node]
        far_child = back[node] if eye_front else front[node]
        first, second = (far_child, near_child) if far_first else (near_child, far_child)
        if st == 0:
            stage[top - 1] = 1
            if first >= 0:
                stack[top], stage[top] = first, 0
                top += 1
        elif st == 1:
            stage[top - 1] = 2
            s, c = poly_start[node], poly_count[node]
            # Sort this node's polygons by source face (submission order).
            ids = node_polys[s:s + c].copy()
            keys = face[ids]
            idx = np.argsort(keys, kind="mergesort")
            if far_first:
                idx = idx[::-1]
            for k in range(c):
                order[n_out] = ids[idx[k]]
                n_out += 1
        else:
            top -= 1
            if second >= 0:
                stack[top], stage[top] = second, 0
                top += 1
    return order[:n_out]


def _eye_point(camera):
    if camera.is_orthographic:
        f = camera.forward
        return -f[0], -f[1], -f[2], 0.0  # eye at infinity behind the camera
    e = camera.eye
    return float(e[0]), float(e[1]), float(e[2]), 1.0


def back_to_front(tree: BSPTree, camera) -> np.ndarray:
    """Polygon indices (into ``tree.triangles``) in painting order for ``camera``."""
    return _walk(tree.plane, tree.front, tree.back, tree.poly_start, tree.poly_count,
                 tree.node_polys, tree.face_id, *_eye_point(camera), True)  # type: ignore[call-arg]


def front_to_back(tree: BSPTree, camera) -> np.ndarray:
    """Polygon indices nearest first (for filling with a coverage mask)."""
    return _walk(tree.plane, tree.front, tree.back, tree.poly_start, tree.poly_count,
                 tree.node_polys, tree.face_id, *_eye_point(camera), False)  # type: ignore[call-arg]
