"""Exact hidden-line removal in object space, for vector output (SVG, pen plotters).

Each edge is clipped to the view volume and projected; then every triangle that may cover
it (found through a uniform grid over the window: candidates only, never the answer) cuts
out the part of the edge it hides. Along a projected segment both the edge's window depth
and the depth of a triangle's plane are affine in the segment parameter ``t`` (window
depth is affine in window x, y over a plane), so "inside the triangle" is the
intersection of three half-lines in ``t`` and "behind it" one more: each occluder hides
one exact interval. The visible parts are the complement of the union of those intervals
(Appel 1967's quantitative invisibility, reduced to the two values visible / hidden).

The visible pieces are then merged where collinear pieces overlap (edges shared by two
objects), joined end to end into polylines, and written in the same pixel geometry as the
raster images (x right, y down, pixel (x, y) covers [x, x+1) x [y, y+1)), so the SVG
overlays the PNG.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..geometry.stage import prepare
from ..geometry.state import RenderState
from ..geometry.viewport import check_size
from ..scene.camera import Camera
from ..scene.mesh import SceneLike, as_scene
from .border import object_borders
from .drawing import LineDrawing, make_drawing
from .grid import window_grid
from .paths import JOIN_PX
from .raster import HiddenLine, chosen_edges, clip_segments

__all__ = ["LineDrawing", "hidden_lines", "visible_pieces"]

# Tolerances, in window pixels and window depth units. Triangles are closed (a point within
# EPS_PX of the outline counts as covered, like the reference ray test's u, v >= 0: an edge
# seen exactly along the shared edge of two nearer faces is hidden by them); a depth within
# EPS_Z of the triangle's plane is not behind it, so edges on the surface and edges that
# share a vertex with an occluder are not hidden there.
EPS_PX = 1e-6
EPS_Z = 1e-9
# Visible or hidden pieces shorter than this (pixels) are dropped: nobody can see them, and
# they are what the EPS_Z margin leaves at vertices shared with an occluder.
MIN_PIECE_PX = 1e-3


@njit(cache=True, nogil=True, inline="always")
def _above(f0, f1, eps, lo, hi):
    """Narrow [lo, hi] to where f0 + t (f1 - f0) > eps."""
    if f0 > eps and f1 > eps:
        return lo, hi
    if f0 <= eps and f1 <= eps:
        return 1.0, 0.0
    t = (eps - f0) / (f1 - f0)
    if f1 > f0:
        return max(lo, t), hi
    return lo, min(hi, t)


@njit(cache=True, nogil=True)
def _cells_crossed(x0, y0, x1, y1, nx, ny, cells):
    """Write the ids (row * nx + column) of the grid cells the segment (x0, y0)-(x1, y1),
    in cell units, passes through into ``cells``, in order (Amanatides & Woo's traversal);
    cells outside the grid are skipped. Returns how many."""
    cx, cy = int(np.floor(x0)), int(np.floor(y0))
    end_x, end_y = int(np.floor(x1)), int(np.floor(y1))
    dx, dy = x1 - x0, y1 - y0
    step_x = 1 if dx > 0 else -1
    step_y = 1 if dy > 0 else -1
    next_x = ((cx + (1 if dx > 0 else 0)) - x0) / dx if dx != 0 else np.inf
    next_y = ((cy + (1 if dy > 0 else 0)) - y0) / dy if dy != 0 else np.inf
    delta_x = abs(1.0 / dx) if dx != 0 else np.inf
    delta_y = abs(1.0 / dy) if dy != 0 else np.inf
    n = 0
    for _ in range(abs(end_x - cx) + abs(end_y - cy) + 1):
        if 0 <= cx < nx and 0 <= cy < ny:
            cells[n] = cy * nx + cx
            n += 1
        if cx == end_x and cy == end_y:
            break
        if next_x < next_y:
            cx += step_x
            next_x += delta_x
        else:
            cy += step_y
            next_y += delta_y
    return n


@njit(cache=True, nogil=True, inline="always")
def _canonical(tri_xy, t):
    """Corner order of triangle ``t`` that does not depend on how it is wound: from its
    lowest corner (x, then y), counter-clockwise in the window; (-1, -1, -1) when it has
    no area. The same arithmetic for either winding: bit-identical intervals."""
    i0 = 0
    for i in (1, 2):
        if tri_xy[t, i, 0] < tri_xy[t, i0, 0] or (tri_xy[t, i, 0] == tri_xy[t, i0, 0]
                                                  and tri_xy[t, i, 1] < tri_xy[t, i0, 1]):
            i0 = i
    i1, i2 = (i0 + 1) % 3, (i0 + 2) % 3
    det = ((tri_xy[t, i1, 0] - tri_xy[t, i0, 0]) * (tri_xy[t, i2, 1] - tri_xy[t, i0, 1])
           - (tri_xy[t, i2, 0] - tri_xy[t, i0, 0]) * (tri_xy[t, i1, 1] - tri_xy[t, i0, 1]))
    if det == 0.0:
        return -1, -1, -1
    return (i0, i1, i2) if det > 0 else (i0, i2, i1)


@njit(cache=True, nogil=True)
def _hidden_intervals(e_lo, e_hi, ends, edge_faces, tri_xy, tri_z, tri_face, start, items,
                      nx, ny, cell):
    """Merged hidden parameter intervals of edges ``e_lo <= e < e_hi``: arrays (edge,)
    and (t0, t1), sorted by edge and t0."""
    n_tri = tri_xy.shape[0]
    stamp = np.full(n_tri, -1, dtype=np.int64)
    cells = np.empty(nx + ny + 4, dtype=np.int64)
    scratch = np.empty((n_tri + 1, 2))
    out_edge = np.empty(max(64, 2 * (e_hi - e_lo)), dtype=np.int64)
    out_t = np.empty((out_edge.shape[0], 2))
    k_out = 0
    for e in range(e_lo, e_hi):
        ax, ay, az = ends[e, 0, 0], ends[e, 0, 1], ends[e, 0, 2]
        bx, by, bz = ends[e, 1, 0], ends[e, 1, 1], ends[e, 1, 2]
        n_int = 0
        # Walk the cells the segment crosses (Amanatides & Woo 1987).
        n_cells = _cells_crossed(ax / cell, ay / cell, bx / cell, by / cell, nx, ny, cells)
        for k in range(n_cells):
            cid = cells[k]
            for q in range(start[cid], start[cid + 1]):
                t = items[q]
                if stamp[t] == e:
                    continue
                stamp[t] = e
                face = tri_face[t]
                if face == edge_faces[e, 0] or face == edge_faces[e, 1]:
                    continue
                i0, i1, i2 = _canonical(tri_xy, t)
                if i0 < 0:
                    continue
                x0, y0 = tri_xy[t, i0, 0], tri_xy[t, i0, 1]
                x1, y1 = tri_xy[t, i1, 0], tri_xy[t, i1, 1]
                x2, y2 = tri_xy[t, i2, 0], tri_xy[t, i2, 1]
                det = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
                lo, hi = 0.0, 1.0
                for ux, uy, vx, vy in ((x0, y0, x1, y1), (x1, y1, x2, y2),
                                       (x2, y2, x0, y0)):
                    ex, ey = vx - ux, vy - uy
                    fa = ex * (ay - uy) - ey * (ax - ux)
                    fb = ex * (by - uy) - ey * (bx - ux)
                    lo, hi = _above(fa, fb, -EPS_PX * np.sqrt(ex * ex + ey * ey), lo,
                                    hi)
                    if lo >= hi:
                        break
                if lo >= hi:
                    continue
                # Plane of the triangle's window depth: z = z0 + gx (x - x0) + gy (y - y0).
                z0, z1, z2 = tri_z[t, i0], tri_z[t, i1], tri_z[t, i2]
                gx = ((z1 - z0) * (y2 - y0) - (z2 - z0) * (y1 - y0)) / det
                gy = ((x1 - x0) * (z2 - z0) - (x2 - x0) * (z1 - z0)) / det
                da = az - (z0 + gx * (ax - x0) + gy * (ay - y0))
                db = bz - (z0 + gx * (bx - x0) + gy * (by - y0))
                lo, hi = _above(da, db, EPS_Z, lo, hi)
                if lo < hi:
                    scratch[n_int, 0], scratch[n_int, 1] = lo, hi
                    n_int += 1
        if n_int == 0:
            continue
        order = np.argsort(scratch[:n_int, 0])
        cur_lo, cur_hi = scratch[order[0], 0], scratch[order[0], 1]
        for r in range(1, n_int + 1):
            if r < n_int and scratch[order[r], 0] <= cur_hi:
                cur_hi = max(cur_hi, scratch[order[r], 1])
                continue
            if k_out >= out_edge.shape[0]:  # grow
                bigger_edge = np.empty(2 * out_edge.shape[0], dtype=np.int64)
                bigger_t = np.empty((2 * out_edge.shape[0], 2))
                bigger_edge[:k_out] = out_edge[:k_out]
                bigger_t[:k_out] = out_t[:k_out]
                out_edge, out_t = bigger_edge, bigger_t
            out_edge[k_out] = e
            out_t[k_out, 0], out_t[k_out, 1] = cur_lo, cur_hi
            k_out += 1
            if r < n_int:
                cur_lo, cur_hi = scratch[order[r], 0], scratch[order[r], 1]
    return out_edge[:k_out].copy(), out_t[:k_out].copy()


def _pieces(ends, edge_idx, t_span):
    """Segments (K, 2, 3) of ``ends[edge_idx]`` between parameters t_span (K, 2)."""
    a = ends[edge_idx, 0]
    d = ends[edge_idx, 1] - a
    return np.stack([a + t_span[:, :1] * d, a + t_span[:, 1:] * d], axis=1)


def _long_enough(segments, min_length=MIN_PIECE_PX):
    """Pieces at least ``min_length`` pixels long (mask): shorter ones are the slivers left
    where a hidden interval stops EPS_Z short of a vertex shared with the occluder."""
    return np.hypot(*(segments[:, 1, :2] - segments[:, 0, :2]).T) >= min_length


def _complement(n_edges, hidden_edge, hidden_t, min_t=1e-9):
    """Visible (edge, t0, t1) rows: [0, 1] minus the hidden intervals, which come sorted
    and disjoint per edge (merged by the kernel)."""
    first = np.r_[True, hidden_edge[1:] != hidden_edge[:-1]] if len(hidden_edge) else \
        np.zeros(0, bool)
    last = np.r_[hidden_edge[1:] != hidden_edge[:-1], True] if len(hidden_edge) else \
        np.zeros(0, bool)
    prev_hi = np.where(first, 0.0, np.r_[0.0, hidden_t[:-1, 1]])
    gaps_before = np.stack([prev_hi, hidden_t[:, 0]], axis=1)
    gaps_after = np.stack([hidden_t[last, 1], np.ones(int(last.sum()))], axis=1)
    has = np.zeros(n_edges, dtype=bool)
    has[hidden_edge] = True
    free = np.flatnonzero(~has)
    edges = np.concatenate([free, hidden_edge, hidden_edge[last]])
    spans = np.concatenate([np.tile([0.0, 1.0], (len(free), 1)), gaps_before, gaps_after])
    keep = spans[:, 1] - spans[:, 0] > min_t
    order = np.lexsort((spans[keep, 0], edges[keep]))
    return edges[keep][order], spans[keep][order]


_CHUNK = 8192  # edges per task: threads share the work and the progress bar moves
def _cut_edges(scene, camera, screen, settings, view_proj, workers, cell, progress):
    """Hidden intervals (edge, (t0, t1)) of the chosen edges, clipped to the view: the
    window-space edges, their kinds and faces, and the grid of triangles used."""
    edges = chosen_edges(scene, camera, screen, settings)
    keep, ends, _ = clip_segments(edges.ends, view_proj, screen.width, screen.height, guard=0)
    bar = None
    if progress and len(ends) > 4 * _CHUNK:
        from tqdm import tqdm

        bar = tqdm(total=len(ends), desc="hidden lines", unit="edge", leave=False)
    hidden_edge, hidden_t, grid = _hidden_intervals_of(
        screen, ends, edges.faces[keep], workers, cell,
        on_done=None if bar is None else (lambda lo, hi: bar.update(hi - lo)))
    if bar is not None:
        bar.close()
    return hidden_edge, hidden_t, ends, edges.kind[keep], edges.faces[keep], grid


def _hidden_intervals_of(screen, ends, own_faces, workers, cell=None, on_done=None) -> tuple:
    """(edge (H,), (t0, t1) (H, 2), grid (start, items, nx, ny, cell)): the merged hidden
    intervals of window-space segments ``ends`` (E, 2, 3) among ``screen``'s triangles,
    none hidden by its ``own_faces`` (E, 2); chunks of _CHUNK segments on ``workers``."""
    width, height = screen.width, screen.height
    if cell is None:
        cell = int(np.clip(np.sqrt(width * height / max(len(screen), 1)) * 2, 4, 64))
    tri_xy = np.ascontiguousarray(screen.xy_window)
    start, items, nx, ny = window_grid(tri_xy, width, height, cell)
    bounds = np.unique(np.r_[0, np.arange(0, len(ends) + _CHUNK, _CHUNK).clip(max=len(ends))])
    results = workers.run(_hidden_intervals, bounds, ends,
                          np.ascontiguousarray(own_faces, dtype=np.int64), tri_xy,
                          np.ascontiguousarray(screen.depth_window), screen.face_id, start,
                          items, nx, ny, cell, on_done=on_done)
    hidden_edge = np.concatenate([r[0] for r in results] + [np.zeros(0, np.int64)])
    hidden_t = np.concatenate([r[1] for r in results] + [np.zeros((0, 2))])
    return hidden_edge, hidden_t, (start, items, nx, ny, cell)


def visible_pieces(screen, view_proj, ends_world, own_faces, workers, cell=None) -> tuple:
    """The visible parts of any world segments (E, 2, 3) among ``screen``'s triangles
    (lines and points of a plot, not a mesh's edges): ``(segment (K,), t (K, 2) where
    each piece starts and ends on its segment (0 and 1 exactly at the segment's ends; in
    between, a fraction along the projected segment), pieces (K, 2, 3) window x, y up,
    depth)``, sorted by segment and t. ``own_faces`` (E, 2): faces that never hide their
    segment (-1: none). A segment of zero length is a point: one piece when visible, none
    when hidden."""
    ends_world = np.asarray(ends_world, dtype=np.float64).reshape(-1, 2, 3)
    keep, ends, t_kept = clip_segments(ends_world, view_proj, screen.width, screen.height,
                                       guard=0)
    own = np.asarray(own_faces, dtype=np.int64)[keep]
    hidden_edge, hidden_t, _ = _hidden_intervals_of(screen, ends, own, workers, cell)
    degenerate = np.all(ends[:, 0, :2] == ends[:, 1, :2], axis=1)
    vis_edge, vis_t = _complement(len(ends), hidden_edge, hidden_t)
    if degenerate.any():  # a point: visible whole or not at all
        whole = ~degenerate[vis_edge] | (vis_t[:, 0] <= 0.0) & (vis_t[:, 1] >= 1.0)
        vis_edge, vis_t = vis_edge[whole], vis_t[whole]
    pieces = _pieces(ends, vis_edge, vis_t)
    # Back to the caller's segments and their parameters (clipping kept t_kept of each).
    span = t_kept[vis_edge]
    t = span[:, :1] + vis_t * (span[:, 1:] - span[:, :1])
    return np.flatnonzero(keep)[vis_edge], t, pieces


def hidden_lines(scene: SceneLike, camera: Camera, width: int, height: int,
                 settings: HiddenLine | None = None, state: RenderState | None = None,
                 threads: int | None = None, with_hidden: bool = True,
                 cell: int | None = None, progress: bool | None = None,
                 join_px: float = JOIN_PX) -> LineDrawing:
    """Exact visible (and hidden) parts of the scene's edges (all or feature edges, per
    ``settings``) as seen by ``camera`` in a ``width`` x ``height`` image. ``state``
    supplies culling and winding (culled faces neither occlude nor contribute edges).
    ``progress`` (default: when stderr is a terminal) shows a bar on big meshes.
    ``join_px``: polyline ends closer than this many pixels are joined (a plotter tool's
    merge tolerance; by default only the ends that meet, within 0.01 px).

    Raises :class:`~hsr.errors.RenderError`, :class:`~hsr.errors.CameraError` or
    :class:`~hsr.errors.MeshError` for invalid arguments, as :func:`hsr.render` does.
    """
    import sys

    from ..parallel import Workers

    check_size(width, height)
    camera.validate()
    scene = as_scene(scene)
    settings = settings or HiddenLine()
    if progress is None:
        progress = sys.stderr.isatty()
    state = state or RenderState()
    state = RenderState(cull=state.cull, front_face=state.front_face)
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    with Workers(threads) as workers:
        screen = prepare(scene, view_proj, width, height, state, {}, workers)
        hidden_edge, hidden_t, ends, kind, faces, grid = _cut_edges(
            scene, camera, screen, settings, view_proj, workers, cell, progress)
    vis_edge, vis_t = _complement(len(ends), hidden_edge, hidden_t)
    visible = _pieces(ends, vis_edge, vis_t)
    hidden = _pieces(ends, hidden_edge, hidden_t)
    keep_visible, keep_hidden = _long_enough(visible), _long_enough(hidden)
    visible, vis_edge = visible[keep_visible], vis_edge[keep_visible]
    visible_kind = kind[vis_edge] | object_borders(scene, view_proj, screen, visible,
                                                   kind[vis_edge], faces[vis_edge], grid)
    # Plotter order: per layer, the pen goes to the nearest free end next.
    drawing = make_drawing(visible, visible_kind, hidden[keep_hidden],
                           kind[hidden_edge[keep_hidden]], width, height, with_hidden,
                           join_px)
    drawing.stats.update(edges=int(len(ends)), triangles=int(len(screen)),
                         grid_cell=int(grid[4]))
    return drawing
