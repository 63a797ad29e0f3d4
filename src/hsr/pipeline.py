"""The geometry stage shared by every algorithm:

model/view/projection -> clip space -> clip (near, far, guard band) -> divide + viewport
-> face culling -> :class:`ScreenTriangles`.

Vertices are transformed once (NumPy, (V, 4) @ (4, 4)); a compiled per-face kernel
classifies each face (degenerate / outside / needs clipping / simple) and projects the
simple ones straight to window space. Only the (usually few) faces that cross a clip plane
go through the Sutherland-Hodgman clipper in :mod:`hsr.clip`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from .clip import clip_planes, clip_triangles
from .conventions import GUARD_BAND_PIXELS
from .mesh import Scene
from .parallel import Workers
from .state import CullMode, FrontFace, RenderState

__all__ = ["ScreenTriangles", "prepare", "scene_clip_vertices"]

# Face status codes of the classification kernel.
SIMPLE, DEGENERATE, OUTSIDE, NEEDS_CLIP = 0, 1, 2, 3


@dataclass
class ScreenTriangles:
    """Triangles in window space, ready for a visibility algorithm. N = triangles after
    clipping and culling, in submission order.

    xy_window : (N, 3, 2) float64, window x, y (pixels, y up, origin bottom-left).
    depth_window : (N, 3) float64, window depth in the depth range.
    face_id : (N,) int64, index of the source face in the scene's global face list.
    front : (N,) bool, front-facing under the state's winding.
    width, height : viewport size in pixels.
    pos_clip : (V, 4) float64 clip-space vertices of the whole scene and
    faces : (F, 3) int64 their global faces, so that attributes can be interpolated on the
        *source* face whatever clipping cut out of it (see fragments.face_barycentrics).
    """

    xy_window: np.ndarray
    depth_window: np.ndarray
    face_id: np.ndarray
    front: np.ndarray
    width: int
    height: int
    pos_clip: np.ndarray
    faces: np.ndarray

    def __len__(self):
        return len(self.face_id)

    def subset(self, keep) -> "ScreenTriangles":
        return ScreenTriangles(self.xy_window[keep], self.depth_window[keep],
                               self.face_id[keep], self.front[keep], self.width, self.height,
                               self.pos_clip, self.faces)


@njit(cache=True, nogil=True, inline="always")
def _to_window(x, y, z, w, half_w, half_h, depth_scale, depth_offset):
    inv_w = 1.0 / w
    return ((x * inv_w + 1.0) * half_w, (y * inv_w + 1.0) * half_h,
            z * inv_w * depth_scale + depth_offset)


@njit(cache=True, nogil=True, inline="always")
def _is_degenerate(positions, a, b, c):
    # Repeated index, or zero area relative to the edge lengths (collinear corners): such
    # a face covers no pixel in OpenGL either, so it is skipped and counted.
    if a == b or b == c or a == c:
        return True
    e1x, e1y, e1z = (positions[b, 0] - positions[a, 0], positions[b, 1] - positions[a, 1],
                     positions[b, 2] - positions[a, 2])
    e2x, e2y, e2z = (positions[c, 0] - positions[a, 0], positions[c, 1] - positions[a, 1],
                     positions[c, 2] - positions[a, 2])
    nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    area2_sq = nx * nx + ny * ny + nz * nz
    scale = max(e1x * e1x + e1y * e1y + e1z * e1z, e2x * e2x + e2y * e2y + e2z * e2z)
    return area2_sq <= 1e-24 * scale * scale


@njit(cache=True)
def degenerate_faces(positions, faces):
    """(F,) bool: faces with a repeated vertex or zero area (see ``_is_degenerate``)."""
    n = faces.shape[0]
    out = np.empty(n, dtype=np.bool_)
    for f in range(n):
        out[f] = _is_degenerate(positions, faces[f, 0], faces[f, 1], faces[f, 2])
    return out


def classify_faces(workers, pos_model, pos_clip, faces, planes, width, height, depth_scale,
                   depth_offset):
    """Per face: status (SIMPLE, DEGENERATE, OUTSIDE, NEEDS_CLIP) and, for SIMPLE faces,
    window coordinates, depth and twice the signed window area (y up). ``planes`` are
    :func:`hsr.clip.clip_planes`' (near, far, guard band); the kernel tests them directly."""
    gx, gy = float(planes[2, 3]), float(planes[4, 3])
    n = faces.shape[0]
    status = np.empty(n, dtype=np.int8)
    xy = np.empty((n, 3, 2))
    depth = np.empty((n, 3))
    area = np.zeros(n)
    workers.run_range(_classify_range, n, pos_model, pos_clip, faces, gx, gy, width, height,
                      depth_scale, depth_offset, status, xy, depth, area)
    return status, xy, depth, area


@njit(cache=True, nogil=True)
def _codes(pos_clip, v, gx, gy):
    """Outcode of vertex ``v`` against the six frustum planes |x|, |y|, |z| <= w (bits
    0-5) and whether it lies outside a clipping plane: near z >= -w, far z <= w, or the
    guard band |x| <= gx w, |y| <= gy w (bit 6). The comparisons are written so that they
    round exactly like the plane dot products the clipper evaluates (``z + w < 0`` etc.)."""
    x, y, z, w = pos_clip[v, 0], pos_clip[v, 1], pos_clip[v, 2], pos_clip[v, 3]
    code = 0
    if x > w:
        code |= 1
    if -x > w:
        code |= 2
    if y > w:
        code |= 4
    if -y > w:
        code |= 8
    if z > w:
        code |= 16
    if -z > w:
        code |= 32
    if (z + w < 0.0 or -z + w < 0.0 or x + gx * w < 0.0 or -x + gx * w < 0.0
            or y + gy * w < 0.0 or -y + gy * w < 0.0):
        code |= 64
    return code


@njit(cache=True, nogil=True)
def _classify_range(lo, hi, pos_model, pos_clip, faces, gx, gy, width, height, depth_scale,
                    depth_offset, status, xy, depth, area):
    half_w, half_h = 0.5 * width, 0.5 * height
    for f in range(lo, hi):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        if _is_degenerate(pos_model, a, b, c):
            status[f] = DEGENERATE
            continue
        code_a, code_b, code_c = _codes(pos_clip, a, gx, gy), _codes(pos_clip, b, gx, gy), \
            _codes(pos_clip, c, gx, gy)
        # Trivial reject: all corners outside one frustum plane.
        if code_a & code_b & code_c & 63:
            status[f] = OUTSIDE
            continue
        if (code_a | code_b | code_c) & 64:
            status[f] = NEEDS_CLIP
            continue
        status[f] = SIMPLE
        for k in range(3):
            v = faces[f, k]
            xy[f, k, 0], xy[f, k, 1], depth[f, k] = _to_window(
                pos_clip[v, 0], pos_clip[v, 1], pos_clip[v, 2], pos_clip[v, 3], half_w, half_h,
                depth_scale, depth_offset)
        area[f] = ((xy[f, 1, 0] - xy[f, 0, 0]) * (xy[f, 2, 1] - xy[f, 0, 1])
                   - (xy[f, 2, 0] - xy[f, 0, 0]) * (xy[f, 1, 1] - xy[f, 0, 1]))


@njit(cache=True)
def project_triangles(pos_clip, width, height, depth_scale, depth_offset):
    """(N, 3, 4) clip-space triangles -> window xy, depth and twice the signed area."""
    n = pos_clip.shape[0]
    xy = np.empty((n, 3, 2))
    depth = np.empty((n, 3))
    area = np.empty(n)
    half_w, half_h = 0.5 * width, 0.5 * height
    for t in range(n):
        for k in range(3):
            xy[t, k, 0], xy[t, k, 1], depth[t, k] = _to_window(
                pos_clip[t, k, 0], pos_clip[t, k, 1], pos_clip[t, k, 2], pos_clip[t, k, 3],
                half_w, half_h, depth_scale, depth_offset)
        area[t] = ((xy[t, 1, 0] - xy[t, 0, 0]) * (xy[t, 2, 1] - xy[t, 0, 1])
                   - (xy[t, 2, 0] - xy[t, 0, 0]) * (xy[t, 1, 1] - xy[t, 0, 1]))
    return xy, depth, area


def scene_clip_vertices(scene: Scene, view_proj: np.ndarray):
    """Model-space and clip-space vertices of all instances and their faces re-indexed
    into them: ``(pos_model (V, 3), pos_clip (V, 4), faces (F, 3))``, submission order.
    (Degeneracy is judged in model space, where a model matrix cannot hide it.)"""
    model, clip, faces = [], [], []
    base = 0
    for inst in scene.instances:
        mvp = view_proj @ inst.model
        mesh = inst.mesh
        model.append(mesh.positions)
        clip.append(mesh.positions @ mvp[:, :3].T + mvp[:, 3])
        faces.append(mesh.faces + base if base else mesh.faces)
        base += len(mesh.positions)
    if len(clip) == 1:
        return model[0], np.ascontiguousarray(clip[0]), faces[0]
    return np.concatenate(model), np.concatenate(clip), np.concatenate(faces)


def _keep_mask(ccw: np.ndarray, state: RenderState) -> tuple[np.ndarray, np.ndarray]:
    """(front, keep) from the counter-clockwise flags and glFrontFace / glCullFace."""
    front = ccw if state.front_face == FrontFace.CCW else ~ccw
    if state.cull == CullMode.BACK:
        return front, front
    if state.cull == CullMode.FRONT:
        return front, ~front
    if state.cull == CullMode.FRONT_AND_BACK:
        return front, np.zeros_like(front)
    return front, np.ones_like(front)


def prepare(scene: Scene, view_proj: np.ndarray, width: int, height: int,
            state: RenderState, stats: dict, workers=None) -> ScreenTriangles:
    """Run the geometry stage; fills ``stats`` with triangle counts."""
    workers = workers or Workers()
    pos_model, pos_clip, faces = scene_clip_vertices(scene, view_proj)
    planes = clip_planes(width, height, GUARD_BAND_PIXELS)
    near, far = state.depth_range
    depth_scale, depth_offset = 0.5 * (far - near), 0.5 * (far + near)
    status, xy, depth, area = classify_faces(
        workers, pos_model, pos_clip, faces, planes, width, height, depth_scale, depth_offset)
    counts = np.bincount(status, minlength=4)
    stats["triangles_in"] = len(faces)
    stats["degenerate"] = int(counts[DEGENERATE])
    stats["outside"] = int(counts[OUTSIDE])
    stats["clipped"] = int(counts[NEEDS_CLIP])

    simple = status == SIMPLE
    front, keep = _keep_mask(area > 0, state)
    chosen_mask = simple & keep
    n_culled = int(np.count_nonzero(simple & ~keep))
    if counts[SIMPLE] == len(faces) and n_culled == 0:  # the common case: no copies
        parts = [(xy, depth, np.arange(len(faces)), front)]
    else:
        chosen = np.flatnonzero(chosen_mask)
        parts = [(xy[chosen], depth[chosen], chosen, front[chosen])]
    if counts[NEEDS_CLIP]:
        clip_faces = np.flatnonzero(status == NEEDS_CLIP)
        tri_clip = np.ascontiguousarray(pos_clip[faces[clip_faces]])
        pieces, parent = clip_triangles(tri_clip, planes)
        p_xy, p_depth, p_area = project_triangles(pieces, width, height, depth_scale,
                                                           depth_offset)
        # Facing is decided once per clipped polygon (sum of its fan's areas), as in GL.
        poly_area = np.bincount(parent, weights=p_area, minlength=len(clip_faces))
        poly_front, poly_keep = _keep_mask(poly_area > 0, state)
        has_pieces = np.bincount(parent, minlength=len(clip_faces)) > 0
        n_culled += int(np.count_nonzero(has_pieces & ~poly_keep))
        sel = np.flatnonzero(poly_keep[parent])
        parts.append((p_xy[sel], p_depth[sel], clip_faces[parent[sel]],
                      poly_front[parent[sel]]))
    stats["culled"] = n_culled
    if len(parts) == 1:
        xy_w, depth_w, face_id, front_w = parts[0]
    else:
        xy_w, depth_w, face_id, front_w = (np.concatenate(c) for c in zip(*parts))
        # Restore submission order; stable keeps a clipped face's fan in order.
        order = np.argsort(face_id, kind="stable")
        xy_w, depth_w, face_id, front_w = (
            xy_w[order], depth_w[order], face_id[order], front_w[order])
    screen = ScreenTriangles(xy_w, depth_w, face_id, front_w, width, height,
                             pos_clip, faces)
    stats["screen_triangles"] = len(screen)
    return screen
