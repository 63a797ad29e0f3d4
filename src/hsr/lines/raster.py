"""Edges and lines: glPolygonMode(GL_LINE / GL_POINT), hidden-line removal by depth test
against a filled, polygon-offset depth buffer, and the edge sets both use (every triangle
edge, or only feature edges: boundaries, creases, silhouettes).

Line rasterization follows OpenGL's aliased-line rule as Mesa's llvmpipe implements it:
endpoints snapped to 1/256 pixel; along the major axis every pixel column (row) whose
centre lies in the half-open span from the start point to the end point gets one
fragment, in the row (column) whose centre is within [-1/2, +1/2) of the line there
(``ceil(v) - 1``: a line exactly on a pixel boundary takes the pixel below / to the left,
the top-left rule applied to the line's one-pixel-wide parallelogram). Depth is
interpolated linearly in window space, as OpenGL does for lines. Measured against
llvmpipe: 14 of 18,759 line pixels differ (all at line ends) over seven views.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..choices import EdgeKind
from ..errors import RenderError, check_choice, check_rgb
from ..geometry.conventions import GUARD_BAND_PIXELS
from ..geometry.setup import ONE as _ONE
from ..geometry.weld import weld
from ..raster.fill import depth_passes
from ..scene.mesh import instance_of

__all__ = ["Edges", "HiddenLine", "EDGE_KINDS", "triangle_edges", "unique_edges",
           "chosen_edges", "clip_segments", "draw_lines", "draw_points", "BOUNDARY", "CREASE",
           "SILHOUETTE", "NONMANIFOLD", "INTERSECTION", "MODEL", "OBJECT_BORDER",
           "as_hidden_line", "fill_state", "check", "draw_hidden_lines"]

BOUNDARY, CREASE, SILHOUETTE, NONMANIFOLD, INTERSECTION, MODEL = 1, 2, 4, 8, 16, 32
OBJECT_BORDER = 64  # of a visible piece, not an edge: see hsr.lines.border
EDGE_KINDS = ("all", "feature")


@dataclass(frozen=True)
class HiddenLine:
    """Settings of hidden-line drawing.

    edges : ``all`` (every edge of the mesh once) or ``feature`` (boundaries, creases
        sharper than ``crease_angle`` degrees, silhouettes, non-manifold edges).
    polygon_offset : (factor, units) pushed onto the filled surfaces (glPolygonOffset) so
        that edges lying on the surface pass the depth test.
    color : line colour; None = white on a dark background, black on a light one.
    fill : ``background`` (a classic hidden-line drawing) or ``shaded`` (edges over the
        shaded image).
    intersections : also draw the lines where faces pass through each other (exact
        segments, hidden like any edge; see :mod:`hsr.lines.intersect`).

    Raises :class:`~hsr.errors.RenderError` for an unknown edge kind or fill, or a crease
    angle outside 0..180.
    """

    edges: EdgeKind = "all"
    crease_angle: float = 30.0
    polygon_offset: tuple = (1.0, 1.0)
    color: tuple | None = None
    fill: str = "background"
    intersections: bool = False

    def line_color(self, background: tuple) -> tuple:
        """The line colour: ``color``, or white on a dark background, black on a light one."""
        if self.color is not None:
            return tuple(self.color)
        return (255, 255, 255) if float(np.mean(background)) < 128 else (0, 0, 0)

    def __post_init__(self):
        check_choice(self.edges, EDGE_KINDS, "edges")
        check_choice(self.fill, ("background", "shaded"), "hidden-line fill")
        angle = self.crease_angle
        if isinstance(angle, bool) or not isinstance(angle, (int, float, np.integer,
                                                             np.floating)) \
                or not 0.0 <= angle <= 180.0:
            raise RenderError(f"crease angle must be a number in 0..180 degrees, got {angle!r}")
        if self.color is not None:
            check_rgb(self.color, "line colour")
        if not isinstance(self.intersections, (bool, np.bool_)):
            raise RenderError(f"intersections must be True or False, got "
                              f"{self.intersections!r}")


@dataclass
class Edges:
    """World-space edges. ``ends`` (E, 2, 3) endpoints, ``faces`` (E, 2) global ids of the
    faces on either side (-1 where there is none), ``kind`` (E,) bit mask of BOUNDARY,
    CREASE, SILHOUETTE, NONMANIFOLD (0 = an ordinary edge)."""

    ends: np.ndarray
    faces: np.ndarray
    kind: np.ndarray

    def __len__(self):
        return len(self.kind)

    def subset(self, keep) -> Edges:
        return Edges(self.ends[keep], self.faces[keep], self.kind[keep])


def _world(inst, points):
    return points @ inst.model[:3, :3].T + inst.model[:3, 3]


def triangle_edges(scene, face_ids) -> Edges:
    """The three edges (v0 v1, v1 v2, v2 v0) of each global face in ``face_ids``, in
    order: what glPolygonMode(GL_LINE) draws."""
    face_ids = np.asarray(face_ids, dtype=np.int64)
    offsets = scene.face_offsets()
    ends = np.empty((len(face_ids), 3, 2, 3))
    owner = instance_of(offsets, face_ids)
    for k in np.unique(owner):
        inst = scene.instances[k]
        sel = owner == k
        tri = _world(inst, inst.mesh.positions[inst.mesh.faces[face_ids[sel] - offsets[k]]])
        ends[sel, :, 0] = tri
        ends[sel, :, 1] = tri[:, [1, 2, 0]]
    faces = np.stack([np.repeat(face_ids, 3), np.full(3 * len(face_ids), -1)], axis=1)
    return Edges(ends.reshape(-1, 2, 3), faces, np.zeros(3 * len(face_ids), dtype=np.uint8))


@njit(cache=True, inline="always")
def _sub(pos, i, j):
    return pos[i, 0] - pos[j, 0], pos[i, 1] - pos[j, 1], pos[i, 2] - pos[j, 2]


@njit(cache=True)
def _half_edges_by_edge(corner, n_pos):
    """Half-edges ``3 f + s`` (edge s of face f) ordered by edge (low vertex, then high),
    faces in order within an edge, and each one's edge key (low * n_pos + high) in that
    order: a counting sort on the low vertex, then an insertion sort of each vertex's few
    half-edges by the high one (both stable; O(n))."""
    n_half = 3 * corner.shape[0]
    start = np.zeros(n_pos + 1, dtype=np.int64)
    for h in range(n_half):
        a, b = corner[h // 3, h % 3], corner[h // 3, (h % 3 + 1) % 3]
        start[min(a, b) + 1] += 1
    for v in range(n_pos):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    order = np.empty(n_half, dtype=np.int64)
    high = np.empty(n_half, dtype=np.int64)
    for h in range(n_half):
        a, b = corner[h // 3, h % 3], corner[h // 3, (h % 3 + 1) % 3]
        v = min(a, b)
        order[fill[v]], high[fill[v]] = h, max(a, b)
        fill[v] += 1
    for v in range(n_pos):
        for i in range(start[v] + 1, start[v + 1]):
            h, key = order[i], high[i]
            j = i - 1
            while j >= start[v] and high[j] > key:
                order[j + 1], high[j + 1] = order[j], high[j]
                j -= 1
            order[j + 1], high[j + 1] = h, key
        for i in range(start[v], start[v + 1]):
            high[i] += v * n_pos
    return order, high


@njit(cache=True)
def _edge_kinds(corner, world_pos, view, orthographic, cos_crease, features_only):
    """Each edge of the faces ``corner`` (F, 3) (welded vertex ids into ``world_pos``)
    once, classified: ``(lo, hi, first, second, kind)``, ``first``/``second`` the rows of
    the faces on either side (-1: none; the first two in face order where there are
    more). ``view``: the eye, or the view direction when ``orthographic``. With
    ``features_only``, ordinary edges (kind 0) are left out."""
    n_faces, n_pos = corner.shape[0], world_pos.shape[0]
    order, key = _half_edges_by_edge(corner, n_pos)
    n_half = 3 * n_faces
    lo = np.empty(n_half, dtype=np.int64)
    hi = np.empty(n_half, dtype=np.int64)
    first = np.empty(n_half, dtype=np.int64)
    second = np.empty(n_half, dtype=np.int64)
    kinds = np.empty(n_half, dtype=np.uint8)
    n_out, i = 0, 0
    while i < n_half:
        j = i
        while j + 1 < n_half and key[j + 1] == key[i]:
            j += 1
        f1, s1 = order[i] // 3, order[i] % 3
        a, b = corner[f1, s1], corner[f1, (s1 + 1) % 3]
        kind, f2 = 0, -1
        if j == i:
            kind = BOUNDARY
        elif j > i + 1:
            kind, f2 = NONMANIFOLD, order[i + 1] // 3
        else:
            f2, s2 = order[i + 1] // 3, order[i + 1] % 3
            p0, p1 = min(a, b), max(a, b)
            c1, c2 = corner[f1, (s1 + 2) % 3], corner[f2, (s2 + 2) % 3]
            ex, ey, ez = _sub(world_pos, p1, p0)
            ux, uy, uz = _sub(world_pos, c1, p0)
            vx, vy, vz = _sub(world_pos, c2, p0)
            # Independent of winding (tessellated CAD and scans are often wound every
            # which way): both normals from the edge's own direction, so the faces fold
            # flat when their far corners lie on opposite sides (n1 . n2 = -|n1||n2|).
            n1x, n1y, n1z = ey * uz - ez * uy, ez * ux - ex * uz, ex * uy - ey * ux
            n2x, n2y, n2z = ey * vz - ez * vy, ez * vx - ex * vz, ex * vy - ey * vx
            len12 = np.sqrt((n1x * n1x + n1y * n1y + n1z * n1z)
                            * (n2x * n2x + n2y * n2y + n2z * n2z))
            if len12 > 0:
                if -(n1x * n2x + n1y * n2y + n1z * n2z) / len12 < cos_crease:
                    kind |= CREASE
            elif cos_crease > 0:
                kind |= CREASE
            # A silhouette: both far corners on one side of the plane through the eye and
            # the edge (for an orthographic camera, the plane along the view).
            if orthographic:
                wx, wy, wz = view[0], view[1], view[2]
            else:
                wx, wy, wz = (world_pos[p0, 0] - view[0], world_pos[p0, 1] - view[1],
                              world_pos[p0, 2] - view[2])
            px, py, pz = ey * wz - ez * wy, ez * wx - ex * wz, ex * wy - ey * wx
            if (px * ux + py * uy + pz * uz) * (px * vx + py * vy + pz * vz) > 0:
                kind |= SILHOUETTE
        if kind != 0 or not features_only:
            lo[n_out], hi[n_out] = min(a, b), max(a, b)
            first[n_out], second[n_out], kinds[n_out] = f1, f2, kind
            n_out += 1
        i = j + 1
    return lo[:n_out], hi[:n_out], first[:n_out], second[:n_out], kinds[:n_out]


def unique_edges(scene, camera, crease_angle: float = 30.0, drawn=None,
                 features_only: bool = False) -> Edges:
    """Every edge of every instance once (vertices welded by exact position, so meshes with
    split vertices still have shared edges), classified. ``drawn`` (F,) bool limits the
    edges to those of faces that are drawn (not culled, not degenerate);
    ``features_only`` leaves out the ordinary edges (kind 0)."""
    offsets = scene.face_offsets()
    cos_crease = float(np.cos(np.radians(crease_angle)))
    if camera.is_orthographic:
        view = np.asarray(camera.forward, dtype=np.float64)
    else:
        view = np.asarray(camera.eye, dtype=np.float64)
    parts = []
    for k, inst in enumerate(scene.instances):
        mesh = inst.mesh
        keep = ~mesh.degenerate_mask()
        if drawn is not None:
            keep &= drawn[offsets[k]:offsets[k + 1]]
        local = np.flatnonzero(keep)
        if len(local) == 0:
            continue
        unique_pos, welded = weld(mesh.positions)
        world_pos = np.ascontiguousarray(_world(inst, unique_pos))
        cad = mesh.feature_lines is not None
        lo, hi, first, second, kind = _edge_kinds(
            np.ascontiguousarray(welded[mesh.faces[local]]), world_pos, view,
            camera.is_orthographic, cos_crease, features_only and not cad)
        ends = np.stack([world_pos[lo], world_pos[hi]], axis=1)
        faces = np.stack([local[first] + offsets[k],
                          np.where(second >= 0, local[np.maximum(second, 0)] + offsets[k], -1)],
                         axis=1)
        if cad:
            # A CAD model draws its own B-rep edges; of the triangles' edges only the
            # silhouettes (a curved face's facets meet at creases nobody drew).
            parts.append(_model_lines(inst, unique_pos, lo, hi, faces))
            kind = kind & SILHOUETTE
            if features_only:
                ends, faces, kind = ends[kind != 0], faces[kind != 0], kind[kind != 0]
        parts.append(Edges(ends, faces, kind))
    if not parts:
        return Edges(np.zeros((0, 2, 3)), np.zeros((0, 2), dtype=np.int64),
                     np.zeros(0, dtype=np.uint8))
    return Edges(np.concatenate([p.ends for p in parts]),
                 np.concatenate([p.faces for p in parts]),
                 np.concatenate([p.kind for p in parts]))


def _model_lines(inst, unique_pos, edge_lo, edge_hi, edge_faces) -> Edges:
    """The instance's ``feature_lines`` in world space, each with the faces of the triangle
    edge it runs along (found by welded vertex ids; -1 where it runs along none)."""
    lines = inst.mesh.feature_lines
    if len(lines) == 0:
        return Edges(np.zeros((0, 2, 3)), np.zeros((0, 2), np.int64), np.zeros(0, np.uint8))
    both, ids = weld(np.concatenate([unique_pos, lines.reshape(-1, 3)]))
    mesh_id, ends_id = ids[:len(unique_pos)], ids[len(unique_pos):].reshape(-1, 2)
    n = len(both)

    def key(a, b):
        return np.minimum(a, b).astype(np.int64) * n + np.maximum(a, b)

    table = key(mesh_id[edge_lo], mesh_id[edge_hi])
    order = np.argsort(table)
    at = np.clip(np.searchsorted(table, key(ends_id[:, 0], ends_id[:, 1]), sorter=order), 0,
                 len(table) - 1)
    found = table[order[at]] == key(ends_id[:, 0], ends_id[:, 1])
    faces = np.where(found[:, None], edge_faces[order[at]], -1)
    return Edges(_world(inst, lines.reshape(-1, 3)).reshape(-1, 2, 3), faces,
                 np.full(len(lines), MODEL, np.uint8))


def clip_segments(ends_world, view_proj, width, height, depth_range=(0.0, 1.0),
                  guard=GUARD_BAND_PIXELS):
    """Clip world-space segments (E, 2, 3) to the view volume in homogeneous clip space
    (Liang-Barsky on the planes w +- z >= 0 and the guard band |x|, |y| <= g w) and map
    them to window space.

    Returns ``(keep (E,) bool, ends_window (E', 2, 3) float64 x, y (y up), depth,
    t (E', 2) the kept parameter span of the original segment)``.
    """
    n = len(ends_world)
    hom = np.concatenate([ends_world, np.ones((n, 2, 1))], axis=2) @ view_proj.T  # (E, 2, 4)
    gx = 2.0 * guard / width + 1.0
    gy = 2.0 * guard / height + 1.0
    planes = np.array([[0, 0, 1, 1], [0, 0, -1, 1], [1, 0, 0, gx], [-1, 0, 0, gx],
                       [0, 1, 0, gy], [0, -1, 0, gy]], dtype=np.float64)
    d = hom @ planes.T  # (E, 2, P): >= 0 inside
    t0 = np.zeros(n)
    t1 = np.ones(n)
    keep = np.ones(n, dtype=bool)
    for p in range(len(planes)):
        da, db = d[:, 0, p], d[:, 1, p]
        keep &= ~((da < 0) & (db < 0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t_cross = da / (da - db)
        enter = (da < 0) & (db >= 0)
        leave = (da >= 0) & (db < 0)
        t0 = np.where(enter, np.maximum(t0, t_cross), t0)
        t1 = np.where(leave, np.minimum(t1, t_cross), t1)
    keep &= t0 < t1
    hom, t0, t1 = hom[keep], t0[keep], t1[keep]
    a = hom[:, 0] + t0[:, None] * (hom[:, 1] - hom[:, 0])
    b = hom[:, 0] + t1[:, None] * (hom[:, 1] - hom[:, 0])
    near_d, far_d = depth_range
    out = np.empty((len(a), 2, 3))
    for j, p in enumerate((a, b)):
        w = p[:, 3]
        out[:, j, 0] = (p[:, 0] / w + 1.0) * 0.5 * width
        out[:, j, 1] = (p[:, 1] / w + 1.0) * 0.5 * height
        out[:, j, 2] = p[:, 2] / w * 0.5 * (far_d - near_d) + 0.5 * (far_d + near_d)
    return keep, out, np.stack([t0, t1], axis=1)


@njit(cache=True, nogil=True, inline="always")
def _depth_stage(depth_test, depth_func, depth_write, z, depth_buf, row, i):
    """The per-fragment depth test and write (no write when the test is off, as in GL);
    True when the fragment passes."""
    if depth_test and not depth_passes(depth_func, z, depth_buf[row, i]):
        return False
    if depth_test and depth_write:
        depth_buf[row, i] = z
    return True


@njit(cache=True, nogil=True, inline="always")
def _snap(v):
    return np.floor(v * _ONE + 0.5) / _ONE


@njit(cache=True, nogil=True)
def draw_lines(ends_window, seg_face, width, height, depth_test, depth_func, depth_write,
               z_lo, z_hi, depth_buf, face_buf, line_face):
    """Rasterize window-space segments (S, 2, 3) in order. A fragment passes glDepthFunc
    against ``depth_buf`` (written when ``depth_write``); passing fragments set
    ``line_face`` to the segment's face and, if ``face_buf`` is not empty, ``face_buf``.
    Returns (fragments tested, fragments written)."""
    tested = 0
    written = 0
    write_face = face_buf.shape[0] > 0
    for s in range(ends_window.shape[0]):
        # Endpoints snapped to the sub-pixel grid the triangles use (as GL implementations
        # snap line vertices before rasterizing).
        xa, ya = _snap(ends_window[s, 0, 0]), _snap(ends_window[s, 0, 1])
        xb, yb = _snap(ends_window[s, 1, 0]), _snap(ends_window[s, 1, 1])
        za, zb = ends_window[s, 0, 2], ends_window[s, 1, 2]
        dx, dy = xb - xa, yb - ya
        x_major = abs(dx) >= abs(dy)
        if x_major:
            a0, a1, length = xa, xb, dx
        else:
            a0, a1, length = ya, yb, dy
        if length == 0.0:
            continue
        # Pixel centres c = k + 0.5 in the half-open span [a0, a1) (or (a1, a0]).
        if length > 0:
            k_first = int(np.ceil(a0 - 0.5))
            k_last = int(np.ceil(a1 - 0.5)) - 1
        else:
            k_first = int(np.floor(a1 - 0.5)) + 1
            k_last = int(np.floor(a0 - 0.5))
        limit = width if x_major else height
        k_first = max(k_first, 0)
        k_last = min(k_last, limit - 1)
        for k in range(k_first, k_last + 1):
            t = (k + 0.5 - a0) / length
            if x_major:
                i = k
                j = int(np.ceil(ya + t * dy)) - 1
            else:
                j = k
                i = int(np.ceil(xa + t * dx)) - 1
            if i < 0 or i >= width or j < 0 or j >= height:
                continue
            z = np.float32(min(max(za + t * (zb - za), z_lo), z_hi))
            row = height - 1 - j
            tested += 1
            if not _depth_stage(depth_test, depth_func, depth_write, z, depth_buf, row, i):
                continue
            line_face[row, i] = seg_face[s]
            if write_face:
                face_buf[row, i] = seg_face[s]
            written += 1
    return tested, written


@njit(cache=True, nogil=True)
def draw_points(points_window, point_face, width, height, depth_test, depth_func,
                depth_write, z_lo, z_hi, depth_buf, face_buf):
    """One-pixel points (glPointSize 1) at window positions (P, 3), in order: the pixel
    containing the point. Returns (fragments tested, fragments written)."""
    tested = 0
    written = 0
    for p in range(points_window.shape[0]):
        i = int(np.floor(points_window[p, 0]))
        j = int(np.floor(points_window[p, 1]))
        if i < 0 or i >= width or j < 0 or j >= height:
            continue
        z = np.float32(min(max(points_window[p, 2], z_lo), z_hi))
        row = height - 1 - j
        tested += 1
        if not _depth_stage(depth_test, depth_func, depth_write, z, depth_buf, row, i):
            continue
        face_buf[row, i] = point_face[p]
        written += 1
    return tested, written


def as_hidden_line(value) -> HiddenLine | None:
    """``render(hidden_line=...)``: True = default settings, False or None = off."""
    if value is True:
        return HiddenLine()
    if value is False or value is None:
        return None
    if not isinstance(value, HiddenLine):
        raise RenderError("hidden_line must be True, False or an hsr.HiddenLine")
    return value


def fill_state(state, hidden_line: HiddenLine | None):
    """The state the surfaces are filled with: hidden lines push the fill back by their
    polygon offset unless the state sets one."""
    if hidden_line is not None and state.polygon_offset == (0.0, 0.0):
        return state.with_(polygon_offset=hidden_line.polygon_offset)
    return state


def check(state, hidden_line: HiddenLine | None, algorithm: str, *, transparent: bool,
          into: bool, counts: bool) -> None:
    """The combinations the line stage cannot draw: polygon modes draw lines or points
    with the z-buffer, alone."""
    if state.polygon_mode == "fill":
        return
    mode = state.polygon_mode.value
    if algorithm != "zbuffer":
        raise RenderError(f"polygon mode {mode} draws lines or points with the z-buffer; "
                          f"{algorithm} only fills")
    if hidden_line is not None or transparent or into or counts:
        raise RenderError(f"polygon mode {mode} does not combine with hidden lines, "
                          f"transparency, into= or counts")


def drawn_faces(screen, n_faces) -> np.ndarray:
    """(F,) bool: faces that reached window space (not degenerate, culled or outside)."""
    drawn = np.zeros(n_faces, dtype=bool)
    drawn[screen.face_id] = True
    return drawn


def polygon_edges(scene, screen, view_proj, state):
    """glPolygonMode(GL_LINE / GL_POINT): the edges (or corners) of every drawn face, in
    submission order, rasterized with the state's depth test into cleared buffers.

    Edges are clipped as segments, so a face cut by the near plane shows its edges up to
    the plane (OpenGL would also outline the cut). Returns (face_id, depth, stats)."""
    width, height = screen.width, screen.height
    face_ids = np.flatnonzero(drawn_faces(screen, scene.n_faces))
    depth = np.full((height, width), np.float32(state.clear_depth), dtype=np.float32)
    face = np.full((height, width), -1, dtype=np.int32)
    z_lo, z_hi = min(state.depth_range), max(state.depth_range)
    if state.polygon_mode == "line":
        edges = triangle_edges(scene, face_ids)
        keep, ends_window, _ = clip_segments(edges.ends, view_proj, width, height,
                                             state.depth_range)
        tested, written = draw_lines(ends_window, edges.faces[keep, 0], width, height,
                                     state.depth_test, state.depth_func.code, state.depth_mask,
                                     z_lo, z_hi, depth, np.zeros((0, 0), np.int32), face)
        stats = {"edges": int(keep.sum())}
    else:
        corners = screen.faces[face_ids].ravel()
        pos_clip = screen.pos_clip[corners]
        w = pos_clip[:, 3]
        inside = np.all(np.abs(pos_clip[:, :3]) <= w[:, None], axis=1) & (w > 0)
        near_d, far_d = state.depth_range
        p = pos_clip[inside]
        points = np.stack([(p[:, 0] / p[:, 3] + 1.0) * 0.5 * width,
                           (p[:, 1] / p[:, 3] + 1.0) * 0.5 * height,
                           p[:, 2] / p[:, 3] * 0.5 * (far_d - near_d) + 0.5 * (far_d + near_d)],
                          axis=1)
        tested, written = draw_points(points, np.repeat(face_ids, 3)[inside], width, height,
                                      state.depth_test, state.depth_func.code,
                                      state.depth_mask, z_lo, z_hi, depth, face)
        stats = {"points": int(inside.sum())}
    stats.update(fragments_tested=int(tested), fragments_written=int(written))
    return face, depth, stats


def chosen_edges(scene, camera, screen, settings: HiddenLine) -> Edges:
    """The edges hidden-line drawing considers: every edge of the drawn faces once, or
    only the feature edges."""
    drawn = drawn_faces(screen, scene.n_faces)
    edges = unique_edges(scene, camera, settings.crease_angle, drawn=drawn,
                         features_only=settings.edges == "feature")
    if not settings.intersections:
        return edges
    from .intersect import intersection_edges

    ids = np.flatnonzero(drawn)
    ends, pair = intersection_edges(scene.world_triangles()[ids])
    return Edges(np.concatenate([edges.ends, ends]),
                 np.concatenate([edges.faces, ids[pair]]),
                 np.concatenate([edges.kind, np.full(len(ends), INTERSECTION, np.uint8)]))


def hidden_line_pass(scene, camera, screen, view_proj, depth_filled, settings: HiddenLine,
                     depth_range):
    """Draw the chosen edges with a LEQUAL depth test against ``depth_filled`` (the depth
    of the filled surfaces, already pushed back by the polygon offset), writing nothing to
    it. Returns (line_face (H, W) int32, -1 where no edge is drawn; stats)."""
    width, height = screen.width, screen.height
    edges = chosen_edges(scene, camera, screen, settings)
    keep, ends_window, _ = clip_segments(edges.ends, view_proj, width, height, depth_range)
    line_face = np.full((height, width), -1, dtype=np.int32)
    z_lo, z_hi = min(depth_range), max(depth_range)
    func = 3 if depth_range[1] >= depth_range[0] else 6  # LEQUAL, or GEQUAL when reversed
    tested, written = draw_lines(ends_window, edges.faces[keep, 0], width, height, True, func,
                                 False, z_lo, z_hi, depth_filled, np.zeros((0, 0), np.int32),
                                 line_face)
    return line_face, {"edges": int(keep.sum()), "line_fragments_tested": int(tested),
                       "line_fragments_written": int(written)}


def draw_hidden_lines(scene, camera, screen, view_proj, fragments, settings: HiddenLine,
                      state, background, color) -> dict:
    """The hidden-line pass of a render: clear ``color`` to the background (for a classic
    drawing), draw the visible edges over the filled depth into it, record the line
    buffer in ``fragments.buffers["lines"]``. Returns the line stats."""
    if settings.fill == "background":
        color[:] = background
    line_face, stats = hidden_line_pass(scene, camera, screen, view_proj,
                                        fragments.depth.copy(), settings, state.depth_range)
    color[line_face >= 0] = np.asarray(settings.line_color(background), dtype=np.uint8)
    fragments.buffers["lines"] = line_face
    stats["line_pixels"] = int(np.count_nonzero(line_face >= 0))
    return stats
