"""Vector output: a line drawing as a layered SVG (one Inkscape layer per kind of line,
in pixels or on a page in millimetres), and an ordered list of window-space polygons.

The BSP walk gives polygons back to front, already cut wherever a cycle or a penetration
would make whole-polygon ordering wrong, so painting them in file order (which is what an
SVG viewer does) is an exact picture with no rasterization: the pixel geometry matches
the raster buffers (same camera, same window coordinates, y flipped to SVG's downward y).
"""

from __future__ import annotations

import os

import numpy as np

from ..errors import OutputError, check_rgb
from ..scene.outputs import staged
from .drawing import HIDDEN_LAYER, LAYERS, LineDrawing
from .page import Page

__all__ = ["write_lines_svg", "write_polygons_svg", "write_svg"]

_INKSCAPE = "http://www.inkscape.org/namespaces/inkscape"


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


def _rgb(c) -> str:
    return f"rgb({int(c[0])},{int(c[1])},{int(c[2])})"


def write_lines_svg(path: str | os.PathLike, drawing: LineDrawing,
                    background: tuple | None = (255, 255, 255), color: tuple = (0, 0, 0),
                    hidden: bool = False, stroke_width: float | None = None,
                    page: Page | None = None) -> None:
    """Write the drawing as SVG: one Inkscape layer (``<g inkscape:groupmode="layer">``,
    which vpype and plotter tools read as layers) per kind of line, numbered as in
    :data:`hsr.lines.drawing.LAYERS` (``layer1`` silhouettes, ...), one ``<path>`` per
    polyline in plotter order; with ``hidden``, the hidden parts dashed in layer 7.

    Without ``page`` the viewBox is the image in pixels, so the SVG overlays the PNG of the
    same render; with a :class:`~hsr.lines.page.Page` the drawing is scaled into its margins,
    in millimetres. ``background`` None draws no background rectangle (a plotter would
    draw its outline). ``stroke_width``: 1 px, or 0.3 mm on a page.

    Raises :class:`~hsr.errors.OutputError` when the file cannot be written or the page
    has no room for the drawing.
    """
    w, h = drawing.width, drawing.height
    check_rgb(color, "line colour")
    if page is None:
        page_w, page_h, scale, dx, dy = w, h, 1.0, 0.0, 0.0
        size = f'width="{w}" height="{h}"'
        stroke_width = 1.0 if stroke_width is None else stroke_width
    else:
        page_w, page_h, scale, dx, dy = page.fit(w, h)
        size = f'width="{page_w:g}mm" height="{page_h:g}mm"'
        stroke_width = 0.3 if stroke_width is None else stroke_width
    if isinstance(stroke_width, bool) or not isinstance(stroke_width, (int, float)) \
            or not 0 < stroke_width < 1e6:
        raise OutputError(f"stroke width must be a positive number, got {stroke_width!r}")

    def layer(number: int, label: str, polylines: list, style: str) -> list:
        out = [f'<g inkscape:groupmode="layer" inkscape:label="{label}" id="layer{number}" '
               f'fill="none" stroke="{_rgb(color)}" stroke-width="{stroke_width:g}" '
               f'stroke-linecap="round" stroke-linejoin="round"{style}>']
        for line in polylines:
            xy = line * scale + (dx, dy)
            out.append('<path d="M' + " L".join(f"{x:.4f} {y:.4f}" for x, y in xy) + '"/>')
        out.append("</g>")
        return out

    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="{_INKSCAPE}" {size} '
             f'viewBox="0 0 {page_w:g} {page_h:g}">']
    if background is not None:
        check_rgb(background, "background")
        parts.append(f'<rect width="{page_w:g}" height="{page_h:g}" fill="{_rgb(background)}"/>')
    if hidden:
        dash = 4 * stroke_width, 3 * stroke_width
        parts += layer(HIDDEN_LAYER, "hidden", drawing.hidden_polylines,
                       f' stroke-opacity="0.45" stroke-dasharray="{dash[0]:g} {dash[1]:g}"')
    number = {name: n for name, _, n in LAYERS}
    for name, polylines in drawing.layers.items():
        parts += layer(number[name], name, polylines, "")
    parts.append("</svg>")
    write_svg(path, parts)
