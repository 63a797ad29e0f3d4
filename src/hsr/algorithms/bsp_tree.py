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
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..errors import RenderError
from ..geometry.clip import grow, split_triangle
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
        """Longest root-to-leaf path (number of nodes)."""
        best, stack = 0, [(0, 1)]
        while stack:
            node, d = stack.pop()
            best = max(best, d)
            for child in (self.front[node], self.back[node]):
                if child >= 0:
                    stack.append((child, d + 1))
        return best


def build(scene, heuristic: str = "balanced", candidates: int = 8,
          split_weight: float = 8.0) -> BSPTree:
    """Build the BSP tree of ``scene``'s world-space triangles (degenerate ones left out)."""
    if heuristic not in HEURISTICS:
        raise RenderError(f"bsp heuristic must be one of {', '.join(HEURISTICS)}; "
                          f"got {heuristic!r}")
    t0 = time.perf_counter()
    scene = as_scene(scene)
    tris = scene.world_triangles()
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    length = np.linalg.norm(normal, axis=1)
    scale = np.maximum(np.einsum("ij,ij->i", tris[:, 1] - tris[:, 0], tris[:, 1] - tris[:, 0]),
                       np.einsum("ij,ij->i", tris[:, 2] - tris[:, 0], tris[:, 2] - tris[:, 0]))
    keep = np.flatnonzero(length > 1e-12 * scale)
    extent = float(np.abs(tris).max()) if len(tris) else 1.0
    n_cand = 1 if heuristic == "first" else max(1, int(candidates))
    weight = 1.0 if heuristic == "min_splits" else float(split_weight)
    balance = 0.0 if heuristic == "min_splits" else 1.0
    arrays = _build(np.ascontiguousarray(tris[keep]), keep.astype(np.int64), n_cand, weight,
                    balance, 1e-9 * max(extent, 1e-300))
    return BSPTree(*arrays, n_faces=len(tris), build_ms=1e3 * (time.perf_counter() - t0),
                   heuristic=heuristic)


@njit(cache=True, nogil=True)
def _plane_of(tri):
    e1 = tri[1] - tri[0]
    e2 = tri[2] - tri[0]
    n = np.array([e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                  e1[0] * e2[1] - e1[1] * e2[0]])
    n /= np.sqrt((n * n).sum())
    return n[0], n[1], n[2], -(n[0] * tri[0, 0] + n[1] * tri[0, 1] + n[2] * tri[0, 2])


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
def _append_pieces(pieces, k, src_face, tris, face, n_poly, idx, count):
    """Store the ``k`` pieces of a split polygon as new polygons ``n_poly...`` of source
    face ``src_face`` and list them in ``idx`` from ``count``. Returns (n_poly, count)."""
    for j in range(k):
        tris[n_poly] = pieces[j]
        face[n_poly] = src_face
        idx[count] = n_poly
        count += 1
        n_poly += 1
    return n_poly, count


@njit(cache=True, nogil=True)
def _build(tris_in, face_in, n_cand, split_weight, balance_weight, eps):
    n0 = tris_in.shape[0]
    tris = np.empty((max(4, 2 * n0), 3, 3))
    tris[:n0] = tris_in
    face = np.empty(max(4, 2 * n0), dtype=np.int64)
    face[:n0] = face_in
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
                poly_count[:0].copy(), node_polys[:0].copy(), tris[:0].copy(), face[:0].copy())
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
                nx, ny, nz, d = _plane_of(tris[cand])
                n_f = n_b = n_s = 0
                for q in range(cnt):
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
        nx, ny, nz, d = _plane_of(tris[best_i])
        plane[node, 0], plane[node, 1], plane[node, 2], plane[node, 3] = nx, ny, nz, d
        # Partition: on-plane polygons stay here; others go front / back (cut if needed).
        front_idx = np.empty(2 * cnt, dtype=np.int64)
        back_idx = np.empty(2 * cnt, dtype=np.int64)
        nf = nb = 0
        poly_start[node] = n_node_polys
        for q in range(cnt):
            p = pool[lo + q]
            side = _side(tris[p], nx, ny, nz, d, eps)
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
                tris = grow(tris, n_poly + k_f + k_b)
                face = grow(face, n_poly + k_f + k_b)
                n_poly, nf = _append_pieces(piece_f, k_f, face[p], tris, face, n_poly,
                                            front_idx, nf)
                n_poly, nb = _append_pieces(piece_b, k_b, face[p], tris, face, n_poly,
                                            back_idx, nb)
        poly_count[node] = n_node_polys - poly_start[node]
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
    return (plane[:n_nodes].copy(), front[:n_nodes].copy(), back[:n_nodes].copy(),
            poly_start[:n_nodes].copy(), poly_count[:n_nodes].copy(),
            node_polys[:n_node_polys].copy(), tris[:n_poly].copy(), face[:n_poly].copy())


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
                 tree.node_polys, tree.face_id, *_eye_point(camera), True)


def front_to_back(tree: BSPTree, camera) -> np.ndarray:
    """Polygon indices nearest first (for filling with a coverage mask)."""
    return _walk(tree.plane, tree.front, tree.back, tree.poly_start, tree.poly_count,
                 tree.node_polys, tree.face_id, *_eye_point(camera), False)
