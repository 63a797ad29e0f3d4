"""Exact visible regions: hidden-surface removal in object space, as geometry.

For every face, the part of its projection that nothing covers, in the pixel geometry of
images (x right, y down; pixel (x, y) covers [x, x+1) x [y, y+1)), independent of any
pixel grid: computed once, it scales to any size.

Method. The geometry stage gives each face's projection, clipped exactly at the near and
far planes and culled as the state says, as window-space triangles whose depth is an
affine function of (x, y) (a plane stays a plane under the projective map). A triangle
T_j hides a point of triangle T_i where it covers the point and its depth there is less:
the convex polygon T_j cut by the half-plane where z_j < z_i (the difference of two affine
functions). So

    visible(T_i) = T_i - union over j of (T_j  cut by  z_j < z_i)

which cuts faces that pass through each other exactly along their intersection line and
needs no depth order: cycles need no special case. Coplanar faces tie as OpenGL breaks
ties: with ``less`` the face submitted first keeps the overlap, with ``lequal`` the last.

Each difference keeps the visible part as disjoint convex pieces: a piece that meets a
hider is split by the hider's edge lines, the part outside each edge kept and the rest
passed to the next edge (what is left is inside the hider). Candidates come from a grid of
cells over the image, nearest first, so a face buried under a near one stops early. All in
float64, in Numba kernels; shapely (``hsr[regions]``) only merges a face's pieces into
polygons with holes when :attr:`Regions.polygons` is read.

A region's boundary belongs to neither face: areas are exact (to float64 rounding), and a
point on a shared edge or vertex lies in no region's interior. Pieces thinner than
rounding (area under :data:`MIN_PIECE_AREA` px^2, slivers left where two hiders share an
edge) are dropped, so a face is reported only with a visible area above it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from ..algorithms.simd import borrowed
from ..errors import HsrError, RenderError
from ..geometry.convex import (
    MAX_VERTICES,
    bounds_overlap,
    clip_half_plane,
    clip_to_view,
    edge_lines,
    side_of_line,
    signed_area,
    triangles_apart,
)
from ..parallel import split_range
from ..scene.camera import Camera
from ..scene.mesh import SceneLike

__all__ = ["Regions", "RegionsError", "visible_regions", "write_regions_svg",
           "write_regions_pdf", "MIN_PIECE_AREA"]

MIN_PIECE_AREA = 1e-9  # px^2: a piece smaller than this is rounding, not surface
GRID = 2.0 ** -30  # px: the snapping grid of the polygons merged from the pieces
# Two planes whose depths differ by less than this (relative) over a triangle are one.
_TIE = 1e-12
_MAX_PIECES = 4096  # convex pieces of one triangle's visible part at a time
_CELL_TRIANGLES = 4.0  # about this many triangles' boxes per grid cell


class RegionsError(HsrError):
    """A scene, camera or state the exact regions cannot answer."""


@dataclass
class Regions:
    """The visible regions of one view, one row per face with a visible part.

    face_id, object_id : (R,) int64, the face (global, submission order) and its instance.
    area : (R,) float64, visible area in px^2.
    fraction : (R,) float64, visible area over the face's projected area inside the view.
    piece_row : (P,) int64, the row each convex piece belongs to; piece_start : (P + 1,)
        int64 offsets into vertices : (V, 2) float64 image coordinates (x right, y down).
    width, height : the view in pixels (the regions lie in [0, W] x [0, H]).
    """

    face_id: np.ndarray
    object_id: np.ndarray
    area: np.ndarray
    fraction: np.ndarray
    piece_row: np.ndarray
    piece_start: np.ndarray
    vertices: np.ndarray
    width: int
    height: int
    stats: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.face_id)

    def __repr__(self) -> str:
        return (f"<hsr.Regions {self.width}x{self.height}: {len(self)} faces visible, "
                f"{len(self.piece_row)} convex pieces, {self.area.sum():.6g} px^2>")

    def pieces(self, row: int) -> list:
        """The convex pieces of row ``row`` as (K, 2) vertex arrays."""
        chosen = np.flatnonzero(self.piece_row == row)
        return [self.vertices[self.piece_start[p]:self.piece_start[p + 1]] for p in chosen]

    @property
    def polygons(self) -> list:
        """One shapely (Multi)Polygon per row: its pieces merged, holes and all (needs
        shapely: ``pip install 'hsr[regions]'``)."""
        from ..errors import require_extra

        require_extra("Regions.polygons", "shapely")
        import shapely

        if not len(self.piece_row):
            return []
        piece_of_vertex = np.repeat(np.arange(len(self.piece_row)), np.diff(self.piece_start))
        parts = shapely.polygons(shapely.linearrings(self.vertices, indices=piece_of_vertex))
        order = np.argsort(self.piece_row, kind="stable")
        bounds = np.searchsorted(self.piece_row[order], np.arange(len(self) + 1))
        # Snap-rounded overlay (GEOS OverlayNG on a 2^-30 px grid): robust where pieces
        # meet along edges computed twice with different rounding.
        parts = shapely.make_valid(parts)
        return [shapely.union_all(parts[order[bounds[r]:bounds[r + 1]]], grid_size=GRID)
                for r in range(len(self))]

    def quality(self, scene: SceneLike, camera: Camera) -> tuple:
        """(cosine, distance), (R,) float64 each: per row, the mean over its visible area of
        the cosine between the face's normal (as wound) and the direction to the eye, and
        of the distance from the eye (world units), as
        :class:`~hsr.visibility.VisibilityMatrix` has them per pixel. Each convex piece
        counts with its area at its centroid, carried back onto the face's plane along
        its ray; ``scene`` and ``camera`` are the ones the regions were computed for."""
        from ..scene.load import scene_of

        triangles = scene_of(scene).world_triangles()
        cx, cy, piece_area = _piece_centroids(self.vertices, self.piece_start)
        view_proj = camera.projection_matrix(self.width / self.height) @ camera.view_matrix
        inv = np.linalg.inv(view_proj)
        ndc = np.stack([2.0 * cx / self.width - 1.0, 1.0 - 2.0 * cy / self.height], axis=1)
        ones = np.ones(len(ndc))
        near = np.c_[ndc, -ones, ones] @ inv.T
        far = np.c_[ndc, ones, ones] @ inv.T
        origin = near[:, :3] / near[:, 3:]
        direction = far[:, :3] / far[:, 3:] - origin
        tri = triangles[self.face_id[self.piece_row]]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        t = (np.einsum("ij,ij->i", normal, tri[:, 0] - origin)
             / np.einsum("ij,ij->i", normal, direction))
        point = origin + t[:, None] * direction
        back = -direction / np.linalg.norm(direction, axis=1, keepdims=True)
        cosine = np.einsum("ij,ij->i", normal, back)
        distance = np.linalg.norm(point - np.asarray(camera.eye, dtype=np.float64), axis=1)
        rows = len(self)
        area = np.bincount(self.piece_row, piece_area, minlength=rows)
        return (np.bincount(self.piece_row, piece_area * cosine, minlength=rows) / area,
                np.bincount(self.piece_row, piece_area * distance, minlength=rows) / area)

    def scaled(self, factor: float) -> Regions:
        """These regions at ``factor`` times the size, without recomputing them."""
        factor = float(factor)
        return Regions(self.face_id, self.object_id, self.area * factor * factor,
                       self.fraction, self.piece_row, self.piece_start,
                       self.vertices * factor, round(self.width * factor),
                       round(self.height * factor), dict(self.stats))


def visible_regions(scene: SceneLike, camera: Camera, width: int, height: int,
                    threads: int | None = None, **state_fields: Any) -> Regions:
    """The exact visible region of every face of ``scene`` seen by ``camera`` in a
    ``width`` x ``height`` view (see the module). ``state_fields`` as :func:`hsr.render`
    takes them: ``cull``, ``front_face``, ``depth_func`` (``less`` or ``lequal``); faces
    crossing the camera's near or far plane are clipped exactly.

    Raises :class:`RegionsError` for any other depth state (no depth test or writes,
    another depth function or clear depth, polygon modes, polygon offset), an empty
    scene or a transparent instance, and what :func:`hsr.render` raises for a bad scene,
    camera or size."""
    from ..geometry.stage import prepare
    from ..geometry.state import RenderState
    from ..geometry.viewport import check_size
    from ..parallel import Workers
    from ..scene.load import scene_of

    scene = scene_of(scene)
    if scene.n_faces == 0:
        raise RegionsError("visible_regions: the scene has no faces")
    if any(inst.opacity < 1.0 for inst in scene.instances):
        raise RegionsError("visible_regions: a transparent instance has no single visible "
                           "face; set every opacity to 1")
    check_size(width, height)
    camera.validate()
    try:
        state = RenderState(**state_fields)
    except TypeError as exc:
        raise RegionsError(f"visible_regions: {exc}") from None
    func = state.depth_func.value
    if (func not in ("less", "lequal") or not state.depth_test or not state.depth_mask
            or state.polygon_mode.value != "fill" or state.polygon_offset != (0.0, 0.0)
            or state.clear_depth != 1.0):
        raise RegionsError("visible_regions: exact regions need filled faces under the "
                           "depth test less or lequal, with depth writes, clear depth 1 "
                           "and no polygon offset")
    stats: dict = {}
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    with Workers(threads) as workers:
        try:
            screen = prepare(scene, view_proj, width, height, state, stats, workers)
        except RenderError as exc:
            raise RegionsError(str(exc)) from None
        return screen_regions(scene, screen.xy_window, screen.depth_window, screen.face_id,
                              width, height, func == "lequal", stats, workers)


class CutTriangles(NamedTuple):
    """The window-space triangles the regions are cut from (image geometry, y down)."""

    xy: np.ndarray  # (T, 3, 2) float64
    planes: np.ndarray  # (T, 3): depth = a x + b y + c
    zmax: np.ndarray  # (T,) greatest depth
    box: np.ndarray  # (T, 4): x0, y0, x1, y1
    face: np.ndarray  # (T,) int64, global face id


class CellGrid(NamedTuple):
    """Cells over the image and, per cell, the triangles whose box meets it, nearest
    first: the entries of cell g are ``start[g]:start[g + 1]``, each with its triangle's
    index, least depth, box, face and corners copied beside it (read in order, not
    gathered)."""

    cell: float  # px, square
    ncx: int
    ncy: int
    start: np.ndarray  # (C + 1,) int64
    tri: np.ndarray  # (E,) int64
    zmin: np.ndarray  # (E,) float64, ascending within a cell
    box: np.ndarray  # (E, 4) float64: x0, y0, x1, y1
    face: np.ndarray  # (E,) int64
    xy: np.ndarray  # (E, 3, 2) float64, the corners


@njit(cache=True, nogil=True)
def _screen_setup(xy_window, depth_window, face_id, height):
    """The :class:`CutTriangles` of window-space triangles (x right, y up; a face seen
    edge-on, which covers no area, left out), and each one's least depth."""
    n = len(face_id)
    xy = np.empty((n, 3, 2))
    planes = np.empty((n, 3))
    zmin, zmax = np.empty(n), np.empty(n)
    box = np.empty((n, 4))
    face = np.empty(n, np.int64)
    m = 0
    for i in range(n):
        x0, x1, x2 = xy_window[i, 0, 0], xy_window[i, 1, 0], xy_window[i, 2, 0]
        # Image geometry: y down from the top edge.
        y0, y1 = height - xy_window[i, 0, 1], height - xy_window[i, 1, 1]
        y2 = height - xy_window[i, 2, 1]
        e1x, e1y, e2x, e2y = x1 - x0, y1 - y0, x2 - x0, y2 - y0
        det = e1x * e2y - e2x * e1y  # twice the signed area
        if det == 0.0:
            continue
        d0, d1, d2 = depth_window[i, 0], depth_window[i, 1], depth_window[i, 2]
        dz1, dz2 = d1 - d0, d2 - d0
        # depth = a x + b y + c through the three corners (Cramer's rule).
        a = (dz1 * e2y - dz2 * e1y) / det
        b = (e1x * dz2 - e2x * dz1) / det
        planes[m, 0], planes[m, 1], planes[m, 2] = a, b, d0 - a * x0 - b * y0
        xy[m, 0, 0], xy[m, 0, 1], xy[m, 1, 0], xy[m, 1, 1] = x0, y0, x1, y1
        xy[m, 2, 0], xy[m, 2, 1] = x2, y2
        box[m, 0], box[m, 1] = min(x0, x1, x2), min(y0, y1, y2)
        box[m, 2], box[m, 3] = max(x0, x1, x2), max(y0, y1, y2)
        zmin[m], zmax[m] = min(d0, d1, d2), max(d0, d1, d2)
        face[m] = face_id[i]
        m += 1
    return CutTriangles(xy[:m], planes[:m], zmax[:m], box[:m], face[:m]), zmin[:m]


def _grid(tris: CutTriangles, zmin: np.ndarray, width: int, height: int,
          members: np.ndarray | None = None) -> CellGrid:
    """The :class:`CellGrid` of the triangles ``members`` (default all) of ``tris``, whose
    least depths are ``zmin``."""
    box = tris.box
    if members is None:
        members = np.arange(len(box))
    cell = max(1.0 / 64, math.sqrt(width * height * _CELL_TRIANGLES / max(len(members), 1)))
    ncx, ncy = int(math.ceil(width / cell)), int(math.ceil(height / cell))
    # Nearest first, ties in submission order: a counting sort by cell keeps that order.
    members = members[np.argsort(zmin[members], kind="stable")]
    start, tri = _fill_grid(box, members, cell, ncx, ncy, float(width), float(height))
    return CellGrid(cell, ncx, ncy, start, tri, zmin[tri], box[tri], tris.face[tri],
                    tris.xy[tri])


@njit(cache=True, nogil=True)
def _fill_grid(box, members, cell, ncx, ncy, width, height):
    """(start (C + 1,), tri (E,)): the ``members`` whose box meets each cell, in their
    order (a counting sort; boxes wholly outside the view in no cell)."""
    n = len(members)
    ranges = np.empty((n, 4), np.int64)  # each member's cells: columns, then rows
    start = np.zeros(ncx * ncy + 1, np.int64)
    for k in range(n):
        i = members[k]
        if box[i, 2] >= 0 and box[i, 0] <= width and box[i, 3] >= 0 and box[i, 1] <= height:
            ranges[k, 0], ranges[k, 1], ranges[k, 2], ranges[k, 3] = _cell_range(
                box[i, 0], box[i, 1], box[i, 2], box[i, 3], cell, ncx, ncy)
        else:
            ranges[k, 0], ranges[k, 1], ranges[k, 2], ranges[k, 3] = 0, -1, 0, -1
        for gy in range(ranges[k, 2], ranges[k, 3] + 1):
            for gx in range(ranges[k, 0], ranges[k, 1] + 1):
                start[gy * ncx + gx + 1] += 1
    for g in range(ncx * ncy):
        start[g + 1] += start[g]
    fill = start[:-1].copy()
    tri = np.empty(start[-1], np.int64)
    for k in range(n):
        for gy in range(ranges[k, 2], ranges[k, 3] + 1):
            for gx in range(ranges[k, 0], ranges[k, 1] + 1):
                g = gy * ncx + gx
                tri[fill[g]] = members[k]
                fill[g] += 1
    return start, tri


@njit(cache=True, nogil=True, inline="always")
def _cell_of(v, cell, count):
    """The grid column (or row) of coordinate ``v``, clamped as :func:`_grid` clamps."""
    return min(max(int(math.floor(v / cell)), 0), count - 1)


@njit(cache=True, nogil=True, inline="always")
def _cell_range(x0, y0, x1, y1, cell, ncx, ncy):
    """(first column, last column, first row, last row) of the cells box (x0, y0, x1, y1)
    meets, clamped to the grid."""
    return (_cell_of(x0, cell, ncx), _cell_of(x1, cell, ncx), _cell_of(y0, cell, ncy),
            _cell_of(y1, cell, ncy))


@njit(cache=True, nogil=True, error_model="numpy")
def _regions_range(lo, hi, tris, grid, later_wins, width, height):
    """Visible convex pieces of triangles ``lo:hi`` of ``tris`` (a
    :class:`CutTriangles`; see the module) against the candidates of ``grid`` (a
    :class:`CellGrid`): (piece triangle (P,), piece vertex ends (P,), vertices (V, 2),
    overflowed)."""
    # The pieces before and after a cut, then four one-polygon buffers; their counts.
    work = np.empty((2 * _MAX_PIECES + 4, MAX_VERTICES, 2))
    counts = np.empty((2, _MAX_PIECES), np.int64)
    lines = np.empty((MAX_VERTICES, 3))
    return _cut_range(lo, hi, tris, grid, later_wins, width, height, work, counts, lines)


@njit(cache=True, nogil=True, error_model="numpy")
def _cut_range(lo, hi, tris, grid, later_wins, width, height, work, counts, lines):
    """:func:`_regions_range` in the scratch arrays it allocated (kept alive there)."""
    cell, ncx, ncy, cell_start, cell_tri, cell_zmin, cell_box, cell_face, cell_xy = grid
    planes, zmax, box, tri_face = tris.planes, tris.zmax, tris.box, tris.face
    # Views without reference counts: each slice handed to a helper in the loops below
    # would otherwise cost two atomic instructions (docs/history.md, "Exact regions without
    # reference counts").
    xy, cell_xy = borrowed(tris.xy), borrowed(cell_xy)
    work, counts, lines = borrowed(work), borrowed(counts), borrowed(lines)
    cur, nxt = work[:_MAX_PIECES], work[_MAX_PIECES:2 * _MAX_PIECES]
    cur_n, nxt_n = counts[0], counts[1]
    tri, tmp = work[2 * _MAX_PIECES], work[2 * _MAX_PIECES + 1]
    rest, hider = work[2 * _MAX_PIECES + 2], work[2 * _MAX_PIECES + 3]
    cap_p, cap_v = 256, 1024
    piece_tri = np.empty(cap_p, np.int64)
    piece_end = np.empty(cap_p, np.int64)
    verts = np.empty((cap_v, 2))
    n_p = 0
    n_v = 0
    overflow = False
    for i in range(lo, hi):
        for k in range(3):
            tri[k, 0] = xy[i, k, 0]
            tri[k, 1] = xy[i, k, 1]
        # The triangle inside the view [0, W] x [0, H].
        n = clip_to_view(tri, 3, float(width), float(height), tmp)
        if n == 0:
            continue
        cur[0, :n] = tri[:n]
        cur_n[0] = n
        count = 1
        ai, bi, ci = planes[i, 0], planes[i, 1], planes[i, 2]
        x0, y0, x1, y1 = box[i, 0], box[i, 1], box[i, 2], box[i, 3]
        z1, face = zmax[i], tri_face[i]
        gx0, gx1, gy0, gy1 = _cell_range(x0, y0, x1, y1, cell, ncx, ncy)
        for gy in range(gy0, gy1 + 1):
            if count == 0:
                break
            for gx in range(gx0, gx1 + 1):
                if count == 0:
                    break
                g = gy * ncx + gx
                for e in range(cell_start[g], cell_start[g + 1]):
                    if cell_zmin[e] > z1:
                        break  # nearest first: the rest of the cell lies behind
                    if (cell_box[e, 2] <= x0 or x1 <= cell_box[e, 0]
                            or cell_box[e, 3] <= y0 or y1 <= cell_box[e, 1]
                            or cell_face[e] == face):
                        continue
                    # Each pair once, in the first cell of the scan both boxes meet.
                    if (max(gx0, _cell_of(cell_box[e, 0], cell, ncx)) != gx
                            or max(gy0, _cell_of(cell_box[e, 1], cell, ncy)) != gy):
                        continue
                    j = cell_tri[e]
                    # Neighbours in a mesh share an edge or a corner and no area: most
                    # candidates of a fine surface (separating axes, before any clipping).
                    hider_xy = cell_xy[e]  # read in order: xy[j] would miss the cache
                    if triangles_apart(xy[i], hider_xy):
                        continue
                    # d = z_i - z_j, affine: > 0 where j is nearer.
                    big = 0.0
                    scale = 1.0
                    for k in range(3):
                        x, y = hider_xy[k, 0], hider_xy[k, 1]
                        d = ai * x + bi * y + ci - (planes[j, 0] * x + planes[j, 1] * y
                                                    + planes[j, 2])
                        big = max(big, abs(d))
                        scale = max(scale, abs(planes[j, 2]))
                    for k in range(3):
                        hider[k, 0] = hider_xy[k, 0]
                        hider[k, 1] = hider_xy[k, 1]
                    if big <= _TIE * scale:
                        # One plane: OpenGL's tie rule (less: the first drawn stays).
                        hides = (tri_face[j] > tri_face[i]) if later_wins else (
                            tri_face[j] < tri_face[i])
                        if not hides:
                            continue
                        hn = 3
                    else:
                        hn = clip_half_plane(hider, 3, ai - planes[j, 0], bi - planes[j, 1],
                                             ci - planes[j, 2], tmp)
                        if hn == 0:
                            continue
                        hider[:hn] = tmp[:hn]
                    hn = edge_lines(hider, hn, lines)
                    if hn == 0:
                        continue  # a sliver: it hides no area
                    m = 0
                    for p in range(count):
                        pn = cur_n[p]
                        if not bounds_overlap(cur[p], pn, hider, hn):
                            if m == _MAX_PIECES:
                                overflow = True
                                break
                            nxt[m, :pn] = cur[p, :pn]
                            nxt_n[m] = pn
                            m += 1
                            continue
                        rn = pn
                        rest[:rn] = cur[p, :rn]
                        for h in range(hn):
                            if m == _MAX_PIECES:
                                overflow = True
                                break
                            side = side_of_line(rest, rn, lines[h, 0], lines[h, 1],
                                                lines[h, 2])
                            if side < 0:
                                continue  # inside this edge: nothing to cut off (most)
                            if side > 0:  # outside it: all of the rest is one piece
                                nxt[m, :rn] = rest[:rn]
                                if abs(signed_area(nxt[m], rn)) > 0.0:
                                    nxt_n[m] = rn
                                    m += 1
                                break
                            on = clip_half_plane(rest, rn, lines[h, 0], lines[h, 1],
                                                 lines[h, 2], nxt[m])
                            if on > 0 and abs(signed_area(nxt[m], on)) > 0.0:
                                nxt_n[m] = on
                                m += 1
                            rn = clip_half_plane(rest, rn, -lines[h, 0], -lines[h, 1],
                                                 -lines[h, 2], tmp)
                            rest[:rn] = tmp[:rn]
                            if rn == 0:
                                break
                        if overflow:
                            break
                    if overflow:
                        return piece_tri[:n_p], piece_end[:n_p], verts[:n_v], True
                    cur, nxt = nxt, cur
                    cur_n, nxt_n = nxt_n, cur_n
                    count = m
                    if count == 0:
                        break
        for p in range(count):
            pn = cur_n[p]
            if abs(signed_area(cur[p], pn)) <= MIN_PIECE_AREA:
                continue
            if n_p == cap_p:
                cap_p *= 2
                grown = np.empty(cap_p, np.int64)
                grown[:n_p] = piece_tri[:n_p]
                piece_tri = grown
                grown = np.empty(cap_p, np.int64)
                grown[:n_p] = piece_end[:n_p]
                piece_end = grown
            while n_v + pn > cap_v:
                cap_v *= 2
                grown_v = np.empty((cap_v, 2))
                grown_v[:n_v] = verts[:n_v]
                verts = grown_v
            verts[n_v:n_v + pn] = cur[p, :pn]
            n_v += pn
            piece_tri[n_p] = i
            piece_end[n_p] = n_v
            n_p += 1
    return piece_tri[:n_p], piece_end[:n_p], verts[:n_v], overflow


def screen_regions(scene, xy_window, depth_window, face_id, width, height, later_wins,
                   stats, workers, hides=None) -> Regions:
    """The regions of the screen triangles; ``hides`` (F,) bool, optional: the faces that
    may hide others (the rest are cut by them but cut nothing: transparent surfaces)."""
    tris, zmin = _screen_setup(np.asarray(xy_window, dtype=np.float64).reshape(-1, 3, 2),
                               np.asarray(depth_window, dtype=np.float64).reshape(-1, 3),
                               np.asarray(face_id, dtype=np.int64), float(height))
    xy, tri_face = tris.xy, tris.face
    # Only hiders in the grid: the others (transparent surfaces) are never a candidate.
    members = None if hides is None else np.flatnonzero(np.asarray(hides, bool)[tri_face])
    grid = _grid(tris, zmin, width, height, members)
    # Eight chunks a thread, taken as threads come free: the work per triangle is uneven
    # (a buried region stops early, a visible one meets all its candidates).
    bounds = split_range(len(xy), min(8 * workers.threads, max(1, len(xy) // 256)))
    parts = workers.run(_regions_range, bounds, tris, grid, later_wins, width, height)
    if any(part[3] for part in parts):
        raise RegionsError(f"visible_regions: a face's visible part broke into more than "
                           f"{_MAX_PIECES} convex pieces")
    piece_tri = np.concatenate([p[0] for p in parts]) if parts else np.zeros(0, np.int64)
    vertices = np.concatenate([p[2] for p in parts]) if parts else np.zeros((0, 2))
    ends, offset = [], 0
    for p in parts:
        ends.append(p[1] + offset)
        offset += len(p[2])
    piece_start = np.concatenate([[0]] + ends).astype(np.int64)
    piece_area = _piece_areas(vertices, piece_start)
    piece_face = tri_face[piece_tri]
    faces, piece_row = np.unique(piece_face, return_inverse=True)
    area = np.bincount(piece_row, piece_area, minlength=len(faces))
    whole = _projected_areas(xy, tri_face, faces, width, height)
    object_id = (np.searchsorted(scene.face_offsets(), faces, side="right") - 1).astype(
        np.int64)
    stats.update(pieces=len(piece_tri), cells=grid.ncx * grid.ncy)
    # A sliver's visible area and its whole come from different clips of it: their
    # rounding can put the ratio a hair above 1, which no face can be.
    fraction = np.minimum(area / whole, 1.0)
    return Regions(faces.astype(np.int64), object_id, area, fraction,
                   piece_row.astype(np.int64), piece_start, vertices, width, height, stats)


def _shoelace(vertices: np.ndarray, piece_start: np.ndarray) -> tuple:
    """(piece of each vertex, index of the next vertex round its piece, x_k y_k+1 -
    x_k+1 y_k): the terms of every piece's shoelace sums."""
    x, y = vertices[:, 0], vertices[:, 1]
    idx = np.arange(len(vertices))
    piece = np.repeat(np.arange(len(piece_start) - 1), np.diff(piece_start))
    nxt = np.where(idx + 1 == piece_start[piece + 1], piece_start[piece], idx + 1)
    return piece, nxt, x * y[nxt] - x[nxt] * y


def _piece_centroids(vertices: np.ndarray, piece_start: np.ndarray) -> tuple:
    """(x, y, area) of each piece's centroid (the shoelace moments)."""
    n_pieces = len(piece_start) - 1
    piece, nxt, cross = _shoelace(vertices, piece_start)
    x, y = vertices[:, 0], vertices[:, 1]
    twice = np.bincount(piece, cross, minlength=n_pieces)
    safe = np.where(twice != 0.0, twice, 1.0)
    cx = np.bincount(piece, (x + x[nxt]) * cross, minlength=n_pieces) / (3.0 * safe)
    cy = np.bincount(piece, (y + y[nxt]) * cross, minlength=n_pieces) / (3.0 * safe)
    return cx, cy, np.abs(0.5 * twice)


def _piece_areas(vertices: np.ndarray, piece_start: np.ndarray) -> np.ndarray:
    """Absolute shoelace area of each piece."""
    if len(piece_start) <= 1:
        return np.zeros(0)
    piece, _, cross = _shoelace(vertices, piece_start)
    return np.abs(0.5 * np.bincount(piece, cross, minlength=len(piece_start) - 1))


def _projected_areas(xy, tri_face, faces, width, height) -> np.ndarray:
    """Each face's projected area inside the view (its clipped triangles are disjoint)."""
    if not len(faces):
        return np.zeros(0)
    clipped = _view_areas(xy, float(width), float(height))
    row = np.minimum(np.searchsorted(faces, tri_face), len(faces) - 1)
    mine = faces[row] == tri_face  # hidden faces have no row
    return np.bincount(row[mine], clipped[mine], minlength=len(faces))


@njit(cache=True, nogil=True)
def _view_areas(xy, width, height):
    out = np.zeros(len(xy))
    a = np.empty((MAX_VERTICES, 2))
    b = np.empty((MAX_VERTICES, 2))
    for i in range(len(xy)):
        for k in range(3):
            a[k, 0] = xy[i, k, 0]
            a[k, 1] = xy[i, k, 1]
        if (min(a[0, 0], a[1, 0], a[2, 0]) < 0.0 or max(a[0, 0], a[1, 0], a[2, 0]) > width
                or min(a[0, 1], a[1, 1], a[2, 1]) < 0.0
                or max(a[0, 1], a[1, 1], a[2, 1]) > height):
            n = clip_to_view(a, 3, width, height, b)
            out[i] = abs(signed_area(a, n)) if n else 0.0
        else:  # inside the view: clipping would keep the corners as they are
            out[i] = abs(signed_area(a, 3))
    return out


def write_regions_svg(path, regions: Regions, colors, background=(0, 0, 0),
                      lines=None, line_color=(0, 0, 0)) -> None:
    """Write ``regions`` as SVG: one filled ``<path>`` per face with a visible part (holes
    by the even-odd rule), coloured ``colors[face_id]`` (an (N, 3) uint8 table indexed by
    face id, as :func:`hsr.appearance.shading.face_colors` gives), carrying its face as
    ``data-face``; no region overlaps another, so nothing hidden lies underneath. With
    ``lines`` (a :class:`hsr.lines.vector.LineDrawing` of the same view) its visible
    polylines are drawn on top. The viewBox is the image: it scales without
    recomputation. Raises :class:`~hsr.errors.OutputError` when the file cannot be
    written and :class:`RegionsError` for colours that do not cover the faces."""
    from ..lines.svg import write_svg

    colors = _checked_colors(regions, colors)
    w, h = regions.width, regions.height
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
             f'viewBox="0 0 {w} {h}">',
             f'<rect width="{w}" height="{h}" fill="{_rgb(background)}"/>',
             '<g id="regions" stroke="none" fill-rule="evenodd">']
    for face, shape in zip(regions.face_id, regions.polygons):
        d = " ".join(_ring_path(ring) for ring in _rings(shape))
        parts.append(f'<path d="{d}" fill="{_rgb(colors[face])}" data-face="{int(face)}"/>')
    parts.append("</g>")
    if lines is not None:
        parts.append(f'<g id="lines" fill="none" stroke="{_rgb(line_color)}" '
                     f'stroke-linecap="round" stroke-linejoin="round">')
        parts.extend('<path d="M' + " L".join(f"{x:.6f} {y:.6f}" for x, y in line) + '"/>'
                     for line in lines.visible_polylines)
        parts.append("</g>")
    parts.append("</svg>")
    write_svg(path, parts)


def write_regions_pdf(path, regions: Regions, colors, background=(0, 0, 0),
                      lines=None, line_color=(0, 0, 0)) -> None:
    """:func:`write_regions_svg` as PDF, one point per pixel, through matplotlib's PDF
    backend (no pyplot state; needs ``pip install 'hsr[mpl]'``). Raises
    :class:`~hsr.errors.OutputError` when the file cannot be written."""
    from ..errors import OutputError, require_extra

    require_extra("writing a PDF", "matplotlib")
    from matplotlib.backends.backend_pdf import FigureCanvasPdf
    from matplotlib.figure import Figure
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path

    from ..scene.outputs import staged

    colors = _checked_colors(regions, colors)
    w, h = regions.width, regions.height
    figure = Figure(figsize=(w / 72.0, h / 72.0), dpi=72)
    axes = figure.add_axes((0.0, 0.0, 1.0, 1.0))
    axes.set_xlim(0, w)
    axes.set_ylim(h, 0)  # image rows go down
    axes.set_axis_off()
    red, green, blue = (float(c) / 255.0 for c in background[:3])
    figure.patch.set_facecolor((red, green, blue))
    for face, shape in zip(regions.face_id, regions.polygons):
        rings = _rings(shape)
        if not rings:
            continue
        vertices = np.concatenate(rings)
        codes = np.concatenate([[Path.MOVETO] + [Path.LINETO] * (len(r) - 2)
                                + [Path.CLOSEPOLY] for r in rings])
        axes.add_patch(PathPatch(Path(vertices, codes), facecolor=colors[face] / 255.0,
                                 edgecolor="none", linewidth=0))
    if lines is not None:
        for line in lines.visible_polylines:
            line = np.asarray(line)
            axes.plot(line[:, 0], line[:, 1], color=np.asarray(line_color) / 255.0,
                      linewidth=0.75, solid_capstyle="round")
    try:
        with staged(path) as tmp:
            FigureCanvasPdf(figure).print_pdf(tmp)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None


def _checked_colors(regions: Regions, colors) -> np.ndarray:
    colors = np.asarray(colors)
    if colors.ndim != 2 or colors.shape[1] != 3 or (
            len(regions) and colors.shape[0] <= int(regions.face_id.max())):
        raise RegionsError(f"colors must be an (N, 3) table indexed by face id, N > "
                           f"{int(regions.face_id.max()) if len(regions) else 0}; got shape "
                           f"{colors.shape}")
    return colors


def _rgb(color) -> str:
    return f"rgb({int(color[0])},{int(color[1])},{int(color[2])})"


def _rings(shape) -> list:
    """Every ring (exteriors and holes) of a shapely (Multi)Polygon or collection."""
    rings = []
    for geom in getattr(shape, "geoms", [shape]):
        if geom.geom_type == "Polygon" and not geom.is_empty:
            rings.append(np.asarray(geom.exterior.coords))
            rings += [np.asarray(hole.coords) for hole in geom.interiors]
        elif hasattr(geom, "geoms"):
            rings += _rings(geom)
    return rings


def _ring_path(ring: np.ndarray) -> str:
    return "M" + " L".join(f"{x:.6f} {y:.6f}" for x, y in ring[:-1]) + " Z"
