"""Vector output: an ordered list of window-space polygons as an SVG drawing.

The BSP walk gives polygons back to front, already cut wherever a cycle or a penetration
would make whole-polygon ordering wrong, so painting them in file order (which is what an
SVG viewer does) is an exact picture with no rasterization: the pixel geometry matches
the raster buffers (same camera, same window coordinates, y flipped to SVG's downward y).
"""

from __future__ import annotations

import os

import numpy as np

from ..errors import OutputError
from ..scene.outputs import staged

__all__ = ["write_polygons_svg", "write_svg"]


def write_svg(path, parts: list) -> None:
    """Write SVG text lines to ``path``, with a one-line error when it cannot."""
    folder = os.path.dirname(os.path.abspath(os.fspath(path)))
    if not os.path.isdir(folder):
        raise OutputError(f"cannot write {path}: directory {folder} does not exist")
    try:
        with staged(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
            fh.write("\n".join(parts) + "\n")
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None


def write_polygons_svg(path, xy_window: np.ndarray, colors: np.ndarray, face_id: np.ndarray,
                       width: int, height: int, background=(0, 0, 0)) -> None:
    """Write triangles (N, 3, 2) in painting order, filled with (N, 3) uint8 colours;
    each carries its source face as ``data-face``."""
    lines = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
             f'viewBox="0 0 {width} {height}">',
             f'<rect width="{width}" height="{height}" '
             f'fill="rgb{tuple(int(c) for c in background)}"/>',
             '<g stroke="none">']
    for tri, color, face in zip(xy_window, colors, face_id):
        points = " ".join(f"{x:.4f},{height - y:.4f}" for x, y in tri)
        lines.append(f'<polygon points="{points}" fill="#{int(color[0]):02x}{int(color[1]):02x}'
                     f'{int(color[2]):02x}" data-face="{int(face)}"/>')
    lines.append("</g></svg>")
    write_svg(path, lines)
