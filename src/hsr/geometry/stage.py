"""The geometry stage shared by every algorithm:

model/view/projection -> clip space -> clip (near, far, guard band) -> divide + viewport
-> face culling -> :class:`ScreenTriangles`.

Vertices are transformed once, their outcodes and window coordinates computed on the way
(a compiled loop, see :func:`scene_clip_vertices`); a compiled per-face kernel classifies
each face (degenerate / outside / needs clipping / simple) and gathers the simple ones'
corners in window space.
Only the (usually few) faces that cross a clip plane go through the Sutherland-Hodgman
clipper in :mod:`hsr.geometry.clip`.

The plain z-buffer does not need the window-space triangles stored: with
``prepare(..., deferred=True)`` it streams faces, their corners gathered from the
vertices' window coordinates, through :func:`classify_setup_range` (classification,
culling and raster set-up in one pass) and the screen triangles are only computed if
something else reads them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ..parallel import Workers
from ..scene.mesh import Scene
from .clip import clip_planes, clip_triangles
from .conventions import GUARD_BAND_PIXELS
from .setup import setup_one
from .state import CullMode, FrontFace, RenderState

__all__ = ["Geometry", "ScreenTriangles", "prepare", "scene_clip_vertices", "screen_arrays"]

# Face status codes of the classification kernel.
SIMPLE, DEGENERATE, OUTSIDE, NEEDS_CLIP, CULLED = 0, 1, 2, 3, 4


@dataclass
class Geometry:
    """The scene in clip space, before classification: what :func:`prepare` starts from.

    pos_clip : (V, 4) clip-space vertices; faces : (F, 3) global faces into them.
    degenerate : (F,) bool, faces of zero area in model space (where a model matrix cannot
        hide it; :meth:`hsr.scene.mesh.Mesh.degenerate_mask`).
    codes : (V,) uint8 outcodes of the clip-space vertices (:func:`_codes`).
    pos_window : (V, 3) window x, y (y up) and depth of the vertices inside the guard band
        (outcode bit 6 clear; NaN for the others, which only the clipper reads), or None
        once released (:meth:`release_window`); read it through :meth:`window`.
    planes : the clipping planes (:func:`hsr.geometry.clip.clip_planes`).
    depth_scale, depth_offset : NDC z -> window depth for the state's depth range.
    stats : the dict that receives the triangle counts once faces are classified.
    """

    degenerate: np.ndarray
    pos_clip: np.ndarray
    codes: np.ndarray
    pos_window: np.ndarray | None
    faces: np.ndarray
    width: int
    height: int
    state: RenderState
    planes: np.ndarray
    depth_scale: float
    depth_offset: float
    stats: dict
    threads: int

    @property
    def guard_band(self) -> tuple[float, float]:
        """(gx, gy): the guard band's |x| <= gx w, |y| <= gy w."""
        return float(self.planes[2, 3]), float(self.planes[4, 3])

    def keep_by_facing(self) -> tuple[bool, bool]:
        """Whether faces of positive / negative window area (counter-clockwise /
        clockwise, y up) survive glFrontFace + glCullFace."""
        _, keep = _keep_mask(np.array([True, False]), self.state)
        return bool(keep[0]), bool(keep[1])

    def window(self, workers) -> np.ndarray:
        """``pos_window``, computed again (on ``workers``) if it was released: the same
        :func:`_to_window` of the same clip coordinates, so bit for bit what the transform
        stored."""
        if self.pos_window is None:
            pos_window = np.empty((len(self.pos_clip), 3))
            workers.run_range(_window_range, len(self.pos_clip), self.pos_clip, self.codes,
                              0.5 * self.width, 0.5 * self.height, self.depth_scale,
                              self.depth_offset, pos_window, min_chunk=65536)
            self.pos_window = pos_window
        return self.pos_window

    def release_window(self) -> None:
        """Drop ``pos_window`` (24 bytes a vertex) once the faces are set up: a frame
        keeps its geometry for attributes read later, and with the window copy kept too,
        the 1M-face terrain's frames grew past the C allocator's trim threshold, so that
        every other render gave its memory back and faulted 17 MB in again (about 10 ms
        here)."""
        self.pos_window = None


class ScreenTriangles:
    """Triangles in window space, ready for a visibility algorithm. N = triangles after
    clipping and culling, in submission order.

    xy_window : (N, 3, 2) float64, window x, y (pixels, y up, origin bottom-left).
    depth_window : (N, 3) float64, window depth in the depth range.
    face_id : (N,) int64, index of the source face in the scene's global face list.
    front : (N,) bool, front-facing under the state's winding.
    width, height : viewport size in pixels.
    pos_clip : (V, 4) float64 clip-space vertices of the whole scene and
    faces : (F, 3) int64 their global faces, so that attributes can be interpolated on the
        *source* face whatever clipping cut out of it (see fragments.face_barycentrics).

    A *deferred* set (``prepare(..., deferred=True)``) computes the four per-triangle
    arrays on first use; until then ``pending`` is true and ``geometry`` holds the clip-space
    scene, which lets the z-buffer stream faces straight into its set-up without storing
    window coordinates per triangle (only per vertex, and only until the set-up is done).
    A *lazy* set (``prepare(..., lazy=True)``) does not even transform the vertices until
    ``geometry``, ``pos_clip`` or ``faces`` is first read (``make_geometry`` makes them).
    """

    def __init__(self, xy_window, depth_window, face_id, front, width, height, pos_clip,
                 faces, geometry: Geometry | None = None, make_geometry=None):
        self._arrays = None if xy_window is None else (xy_window, depth_window, face_id,
                                                       front)
        self.width, self.height = width, height
        self._pos_clip, self._faces = pos_clip, faces
        self._geometry, self._make_geometry = geometry, make_geometry

    @property
    def geometry(self) -> Geometry | None:
        if self._geometry is None and self._make_geometry is not None:
            self._geometry, self._make_geometry = self._make_geometry(), None
        return self._geometry

    def _source(self) -> Geometry:
        geometry = self.geometry
        if geometry is None:  # a set has its clip-space vertices, or what makes them
            raise ValueError("screen triangles made without their clip-space vertices")
        return geometry

    @property
    def pos_clip(self) -> np.ndarray:
        return self._source().pos_clip if self._pos_clip is None else self._pos_clip

    @property
    def faces(self) -> np.ndarray:
        return self._source().faces if self._faces is None else self._faces

    @property
    def pending(self) -> bool:
        return self._arrays is None

    def _array(self, k):
        if self._arrays is None:
            with Workers(self.geometry.threads) as workers:
                self._arrays = screen_arrays(self.geometry, workers)
        return self._arrays[k]

    xy_window = property(lambda self: self._array(0))
    depth_window = property(lambda self: self._array(1))
    face_id = property(lambda self: self._array(2))
    front = property(lambda self: self._array(3))

    def __len__(self):
        return len(self.face_id)

    def subset(self, keep) -> ScreenTriangles:
        return ScreenTriangles(self.xy_window[keep], self.depth_window[keep],
                               self.face_id[keep], self.front[keep], self.width, self.height,
                               self.pos_clip, self.faces)


@njit(cache=True, nogil=True, inline="always")
def _to_window(x, y, z, w, half_w, half_h, depth_scale, depth_offset):
    inv_w = 1.0 / w
    return ((x * inv_w + 1.0) * half_w, (y * inv_w + 1.0) * half_h,
            z * inv_w * depth_scale + depth_offset)


def classify_faces(workers, geometry: Geometry):
    """Per face: status (SIMPLE, DEGENERATE, OUTSIDE, NEEDS_CLIP) and, for SIMPLE faces,
    window coordinates, depth and twice the signed window area (y up)."""
    n = geometry.faces.shape[0]
    status = np.empty(n, dtype=np.int8)
    xy = np.empty((n, 3, 2))
    depth = np.empty((n, 3))
    area = np.zeros(n)
    workers.run_range(_classify_range, n, geometry.degenerate, geometry.window(workers),
                      geometry.codes, geometry.faces, status, xy, depth, area)
    return status, xy, depth, area


@njit(cache=True, nogil=True, inline="always")
def _codes(pos_clip, v, gx, gy):
    """Outcode of vertex ``v`` against the six frustum planes |x|, |y|, |z| <= w (bits
    0-5) and whether it lies outside a clipping plane: near z >= -w, far z <= w, or the
    guard band |x| <= gx w, |y| <= gy w (bit 6). The comparisons are written so that they
    round exactly like the plane dot products the clipper evaluates (``z + w < 0`` etc.)."""
    x, y, z, w = pos_clip[v, 0], pos_clip[v, 1], pos_clip[v, 2], pos_clip[v, 3]
    code = 0
    if x > w:
        code |= 1
    if -x > w:
        code |= 2
    if y > w:
        code |= 4
    if -y > w:
        code |= 8
    if z > w:
        code |= 16
    if -z > w:
        code |= 32
    if (z + w < 0.0 or -z + w < 0.0 or x + gx * w < 0.0 or -x + gx * w < 0.0
            or y + gy * w < 0.0 or -y + gy * w < 0.0):
        code |= 64
    return code


@njit(cache=True, nogil=True, inline="always")
def _classify_one(degenerate, codes, f, a, b, c):
    """Status of face f with corners a, b, c: DEGENERATE, OUTSIDE, NEEDS_CLIP or SIMPLE
    (``codes``: the vertices' outcodes)."""
    if degenerate[f]:
        return DEGENERATE
    code_a, code_b, code_c = codes[a], codes[b], codes[c]
    # Trivial reject: all corners outside one frustum plane.
    if code_a & code_b & code_c & 63:
        return OUTSIDE
    if (code_a | code_b | code_c) & 64:
        return NEEDS_CLIP
    return SIMPLE


@njit(cache=True, nogil=True)
def _classify_range(lo, hi, degenerate, pos_window, codes, faces, status, xy, depth, area):
    for f in range(lo, hi):
        # Status kept in a register and stored once (see setup_one on stores).
        face_status = _classify_one(degenerate, codes, f, faces[f, 0], faces[f, 1], faces[f, 2])
        status[f] = face_status
        if face_status != SIMPLE:
            continue
        for k in range(3):
            v = faces[f, k]
            xy[f, k, 0], xy[f, k, 1], depth[f, k] = (pos_window[v, 0], pos_window[v, 1],
                                                     pos_window[v, 2])
        area[f] = ((xy[f, 1, 0] - xy[f, 0, 0]) * (xy[f, 2, 1] - xy[f, 0, 1])
                   - (xy[f, 2, 0] - xy[f, 0, 0]) * (xy[f, 1, 1] - xy[f, 0, 1]))


@njit(cache=True, nogil=True)
def classify_setup_range(lo, hi, base, degenerate, pos_window, codes, faces, width, height,
                         keep_ccw, keep_cw, offset_factor, offset_units, status, vert_fixed,
                         edge_bias, bbox, zplane, delta):
    """The geometry stage and the raster set-up in one pass (the z-buffer's streamed
    path): classify faces ``lo .. hi`` as :func:`classify_faces` does, cull by facing
    (``keep_ccw`` / ``keep_cw``: keep faces of positive / negative window area) and set up
    the kept simple ones into record ``f - base`` (:func:`hsr.geometry.setup.setup_one`; every
    other record gets an empty box). The corners are read from the vertices' window
    coordinates (``pos_window``) and not stored per face, which saves writing and
    re-reading 72 bytes per face.
    Adds the per-row work to ``delta`` ((H + 1,) zeros, one per call), as
    :func:`hsr.geometry.setup.setup_triangles` gathers it, and returns (widest row,
    triangles set up that hold a pixel centre)."""
    widest = 1
    covering = 0
    for f in range(lo, hi):
        r = f - base
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        # Status kept in a register and stored once (see setup_one on stores).
        face_status = _classify_one(degenerate, codes, f, a, b, c)
        if face_status == SIMPLE:
            x0, y0, z0 = pos_window[a, 0], pos_window[a, 1], pos_window[a, 2]
            x1, y1, z1 = pos_window[b, 0], pos_window[b, 1], pos_window[b, 2]
            x2, y2, z2 = pos_window[c, 0], pos_window[c, 1], pos_window[c, 2]
            # The same area expression as _classify_range, so facing is decided identically.
            area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
            if not (keep_ccw if area > 0 else keep_cw):
                face_status = CULLED
        status[f] = face_status
        if face_status != SIMPLE:
            bbox[r, 0], bbox[r, 1], bbox[r, 2], bbox[r, 3] = 0, -1, 0, -1
            continue
        right = setup_one(r, x0, y0, z0, x1, y1, z1, x2, y2, z2, width, height, vert_fixed,
                          edge_bias, bbox, zplane, offset_factor, offset_units, delta)
        widest = max(widest, right)
        covering += right > 0
    return widest, covering


@njit(cache=True)
def project_triangles(pos_clip, width, height, depth_scale, depth_offset):
    """(N, 3, 4) clip-space triangles -> window xy, depth and twice the signed area."""
    n = pos_clip.shape[0]
    xy = np.empty((n, 3, 2))
    depth = np.empty((n, 3))
    area = np.empty(n)
    half_w, half_h = 0.5 * width, 0.5 * height
    for t in range(n):
        for k in range(3):
            xy[t, k, 0], xy[t, k, 1], depth[t, k] = _to_window(
                pos_clip[t, k, 0], pos_clip[t, k, 1], pos_clip[t, k, 2], pos_clip[t, k, 3],
                half_w, half_h, depth_scale, depth_offset)
        area[t] = ((xy[t, 1, 0] - xy[t, 0, 0]) * (xy[t, 2, 1] - xy[t, 0, 1])
                   - (xy[t, 2, 0] - xy[t, 0, 0]) * (xy[t, 1, 1] - xy[t, 0, 1]))
    return xy, depth, area


def scene_clip_vertices(scene: Scene, view_proj: np.ndarray, guard_band, viewport,
                        workers=None):
    """Clip-space vertices of all instances, their outcodes (:func:`_codes`, for the
    ``guard_band`` (gx, gy)), their window coordinates for ``viewport`` (width, height,
    depth_scale, depth_offset), their faces re-indexed into them and which faces are
    degenerate (judged in model space, where a model matrix cannot hide it):
    ``(pos_clip (V, 4), codes (V,) uint8, pos_window (V, 3), faces (F, 3), degenerate (F,)
    bool)``, in submission order. All instances go through one compiled call (a scene of
    many small parts would otherwise pay a thread hand-off per part, every view)."""
    workers = workers or Workers()
    instances = scene.instances
    if len(instances) == 1:
        mesh = instances[0].mesh
        pos_model, faces, degenerate = mesh.positions, mesh.faces, mesh.degenerate_mask()
        owner, matrices = _ONE_OWNER, (view_proj @ instances[0].model)[None]
    else:
        pos_model, faces, degenerate, owner = scene.assembled()
        matrices = np.stack([view_proj @ inst.model for inst in instances])
    pos_clip = np.empty((len(pos_model), 4))
    codes = np.empty(len(pos_model), dtype=np.uint8)
    pos_window = np.empty((len(pos_model), 3))
    gx, gy = guard_band
    width, height, depth_scale, depth_offset = viewport
    workers.run_range(_transform_range, len(pos_model), pos_model, owner,
                      np.ascontiguousarray(matrices), pos_clip, float(gx), float(gy), codes,
                      0.5 * width, 0.5 * height, float(depth_scale), float(depth_offset),
                      pos_window, min_chunk=65536)
    return pos_clip, codes, pos_window, faces, degenerate


_ONE_OWNER = np.zeros(0, dtype=np.int64)


@njit(cache=True, nogil=True)
def _transform_range(lo, hi, points, owner, matrices, out, gx, gy, codes, half_w, half_h,
                     depth_scale, depth_offset, pos_window):
    """Points ``lo .. hi`` each through its instance's matrix ``matrices[owner[i]]``
    (``owner`` empty: all through ``matrices[0]``) into ``out``, their outcodes
    (:func:`_codes`, guard band ``gx``, ``gy``) and, for those inside the guard band, their
    window coordinates into ``pos_window`` (NaN for the others), all computed while the
    point is at hand rather than by more passes over the clip-space array.

    Window coordinates per vertex rather than per face corner: a vertex of a closed mesh
    is a corner of about six faces, and the division and viewport transform were a third
    of the z-buffer's set-up (1M-face terrain: 47 -> 36 ms on one thread, bit-identical,
    as the same :func:`_to_window` of the same clip coordinates).

    A compiled loop rather than NumPy's ``@``: a large matrix product goes to OpenBLAS,
    whose own threads keep spinning for a while after it returns and, on a machine with
    few cores, take the CPU from the kernels that run next (measured: the 1M-triangle
    terrain's set-up ran at half speed behind it)."""
    one = owner.shape[0] == 0
    for i in range(lo, hi):
        k = 0 if one else owner[i]
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for r in range(4):
            out[i, r] = (matrices[k, r, 0] * x + matrices[k, r, 1] * y + matrices[k, r, 2] * z
                         + matrices[k, r, 3])
        code = _codes(out, i, gx, gy)
        codes[i] = code
        pos_window[i, 0], pos_window[i, 1], pos_window[i, 2] = _vertex_window(
            code, out[i, 0], out[i, 1], out[i, 2], out[i, 3], half_w, half_h, depth_scale,
            depth_offset)


@njit(cache=True, nogil=True)
def _window_range(lo, hi, pos_clip, codes, half_w, half_h, depth_scale, depth_offset,
                  pos_window):
    """``pos_window`` of vertices ``lo .. hi`` from their clip coordinates and outcodes, as
    :func:`_transform_range` stores it."""
    for i in range(lo, hi):
        pos_window[i, 0], pos_window[i, 1], pos_window[i, 2] = _vertex_window(
            codes[i], pos_clip[i, 0], pos_clip[i, 1], pos_clip[i, 2], pos_clip[i, 3], half_w,
            half_h, depth_scale, depth_offset)


@njit(cache=True, nogil=True, inline="always")
def _vertex_window(code, x, y, z, w, half_w, half_h, depth_scale, depth_offset):
    """A vertex's window x, y, depth, or NaNs outside a clipping plane (outcode bit 6),
    where only the clipper reads the vertex."""
    if code & 64:
        return np.nan, np.nan, np.nan
    return _to_window(x, y, z, w, half_w, half_h, depth_scale, depth_offset)


def _keep_mask(ccw: np.ndarray, state: RenderState) -> tuple[np.ndarray, np.ndarray]:
    """(front, keep) from the counter-clockwise flags and glFrontFace / glCullFace."""
    front = ccw if state.front_face == FrontFace.CCW else ~ccw
    if state.cull == CullMode.BACK:
        return front, front
    if state.cull == CullMode.FRONT:
        return front, ~front
    if state.cull == CullMode.FRONT_AND_BACK:
        return front, np.zeros_like(front)
    return front, np.ones_like(front)


def prepare(scene: Scene, view_proj: np.ndarray, width: int, height: int,
            state: RenderState, stats: dict, workers=None, deferred: bool = False,
            lazy: bool = False) -> ScreenTriangles:
    """Run the geometry stage; fills ``stats`` with triangle counts. With ``deferred`` only
    the vertices are transformed now; faces are classified, clipped and projected when the
    screen triangles are first read (or streamed by the z-buffer, which fills ``stats``).
    With ``lazy`` (implies deferred) nothing is done until the clip-space vertices or the
    screen triangles are first read: the ray caster walks world space and reads neither
    unless a later pass (per-pixel shading, hidden lines, ...) does (a 1M-face terrain:
    its 500k vertices' transform, ~4 ms of a 1024x1024 frame, saved)."""
    workers = workers or Workers()
    if lazy:
        threads = workers.threads

        def make_geometry():
            with Workers(threads) as lazy_workers:
                return _geometry(scene, view_proj, width, height, state, stats, lazy_workers)

        return ScreenTriangles(None, None, None, None, width, height, None, None,
                               make_geometry=make_geometry)
    geometry = _geometry(scene, view_proj, width, height, state, stats, workers)
    if deferred:
        return ScreenTriangles(None, None, None, None, width, height, geometry.pos_clip,
                               geometry.faces, geometry)
    xy_window, depth_window, face_id, front = screen_arrays(geometry, workers)
    return ScreenTriangles(xy_window, depth_window, face_id, front, width, height,
                           geometry.pos_clip, geometry.faces)


def _geometry(scene, view_proj, width, height, state, stats, workers) -> Geometry:
    """The scene's vertices through ``view_proj``: :class:`Geometry` for ``state``."""
    near, far = state.depth_range
    planes = clip_planes(width, height, GUARD_BAND_PIXELS)
    depth_scale, depth_offset = 0.5 * (far - near), 0.5 * (far + near)
    pos_clip, codes, pos_window, faces, degenerate = scene_clip_vertices(
        scene, view_proj, (planes[2, 3], planes[4, 3]),
        (width, height, depth_scale, depth_offset), workers)
    return Geometry(degenerate, pos_clip, codes, pos_window, faces, width, height, state,
                    planes, depth_scale, depth_offset, stats, workers.threads)


def clip_and_project(geometry: Geometry, clip_faces: np.ndarray):
    """Clip the faces ``clip_faces`` (global indices) and project the pieces that survive
    culling. Facing is decided once per clipped polygon (sum of its fan's areas), as in GL.
    Returns (xy, depth, parent face, front, number of polygons culled)."""
    state, width, height = geometry.state, geometry.width, geometry.height
    tri_clip = np.ascontiguousarray(geometry.pos_clip[geometry.faces[clip_faces]])
    pieces, parent = clip_triangles(tri_clip, geometry.planes)
    p_xy, p_depth, p_area = project_triangles(pieces, width, height, geometry.depth_scale,
                                              geometry.depth_offset)
    poly_area = np.bincount(parent, weights=p_area, minlength=len(clip_faces))
    poly_front, poly_keep = _keep_mask(poly_area > 0, state)
    has_pieces = np.bincount(parent, minlength=len(clip_faces)) > 0
    n_culled = int(np.count_nonzero(has_pieces & ~poly_keep))
    sel = np.flatnonzero(poly_keep[parent])
    return (p_xy[sel], p_depth[sel], clip_faces[parent[sel]], poly_front[parent[sel]],
            n_culled)


@njit(cache=True, nogil=True)
def status_counts(status):
    """(CULLED + 1,) int64 number of faces of each status: one pass over the int8 codes
    (``np.bincount`` first widens them to int64, 5 ms on a million faces). One counter per
    status, each a comparison summed (no increment of a counter picked by the data, whose
    chain of loads and stores through memory cost 2.5 ms there), so it vectorises."""
    simple = degenerate = outside = needs_clip = culled = 0
    for f in range(status.shape[0]):
        code = status[f]
        simple += code == SIMPLE
        degenerate += code == DEGENERATE
        outside += code == OUTSIDE
        needs_clip += code == NEEDS_CLIP
        culled += code == CULLED
    return np.array([simple, degenerate, outside, needs_clip, culled], dtype=np.int64)


def screen_arrays(geometry: Geometry, workers):
    """Classify, clip, cull and project ``geometry``'s faces: (xy_window, depth_window,
    face_id, front) in submission order; the counts go to ``geometry.stats``."""
    state, faces, stats = geometry.state, geometry.faces, geometry.stats
    status, xy, depth, area = classify_faces(workers, geometry)
    counts = status_counts(status)
    simple = status == SIMPLE
    front, keep = _keep_mask(area > 0, state)
    n_culled = int(np.count_nonzero(simple & ~keep))
    if counts[SIMPLE] == len(faces) and n_culled == 0:  # the common case: no copies
        parts = [(xy, depth, np.arange(len(faces)), front)]
    else:
        chosen = np.flatnonzero(simple & keep)
        parts = [(xy[chosen], depth[chosen], chosen, front[chosen])]
    if counts[NEEDS_CLIP]:
        *clipped, n_clip_culled = clip_and_project(geometry,
                                                   np.flatnonzero(status == NEEDS_CLIP))
        parts.append(tuple(clipped))
        n_culled += n_clip_culled
    if len(parts) == 1:
        xy_w, depth_w, face_id, front_w = parts[0]
    else:
        xy_w, depth_w, face_id, front_w = (np.concatenate(c) for c in zip(*parts))
        # Restore submission order; stable keeps a clipped face's fan in order.
        order = np.argsort(face_id, kind="stable")
        xy_w, depth_w, face_id, front_w = (
            xy_w[order], depth_w[order], face_id[order], front_w[order])
    stats.update(geometry_counts(len(faces), counts, n_culled, len(face_id)))
    return xy_w, depth_w, face_id, front_w


def geometry_counts(n_faces, status_counts, n_culled, n_screen) -> dict:
    """The geometry stage's entries of ``Frame.stats``."""
    return {"triangles_in": int(n_faces), "degenerate": int(status_counts[DEGENERATE]),
            "outside": int(status_counts[OUTSIDE]), "clipped": int(status_counts[NEEDS_CLIP]),
            "culled": int(n_culled), "screen_triangles": int(n_screen)}
