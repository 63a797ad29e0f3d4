"""Homogeneous polygon clipping (Sutherland-Hodgman, 1974) in clip space.

Clipping happens before the perspective divide: a triangle whose corners lie on both sides
of the eye plane (w of both signs) would otherwise project "through infinity" and wrap
around the screen. Each plane is ``dot(plane, (x, y, z, w)) >= 0`` = inside. The pieces
keep the index of their source triangle; attributes are later interpolated on the source
face itself (fragments.face_barycentrics), so the clipper carries positions only.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["clip_planes", "clip_triangles", "split_triangle", "grow"]

# Vertex record: x, y, z, w (clip space).
_REC = 4


def clip_planes(width: int, height: int, guard_band_pixels: float) -> np.ndarray:
    """(6, 4) planes: near, far and a guard band in x and y ``guard_band_pixels`` beyond
    the viewport edges (keeps window coordinates small enough for exact integer edges)."""
    gx = 1.0 + 2.0 * guard_band_pixels / width
    gy = 1.0 + 2.0 * guard_band_pixels / height
    return np.array(
        [
            [0.0, 0.0, 1.0, 1.0],  # near:  z >= -w
            [0.0, 0.0, -1.0, 1.0],  # far:   z <=  w
            [1.0, 0.0, 0.0, gx],  # left guard band
            [-1.0, 0.0, 0.0, gx],  # right guard band
            [0.0, 1.0, 0.0, gy],  # bottom guard band
            [0.0, -1.0, 0.0, gy],  # top guard band
        ]
    )


@njit(cache=True)
def _intersect(a, da, b, db, out):
    # Always interpolate from the inside vertex towards the outside one, so two triangles
    # sharing the clipped edge compute bit-identical new vertices (no cracks).
    if da >= 0.0:
        t = da / (da - db)
        for k in range(_REC):
            out[k] = a[k] + t * (b[k] - a[k])
    else:
        t = db / (db - da)
        for k in range(_REC):
            out[k] = b[k] + t * (a[k] - b[k])


@njit(cache=True)
def clip_triangles(pos_clip, planes):
    """Clip triangles against ``planes`` and fan-triangulate the resulting polygons.

    Parameters: ``pos_clip`` (K, 3, 4) float64; ``planes`` (P, 4).
    Returns ``(out_pos_clip (N, 3, 4), parent (N,) int64)``: for each output triangle its
    clip-space corners and the index of its source triangle in ``pos_clip``. Fully clipped
    triangles vanish.
    """
    n_in = pos_clip.shape[0]
    n_planes = planes.shape[0]
    max_verts = 3 + n_planes
    max_tris = max_verts - 2
    out_pos = np.empty((n_in * max_tris, 3, 4))
    parent = np.empty(n_in * max_tris, dtype=np.int64)
    poly = np.empty((max_verts, _REC))
    tmp = np.empty((max_verts, _REC))
    dist = np.empty(max_verts)
    n_out = 0
    for t in range(n_in):
        for k in range(3):
            for c in range(4):
                poly[k, c] = pos_clip[t, k, c]
        n = 3
        for p in range(n_planes):
            all_in = True
            for k in range(n):
                d = (planes[p, 0] * poly[k, 0] + planes[p, 1] * poly[k, 1]
                     + planes[p, 2] * poly[k, 2] + planes[p, 3] * poly[k, 3])
                dist[k] = d
                if d < 0.0:
                    all_in = False
            if all_in:
                continue
            m = 0
            for k in range(n):
                k2 = (k + 1) % n
                if dist[k] >= 0.0:
                    tmp[m, :] = poly[k, :]
                    m += 1
                if (dist[k] >= 0.0) != (dist[k2] >= 0.0):
                    _intersect(poly[k], dist[k], poly[k2], dist[k2], tmp[m])
                    m += 1
            n = m
            for k in range(n):
                poly[k, :] = tmp[k, :]
            if n < 3:
                break
        if n < 3:
            continue
        for k in range(1, n - 1):
            for c in range(4):
                out_pos[n_out, 0, c] = poly[0, c]
                out_pos[n_out, 1, c] = poly[k, c]
                out_pos[n_out, 2, c] = poly[k + 1, c]
            parent[n_out] = t
            n_out += 1
    return out_pos[:n_out].copy(), parent[:n_out].copy()


@njit(cache=True, nogil=True)
def grow(a, n):
    """``a``, or a copy at least twice as long along axis 0 when it holds fewer than
    ``n`` rows (amortised append for the splitters' growing arrays)."""
    if n <= a.shape[0]:
        return a
    shape = (max(n, 2 * a.shape[0]),) + a.shape[1:]
    b = np.empty(shape, dtype=a.dtype)
    b[: a.shape[0]] = a
    return b


@njit(cache=True, nogil=True)
def split_triangle(tri, nx, ny, nz, d, eps, out_front, out_back):
    """Cut a triangle (3, 3) by the plane ``n . p + d = 0`` (Sutherland-Hodgman against
    each side; distances within ``eps`` count as on the plane); fan-triangulate both
    parts, keeping the winding. Returns (n_front, n_back) triangles written to
    ``out_front`` (n . p + d > 0 side) and ``out_back`` ((2, 3, 3) each). Used by the BSP
    build in world space and by Newell's algorithm in window space."""
    s = np.empty(3)
    for k in range(3):
        s[k] = nx * tri[k, 0] + ny * tri[k, 1] + nz * tri[k, 2] + d
        if abs(s[k]) <= eps:
            s[k] = 0.0
    fp = np.empty((4, 3))
    bp = np.empty((4, 3))
    nf = nb = 0
    for k in range(3):
        k2 = (k + 1) % 3
        a, b = tri[k], tri[k2]
        sa, sb = s[k], s[k2]
        if sa >= 0.0:
            fp[nf] = a
            nf += 1
        if sa <= 0.0:
            bp[nb] = a
            nb += 1
        if (sa > 0.0 and sb < 0.0) or (sa < 0.0 and sb > 0.0):
            # Interpolate from the front corner so both pieces get the same point.
            if sa > 0.0:
                p = a + (sa / (sa - sb)) * (b - a)
            else:
                p = b + (sb / (sb - sa)) * (a - b)
            fp[nf] = p
            nf += 1
            bp[nb] = p
            nb += 1
    n_front = 0
    for k in range(1, nf - 1):
        out_front[n_front, 0] = fp[0]
        out_front[n_front, 1] = fp[k]
        out_front[n_front, 2] = fp[k + 1]
        n_front += 1
    n_back = 0
    for k in range(1, nb - 1):
        out_back[n_back, 0], out_back[n_back, 1], out_back[n_back, 2] = bp[0], bp[k], bp[k + 1]
        n_back += 1
    return n_front, n_back
