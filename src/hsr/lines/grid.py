"""A uniform grid over the window listing the triangles near each cell: the candidates an
edge or a point is tested against (never the answer itself)."""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["GRID_MARGIN_PX", "window_grid"]

# Triangles are listed in every cell their bounding box comes within this of, so a segment
# walked through the cells it crosses meets every triangle within EPS_PX of it (even along
# a cell's border or through its corner).
GRID_MARGIN_PX = 1e-3


@njit(cache=True, nogil=True)
def window_grid(xy, width, height, cell):
    """Uniform grid over the window: (cell_start, items) listing the triangles whose
    bounding box, grown by GRID_MARGIN_PX, touches each cell."""
    nx = (width + cell - 1) // cell
    ny = (height + cell - 1) // cell
    n = xy.shape[0]
    boxes = np.empty((n, 4), dtype=np.int64)
    count = np.zeros(nx * ny + 1, dtype=np.int64)
    for t in range(n):
        x_lo = min(xy[t, 0, 0], xy[t, 1, 0], xy[t, 2, 0])
        x_hi = max(xy[t, 0, 0], xy[t, 1, 0], xy[t, 2, 0])
        y_lo = min(xy[t, 0, 1], xy[t, 1, 1], xy[t, 2, 1])
        y_hi = max(xy[t, 0, 1], xy[t, 1, 1], xy[t, 2, 1])
        c0 = max(int(np.floor((x_lo - GRID_MARGIN_PX) / cell)), 0)
        c1 = min(int(np.floor((x_hi + GRID_MARGIN_PX) / cell)), nx - 1)
        r0 = max(int(np.floor((y_lo - GRID_MARGIN_PX) / cell)), 0)
        r1 = min(int(np.floor((y_hi + GRID_MARGIN_PX) / cell)), ny - 1)
        boxes[t, 0], boxes[t, 1], boxes[t, 2], boxes[t, 3] = c0, c1, r0, r1
        for r in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                count[r * nx + c + 1] += 1
    start = np.cumsum(count)
    items = np.empty(start[-1], dtype=np.int64)
    fill = start[:-1].copy()
    for t in range(n):
        for r in range(boxes[t, 2], boxes[t, 3] + 1):
            for c in range(boxes[t, 0], boxes[t, 1] + 1):
                items[fill[r * nx + c]] = t
                fill[r * nx + c] += 1
    return start, items, nx, ny
