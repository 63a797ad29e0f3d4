"""Object borders: the visible silhouette and boundary pieces that outline an object against
the background or another object, as opposed to a fold of the object in front of itself
(Blender Line Art's "contour" and "silhouette" split the same way).

A piece is judged at its midpoint: a quarter pixel off it, on the side away from its
faces, the nearest surface (the same depth test as the hidden-line cut, over the same grid
of candidate triangles) belongs to another object, or there is none. A piece along which
what lies behind changes takes the label of its middle.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..scene.mesh import instance_of
from .raster import BOUNDARY, OBJECT_BORDER, SILHOUETTE

__all__ = ["object_borders", "OFFSET_PX"]

OFFSET_PX = 0.25  # how far off the piece the side beyond it is looked at


@njit(cache=True, nogil=True)
def _nearest_faces(points, tri_xy, tri_z, tri_face, start, items, nx, ny, cell):
    """Face of the nearest triangle (least window depth) covering each window point
    (x, y up), -1 where none does."""
    out = np.full(points.shape[0], -1, dtype=np.int64)
    for k in range(points.shape[0]):
        px, py = points[k, 0], points[k, 1]
        cx, cy = int(np.floor(px / cell)), int(np.floor(py / cell))
        if not (0 <= cx < nx and 0 <= cy < ny):
            continue
        cid = cy * nx + cx
        best = np.inf
        for q in range(start[cid], start[cid + 1]):
            t = items[q]
            x0, y0 = tri_xy[t, 0, 0], tri_xy[t, 0, 1]
            x1, y1 = tri_xy[t, 1, 0], tri_xy[t, 1, 1]
            x2, y2 = tri_xy[t, 2, 0], tri_xy[t, 2, 1]
            det = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
            if det == 0.0:
                continue
            # Barycentric coordinates of the point; inside when all are >= 0.
            b1 = ((px - x0) * (y2 - y0) - (x2 - x0) * (py - y0)) / det
            b2 = ((x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)) / det
            b0 = 1.0 - b1 - b2
            if b0 < 0.0 or b1 < 0.0 or b2 < 0.0:
                continue
            z = b0 * tri_z[t, 0] + b1 * tri_z[t, 1] + b2 * tri_z[t, 2]
            if z < best:
                best, out[k] = z, tri_face[t]
    return out


def _face_centres(scene, face_ids) -> np.ndarray:
    """World-space centres (K, 3) of the global faces ``face_ids``."""
    offsets = scene.face_offsets()
    owner = instance_of(offsets, face_ids)
    out = np.empty((len(face_ids), 3))
    for k in np.unique(owner):
        inst, mine = scene.instances[k], owner == k
        corners = inst.mesh.positions[inst.mesh.faces[face_ids[mine] - offsets[k]]]
        out[mine] = corners.mean(axis=1) @ inst.model[:3, :3].T + inst.model[:3, 3]
    return out


def object_borders(scene, view_proj, screen, pieces, kinds, faces, grid) -> np.ndarray:
    """(K,) uint8: OBJECT_BORDER for each visible piece (window x, y up, depth) of a
    silhouette or boundary edge that outlines its object, else 0. ``faces`` (K, 2): the
    edge's faces; ``grid``: (start, items, nx, ny, cell) over ``screen``'s triangles."""
    out = np.zeros(len(pieces), dtype=np.uint8)
    chosen = np.flatnonzero((kinds & (SILHOUETTE | BOUNDARY)) != 0)
    if len(chosen) == 0:
        return out
    width, height = screen.width, screen.height
    piece = pieces[chosen]
    # The side of the piece the first face lies on, from the face's centre in the window.
    clip = np.c_[_face_centres(scene, faces[chosen, 0]), np.ones(len(chosen))] \
        @ np.asarray(view_proj).T
    w = np.where(np.abs(clip[:, 3:]) > 1e-300, clip[:, 3:], 1e-300)
    centre = np.c_[(clip[:, 0:1] / w + 1) * width / 2, (clip[:, 1:2] / w + 1) * height / 2]
    a, b = piece[:, 0, :2], piece[:, 1, :2]
    d = b - a
    normal = np.c_[-d[:, 1], d[:, 0]] / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-300)[:, None]
    mid = (a + b) / 2
    side = np.sign(np.einsum("ij,ij->i", centre - mid, normal))
    # A face behind the eye (w < 0) shows its centre mirrored: flip the side back.
    side = np.where(clip[:, 3] < 0, -side, side)
    beyond = mid - side[:, None] * normal * OFFSET_PX
    start, items, nx, ny, cell = grid
    nearest = _nearest_faces(np.ascontiguousarray(beyond),
                             np.ascontiguousarray(screen.xy_window),
                             np.ascontiguousarray(screen.depth_window), screen.face_id, start,
                             items, nx, ny, cell)
    offsets = scene.face_offsets()
    own = instance_of(offsets, faces[chosen, 0])
    other = np.where(nearest >= 0, instance_of(offsets, np.maximum(nearest, 0)), -1)
    out[chosen[(nearest < 0) | (other != own)]] = OBJECT_BORDER
    return out
