"""A line drawing: the visible (and hidden) pieces of a scene's edges, labelled by kind and
gathered into one layer of plotter-ordered polylines per kind.

An edge can be several kinds at once (a crease on the silhouette); it is drawn once, in the
layer of its first kind in :data:`LAYERS` order. Layer numbers are fixed, so pen 1 always
draws silhouettes, whatever the model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .paths import (
    JOIN_PX,
    join_polylines,
    merge_collinear,
    merge_runs,
    order_for_plotter,
    pen_travel,
)
from .raster import (
    BOUNDARY,
    CREASE,
    INTERSECTION,
    MODEL,
    NONMANIFOLD,
    OBJECT_BORDER,
    SILHOUETTE,
)

__all__ = ["HIDDEN_LAYER", "LAYERS", "LineDrawing", "layer_of", "make_drawing"]

# (name, kind bit, layer number), in the order an edge of several kinds is assigned;
# "border" is the visible silhouettes and boundaries that outline an object against the
# background or another object, "model" a CAD model's own (B-rep) edges, "edge" (bit 0)
# every other edge (drawing all edges of a mesh); 7 is the hidden layer.
LAYERS = (("border", OBJECT_BORDER, 9), ("silhouette", SILHOUETTE, 1), ("boundary", BOUNDARY, 2),
          ("nonmanifold", NONMANIFOLD, 5), ("intersection", INTERSECTION, 4),
          ("crease", CREASE, 3), ("model", MODEL, 6), ("edge", 0, 8))
HIDDEN_LAYER = 7  # the hidden parts, whatever their kinds


@dataclass
class LineDrawing:
    """Visible (and hidden) edge pieces of a scene seen by a camera.

    visible, hidden : (S, 2, 3) float64 segments in window space (x, y up, depth).
    visible_kind, hidden_kind : (S,) uint8 bit masks of each segment's kinds
        (:data:`hsr.lines.raster.BOUNDARY`, ``CREASE``, ``SILHOUETTE``, ``NONMANIFOLD``,
        ``INTERSECTION``; 0 = an ordinary edge).
    layers : {layer name: list of (n, 2) float64 polylines in image coordinates (x right,
        y down)}, merged, joined and ordered for a plotter, in layer number order (see
        :data:`LAYERS`); only layers with lines.
    visible_polylines : every layer's polylines in one list, layer after layer.
    hidden_polylines : the hidden parts' polylines, whatever their kinds, as one layer
        (joined and ordered when first asked for: most drawings never draw them).
    width, height : the image size.
    stats : counts.
    """

    visible: np.ndarray
    hidden: np.ndarray
    visible_polylines: list
    width: int
    height: int
    stats: dict = field(default_factory=dict)
    visible_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint8))
    hidden_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, np.uint8))
    layers: dict = field(default_factory=dict)
    with_hidden: bool = True
    join_px: float = JOIN_PX

    @cached_property
    def hidden_polylines(self) -> list:
        if not self.with_hidden or len(self.hidden) == 0:
            return []
        return order_for_plotter(join_polylines(merge_collinear(self.hidden), self.height,
                                                self.join_px))


def layer_of(kind: np.ndarray) -> np.ndarray:
    """The layer name (object array) of each kind mask (S,)."""
    names = np.array([name for name, _, _ in LAYERS], dtype=object)
    return names[_layer_index(np.asarray(kind))]


def _layer_index(kind: np.ndarray) -> np.ndarray:
    """Index into LAYERS of each kind mask: its first kind in LAYERS order."""
    index = np.full(len(kind), len(LAYERS) - 1, dtype=np.int64)
    for k in range(len(LAYERS) - 2, -1, -1):
        index[(kind & LAYERS[k][1]) != 0] = k
    return index


def _layered(segments: np.ndarray, kind: np.ndarray, height: int, join_px: float) -> dict:
    """{layer name: ordered polylines}. Collinear overlaps are merged across kinds first (an
    edge two objects share is drawn once), each run in the layer of its members' kinds."""
    runs, run_of = merge_runs(segments)
    run_kind = np.zeros(len(runs), dtype=np.uint8)
    np.bitwise_or.at(run_kind, run_of, kind.astype(np.uint8))
    index = _layer_index(run_kind)
    out = {}
    for k, (name, _, _) in sorted(enumerate(LAYERS), key=lambda item: item[1][2]):
        mine = runs[index == k]
        if len(mine):
            out[name] = order_for_plotter(join_polylines(mine, height, join_px))
    return out


def make_drawing(visible, visible_kind, hidden, hidden_kind, width: int, height: int,
                 with_hidden: bool = True, join_px: float = JOIN_PX) -> LineDrawing:
    """The drawing of window-space pieces and their kinds: layers of ordered polylines; the
    hidden parts as one layer (one pen, dashed), whatever their kinds. Ends closer than
    ``join_px`` pixels are joined (a plotter tool's merge tolerance, or the default's
    hairline)."""
    layers = _layered(visible, visible_kind, height, join_px)
    drawing = LineDrawing(visible, hidden, [p for lines in layers.values() for p in lines],
                          width, height, visible_kind=visible_kind, hidden_kind=hidden_kind,
                          layers=layers, with_hidden=with_hidden, join_px=join_px)
    drawing.stats = {"visible_pieces": int(len(visible)), "hidden_pieces": int(len(hidden)),
                     "polylines": len(drawing.visible_polylines),
                     "pen_travel": sum(pen_travel(lines) for lines in layers.values()),
                     "layers": {name: len(lines) for name, lines in layers.items()}}
    return drawing
