"""What a visibility algorithm returns: which screen triangle is visible at each pixel
and its window depth. Shading, texturing and fog read only this record."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from .pipeline import ScreenTriangles

__all__ = ["Fragments", "perspective_barycentrics"]


@dataclass
class Fragments:
    """Per-pixel visibility, image rows (row 0 = top).

    tri_index : (H, W) int32, index into ``screen`` of the visible triangle, -1 = none.
    depth : (H, W) float32, the depth buffer (window depth; clear value where untouched).
    screen : the ScreenTriangles the indices refer to.
    stats : algorithm-specific counts (fragments tested / written, ...).
    count_tested, count_written : (H, W) int32 per-pixel fragment counts, when requested.
    """

    tri_index: np.ndarray
    depth: np.ndarray
    screen: ScreenTriangles
    stats: dict = field(default_factory=dict)
    count_tested: np.ndarray | None = None
    count_written: np.ndarray | None = None

    @property
    def face_id(self) -> np.ndarray:
        """(H, W) int32: source face index, -1 for background."""
        return lookup_ids(self.tri_index, self.screen.face_id)


@njit(cache=True, parallel=True)
def lookup_ids(index, table):
    """(H, W) int32: ``table[index]`` where ``index >= 0``, else -1."""
    out = np.empty(index.shape, dtype=np.int32)
    for r in prange(index.shape[0]):
        for c in range(index.shape[1]):
            i = index[r, c]
            out[r, c] = table[i] if i >= 0 else -1
    return out


def perspective_barycentrics(fragments: Fragments) -> np.ndarray:
    """(H, W, 3) float64 perspective-correct barycentrics of each pixel centre on its
    *source* face (zeros for background).

    Screen-space barycentrics ``l_i`` of the pixel centre in the visible screen triangle
    become ``b_i = (l_i / w_i) / sum_j (l_j / w_j)`` (1/w interpolates linearly in screen
    space), then map through the corners' own barycentrics on the source face (a clipped
    triangle's corners lie inside its source face).
    """
    screen = fragments.screen
    height, width = fragments.tri_index.shape
    out = np.zeros((height, width, 3))
    rows, cols = np.nonzero(fragments.tri_index >= 0)
    if len(rows) == 0:
        return out
    t = fragments.tri_index[rows, cols]
    px = cols + 0.5
    py = (height - 1 - rows) + 0.5  # window y (up)
    v = screen.xy_window[t]  # (K, 3, 2)
    d1 = v[:, 1] - v[:, 0]
    d2 = v[:, 2] - v[:, 0]
    dp_x = px - v[:, 0, 0]
    dp_y = py - v[:, 0, 1]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    safe = np.where(det == 0.0, 1.0, det)
    l1 = (dp_x * d2[:, 1] - dp_y * d2[:, 0]) / safe
    l2 = (d1[:, 0] * dp_y - d1[:, 1] * dp_x) / safe
    lam = np.stack([1.0 - l1 - l2, l1, l2], axis=1)
    lam = np.where(det[:, None] == 0.0, 1.0 / 3.0, lam)
    persp = lam * screen.inv_w[t]
    persp /= persp.sum(axis=1, keepdims=True)
    out[rows, cols] = np.einsum("ki,kij->kj", persp, screen.corner_barycentrics(t))
    return out
