"""The geometry stage shared by every algorithm:

model/view/projection -> clip space -> clip (near, far, guard band) -> divide + viewport
-> face culling -> :class:`ScreenTriangles`.

Written once, vectorised in NumPy; only the (few) triangles that cross a clip plane go
through the compiled Sutherland-Hodgman clipper.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .clip import clip_planes, clip_triangles
from .conventions import GUARD_BAND_PIXELS
from .mesh import Scene
from .state import CullMode, FrontFace, RenderState

__all__ = ["ScreenTriangles", "transform_scene", "prepare"]


@dataclass
class ScreenTriangles:
    """Triangles in window space, ready for a visibility algorithm. N = triangles after
    clipping and culling, in submission order.

    xy_window : (N, 3, 2) float64, window x, y (pixels, y up, origin bottom-left).
    depth_window : (N, 3) float64, window depth in the depth range.
    inv_w : (N, 3) float64, 1 / w_clip per corner (for perspective-correct barycentrics).
    bary_source : (N, 3, 3) float64, barycentrics of each corner on its source face.
    face_id : (N,) int64, index of the source face in the scene's global face list.
    front : (N,) bool, front-facing under the state's winding.
    width, height : viewport size in pixels.
    """

    xy_window: np.ndarray
    depth_window: np.ndarray
    inv_w: np.ndarray
    bary_source: np.ndarray
    face_id: np.ndarray
    front: np.ndarray
    width: int
    height: int

    def __len__(self):
        return len(self.face_id)

    def subset(self, keep: np.ndarray) -> "ScreenTriangles":
        return ScreenTriangles(self.xy_window[keep], self.depth_window[keep], self.inv_w[keep],
                               self.bary_source[keep], self.face_id[keep], self.front[keep],
                               self.width, self.height)


def transform_scene(scene: Scene, view_proj: np.ndarray):
    """Clip-space corners of every face: ``(F, 3, 4)`` float64, plus the ``(F,)``
    degenerate mask (repeated index or zero area in model space)."""
    parts, degenerate = [], []
    for inst in scene.instances:
        mvp = view_proj @ inst.model
        mesh = inst.mesh
        pos_clip = mesh.positions @ mvp[:, :3].T + mvp[:, 3]
        parts.append(pos_clip[mesh.faces])
        degenerate.append(mesh.degenerate_mask())
    return np.concatenate(parts), np.concatenate(degenerate)


def prepare(scene: Scene, view_proj: np.ndarray, width: int, height: int,
            state: RenderState, stats: dict) -> ScreenTriangles:
    """Run the geometry stage; fills ``stats`` with triangle counts."""
    tri_clip, degenerate = transform_scene(scene, view_proj)
    n_faces = len(tri_clip)
    stats["triangles_in"] = n_faces
    stats["degenerate"] = int(degenerate.sum())
    face_id = np.flatnonzero(~degenerate)
    tri_clip = tri_clip[face_id]

    planes = clip_planes(width, height, GUARD_BAND_PIXELS)
    # Signed distance of every corner to every clip plane: (F, 3, 6).
    dist = tri_clip @ planes.T
    w = tri_clip[..., 3:4]
    # Outside the view frustum proper (|x|, |y| <= w) or beyond near/far: cull whole.
    frustum = np.concatenate([tri_clip[..., 0:2] + w, w - tri_clip[..., 0:2]], axis=-1)
    outside = (dist[..., :2] < 0).all(axis=1).any(axis=1) | (frustum < 0).all(axis=1).any(axis=1)
    needs_clip = (dist < 0).any(axis=(1, 2)) & ~outside
    stats["outside"] = int(outside.sum())
    stats["clipped"] = int(needs_clip.sum())

    simple = ~outside & ~needs_clip
    pos_parts = [tri_clip[simple]]
    bary_parts = [np.broadcast_to(np.eye(3), (int(simple.sum()), 3, 3))]
    face_parts = [face_id[simple]]
    # Polygon id per output triangle: facing is decided per clipped polygon, as in GL.
    poly_parts = [np.arange(int(simple.sum()))]
    if needs_clip.any():
        clip_idx = np.flatnonzero(needs_clip)
        pos, bary, parent = clip_triangles(np.ascontiguousarray(tri_clip[clip_idx]), planes)
        pos_parts.append(pos)
        bary_parts.append(bary)
        face_parts.append(face_id[clip_idx][parent])
        poly_parts.append(int(simple.sum()) + parent)
    pos_clip = np.concatenate(pos_parts)
    bary_source = np.ascontiguousarray(np.concatenate(bary_parts))
    tri_face = np.concatenate(face_parts)
    polygon = np.concatenate(poly_parts)
    # Restore submission order (clipped pieces were appended at the end); stable keeps
    # the fan order of the pieces of one face.
    if needs_clip.any():
        order = np.argsort(tri_face, kind="stable")
        pos_clip, bary_source, tri_face, polygon = (
            pos_clip[order], bary_source[order], tri_face[order], polygon[order])

    # Perspective divide and viewport transform.
    inv_w = 1.0 / pos_clip[..., 3]
    ndc = pos_clip[..., :3] * inv_w[..., None]
    xy_window = np.empty(ndc.shape[:-1] + (2,))
    xy_window[..., 0] = (ndc[..., 0] + 1.0) * (0.5 * width)
    xy_window[..., 1] = (ndc[..., 1] + 1.0) * (0.5 * height)
    near, far = state.depth_range
    depth_window = ndc[..., 2] * (0.5 * (far - near)) + 0.5 * (far + near)

    # Facing from the signed window-space area of the whole (clipped) polygon.
    d1 = xy_window[:, 1] - xy_window[:, 0]
    d2 = xy_window[:, 2] - xy_window[:, 0]
    area = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    if needs_clip.any():
        area = np.bincount(polygon, weights=area)[polygon]
    ccw = area > 0
    front = ccw if state.front_face == FrontFace.CCW else ~ccw
    keep = np.ones(len(front), dtype=bool)
    if state.cull == CullMode.BACK:
        keep = front
    elif state.cull == CullMode.FRONT:
        keep = ~front
    elif state.cull == CullMode.FRONT_AND_BACK:
        keep = np.zeros(len(front), dtype=bool)
    culled_faces = np.unique(tri_face[~keep])
    stats["culled"] = int(len(culled_faces))
    screen = ScreenTriangles(np.ascontiguousarray(xy_window), np.ascontiguousarray(depth_window),
                             np.ascontiguousarray(inv_w), bary_source, tri_face, front,
                             width, height)
    if not keep.all():
        screen = screen.subset(keep)
    stats["screen_triangles"] = len(screen)
    return screen
