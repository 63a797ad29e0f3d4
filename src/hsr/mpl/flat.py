"""The 2D artists that replace an axes' 3D ones for one draw: each polygon's exact visible
region (hsr.visible_regions' kernel), the visible pieces of outlines and lines and the
markers whose centre is visible (the exact segment cut of lines/vector.py), in display
pixels of this draw.

Layering needs no depth sort: visible regions are disjoint, and a visible line piece or
marker centre lies in front of every surface there, so fills go first, then outlines and
lines, then markers.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ..errors import HsrWarning
from .gather import Gathered, gather
from .view import camera_for

# Above mplot3d's axis zorder, in this order (fills under lines under markers).
_FILL, _EDGE, _LINE, _MARK = 0.0, 0.1, 0.2, 0.3


def _triangulate(polygon: np.ndarray) -> np.ndarray:
    """(k, 3) vertex indices of a polygon: a fan for triangles and quads (what Agg fills of
    a convex projected quad), else ear-free constrained Delaunay in the polygon's best-fit
    plane (shapely) for a planar one, a fan for a non-planar one."""
    n = len(polygon)
    fan = np.stack([np.zeros(n - 2, np.int64), np.arange(1, n - 1), np.arange(2, n)], axis=1)
    if n <= 4:
        return fan
    centre = polygon.mean(axis=0)
    _, sing, basis = np.linalg.svd(polygon - centre)
    if sing[2] > 1e-9 * max(sing[0], 1e-300):
        return fan
    import shapely

    uv = (polygon - centre) @ basis[:2].T
    shape = shapely.make_valid(shapely.Polygon(uv))
    tris = shapely.get_parts(shapely.constrained_delaunay_triangles(shape))
    out = []
    for tri in tris:
        corners = np.asarray(tri.exterior.coords)[:3]
        # Delaunay corners are the polygon's own vertices (or crossings of its edges).
        d = np.linalg.norm(uv[None, :, :] - corners[:, None, :], axis=2)
        out.append(np.argmin(d, axis=1))
    out = np.asarray(out, dtype=np.int64).reshape(-1, 3)
    keep = (out[:, 0] != out[:, 1]) & (out[:, 1] != out[:, 2]) & (out[:, 0] != out[:, 2])
    return out[keep]


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
        n_tri = 0
        for f, fill in enumerate(got.fills):
            for p, poly in enumerate(fill.polygons):
                idx = _triangulate(poly)
                n_poly = len(poly_fill)
                tris.append(poly[idx])
                tri_poly.append(np.full(len(idx), n_poly))
                m = len(poly) if fill.closed else len(poly) - 1
                edges.append(np.stack([poly, np.roll(poly, -1, axis=0)], axis=1)[:m])
                edge_own.append(_outline_owners(idx, len(poly), n_tri)[:m])
                edge_poly.append(np.full(m, n_poly))
                poly_fill.append(f)
                poly_index.append(p)
                n_tri += len(idx)
        self.triangles = _cat(tris, (0, 3, 3))
        self.tri_poly = _cat(tri_poly, (0,), np.int64)
        self.edges = _cat(edges, (0, 2, 3))
        self.edge_own = _cat(edge_own, (0,), np.int64)
        self.edge_poly = _cat(edge_poly, (0,), np.int64)
        self.poly_fill = np.asarray(poly_fill, dtype=np.int64)
        self.poly_index = np.asarray(poly_index, dtype=np.int64)
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
    """What the camera sees of a Flattened axes: ``regions`` (hsr Regions of its triangles,
    or None), and the visible pieces of its edges, segments and points (one list: edges
    first, then segments, then points as zero-length segments): ``item`` (K,), ``t``
    (K, 2) and ``pieces`` (K, 2, 3) window x, y up, depth."""

    def __init__(self, flat: Flattened, camera, width: int, height: int,
                 edge_drawn: np.ndarray) -> None:
        from ..geometry.stage import prepare
        from ..geometry.state import RenderState
        from ..lines.raster import clip_segments
        from ..lines.vector import visible_pieces
        from ..parallel import Workers
        from ..scene.mesh import Mesh, Scene
        from ..visibility.regions import _regions

        self.width, self.height = width, height
        edges = np.flatnonzero(edge_drawn[flat.edge_poly]) if len(flat.edges) else \
            np.zeros(0, np.int64)
        self.edge_ids = edges
        ends = np.concatenate([flat.edges[edges], flat.segments,
                               np.repeat(flat.points[:, None, :], 2, axis=1)])
        own = np.full((len(ends), 2), -1, dtype=np.int64)
        own[:len(edges), 0] = flat.edge_own[edges]
        self.n_edges, self.n_segments = len(edges), len(flat.segments)
        view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
        self.regions = None
        if not len(flat.triangles):
            keep, pieces, t = clip_segments(ends, view_proj, width, height, guard=0)
            self.item, self.t, self.pieces = np.flatnonzero(keep), t, pieces
            return
        n = len(flat.triangles)
        scene = Scene([Mesh(flat.triangles.reshape(-1, 3),
                            np.arange(3 * n, dtype=np.int64).reshape(-1, 3), name="mplot3d")])
        with Workers() as workers:
            screen = prepare(scene, view_proj, width, height, RenderState(cull="none"), {},
                             workers)
            if len(screen):
                self.regions = _regions(scene, screen.xy_window, screen.depth_window,
                                        screen.face_id, width, height, False, {}, workers)
            self.item, self.t, self.pieces = visible_pieces(screen, view_proj, ends, own,
                                                            workers)


def _joined(seg_key: np.ndarray, seg_number: np.ndarray, t: np.ndarray,
            pieces: np.ndarray) -> tuple:
    """Join visible pieces (sorted by segment) that continue each other (one ends at its
    segment's end, the next starts at the following segment's start, same polyline) into
    polylines: (list of (n, 2) display points, (L,) the key of each)."""
    lines, keys = [], []
    current: list = []
    for k in range(len(pieces)):
        starts_at_0 = t[k, 0] <= 1e-12
        cont = (current and seg_key[k] == seg_key[k - 1] and
                seg_number[k] == seg_number[k - 1] + 1 and t[k - 1, 1] >= 1 - 1e-12 and
                starts_at_0)
        if cont:
            current.append(pieces[k, 1, :2])
        else:
            if current:
                lines.append(np.array(current))
                keys.append(seg_key[k - 1])
            current = [pieces[k, 0, :2], pieces[k, 1, :2]]
    if current:
        lines.append(np.array(current))
        keys.append(seg_key[len(pieces) - 1])
    return lines, np.asarray(keys, dtype=np.int64)


def _flat_classes():
    """PathCollection / LineCollection that Axes3D.draw can ask for a 3D projection."""
    from matplotlib.collections import LineCollection, PathCollection

    class FlatPaths(PathCollection):
        def do_3d_projection(self):
            return 0.0

    class FlatLines(LineCollection):
        def do_3d_projection(self):
            return 0.0

    return FlatPaths, FlatLines


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
    from matplotlib.lines import Line2D
    from matplotlib.path import Path
    from matplotlib.transforms import IdentityTransform

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
    edge_drawn = np.zeros(len(flat.poly_fill), bool)
    for p, (f, i) in enumerate(zip(flat.poly_fill, flat.poly_index)):
        fill = got.fills[f]
        edge_drawn[p] = fill.edge_rgba[i, 3] > 0 and fill.edge_width[i] > 0
    seen = VisibleParts(flat, camera, width, height, edge_drawn)
    FlatPaths, FlatLines = _flat_classes()
    added: list = []
    replaced = {id(x.artist) for x in got.fills + got.lines + got.markers}

    # Fills: each polygon's pieces as one compound path.
    if seen.regions is not None and len(seen.regions):
        reg = seen.regions
        piece_poly = flat.tri_poly[reg.face_id[reg.piece_row]]
        order = np.argsort(piece_poly, kind="stable")
        starts = reg.piece_start
        for f, fill in enumerate(got.fills):
            mine = order[flat.poly_fill[piece_poly[order]] == f]
            if not len(mine):
                continue
            paths, colors = [], []
            polys = piece_poly[mine]
            cuts = np.flatnonzero(np.r_[True, polys[1:] != polys[:-1], True])
            for a, b in zip(cuts[:-1], cuts[1:]):
                verts, codes = [], []
                for piece in mine[a:b]:
                    ring = reg.vertices[starts[piece]:starts[piece + 1]].copy()
                    ring[:, 1] = height - ring[:, 1]
                    verts.append(np.vstack([ring, ring[:1]]))
                    c = np.full(len(ring) + 1, Path.LINETO, dtype=np.uint8)
                    c[0], c[-1] = Path.MOVETO, Path.CLOSEPOLY
                    codes.append(c)
                paths.append(Path(np.concatenate(verts), np.concatenate(codes)))
                colors.append(fill.face_rgba[flat.poly_index[polys[a]]])
            art = FlatPaths(paths, facecolors=np.array(colors), edgecolors="none",
                            linewidths=0.0, transform=IdentityTransform(),
                            antialiaseds=fill.artist.get_antialiased()
                            if hasattr(fill.artist, "get_antialiased") else True)
            art.set_transform(IdentityTransform())
            _like(art, fill.artist, figure, "fill")
            added.append((art, _FILL))

    # Outlines of polygons, then lines: visible pieces joined where they continue.
    item, t, pieces = seen.item, seen.t, seen.pieces
    is_edge = item < seen.n_edges
    if is_edge.any():
        edge = seen.edge_ids[item[is_edge]]
        poly = flat.edge_poly[edge]
        # Pieces of a polygon's ring continue each other from edge k to k + 1.
        lines, keys = _joined(poly, edge, t[is_edge], pieces[is_edge])
        for f, fill in enumerate(got.fills):
            mine = np.flatnonzero(flat.poly_fill[keys] == f) if len(keys) else []
            if not len(mine):
                continue
            idx = flat.poly_index[keys[mine]]
            art = FlatLines([lines[k] for k in mine], colors=fill.edge_rgba[idx],
                            linewidths=fill.edge_width[idx], transform=IdentityTransform(),
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
            mine = np.flatnonzero((keys >> 32) == g) if len(keys) else []
            if not len(mine):
                continue
            line_idx = keys[mine] & ((1 << 32) - 1)
            styles = [group.styles[i] for i in line_idx]
            art = FlatLines([lines[k] for k in mine], colors=group.rgba[line_idx],
                            linewidths=group.width[line_idx], linestyles=styles,
                            transform=IdentityTransform())
            art.set_transform(IdentityTransform())
            if hasattr(group.artist, "get_dash_capstyle"):
                art.set_capstyle(group.artist.get_solid_capstyle())
                art.set_joinstyle(group.artist.get_solid_joinstyle())
            _like(art, group.artist, figure, "line")
            added.append((art, _LINE))

    # Markers whose centre is visible, in mplot3d's order (far to near).
    is_point = item >= seen.n_edges + seen.n_segments
    q = item[is_point] - seen.n_edges - seen.n_segments
    xy = pieces[is_point, 0, :2]
    for g, marks in enumerate(got.markers):
        sel = (flat.point_kind[q] == 0) & (flat.point_group[q] == g)
        idx = flat.point_index[q[sel]]
        rank = np.empty(len(marks.order), np.int64)
        rank[marks.order] = np.arange(len(marks.order))
        o = np.argsort(rank[idx], kind="stable")
        idx, pos = idx[o], xy[sel][o]
        art = FlatPaths(marks.artist.get_paths(), sizes=marks.sizes[idx],
                        offsets=pos, offset_transform=IdentityTransform(),
                        facecolors=marks.face_rgba[idx], edgecolors=marks.edge_rgba[idx],
                        linewidths=marks.widths[idx])
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
    return replaced, added
