"""The shading stage, shared by every algorithm: turns per-pixel visibility (face id,
depth) into colours. Nothing here decides visibility.

Modes: ``flat`` (Lambert, light along the view direction: tinyrenderer's look; two-sided so
back faces drawn with culling off are lit too), ``normal`` (world normal as RGB),
``random`` (a hashed colour per face: Gambetta's look), ``depth`` (linear eye depth, near
= bright)."""

from __future__ import annotations

import numpy as np
from numba import njit

from .errors import RenderError

__all__ = ["SHADING_MODES", "face_colors", "paint_faces", "shade_depth",
           "face_random_colors", "linear_eye_depth"]

SHADING_MODES = ("flat", "normal", "random", "depth")
_DEFAULT_BASE = np.array([230.0, 230.0, 230.0])


@njit(cache=True, nogil=True)
def _face_rgb(lo, hi, positions, faces, linear, forward, base_rgb, mode, visible, out):
    """(F, 3) uint8 colour per face from its normal after the linear map ``linear``.

    mode 0 (flat): ``base * |n . forward|``, Lambert with a light along the view direction,
    two-sided. mode 1 (normal): ``(n * 0.5 + 0.5) * 255``. ``base_rgb`` is (F, 3) or (1, 3).
    Only faces with ``visible[f]`` are computed (the others are never looked up).
    """
    per_face = base_rgb.shape[0] == faces.shape[0]
    p = np.empty((3, 3))
    for f in range(lo, hi):
        if not visible[f]:
            continue
        for k in range(3):
            v = faces[f, k]
            for r in range(3):
                p[k, r] = (linear[r, 0] * positions[v, 0] + linear[r, 1] * positions[v, 1]
                           + linear[r, 2] * positions[v, 2])
        e1x, e1y, e1z = p[1, 0] - p[0, 0], p[1, 1] - p[0, 1], p[1, 2] - p[0, 2]
        e2x, e2y, e2z = p[2, 0] - p[0, 0], p[2, 1] - p[0, 1], p[2, 2] - p[0, 2]
        nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0.0:
            nx, ny, nz = nx / length, ny / length, nz / length
        b = f if per_face else 0
        if mode == 0:
            shade = abs(nx * forward[0] + ny * forward[1] + nz * forward[2])
            for c in range(3):
                out[f, c] = np.uint8(min(255.0, base_rgb[b, c] * shade))
        else:
            out[f, 0] = np.uint8(min(255.0, (nx * 0.5 + 0.5) * 255.0))
            out[f, 1] = np.uint8(min(255.0, (ny * 0.5 + 0.5) * 255.0))
            out[f, 2] = np.uint8(min(255.0, (nz * 0.5 + 0.5) * 255.0))


def paint_faces(workers, face_id, face_rgb, background, image):
    """``image = face_rgb[face_id]`` where a face is visible, else the background
    (``face_rgb`` may be empty: every pixel gets the background). Returns the number of
    covered pixels."""
    return sum(workers.run_range(_paint_rows, face_id.shape[0], face_id, face_rgb,
                                 background, image))


@njit(cache=True, nogil=True)
def _paint_rows(lo, hi, face_id, face_rgb, background, image):
    paint = face_rgb.shape[0] > 0
    covered = 0
    for r in range(lo, hi):
        for c in range(face_id.shape[1]):
            f = face_id[r, c]
            if f >= 0:
                covered += 1
            if f >= 0 and paint:
                image[r, c, 0] = face_rgb[f, 0]
                image[r, c, 1] = face_rgb[f, 1]
                image[r, c, 2] = face_rgb[f, 2]
            else:
                image[r, c, 0] = background[0]
                image[r, c, 1] = background[1]
                image[r, c, 2] = background[2]
    return covered


@njit(cache=True, nogil=True)
def visible_faces(face_id, n_faces):
    """(F,) bool: faces that appear in the image."""
    seen = np.zeros(n_faces, dtype=np.bool_)
    for r in range(face_id.shape[0]):
        for c in range(face_id.shape[1]):
            if face_id[r, c] >= 0:
                seen[face_id[r, c]] = True
    return seen


def face_colors(mode: str, scene, camera, workers, face_id=None) -> np.ndarray:
    """(F, 3) uint8 colour of the faces visible in ``face_id`` (all faces when None) for
    the per-face shading modes (other rows are left unset); (0, 3) for ``depth``, which
    is per pixel."""
    if mode not in SHADING_MODES:
        raise RenderError(f"shading must be one of {', '.join(SHADING_MODES)}; got {mode!r}")
    if mode == "depth":
        return np.zeros((0, 3), dtype=np.uint8)
    if mode == "random":
        return face_random_colors(scene.n_faces)
    if face_id is None:
        visible = np.ones(scene.n_faces, dtype=np.bool_)
    else:
        visible = visible_faces(face_id, scene.n_faces)
    out = np.empty((scene.n_faces, 3), dtype=np.uint8)
    offsets = scene.face_offsets()
    for k, inst in enumerate(scene.instances):
        lo, hi = offsets[k], offsets[k + 1]
        if not visible[lo:hi].any():
            continue
        mesh = inst.mesh
        base = (mesh.face_colors.astype(np.float64) if mesh.face_colors is not None
                else _DEFAULT_BASE[None, :])
        workers.run_range(_face_rgb, mesh.n_faces, mesh.positions, mesh.faces,
                          np.ascontiguousarray(inst.model[:3, :3]), camera.forward, base,
                          0 if mode == "flat" else 1, visible[lo:hi], out[lo:hi])
    return out


def shade_depth(image, face_id, depth, camera, depth_range=(0.0, 1.0)) -> None:
    """Paint linear eye depth into ``image`` where a face is visible: near = bright (255),
    far = dark (40), scaled over the visible range."""
    covered = face_id >= 0
    if not covered.any():
        return
    eye_depth = linear_eye_depth(depth[covered], camera, depth_range)
    lo, hi = float(eye_depth.min()), float(eye_depth.max())
    scale = (eye_depth - lo) / (hi - lo) if hi > lo else np.zeros_like(eye_depth)
    gray = np.round(255.0 - 215.0 * scale).astype(np.uint8)
    image[covered] = gray[:, None]


def face_random_colors(n_faces: int) -> np.ndarray:
    """(F, 3) uint8 distinct-looking colours from a hash of the face index (deterministic,
    no global random state): Gambetta's one-colour-per-triangle look."""
    h = np.arange(n_faces, dtype=np.uint64) * np.uint64(0x9E3779B97F4A7C15)
    h ^= h >> np.uint64(29)
    h *= np.uint64(0xBF58476D1CE4E5B9)
    h ^= h >> np.uint64(32)
    rgb = np.stack([(h >> np.uint64(s)) & np.uint64(0xFF) for s in (0, 8, 16)], axis=1)
    return (64 + (rgb.astype(np.float64) * (191.0 / 255.0))).astype(np.uint8)


def linear_eye_depth(depth_window, camera, depth_range=(0.0, 1.0)) -> np.ndarray:
    """Distance along the view axis (positive, world units) from window depth."""
    near_d, far_d = depth_range
    z_ndc = (np.asarray(depth_window, dtype=np.float64) - 0.5 * (far_d + near_d)) * (
        2.0 / (far_d - near_d) if far_d != near_d else 0.0)
    n, f = camera.near, camera.far
    if camera.is_orthographic:
        return 0.5 * (z_ndc * (f - n) + (f + n))
    return 2.0 * f * n / ((f + n) - z_ndc * (f - n))
