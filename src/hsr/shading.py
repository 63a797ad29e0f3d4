"""The shading stage, shared by every algorithm: turns per-pixel visibility (face id,
depth) into colours. Nothing here decides visibility."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .errors import RenderError

__all__ = ["SHADING_MODES", "shade", "face_random_colors", "world_face_normals"]

SHADING_MODES = ("flat", "normal", "random", "depth")
_DEFAULT_BASE = np.array([230.0, 230.0, 230.0])


@njit(cache=True, parallel=True)
def _face_normals(positions, faces, linear):
    """(F, 3) unit normals of faces after the linear map ``linear`` (3x3); zero if degenerate."""
    n = faces.shape[0]
    out = np.zeros((n, 3))
    for f in prange(n):
        p = np.empty((3, 3))
        for k in range(3):
            v = faces[f, k]
            for r in range(3):
                p[k, r] = (linear[r, 0] * positions[v, 0] + linear[r, 1] * positions[v, 1]
                           + linear[r, 2] * positions[v, 2])
        e1 = p[1] - p[0]
        e2 = p[2] - p[0]
        nx = e1[1] * e2[2] - e1[2] * e2[1]
        ny = e1[2] * e2[0] - e1[0] * e2[2]
        nz = e1[0] * e2[1] - e1[1] * e2[0]
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0.0:
            out[f, 0], out[f, 1], out[f, 2] = nx / length, ny / length, nz / length
    return out


@njit(cache=True, parallel=True)
def _paint(face_id, face_rgb, image):
    """image[r, c] = face_rgb[face_id[r, c]] where a face is visible."""
    for r in prange(face_id.shape[0]):
        for c in range(face_id.shape[1]):
            f = face_id[r, c]
            if f >= 0:
                image[r, c, 0] = face_rgb[f, 0]
                image[r, c, 1] = face_rgb[f, 1]
                image[r, c, 2] = face_rgb[f, 2]


def world_face_normals(scene) -> np.ndarray:
    """(F, 3) unit world-space face normals in submission order (zero for degenerate)."""
    parts = [_face_normals(inst.mesh.positions, inst.mesh.faces,
                           np.ascontiguousarray(inst.model[:3, :3]))
             for inst in scene.instances]
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def face_base_colors(scene) -> np.ndarray:
    """(F, 3) float base colours: the meshes' face colours, light grey where none."""
    parts = []
    for inst in scene.instances:
        if inst.mesh.face_colors is not None:
            parts.append(inst.mesh.face_colors.astype(np.float64))
        else:
            parts.append(np.broadcast_to(_DEFAULT_BASE, (inst.mesh.n_faces, 3)))
    return np.concatenate(parts)


def face_random_colors(n_faces: int) -> np.ndarray:
    """(F, 3) uint8 distinct-looking colours from a hash of the face index (deterministic,
    no global random state): Gambetta's one-colour-per-triangle look."""
    h = np.arange(n_faces, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)
    h ^= h >> np.uint64(29)
    h *= np.uint64(0xBF58476D1CE4E5B9)
    h ^= h >> np.uint64(32)
    rgb = np.stack([(h >> np.uint64(s)) & np.uint64(0xFF) for s in (0, 8, 16)], axis=1)
    return (64 + (rgb.astype(np.float64) * (191.0 / 255.0))).astype(np.uint8)


def shade(mode: str, scene, camera, face_id: np.ndarray, depth: np.ndarray,
          background=(0, 0, 0), depth_range=(0.0, 1.0)) -> np.ndarray:
    """(H, W, 3) uint8 image.

    flat   : Lambert with a directional light along the view direction (tinyrenderer's
             look); two-sided, so back faces drawn with culling off are lit too.
    normal : world-space face normal mapped to RGB (n * 0.5 + 0.5).
    random : one hashed colour per face (Gambetta's look).
    depth  : linear eye depth, near = bright, scaled over the visible range.
    """
    if mode not in SHADING_MODES:
        raise RenderError(f"shading must be one of {', '.join(SHADING_MODES)}; got {mode!r}")
    height, width = face_id.shape
    image = np.empty((height, width, 3), dtype=np.uint8)
    image[:] = np.asarray(background, dtype=np.uint8)
    covered = face_id >= 0
    if not covered.any():
        return image
    if mode == "flat":
        intensity = np.abs(world_face_normals(scene) @ camera.forward)
        face_rgb = np.clip(face_base_colors(scene) * intensity[:, None], 0, 255).astype(np.uint8)
    elif mode == "normal":
        face_rgb = np.clip((world_face_normals(scene) * 0.5 + 0.5) * 255.0, 0, 255).astype(
            np.uint8)
    elif mode == "random":
        face_rgb = face_random_colors(scene.n_faces)
    if mode != "depth":
        _paint(face_id, face_rgb, image)
    else:
        eye_depth = linear_eye_depth(depth[covered], camera, depth_range)
        lo, hi = float(eye_depth.min()), float(eye_depth.max())
        scale = (eye_depth - lo) / (hi - lo) if hi > lo else np.zeros_like(eye_depth)
        gray = np.round(255.0 - 215.0 * scale).astype(np.uint8)  # near 255, far 40
        image[covered] = gray[:, None]
    return image


def linear_eye_depth(depth_window, camera, depth_range=(0.0, 1.0)) -> np.ndarray:
    """Distance along the view axis (positive, world units) from window depth."""
    near_d, far_d = depth_range
    z_ndc = (np.asarray(depth_window, dtype=np.float64) - 0.5 * (far_d + near_d)) * (
        2.0 / (far_d - near_d) if far_d != near_d else 0.0)
    n, f = camera.near, camera.far
    if camera.is_orthographic:
        return 0.5 * (z_ndc * (f - n) + (f + n))
    return 2.0 * f * n / ((f + n) - z_ndc * (f - n))
