"""The 2D artists that replace an axes' 3D ones for one draw: each polygon's exact visible
region (hsr.visible_regions' kernel), the visible pieces of outlines and lines and the
markers whose centre is visible (the exact segment cut of lines/vector.py), in display
pixels of this draw.

Layering needs no depth sort: visible regions are disjoint, and a visible line piece or
marker centre lies in front of every surface there, so fills go first, then outlines and
lines, then markers.
"""

from __future__ import annotations

import functools
import math
import warnings

import numpy as np

from ..errors import HsrWarning
from ..geometry.merge import merge_pieces, pieces_in_order
from .gather import Gathered, gather
from .view import camera_for
from .whole import whole_polygons

# Above mplot3d's axis zorder, in this order (fills under lines under markers).
_FILL, _GLASS, _EDGE, _LINE, _MARK = 0.0, 0.05, 0.1, 0.2, 0.3


def _delaunay(polygon: np.ndarray) -> np.ndarray | None:
    """(k, 3) vertex indices triangulating a planar polygon of more than four vertices
    (constrained Delaunay in its best-fit plane, shapely), or None for a non-planar one
    (fanned, as Agg fills the projection of a convex one)."""
    centre = polygon.mean(axis=0)
    _, sing, basis = np.linalg.svd(polygon - centre)
    if sing[2] > 1e-9 * max(sing[0], 1e-300):
        return None
    import shapely

    uv = (polygon - centre) @ basis[:2].T
    shape = shapely.make_valid(shapely.Polygon(uv))
    out = []
    for tri in shapely.get_parts(shapely.constrained_delaunay_triangles(shape)):
        corners = np.asarray(tri.exterior.coords)[:3]
        # Corners are the polygon's own vertices (or where its edges cross: the nearest).
        d = np.linalg.norm(uv[None, :, :] - corners[:, None, :], axis=2)
        out.append(np.argmin(d, axis=1))
    idx = np.asarray(out, dtype=np.int64).reshape(-1, 3)
    keep = (idx[:, 0] != idx[:, 1]) & (idx[:, 1] != idx[:, 2]) & (idx[:, 0] != idx[:, 2])
    return idx[keep]


def _outline_owners(idx: np.ndarray, n: int, first_tri: int) -> np.ndarray:
    """(n,) the triangle holding each outline edge (k, k + 1) of an n-gon triangulated as
    ``idx``: it never hides its own edge."""
    owner = np.full(n, first_tri, dtype=np.int64)
    for k, tri in enumerate(idx):
        for u, v in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
            if (v - u) % n == 1:
                owner[u] = first_tri + k
            elif (u - v) % n == 1:
                owner[v] = first_tri + k
    return owner


def _fill_geometry(fill) -> tuple:
    """Triangles (T, 3) vertex indices and their polygons (T,), outline edges (E, 2)
    vertex indices, their polygons and owner triangles (E,), for one Fill: fans, except
    constrained Delaunay for planar polygons of more than four vertices."""
    starts = fill.starts
    n = np.diff(starts)
    count = np.maximum(n - 2, 0)
    poly = np.repeat(np.arange(len(n)), count)
    k = np.arange(len(poly)) - np.repeat(np.cumsum(count) - count, count)
    s = starts[poly]
    tris = np.stack([s, s + k + 1, s + k + 2], axis=1)
    special = {}
    for p in np.flatnonzero(n > 4):
        idx = _delaunay(fill.vertices[starts[p]:starts[p + 1]])
        if idx is not None:
            special[p] = idx
    if special:
        drop = np.isin(poly, list(special))
        tri_parts, poly_parts = [tris[~drop]], [poly[~drop]]
        for p, idx in special.items():
            tri_parts.append(idx + starts[p])
            poly_parts.append(np.full(len(idx), p))
        tris, poly = np.concatenate(tri_parts), np.concatenate(poly_parts)
        order = np.argsort(poly, kind="stable")
        tris, poly = tris[order], poly[order]
    first_tri = np.searchsorted(poly, np.arange(len(n)))
    m = n if fill.closed else n - 1
    e_poly = np.repeat(np.arange(len(n)), m)
    e_k = np.arange(len(e_poly)) - np.repeat(np.cumsum(m) - m, m)
    e_n = n[e_poly]
    edges = np.stack([starts[e_poly] + e_k, starts[e_poly] + (e_k + 1) % e_n], axis=1)
    owner = first_tri[e_poly] + np.clip(e_k - 1, 0, np.maximum(e_n - 3, 0))
    for p, idx in special.items():
        mine = e_poly == p
        owner[mine] = _outline_owners(idx, int(n[p]), int(first_tri[p]))[:int(m[p])]
    return tris, poly, edges, e_poly, owner


class Flattened:
    """A Gathered axes as one triangle soup, one segment list and one point list (box
    coordinates), with where each item came from:

    triangles (T, 3, 3), tri_poly (T,); poly_fill, poly_index (P,): the Fill and polygon;
    edges (E, 2, 3), edge_own (E,) the triangle holding it, edge_poly (E,);
    segments (S, 2, 3), seg_group, seg_line, seg_number (S,): Lines group, polyline and
    segment number in it;
    points (Q, 3), point_kind (Q,) 0 scatter marker / 1 line vertex, point_group,
    point_index (Q,)."""

    def __init__(self, got: Gathered) -> None:
        tris: list = []
        tri_poly: list = []
        edges: list = []
        edge_own: list = []
        edge_poly: list = []
        poly_fill: list = []
        poly_index: list = []
        n_tri = n_poly = 0
        for f, fill in enumerate(got.fills):
            t_idx, t_poly, e_idx, e_poly, owner = _fill_geometry(fill)
            tris.append(fill.vertices[t_idx])
            tri_poly.append(t_poly + n_poly)
            edges.append(fill.vertices[e_idx])
            edge_own.append(owner + n_tri)
            edge_poly.append(e_poly + n_poly)
            count = len(fill.starts) - 1
            poly_fill.append(np.full(count, f))
            poly_index.append(np.arange(count))
            n_tri += len(t_idx)
            n_poly += count
        self.triangles = _cat(tris, (0, 3, 3))
        self.tri_poly = _cat(tri_poly, (0,), np.int64)
        self.edges = _cat(edges, (0, 2, 3))
        self.edge_own = _cat(edge_own, (0,), np.int64)
        self.edge_poly = _cat(edge_poly, (0,), np.int64)
        self.poly_fill = _cat(poly_fill, (0,), np.int64)
        self.poly_index = _cat(poly_index, (0,), np.int64)
        segs: list = []
        seg_group: list = []
        seg_line: list = []
        seg_number: list = []
        points: list = []
        point_kind: list = []
        point_group: list = []
        point_index: list = []
        for g, lines in enumerate(got.lines):
            for i, pts in enumerate(lines.polylines):
                finite = np.all(np.isfinite(pts), axis=1)
                if len(pts) >= 2:
                    ok = np.flatnonzero(finite[:-1] & finite[1:])
                    segs.append(np.stack([pts[ok], pts[ok + 1]], axis=1))
                    seg_group.append(np.full(len(ok), g))
                    seg_line.append(np.full(len(ok), i))
                    seg_number.append(ok)
                if lines.markers:
                    ok = np.flatnonzero(finite)
                    points.append(pts[ok])
                    point_kind.append(np.ones(len(ok), np.int64))
                    point_group.append(np.full(len(ok), g))
                    point_index.append(ok)
        for g, marks in enumerate(got.markers):
            ok = np.flatnonzero(np.all(np.isfinite(marks.centres), axis=1))
            points.append(marks.centres[ok])
            point_kind.append(np.zeros(len(ok), np.int64))
            point_group.append(np.full(len(ok), g))
            point_index.append(ok)
        self.segments = _cat(segs, (0, 2, 3))
        self.seg_group = _cat(seg_group, (0,), np.int64)
        self.seg_line = _cat(seg_line, (0,), np.int64)
        self.seg_number = _cat(seg_number, (0,), np.int64)
        self.points = _cat(points, (0, 3))
        self.point_kind = _cat(point_kind, (0,), np.int64)
        self.point_group = _cat(point_group, (0,), np.int64)
        self.point_index = _cat(point_index, (0,), np.int64)

    def all_points(self) -> np.ndarray:
        """Every vertex (box coordinates), to fit the camera's near and far planes."""
        return np.concatenate([self.triangles.reshape(-1, 3), self.segments.reshape(-1, 3),
                               self.points])


def _cat(parts: list, empty_shape: tuple, dtype=np.float64) -> np.ndarray:
    return np.concatenate(parts).astype(dtype, copy=False) if parts else \
        np.zeros(empty_shape, dtype)


class VisibleParts:
    """What the camera sees of a Flattened axes.

    ``regions``: hsr Regions of the scene's faces (or None), the scene being the opaque
    triangles, then the pieces a BSP tree cuts the transparent ones into (split where they
    cross), in painting order; ``face_poly`` (F,) each scene face's polygon and
    ``face_glass`` (F,) its place in that order (-1: opaque). Only opaque faces hide:
    a transparent piece is cut by the opaque faces in front of it, never by another
    transparent one. Fully transparent faces (alpha 0) are left out.

    The visible pieces of edges, segments and points (one list: edges first, then
    segments, then points as zero-length segments), hidden by the opaque faces: ``item``
    (K,), ``t`` (K, 2) and ``pieces`` (K, 2, 3) window x, y up, depth."""

    def __init__(self, flat: Flattened, camera, width: int, height: int,
                 edge_drawn: np.ndarray, poly_alpha: np.ndarray) -> None:
        from ..algorithms import bsp_tree
        from ..geometry.stage import prepare
        from ..geometry.state import CullMode, RenderState
        from ..lines.raster import clip_segments
        from ..lines.vector import visible_pieces
        from ..parallel import Workers
        from ..visibility.regions import screen_regions

        self.width, self.height = width, height
        edges = np.flatnonzero(edge_drawn[flat.edge_poly]) if len(flat.edges) else \
            np.zeros(0, np.int64)
        self.edge_ids = edges
        ends = np.concatenate([flat.edges[edges], flat.segments,
                               np.repeat(flat.points[:, None, :], 2, axis=1)])
        self.n_edges, self.n_segments = len(edges), len(flat.segments)
        view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
        self.regions = None
        alpha = poly_alpha[flat.tri_poly]
        opaque = np.flatnonzero(alpha >= 1.0)
        glass = np.flatnonzero((alpha > 0.0) & (alpha < 1.0))
        tris, self.face_poly = flat.triangles[opaque], flat.tri_poly[opaque]
        self.face_glass = np.full(len(opaque), -1, np.int64)
        if len(glass):
            glass_scene = soup_scene(flat.triangles[glass])
            tree = bsp_tree.build(glass_scene)
            order = bsp_tree.back_to_front(tree, camera)
            tris = np.concatenate([tris, tree.triangles[order]])
            self.face_poly = np.concatenate([self.face_poly,
                                             flat.tri_poly[glass][tree.face_id[order]]])
            self.face_glass = np.concatenate([self.face_glass, np.arange(len(order))])
        # An outline edge is never hidden by the (opaque) triangle that holds it.
        scene_face = np.full(len(flat.triangles), -1, np.int64)
        scene_face[opaque] = np.arange(len(opaque))
        own = np.full((len(ends), 2), -1, dtype=np.int64)
        own[:len(edges), 0] = scene_face[flat.edge_own[edges]]
        if not len(opaque):
            keep, pieces, t = clip_segments(ends, view_proj, width, height, guard=0)
            self.item, self.t, self.pieces = np.flatnonzero(keep), t, pieces
        if not len(tris):
            return
        scene = soup_scene(tris)
        with Workers() as workers:
            screen = prepare(scene, view_proj, width, height, RenderState(cull=CullMode.NONE), {},
                             workers)
            if len(screen):
                self.regions = screen_regions(scene, screen.xy_window, screen.depth_window,
                                              screen.face_id, width, height, False, {},
                                              workers, hides=self.face_glass < 0)
            if len(opaque):
                hiders = _Subset(screen, self.face_glass[screen.face_id] < 0)
                self.item, self.t, self.pieces = visible_pieces(hiders, view_proj, ends, own,
                                                                workers)


def soup_scene(triangles: np.ndarray):
    """An hsr Scene of a (T, 3, 3) triangle soup: face f is triangle f."""
    from ..scene.mesh import Mesh, Scene

    n = len(triangles)
    return Scene([Mesh(triangles.reshape(-1, 3), np.arange(3 * n, dtype=np.int64).reshape(-1, 3),
                       name="mplot3d")])


class _Subset:
    """The screen triangles of ``mask`` (what lines/vector.visible_pieces reads)."""

    def __init__(self, screen, mask: np.ndarray) -> None:
        self.xy_window = np.ascontiguousarray(screen.xy_window[mask])
        self.depth_window = np.ascontiguousarray(screen.depth_window[mask])
        self.face_id = np.ascontiguousarray(screen.face_id[mask])
        self.width, self.height = screen.width, screen.height

    def __len__(self) -> int:
        return len(self.face_id)


def _joined(seg_key: np.ndarray, seg_number: np.ndarray, t: np.ndarray,
            pieces: np.ndarray) -> tuple:
    """Join visible pieces (sorted by segment) that continue each other (one ends at its
    segment's end, the next starts at the following segment's start, same polyline) into
    polylines: (list of (n, 2) display points, (L,) the key of each)."""
    if not len(pieces):
        return [], np.zeros(0, np.int64)
    cont = np.zeros(len(pieces), bool)
    cont[1:] = ((seg_key[1:] == seg_key[:-1]) & (seg_number[1:] == seg_number[:-1] + 1)
                & (t[:-1, 1] >= 1 - 1e-12) & (t[1:, 0] <= 1e-12))
    first = np.flatnonzero(~cont)
    # Each polyline: its first piece's start, then every piece's end.
    points = np.concatenate([pieces[:, :1, :2], pieces[:, 1:, :2]], axis=1)
    keep = np.ones((len(pieces), 2), bool)
    keep[cont, 0] = False
    flat_points = points[keep]
    sizes = np.add.reduceat(keep.sum(axis=1), first)
    lines = np.split(flat_points, np.cumsum(sizes)[:-1])
    return lines, seg_key[first]


def _compound_paths(ring_xy, ring_start, group_ring) -> list:
    """One matplotlib Path per group of rings: MOVETO, LINETOs, CLOSEPOLY per ring."""
    from matplotlib.path import Path

    n_ring = len(ring_start) - 1
    size = np.diff(ring_start) + 1  # each ring and its closing vertex
    out_start = np.r_[0, np.cumsum(size)]
    verts = np.empty((out_start[-1], 2))
    src = np.repeat(ring_start[:-1] - out_start[:-1], size) + np.arange(out_start[-1])
    last = out_start[1:] - 1
    src[last] = ring_start[:-1]  # the closing vertex repeats the first (CLOSEPOLY ignores it)
    verts[:] = ring_xy[src]
    codes = np.full(len(verts), Path.LINETO, dtype=np.uint8)
    codes[out_start[:-1]] = Path.MOVETO
    codes[last] = Path.CLOSEPOLY
    bounds = out_start[group_ring]
    # Path's own constructor checks each array again (a third of the draw for 10k paths).
    make = getattr(Path, "_fast_from_codes_and_verts", Path)
    return [make(verts[bounds[g]:bounds[g + 1]], codes[bounds[g]:bounds[g + 1]])
            for g in range(len(group_ring) - 1)] if n_ring else []


def _one_if_same(values: np.ndarray) -> np.ndarray:
    """One value where all are equal: the SVG and PDF backends then define the marker once
    and place it at each offset."""
    return values[:1] if len(values) and np.all(values == values[0]) else values


def _per_polygon(got, flat, name: str) -> np.ndarray:
    """A Fill field (face_rgba, edge_rgba, edge_width) for every polygon of ``flat``."""
    if not len(flat.poly_fill):
        return np.zeros((0, 4)) if name.endswith("rgba") else np.zeros(0)
    parts = [getattr(fill, name) for fill in got.fills]
    offsets = np.r_[0, np.cumsum([len(p) for p in parts])]
    return np.concatenate(parts)[offsets[flat.poly_fill] + flat.poly_index]


def _antialiased(artist) -> bool:
    value = artist.get_antialiased() if hasattr(artist, "get_antialiased") else True
    return bool(np.all(value))


def _merged_paths(reg, pieces: np.ndarray, key: np.ndarray, height: int,
                  path_of=None) -> tuple:
    """(path keys (P,), paths (P,)): the regions' ``pieces`` grouped by ``key``, each
    group's pieces merged into rings, as display-space compound paths: one per key, or
    with ``path_of`` (keys (G,) -> ints), one per value it gives (groups that share a
    colour need not be drawn apart: their regions are disjoint)."""
    order = np.argsort(key, kind="stable")
    chosen = pieces[order]
    verts, start = pieces_in_order(reg.vertices, reg.piece_start, chosen)
    keys = key[order]
    groups = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1], True])
    ring_xy, ring_start, group_ring = merge_pieces(verts, start, groups)
    ring_xy[:, 1] = height - ring_xy[:, 1]  # image rows -> display y up
    group_key = keys[groups[:-1]]
    path_id = group_key if path_of is None else path_of(group_key)
    by_path = np.argsort(path_id, kind="stable")
    n_rings = np.diff(group_ring)[by_path]
    ring_order = np.repeat(group_ring[:-1][by_path] - (np.cumsum(n_rings) - n_rings),
                           n_rings) + np.arange(int(n_rings.sum()))
    ring_xy, ring_start = pieces_in_order(ring_xy, ring_start, ring_order)
    ids = path_id[by_path]
    cuts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1], True])
    path_ring = np.r_[0, np.cumsum(n_rings)][cuts]
    # A path whose pieces merged into no ring (slivers of a face seen edge-on, which
    # cancel on the snap grid) covers nothing: it is left out with its key.
    drawn = np.diff(path_ring) > 0
    path_ring = np.r_[path_ring[:-1][drawn], path_ring[-1]]
    return ids[cuts[:-1]][drawn], _compound_paths(ring_xy, ring_start, path_ring)


@functools.cache
def _flat_classes():
    """PathCollection / LineCollection / PathPatch that Axes3D.draw can ask for a 3D
    projection (made once, when matplotlib is first needed)."""
    from matplotlib.collections import LineCollection, PathCollection
    from matplotlib.patches import PathPatch

    class FlatPaths(PathCollection):
        def do_3d_projection(self):
            return 0.0

    class FlatLines(LineCollection):
        def do_3d_projection(self):
            return 0.0

    class FlatPatch(PathPatch):
        def do_3d_projection(self):
            return 0.0

    return FlatPaths, FlatLines, FlatPatch


def _like(new, old, figure, kind: str) -> None:
    """Clip and figure of the original artist, set before the new one joins the axes, and
    an id (``hsr3d-fill``, ``-edge``, ``-line``, ``-marker``) that SVG output keeps."""
    new.set_gid(f"hsr3d-{kind}")
    new.set_clip_on(old.get_clip_on())
    new.set_clip_box(old.get_clip_box())
    new.set_clip_path(old.get_clip_path())
    new.set_figure(figure)
    new.set_label("_hsr_" + str(old.get_label()))


def flat_artists(ax) -> tuple:
    """(ids of the 3D artists drawn here, [(2D artist, rank)]) for the axes' current view
    (``ax.M`` set). Warns, naming each, of 3D artists left to mplot3d."""
    got = gather(ax)
    for artist, why in got.skipped:
        warnings.warn(f"hsr.mpl: {type(artist).__name__} {artist.get_label()!r} is drawn by "
                      f"mplot3d, not hidden exactly: {why}", HsrWarning, stacklevel=3)
    if not (got.fills or got.lines or got.markers):
        return set(), []
    figure = ax.get_figure(root=True) if hasattr(ax, "get_figure") else ax.figure
    width = max(1, int(math.ceil(figure.bbox.width)))
    height = max(1, int(math.ceil(figure.bbox.height)))
    flat = Flattened(got)
    camera = camera_for(ax, flat.all_points(), width, height)
    face_rgba = _per_polygon(got, flat, "face_rgba")
    edge_rgba = _per_polygon(got, flat, "edge_rgba")
    edge_width = _per_polygon(got, flat, "edge_width")
    edge_drawn = (edge_rgba[:, 3] > 0) & (edge_width > 0) if len(edge_rgba) else \
        np.zeros(0, bool)
    seen = VisibleParts(flat, camera, width, height, edge_drawn,
                        face_rgba[:, 3] if len(face_rgba) else np.zeros(0))
    whole = whole_polygons(got, flat, seen, camera, face_rgba)
    added = (_fill_artists(got, flat, seen, face_rgba, figure, whole)
             + _whole_artists(got, flat, seen, whole, figure)
             + _line_artists(got, flat, seen, edge_rgba, edge_width, figure, whole)
             + _marker_artists(got, flat, seen, figure))
    for artist, _ in added:
        _unclip_if_inside(artist, figure.dpi)
    return {id(x.artist) for x in got.fills + got.lines + got.markers}, added


def _unclip_if_inside(artist, dpi: float) -> None:
    """Turn the clip off where the drawing lies inside its clip box anyway: SVG and PDF
    write a clip path per clipped artist, and mplot3d clips each to the axes (markers keep
    theirs: their extent is the marker's)."""
    box = artist.get_clip_box()
    if not artist.get_clip_on() or box is None or artist.get_clip_path() is not None:
        return
    if hasattr(artist, "get_segments"):
        parts = [np.asarray(seg, float).reshape(-1, 2) for seg in artist.get_segments()]
    elif hasattr(artist, "get_paths") and artist.get_gid() != "hsr3d-marker":
        parts = [path.vertices for path in artist.get_paths()]
    elif hasattr(artist, "get_path") and not hasattr(artist, "get_xdata"):
        parts = [artist.get_path().vertices]
    else:
        return
    points = np.concatenate(parts) if parts else np.zeros((0, 2))
    if not len(points):
        return
    width = np.max(np.atleast_1d(artist.get_linewidth()), initial=0.0) * dpi / 72
    # A miter join reaches out up to its limit (4, the SVG default) times half the
    # width; antialiasing a pixel more.
    margin = 2.0 * width + 1.0
    x0, y0, x1, y1 = box.extents
    x, y = points[:, 0], points[:, 1]  # a column's min is 30x faster than min(axis=0)
    if x.min() - margin >= x0 and y.min() - margin >= y0 and x.max() + margin <= x1 and \
            y.max() + margin <= y1:
        artist.set_clip_on(False)


def _fill_artists(got, flat, seen, face_rgba, figure, whole: dict) -> list:
    """[(2D artist, rank)] of the polygons' visible regions: opaque ones one path per fill
    artist and colour, transparent pieces back to front (``whole`` polygons left out)."""
    from matplotlib.transforms import IdentityTransform

    if seen.regions is None or not len(seen.regions):
        return []
    FlatPaths, _, _ = _flat_classes()
    added: list = []
    reg, height = seen.regions, seen.height
    piece_face = reg.face_id[reg.piece_row]
    glass = seen.face_glass[piece_face]
    # Opaque fills: each polygon's pieces merged into rings, one path per polygon.
    opaque = np.flatnonzero((glass < 0) & ~np.isin(seen.face_poly[piece_face], list(whole)))
    # One path per fill artist and colour: a colormap's few hundred colours are a
    # few hundred paths, not one per polygon (and no seams inside a colour).
    # Grouped by 8-bit RGBA, what every backend writes (np.unique on float rows
    # sorts lexically: a fifth of a 90k-quad draw).
    code = np.round(np.clip(face_rgba, 0, 1) * 255).astype(np.uint32) @ \
        np.array([1 << 24, 1 << 16, 1 << 8, 1], np.uint32)
    _, first, colour_id = np.unique(code, return_index=True, return_inverse=True)
    colours = face_rgba[first]
    n_col = len(colours)
    ids, paths = _merged_paths(
        reg, opaque, seen.face_poly[piece_face[opaque]], height,
        path_of=lambda poly: flat.poly_fill[poly] * n_col + colour_id.ravel()[poly]) \
        if len(opaque) else (np.zeros(0, np.int64), [])
    for f, fill in enumerate(got.fills):
        mine = np.flatnonzero(ids // n_col == f)
        if not len(mine):
            continue
        art = FlatPaths([paths[k] for k in mine], facecolors=colours[ids[mine] % n_col],
                        edgecolors="none", linewidths=0.0,
                        antialiaseds=_antialiased(fill.artist))
        art.set_transform(IdentityTransform())
        _like(art, fill.artist, figure, "fill")
        added.append((art, _FILL))
    # Transparent fills: each BSP piece's visible part, back to front, in one
    # collection so that pieces of different artists interleave as they must.
    clear = np.flatnonzero(glass >= 0)
    if len(clear):
        # Consecutive pieces of one polygon (a quad's two triangles, one node's
        # coplanar pieces) become one path: drawn apart, their shared edges would
        # blend twice.
        frag_poly = seen.face_poly[seen.face_glass >= 0]
        run = np.cumsum(np.r_[True, frag_poly[1:] != frag_poly[:-1]]) - 1
        runs, paths = _merged_paths(reg, clear, run[glass[clear]], height)
        frag_poly = frag_poly[np.searchsorted(run, runs)]
        first_art = got.fills[int(flat.poly_fill[frag_poly[0]])].artist
        art = FlatPaths(paths, facecolors=face_rgba[frag_poly], edgecolors="none",
                        linewidths=0.0, antialiaseds=_antialiased(first_art))
        art.set_transform(IdentityTransform())
        _like(art, first_art, figure, "glass")
        added.append((art, _GLASS))
    return added


def _line_artists(got, flat, seen, edge_rgba, edge_width, figure, whole: dict) -> list:
    """[(2D artist, rank)] of the visible pieces of polygon outlines (but ``whole``
    polygons') and of lines, joined where they continue each other."""
    from matplotlib.transforms import IdentityTransform

    _, FlatLines, _ = _flat_classes()
    added: list = []
    item, t, pieces = seen.item, seen.t, seen.pieces
    is_edge = item < seen.n_edges
    if whole and is_edge.any():
        is_edge[is_edge] = ~np.isin(flat.edge_poly[seen.edge_ids[item[is_edge]]], list(whole))
    if is_edge.any():
        edge = seen.edge_ids[item[is_edge]]
        poly = flat.edge_poly[edge]
        # Pieces of a polygon's ring continue each other from edge k to k + 1.
        lines, keys = _joined(poly, edge, t[is_edge], pieces[is_edge])
        for f, fill in enumerate(got.fills):
            mine = np.flatnonzero(flat.poly_fill[keys] == f) if len(keys) else \
                np.zeros(0, np.int64)
            if not len(mine):
                continue
            art = FlatLines([lines[k] for k in mine], colors=edge_rgba[keys[mine]],
                            linewidths=edge_width[keys[mine]], transform=IdentityTransform(),
                            linestyles=fill.artist.get_linestyle()
                            if hasattr(fill.artist, "get_linestyle") else "solid")
            art.set_transform(IdentityTransform())
            _like(art, fill.artist, figure, "edge")
            added.append((art, _EDGE))
    is_seg = (item >= seen.n_edges) & (item < seen.n_edges + seen.n_segments)
    if is_seg.any():
        s = item[is_seg] - seen.n_edges
        key = flat.seg_group[s] * (1 << 32) + flat.seg_line[s]
        lines, keys = _joined(key, flat.seg_number[s], t[is_seg], pieces[is_seg])
        for g, group in enumerate(got.lines):
            mine = np.flatnonzero((keys >> 32) == g) if len(keys) else np.zeros(0, np.int64)
            if not len(mine):
                continue
            line_idx = keys[mine] & ((1 << 32) - 1)
            styles = [group.styles[i] for i in line_idx]
            art = FlatLines([lines[k] for k in mine], colors=group.rgba[line_idx],
                            linewidths=group.width[line_idx], linestyles=styles,
                            transform=IdentityTransform())
            art.set_transform(IdentityTransform())
            if hasattr(group.artist, "get_dash_capstyle"):  # a Line3D: its caps and joins
                solid = group.artist.get_linestyle() in ("-", "solid")
                art.set_capstyle(group.artist.get_solid_capstyle() if solid
                                 else group.artist.get_dash_capstyle())
                art.set_joinstyle(group.artist.get_solid_joinstyle() if solid
                                  else group.artist.get_dash_joinstyle())
            _like(art, group.artist, figure, "line")
            added.append((art, _LINE))
    return added


def _whole_artists(got, flat, seen, whole: dict, figure) -> list:
    """[(2D artist, rank)] of the polygons nothing hides: mplot3d's own patch (its path,
    fill, edge, style and hatch) at hsr's projection, above every fill as outlines are."""
    from matplotlib.path import Path
    from matplotlib.transforms import IdentityTransform

    _, _, FlatPatch = _flat_classes()
    added: list = []
    for p, xy in whole.items():
        artist = got.fills[int(flat.poly_fill[p])].artist
        codes = getattr(artist, "_code3d", None)
        display = np.column_stack([xy[:, 0], seen.height - xy[:, 1]])
        patch = FlatPatch(Path(display, codes if codes is not None and
                               len(codes) == len(display) else None))
        patch.update_from(artist)
        patch.set_transform(IdentityTransform())
        _like(patch, artist, figure, "fill")
        added.append((patch, _EDGE))
    return added


def _marker_artists(got, flat, seen, figure) -> list:
    """[(2D artist, rank)] of the markers whose centre is visible, in mplot3d's order (far
    to near), and of the visible vertices of lines drawn with markers."""
    from matplotlib.lines import Line2D
    from matplotlib.transforms import IdentityTransform

    FlatPaths, _, _ = _flat_classes()
    added: list = []
    is_point = seen.item >= seen.n_edges + seen.n_segments
    q = seen.item[is_point] - seen.n_edges - seen.n_segments
    xy = seen.pieces[is_point, 0, :2]
    for g, marks in enumerate(got.markers):
        sel = (flat.point_kind[q] == 0) & (flat.point_group[q] == g)
        idx = flat.point_index[q[sel]]
        rank = np.empty(len(marks.order), np.int64)
        rank[marks.order] = np.arange(len(marks.order))
        o = np.argsort(rank[idx], kind="stable")
        idx, pos = idx[o], xy[sel][o]
        art = FlatPaths(marks.artist.get_paths(), sizes=_one_if_same(marks.sizes[idx]),
                        offsets=pos, offset_transform=IdentityTransform(),
                        facecolors=marks.face_rgba[idx], edgecolors=marks.edge_rgba[idx],
                        linewidths=_one_if_same(marks.widths[idx]))
        art.set_transform(IdentityTransform())
        _like(art, marks.artist, figure, "marker")
        added.append((art, _MARK))
    for g, group in enumerate(got.lines):
        if not group.markers:
            continue
        sel = (flat.point_kind[q] == 1) & (flat.point_group[q] == g)
        pos = xy[sel]
        art = Line2D(pos[:, 0], pos[:, 1])
        art.update_from(group.artist)
        art.set_linestyle("None")
        art.set_transform(IdentityTransform())
        _like(art, group.artist, figure, "marker")
        added.append((art, _MARK))
    return added
