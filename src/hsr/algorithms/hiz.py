"""Conservative visibility by occlusion culling (seed 004): draw objects front to back and
skip an object whose bounding box lies entirely behind what is already drawn.

The test is conservative, never skipping anything visible: an object is skipped only when
its nearest possible window depth (the smallest depth of its box corners; window depth is
monotonic in eye depth, and a box's nearest point is a corner) is *strictly* greater than
the farthest depth stored in every block of a hierarchical z-buffer (max depth per block
of pixels) that its screen rectangle overlaps. Then every fragment it could produce fails
LESS and LEQUAL alike. A box reaching in front of the near plane is always drawn.

Drawing front to back instead of in submission order changes nothing: the fill breaks
equal depths by face id exactly as submission order would (see ``fill_band``), so the
result equals the plain z-buffer's bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = ["ObjectBounds", "object_bounds", "box_corners", "pixel_rect", "BLOCK"]

BLOCK = 16  # pixels per hierarchical-z block side


@dataclass
class ObjectBounds:
    """Per instance of a scene: ``face_offsets`` (n + 1,) and the clip-space corners of
    its world bounding box ``corners_clip`` (n, 8, 4)."""

    face_offsets: np.ndarray
    corners_clip: np.ndarray


def box_corners(lo, hi) -> np.ndarray:
    """(8, 4) homogeneous corners of the axis-aligned box [lo, hi]."""
    return np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])])


def object_bounds(scene, view_proj) -> ObjectBounds:
    corners = []
    bounds = {}  # instances often share a mesh
    for inst in scene.instances:
        key = id(inst.mesh)
        if key not in bounds:
            bounds[key] = inst.mesh.bounds()
        lo, hi = bounds[key]
        corners.append(box_corners(lo, hi) @ (view_proj @ inst.model).T)
    return ObjectBounds(scene.face_offsets(), np.array(corners))


@njit(cache=True, nogil=True)
def screen_box(corners_clip, width, height, depth_scale, depth_offset):
    """(x0, x1, r0, r1, z_min, ok): inclusive pixel columns and image rows that the box
    may cover, and its nearest window depth; ok is False when a corner is in front of the
    near plane (or behind the eye), where the box must be treated as visible."""
    x_lo, x_hi, y_lo, y_hi, z_min = np.inf, -np.inf, np.inf, -np.inf, np.inf
    for k in range(8):
        x, y, z, w = corners_clip[k, 0], corners_clip[k, 1], corners_clip[k, 2], corners_clip[k, 3]
        if w <= 0.0 or z < -w:
            return 0, width - 1, 0, height - 1, -np.inf, False
        xw = (x / w + 1.0) * 0.5 * width
        yw = (y / w + 1.0) * 0.5 * height
        zw = z / w * depth_scale + depth_offset
        x_lo, x_hi = min(x_lo, xw), max(x_hi, xw)
        y_lo, y_hi = min(y_lo, yw), max(y_hi, yw)
        z_min = min(z_min, zw)
    x0, x1, r0, r1 = pixel_rect(x_lo, x_hi, y_lo, y_hi, width, height)
    return x0, x1, r0, r1, z_min, True


@njit(cache=True, nogil=True, inline="always")
def pixel_rect(x_lo, x_hi, y_lo, y_hi, width, height):
    """(x0, x1, r0, r1): inclusive pixel columns and image rows (row 0 the top) whose
    centres may lie in the window-space rectangle x_lo .. x_hi, y_lo .. y_hi (y up), with
    a pixel of margin for snapping; x0 > x1 or r0 > r1 when it is off the image.

    The bounds are clamped to a little beyond the image before they become integers: a
    float beyond the int64 range does not convert (a box corner projected to 1e30 pixels
    came out as the most negative integer, and the box as off the image)."""
    x_lo, x_hi = min(max(x_lo, -2.0), width + 2.0), min(max(x_hi, -2.0), width + 2.0)
    y_lo, y_hi = min(max(y_lo, -2.0), height + 2.0), min(max(y_hi, -2.0), height + 2.0)
    x0 = max(int(np.floor(x_lo)) - 1, 0)
    x1 = min(int(np.ceil(x_hi)) + 1, width - 1)
    j0 = max(int(np.floor(y_lo)) - 1, 0)
    j1 = min(int(np.ceil(y_hi)) + 1, height - 1)
    return x0, x1, height - 1 - j1, height - 1 - j0


@njit(cache=True, nogil=True)
def rect_hidden(hzb, x0, x1, r0, r1, z_min):
    """True when every hierarchical-z block under the rectangle holds only depths
    strictly nearer than ``z_min``."""
    if x0 > x1 or r0 > r1:
        return True  # off screen
    for br in range(r0 // BLOCK, r1 // BLOCK + 1):
        for bc in range(x0 // BLOCK, x1 // BLOCK + 1):
            if not hzb[br, bc] < z_min:
                return False
    return True


@njit(cache=True, nogil=True)
def update_hzb(depth, hzb, x0, x1, r0, r1):
    """Recompute the max depth of the blocks under the rectangle."""
    height, width = depth.shape
    if x0 > x1 or r0 > r1:
        return
    for br in range(r0 // BLOCK, r1 // BLOCK + 1):
        for bc in range(x0 // BLOCK, x1 // BLOCK + 1):
            m = -np.inf
            for r in range(br * BLOCK, min((br + 1) * BLOCK, height)):
                for c in range(bc * BLOCK, min((bc + 1) * BLOCK, width)):
                    m = max(m, depth[r, c])
            hzb[br, bc] = m
