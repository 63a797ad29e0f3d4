"""Patches that nothing hides, drawn as mplot3d draws them: one path, filled and stroked.

For such a polygon mplot3d's own picture is already exact, and its path is the smallest
file: hsr's visible region would be the same area as convex pieces merged into rings (a
self-crossing outline cut into one ring per lobe), and its outline a stroke of its own.
A polygon is drawn whole when all of these hold:

- it is an opaque ``Patch3D`` (a patch is one polygon, drawn by mplot3d as one path)
  with a visible part;
- every stroked edge of its outline is visible from end to end;
- its path, filled by matplotlib's nonzero rule, holds no visible piece of any other
  polygon. This also settles the fill rule: where the path's fill and hsr's
  triangulation of it differ (a lobe wound twice), what lies behind shows in hsr's
  regions there, and the patch is drawn as its visible region instead.

Its own triangles are not asked to be uncut: where the outline crosses itself, the
triangulation's corners snap to the nearest vertex and its triangles may overlap each
other, in one colour. Anything in front of the patch inside its fill would leave a
visible piece there, which the last test sees.
"""

from __future__ import annotations

import numpy as np

from ..geometry.merge import pieces_in_order

# Overlap (px^2) still counted as none: pieces that share an edge, computed twice.
_TOUCH_AREA = 1e-6
# Winding numbers take a (points x vertices) table; this many cells a block.
_WINDING_BLOCK = 1 << 22


def winding_numbers(points: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """(K,) winding number of the closed polygon ``ring`` (n, 2) about each of ``points``
    (K, 2): upward edge crossings to the point's right count +1, downward ones -1
    (Sunday's crossing form of the winding number)."""
    a, b = ring, np.roll(ring, -1, axis=0)
    out = np.zeros(len(points), np.int64)
    step = max(1, _WINDING_BLOCK // max(len(ring), 1))
    for lo in range(0, len(points), step):
        p = points[lo:lo + step, None, :]
        side = (b[:, 0] - a[:, 0]) * (p[..., 1] - a[:, 1]) - \
            (p[..., 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
        up = (a[:, 1] <= p[..., 1]) & (b[:, 1] > p[..., 1]) & (side > 0)
        down = (a[:, 1] > p[..., 1]) & (b[:, 1] <= p[..., 1]) & (side < 0)
        out[lo:lo + step] = up.sum(axis=1) - down.sum(axis=1)
    return out


def nonzero_region(ring: np.ndarray):
    """The shapely region a path through ``ring`` (n, 2), closed or not, covers when filled
    by the nonzero rule (matplotlib's): the faces of its noded outline whose winding number
    is not zero."""
    import shapely

    closed = np.vstack([ring, ring[:1]])
    outline = shapely.LinearRing(closed)
    if shapely.is_simple(outline):
        return shapely.Polygon(closed)
    faces = shapely.get_parts(shapely.polygonize(
        shapely.get_parts(shapely.node(shapely.LineString(closed)))))
    if not len(faces):
        return shapely.Polygon()
    inside = shapely.get_coordinates(shapely.point_on_surface(faces))
    return shapely.union_all(faces[winding_numbers(inside, ring) != 0])


def whole_polygons(got, flat, seen, camera, face_rgba: np.ndarray) -> dict:
    """{polygon: (n, 2) image x, y (y down) of its vertices} for the polygons drawn whole
    (see the module's docstring)."""
    from mpl_toolkits.mplot3d import art3d

    from ..visibility.queries import project_points

    reg = seen.regions
    if reg is None or not len(reg):
        return {}
    patches = [f for f, fill in enumerate(got.fills) if isinstance(fill.artist, art3d.Patch3D)]
    if not patches:
        return {}
    candidates = np.flatnonzero(np.isin(flat.poly_fill, patches) & (face_rgba[:, 3] >= 1.0))
    piece_poly = seen.face_poly[reg.face_id[reg.piece_row]]
    shown = set(piece_poly.tolist())
    outline_whole = _outlines_whole(flat, seen)
    box = _piece_boxes(reg)
    out = {}
    for p in candidates.tolist():
        if p not in shown or not outline_whole[p]:
            continue
        fill = got.fills[int(flat.poly_fill[p])]
        k = int(flat.poly_index[p])
        xy, _ = project_points(camera, fill.vertices[fill.starts[k]:fill.starts[k + 1]],
                               seen.width, seen.height)
        if not np.all(np.isfinite(xy)) or _others_inside(xy, reg, box, piece_poly != p):
            continue
        out[p] = xy
    return out


def _piece_boxes(reg) -> np.ndarray:
    """(P, 4) each piece's x min, y min, x max, y max."""
    starts = reg.piece_start[:-1]
    lo = np.minimum.reduceat(reg.vertices, starts, axis=0)
    hi = np.maximum.reduceat(reg.vertices, starts, axis=0)
    return np.concatenate([lo, hi], axis=1)


def _outlines_whole(flat, seen) -> np.ndarray:
    """(P,) bool: every stroked edge of the polygon is seen from end to end, as one piece
    (a zero-length edge, a repeated vertex, as none)."""
    whole = np.ones(len(flat.poly_fill), bool)
    drawn = seen.edge_ids
    if not len(drawn):
        return whole
    is_edge = seen.item < seen.n_edges
    edge_of_piece = drawn[seen.item[is_edge]]
    t = seen.t[is_edge]
    count = np.bincount(edge_of_piece, minlength=len(flat.edges))[drawn]
    full = np.zeros(len(flat.edges), bool)
    full[edge_of_piece[(t[:, 0] <= 1e-12) & (t[:, 1] >= 1 - 1e-12)]] = True
    point = np.all(flat.edges[drawn, 0] == flat.edges[drawn, 1], axis=1)
    seen_whole = ((count == 1) & full[drawn]) | ((count == 0) & point)
    whole[flat.edge_poly[drawn[~seen_whole]]] = False
    return whole


def _others_inside(xy: np.ndarray, reg, box: np.ndarray, others: np.ndarray) -> bool:
    """Whether any visible piece of another polygon overlaps the nonzero fill of ``xy``."""
    import shapely

    lo, hi = xy.min(axis=0), xy.max(axis=0)
    near = np.flatnonzero(others & (box[:, 0] < hi[0]) & (box[:, 2] > lo[0])
                          & (box[:, 1] < hi[1]) & (box[:, 3] > lo[1]))
    if not len(near):
        return False
    region = nonzero_region(xy)
    vertices, start = pieces_in_order(reg.vertices, reg.piece_start, near)
    owner = np.repeat(np.arange(len(near)), np.diff(start))
    pieces = shapely.polygons(shapely.linearrings(vertices, indices=owner))
    return float(shapely.area(shapely.intersection(region, pieces)).sum()) > _TOUCH_AREA
