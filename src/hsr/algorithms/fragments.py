"""What a visibility algorithm returns: which face is visible at each pixel and its
window depth. Shading, texturing and fog read only this record."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.stage import ScreenTriangles

__all__ = ["Fragments", "face_barycentrics", "barycentrics_at"]


@dataclass
class Fragments:
    """Per-pixel visibility, image rows (row 0 = top).

    face_id : (H, W) int32, global index of the visible face, -1 = none.
    depth : (H, W) float32, the depth buffer (window depth; clear value where untouched).
    screen : the ScreenTriangles the algorithm worked on.
    stats : algorithm-specific counts (fragments tested / written, ...).
    count_tested, count_written : (H, W) int32 per-pixel fragment counts, when requested.
    buffers : further per-pixel results an algorithm offers (the ray caster's
        ``distance`` and ``barycentrics``).
    """

    face_id: np.ndarray
    depth: np.ndarray
    screen: ScreenTriangles
    stats: dict = field(default_factory=dict)
    count_tested: np.ndarray | None = None
    count_written: np.ndarray | None = None
    buffers: dict = field(default_factory=dict)


def face_barycentrics(fragments: Fragments) -> np.ndarray:
    """(H, W, 3) float64 perspective-correct barycentrics of each pixel centre on its
    visible face (zeros for background); see :func:`barycentrics_at`."""
    screen = fragments.screen
    height, width = fragments.face_id.shape
    out = np.zeros((height, width, 3))
    rows, cols = np.nonzero(fragments.face_id >= 0)
    out[rows, cols] = barycentrics_at(screen, rows, cols, fragments.face_id[rows, cols])
    return out


def barycentrics_at(screen: ScreenTriangles, rows, cols, faces) -> np.ndarray:
    """(K, 3) float64 perspective-correct barycentrics of pixel centres (``rows``,
    ``cols``; row 0 = top) on the global faces ``faces``.

    Computed on the *source* face from its clip-space corners, so it is right whatever
    clipping cut out of the face (homogeneous rasterization, Olano & Greer 1997): the point
    seen through NDC position (x, y) satisfies ``sum_i b_i (x_i - x w_i) = 0`` and
    ``sum_i b_i (y_i - y w_i) = 0``, so ``b`` is the cross product of those two rows,
    normalised to sum 1. This equals interpolating ``l_i / w_i`` in screen space.
    """
    if len(rows) == 0:
        return np.zeros((0, 3))
    width, height = screen.width, screen.height
    corners = screen.pos_clip[screen.faces[faces]]  # (K, 3, 4)
    x_ndc = (np.asarray(cols) + 0.5) * (2.0 / width) - 1.0
    y_ndc = ((height - 1 - np.asarray(rows)) + 0.5) * (2.0 / height) - 1.0  # window y is up
    u = corners[:, :, 0] - x_ndc[:, None] * corners[:, :, 3]
    v = corners[:, :, 1] - y_ndc[:, None] * corners[:, :, 3]
    b = np.cross(u, v)
    total = b.sum(axis=1, keepdims=True)
    return b / np.where(total == 0.0, 1.0, total)
