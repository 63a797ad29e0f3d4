"""Ray casting: one primary ray per pixel centre through the camera, nearest hit wins
(seed 004). ``accel="bvh"`` (default) walks a bounding volume hierarchy; ``accel="none"``
is the literal O(pixels x triangles) loop, for small scenes and teaching."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..errors import RenderError
from ..geometry.stage import ScreenTriangles
from ..geometry.state import RenderState
from ..parallel import Workers, split_range
from .bvh.choice import choose_walk
from .bvh.hits import NEAREST
from .bvh.layout import LANES, NODE_WORDS, ROW_VALUES, child
from .bvh.packets import trace_packets
from .bvh.ranking import clip_zw, depth32, ranks_before, window_ranking
from .bvh.sah import BVH, build
from .bvh.triangle import intersect, ray_frame
from .bvh.walk import trace_range
from .fragments import Fragments
from .hiz import pixel_rect
from .support import Needs, refuse_unless_nearest_wins, refuse_unsupported

NAME = "raycast"
# Accepted keys of render(..., options=...) and what each takes.
OPTIONS = {"accel": ("bvh", "none"), "bvh": BVH, "force": bool, "buffers": bool}
DESCRIPTION = "one ray per pixel in world space; BVH (binned SAH) or naive; watertight test"
NAIVE_LIMIT = 2_000_000_000  # ray-triangle tests allowed for accel="none" without force


def check(state: RenderState, needs: Needs) -> None:
    """Raise :class:`RenderError` for a request raycast cannot honour exactly."""
    refuse_unless_nearest_wins(NAME, state)
    if needs.counts:
        raise RenderError("raycast does not record per-pixel fragment counts")
    refuse_unsupported(NAME, state, needs)


def resolve(screen: ScreenTriangles, state: RenderState, workers: Workers | None = None,
            counts: bool = False, view=None, accel: str = "bvh", bvh: BVH | None = None,
            force: bool = False, buffers: bool = False, **_) -> Fragments:
    """``buffers=True`` also returns per-pixel ray ``distance`` (from the eye, or the eye
    plane for orthographic cameras) and ``barycentrics`` in ``fragments.buffers``."""
    if view is None:
        raise RenderError("raycast needs the scene and camera (call it through hsr.render)")
    if accel not in ("bvh", "none"):
        raise RenderError(f"raycast accel must be 'bvh' or 'none', got {accel!r}")
    workers = workers or Workers()
    width, height = screen.width, screen.height
    stats: dict = {"accel": accel}
    if accel == "none":
        triangles = view.scene.world_triangles()
        if width * height * len(triangles) > NAIVE_LIMIT and not force:
            raise RenderError(
                f"naive ray casting would run {width * height * len(triangles):.2e} ray-triangle "
                f"tests (limit {NAIVE_LIMIT:.0e}); use accel='bvh' or force=True")
        used = None
    else:
        if bvh is None:
            bvh = build(view.scene, workers.threads)
        elif not isinstance(bvh, BVH):
            raise RenderError(f"raycast option bvh must be an hsr.raycast.BVH (from "
                              f"hsr.raycast.build), got {type(bvh).__name__}")
        elif bvh.n_faces != view.scene.n_faces:
            raise RenderError("the BVH was built for another scene")
        triangles = None
        used = bvh
        stats.update(bvh_nodes=bvh.n_wide_nodes, bvh_build_ms=bvh.build_ms)
    face, depth, distance, bary, ray_counts = cast(triangles, view.camera, width, height,
                                                   state, workers, used, extras=buffers)
    stats.update(ray_counts)
    fragments = Fragments(face, depth, screen, stats)
    if buffers:
        fragments.buffers = {"distance": distance, "barycentrics": bary}
    return fragments


# The walks of the pixels' rays (stats["ray_walk"] names them).
NAIVE, PACKETS, INTERLEAVED = 0, 1, 2
WALKS = ("naive", "packets", "interleaved")
# Pixels whose rays one call of the walk takes (a few rows): their rays and answers,
# ~100 bytes a pixel, stay in a core's cache between being made, walked and written out.
BLOCK_PIXELS = 4096


def cast(triangles, camera, width, height, state, workers, bvh: BVH | None = None,
         extras: bool = True):
    """Cast one ray per pixel centre to the far plane (t = 1): from the eye for a
    perspective camera, the near plane at t = near / far, and from the near plane (t =
    0) for an orthographic one. Returns (face_id, depth, distance, barycentrics, counts); without
    ``extras`` distance and barycentrics are None (less memory traffic); ``counts``:
    ``ray_triangle_tests``, ``ray_walk`` (one of "naive", "packets", "interleaved",
    below) and ``rays_cast`` (the pixels whose ray was walked: with a ``bvh``, only
    those where the BVH's top boxes project, :func:`_pixel_spans`; the others show
    the background). ``triangles``: (F, 3, 3) world-space corners in face order,
    tested one by one when there is no ``bvh``.

    Hits are ranked as the z-buffer ranks fragments: by float32 window depth, equal
    depths by submission order (GL_LEQUAL: the later face; GL_LESS: the earlier), so
    coplanar faces resolve alike. With a ``bvh`` the rays go through the walks of
    :mod:`hsr.algorithms.bvh.walk` with the render state as their ``raster``: in packets
    of four neighbouring pixels (:func:`hsr.algorithms.bvh.packets.trace_packets`), whose rays
    meet the same boxes, unless there are more than
    :data:`hsr.algorithms.bvh.choice.PACKET_FACES_PER_PIXEL` faces a pixel
    (:func:`hsr.algorithms.bvh.choice.choose_walk`); then interleaved one by one
    (:func:`hsr.algorithms.bvh.walk.trace_range`), which overlaps the cache misses of rays
    that each meet triangles of their own."""
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    inv = np.linalg.inv(view_proj)
    cull_code = ["none", "back", "front", "front_and_back"].index(state.cull.value)
    front_ccw = state.front_face.value == "ccw"
    lequal = state.depth_func.value == "lequal"
    face = workers.output((height, width), np.int32)
    depth = workers.output((height, width), np.float32)
    shape = (height, width) if extras else (1, 1)
    distance = workers.output(shape, np.float64)
    bary = workers.output(shape + (3,), np.float64)
    eye = np.asarray(camera.eye, dtype=np.float64)
    forward = np.asarray(camera.forward, dtype=np.float64)
    # Many row chunks, handed out as threads free up: rays cost unevenly across the image.
    rows = split_range(height, 8 * workers.threads)
    clear = np.float32(state.clear_depth)
    raster = (cull_code, front_ccw, lequal, window_ranking(view_proj, state.depth_range))
    if bvh is None:
        walk = NAIVE
        # (The faces' corners as the walks' rows: hsr.algorithms.bvh.layout.)
        face_rows = np.ascontiguousarray(triangles).reshape(len(triangles), ROW_VALUES)
        nodes = (face_rows, np.zeros(0, np.int32), np.zeros((1, NODE_WORDS), np.float32),
                 np.zeros((1, NODE_WORDS), np.int32), 0, 0, 0)
    else:
        walk = (PACKETS if choose_walk(width * height, bvh.n_faces) is trace_packets
                else INTERLEAVED)
        nodes = bvh.walked
    spans = np.empty((height, 2), dtype=np.int64)
    if bvh is None:
        spans[:, 0], spans[:, 1] = 0, width
    else:
        _pixel_spans(bvh.node_box, bvh.node_link, bvh.root_ref, bvh.root_count,
                     len(bvh.leaf_face), bvh.bounds, view_proj, width, height, SPAN_LEVELS,
                     spans)
    # A perspective camera's rays start at its eye, all at one point, so a packet's tests
    # share the origin (simd.packet_keys8_shared, leaf_filter4_rays). The near plane lies at
    # the fraction near / far of the way from the eye to the far plane, on every pixel's ray.
    # (Measurements: docs/history.md, "Ray core".)
    t_near = 0.0 if camera.is_orthographic else float(camera.near) / float(camera.far)
    tests = workers.run(_cast_rows, rows, inv, width, height, raster, walk, *nodes, eye,
                        camera.is_orthographic, forward, face, depth, distance, bary, clear,
                        extras, spans, t_near)
    if min(tests) < 0:
        raise RenderError("the camera's pixel rays are not finite; check its matrices")
    counts = {"ray_triangle_tests": int(sum(tests)), "ray_walk": WALKS[walk],
              "rays_cast": int(np.maximum(spans[:, 1] - spans[:, 0], 0).sum())}
    if not extras:
        return face, depth, None, None, counts
    return face, depth, distance, bary, counts


# Wide levels of the BVH whose boxes bound the pixels a ray can hit (4**3 boxes at most).
SPAN_LEVELS = 3


@njit(cache=True, nogil=True)
def _pixel_spans(node_box, node_link, root_ref, root_count, n_slots, bounds, view_proj,
                 width, height, levels, spans):
    """Per row, the columns ``spans[r, 0] .. spans[r, 1] - 1`` outside which no pixel's
    ray can hit a face: the pixels covered by the screen rectangles of the BVH's boxes
    ``levels`` wide levels down (boxes that hold every face), so the ray caster makes
    and walks no ray elsewhere. A camera sees only what projects inside its image, and
    a model seldom fills it: the 1M-face terrain seen edge-on (the benchmark's view)
    covers 5% of a 1024x1024 image, yet its other rays were a third of the cast, each
    walked until it missed the top boxes.

    Exact by construction: the box's eight corners are projected; if all lie in front of
    the eye (clip w > 0), so does all of the box (w is affine), and the projection of
    the box is the convex hull of the corners' projections, inside their bounding
    rectangle. A ray runs from the near to the far plane, every point of it projecting
    to its pixel's centre, so a ray that hits a face in the box has its pixel centre in
    the rectangle. One pixel of margin covers rounding. Every point of a ray lies in
    front of the eye plane (clip w >= the near distance; 1 for an orthographic camera),
    so a box wholly at or behind it covers nothing, and one across it the whole image."""
    spans[:, 0], spans[:, 1] = width, 0
    if n_slots == 0:
        return
    if root_count != 0:  # the root is a leaf: the scene's box
        _cover_box(bounds[0, 0], bounds[0, 1], bounds[0, 2], bounds[1, 0], bounds[1, 1],
                   bounds[1, 2], view_proj, width, height, spans)
        return
    level = np.empty(LANES ** levels, dtype=np.int64)
    below = np.empty(LANES ** levels, dtype=np.int64)
    level[0], n_level = root_ref, 1
    for depth in range(levels):
        n_below = 0
        for j in range(n_level):
            w = level[j]
            for lane in range(LANES):
                ref, count = child(node_link, w, lane)
                if count < 0:  # an empty lane
                    continue
                if count == 0 and depth + 1 < levels:  # a wide node: its boxes, lower
                    below[n_below] = ref
                    n_below += 1
                    continue
                _cover_box(node_box[w, lane], node_box[w, LANES + lane],
                           node_box[w, 2 * LANES + lane], node_box[w, 3 * LANES + lane],
                           node_box[w, 4 * LANES + lane], node_box[w, 5 * LANES + lane],
                           view_proj, width, height, spans)
        if n_below == 0:
            break
        level[:n_below] = below[:n_below]
        n_level = n_below


@njit(cache=True, nogil=True)
def _cover_box(lo_x, lo_y, lo_z, hi_x, hi_y, hi_z, view_proj, width, height, spans):
    """Widen ``spans`` to the pixels whose centres may lie in the screen rectangle of the
    box, with a pixel of margin (:func:`hsr.algorithms.hiz.pixel_rect`, as the z-buffer's
    occlusion culling takes it; see :func:`_pixel_spans`)."""
    x0 = y0 = np.inf
    x1 = y1 = -np.inf
    behind, whole = 0, False
    for corner in range(8):
        x = hi_x if corner & 1 else lo_x
        y = hi_y if corner & 2 else lo_y
        z = hi_z if corner & 4 else lo_z
        cx = view_proj[0, 0] * x + view_proj[0, 1] * y + view_proj[0, 2] * z + view_proj[0, 3]
        cy = view_proj[1, 0] * x + view_proj[1, 1] * y + view_proj[1, 2] * z + view_proj[1, 3]
        cw = view_proj[3, 0] * x + view_proj[3, 1] * y + view_proj[3, 2] * z + view_proj[3, 3]
        if not cw > 0.0:
            behind += cw <= 0.0
            whole |= cw != cw
            continue
        # Window coordinates (x right, y up), pixel (c, r) centred at (c + 0.5,
        # height - r - 0.5).
        xw = (cx / cw + 1.0) * (0.5 * width)
        yw = (cy / cw + 1.0) * (0.5 * height)
        whole |= xw != xw or yw != yw
        x0, x1, y0, y1 = min(x0, xw), max(x1, xw), min(y0, yw), max(y1, yw)
    if behind == 8:  # all of the box behind the eye plane, where no ray reaches
        return
    if whole or behind > 0:  # across the eye plane, or NaN (not expected): all pixels
        x0, y0, x1, y1 = -np.inf, -np.inf, np.inf, np.inf
    c_lo, c_hi, r_lo, r_hi = pixel_rect(x0, x1, y0, y1, width, height)
    if c_lo > c_hi:
        return
    for r in range(r_lo, r_hi + 1):
        spans[r, 0] = min(spans[r, 0], c_lo)
        spans[r, 1] = max(spans[r, 1], c_hi + 1)


# error_model "numpy": IEEE division without Numba's zero test, which kept the loop
# from being vectorized.
@njit(cache=True, nogil=True, error_model="numpy")
def row_rays(inv_view_proj, width, height, r, c_lo, c_hi, eye, from_eye, rays):
    """The rays of row ``r``'s pixel centres (row 0 is the top), columns ``c_lo`` ..
    ``c_hi - 1``, into ``rays[:, :c_hi - c_lo]`` (``rays`` (6, width)):
    origins x, y, z and directions x, y, z, a row of each. The far point: the centre
    un-projected at the far plane (NDC z = 1, t = 1). With ``from_eye`` (perspective
    cameras) the ray runs from ``eye`` to it, the near plane at t = near / far (see
    :func:`cast`); else from the centre un-projected at the near plane (NDC z = -1, t =
    0). The two homogeneous points share all but their z term, and each is divided by
    its w once (a reciprocal, not three divisions). Written a component to a row so that
    the loop runs in SIMD lanes (measurements: docs/history.md, "Ray core")."""
    m = inv_view_proj
    y = 1.0 - (r + 0.5) * (2.0 / height)  # (the divisions by the size are hoisted)
    ex, ey, ez = eye[0], eye[1], eye[2]
    for j in range(c_hi - c_lo):
        x = (c_lo + j + 0.5) * (2.0 / width) - 1.0
        bx = m[0, 0] * x + m[0, 1] * y + m[0, 3]
        by = m[1, 0] * x + m[1, 1] * y + m[1, 3]
        bz = m[2, 0] * x + m[2, 1] * y + m[2, 3]
        bw = m[3, 0] * x + m[3, 1] * y + m[3, 3]
        near = 1.0 / (bw - m[3, 2])
        far = 1.0 / (bw + m[3, 2])
        # Selects, not branches: a branch in the loop left it scalar (vdivsd, no zmm).
        ox = ex if from_eye else (bx - m[0, 2]) * near
        oy = ey if from_eye else (by - m[1, 2]) * near
        oz = ez if from_eye else (bz - m[2, 2]) * near
        rays[0, j], rays[1, j], rays[2, j] = ox, oy, oz
        rays[3, j] = (bx + m[0, 2]) * far - ox
        rays[4, j] = (by + m[1, 2]) * far - oy
        rays[5, j] = (bz + m[2, 2]) * far - oz


@njit(cache=True, nogil=True, inline="always")
def _eye_distance(px, py, pz, eye, ortho, forward):
    """Distance of the hit point from the eye, or from the eye plane for an orthographic
    camera (its rays are parallel)."""
    if ortho:
        return (px - eye[0]) * forward[0] + (py - eye[1]) * forward[1] + (
            pz - eye[2]) * forward[2]
    return np.sqrt((px - eye[0]) ** 2 + (py - eye[1]) ** 2 + (pz - eye[2]) ** 2)


@njit(cache=True, nogil=True, error_model="numpy")
def _cast_rows(r_lo, r_hi, inv_view_proj, width, height, raster, walk, tris, leaf_face,
               node_box, node_link, root_ref, root_count, wide_depth, eye, ortho, forward,
               face_buf, depth_buf, dist_buf, bary_buf, clear_depth, extras, spans, t_near):
    """Rows r_lo .. r_hi - 1, a block of rows at a time: the block's rays made, walked
    (``walk``: :data:`PACKETS` and :data:`INTERLEAVED` through the BVH with
    :func:`hsr.algorithms.bvh.packets.trace_packets` / ``trace_range`` and ``raster``;
    :data:`NAIVE` by :func:`_naive_walk`, ``tris`` then the faces in order) and their
    answers written to the buffers. Returns the triangle tests made, or -1 for rays
    the walk refused (not finite)."""
    lequal, rank = raster[2], raster[3]
    block_rows = max(1, BLOCK_PIXELS // width)
    n_max = block_rows * width
    origins, directions, row = np.empty((n_max, 3)), np.empty((n_max, 3)), np.empty((6, width))
    out_t, out_face = np.empty(n_max), np.empty(n_max, dtype=np.int32)
    out_object, out_uv = np.empty(n_max, dtype=np.int32), np.empty((n_max, 2))
    no_normal, no_count = np.empty((0, 3)), np.empty(0, dtype=np.int32)
    t_min, t_max = np.full(1, t_near), np.ones(1)
    no_offsets = np.zeros(1, dtype=np.int64)
    tests = 0
    for b_lo in range(r_lo, r_hi, block_rows):
        b_hi = min(r_hi, b_lo + block_rows)
        # The block's rays in row order (a packet is a run of four pixels of a row; 2x2
        # quads measured the same at the bunny), only for pixels within the rows' spans
        # (see _pixel_spans).
        i = 0
        for r in range(b_lo, b_hi):
            c_lo, c_hi = spans[r, 0], spans[r, 1]
            row_rays(inv_view_proj, width, height, r, c_lo, c_hi, eye, not ortho, row)
            for j in range(c_hi - c_lo):
                origins[i, 0], origins[i, 1], origins[i, 2] = row[0, j], row[1, j], row[2, j]
                directions[i, 0], directions[i, 1] = row[3, j], row[4, j]
                directions[i, 2] = row[5, j]
                i += 1
        n = i
        problem = 0
        if walk == NAIVE:
            made = _naive_walk(n, origins, directions, t_near, raster, tris, out_t, out_face,
                               out_uv)
        elif walk == PACKETS:
            made, problem, _ = trace_packets(
                0, n, origins, directions, t_min, t_max, NEAREST, raster, tris, leaf_face,
                node_box, node_link, root_ref, root_count, wide_depth, no_offsets, out_t,
                out_face, out_object, out_uv, no_normal, no_count)
        else:
            made, problem, _ = trace_range(
                0, n, origins, directions, t_min, t_max, NEAREST, raster, tris, leaf_face,
                node_box, node_link, root_ref, root_count, wide_depth, no_offsets, out_t,
                out_face, out_object, out_uv, no_normal, no_count)
        if problem:
            return -1
        tests += made
        first = 0  # the ray of row r's first pixel in its span
        for r in range(b_lo, b_hi):
            for c in range(width):
                face_buf[r, c] = -1
                depth_buf[r, c] = clear_depth
                if extras:
                    dist_buf[r, c] = np.inf
                    bary_buf[r, c, 0] = bary_buf[r, c, 1] = bary_buf[r, c, 2] = 0.0
            c_lo, c_hi = spans[r, 0], spans[r, 1]
            for c in range(c_lo, c_hi):
                k = first + c - c_lo  # pixel (r, c)'s ray
                f = out_face[k]
                if f < 0:
                    continue
                t = out_t[k]
                # The walk's window depth of the hit, recomputed from the same numbers.
                ox, oy, oz = origins[k, 0], origins[k, 1], origins[k, 2]
                dx, dy, dz = directions[k, 0], directions[k, 1], directions[k, 2]
                zc0, zc1, wc0, wc1 = clip_zw(rank, ox, oy, oz, dx, dy, dz)
                z = depth32(t, zc0, zc1, wc0, wc1, rank[8], rank[9])
                if not (z < clear_depth or (lequal and z == clear_depth)):
                    continue
                face_buf[r, c] = f
                depth_buf[r, c] = z
                if extras:
                    dist_buf[r, c] = _eye_distance(ox + t * dx, oy + t * dy, oz + t * dz,
                                                   eye, ortho, forward)
                    v, w = out_uv[k, 0], out_uv[k, 1]
                    bary_buf[r, c, 0], bary_buf[r, c, 1] = 1.0 - v - w, v
                    bary_buf[r, c, 2] = w
            first += max(0, c_hi - c_lo)
    return tests


@njit(cache=True, nogil=True)
def _naive_walk(n, origins, directions, t_near, raster, tris, out_t, out_face, out_uv):
    """Rays 0 .. n - 1, each against every face in order (``tris``: the faces' world
    corners as rows, :mod:`hsr.algorithms.bvh.layout`): the literal method, with the
    walks' answers (``out_t``, ``out_face``, the weights of corners 1 and 2 in
    ``out_uv``) and ranking. Returns the tests made."""
    cull_code, front_ccw, lequal, rank = raster
    for i in range(n):
        ox, oy, oz = origins[i, 0], origins[i, 1], origins[i, 2]
        dx, dy, dz = directions[i, 0], directions[i, 1], directions[i, 2]
        kx, ky, kz, sx, sy, sz, okx, oky, okz = ray_frame(ox, oy, oz, dx, dy, dz)
        zc0, zc1, wc0, wc1 = clip_zw(rank, ox, oy, oz, dx, dy, dz)
        best_t, best_z, best_f = np.inf, np.float32(np.inf), -1
        bv = bw = 0.0
        for f in range(tris.shape[0]):
            t, _, v, w = intersect(tris, f, okx, oky, okz, kx, ky, kz, sx, sy, sz,
                                    cull_code, front_ccw, dx, dy, dz)
            if t_near <= t <= 1.0:
                z = depth32(t, zc0, zc1, wc0, wc1, rank[8], rank[9])
                if ranks_before(z, f, best_z, best_f, lequal):
                    best_t, best_z, best_f, bv, bw = t, z, f, v, w
        out_t[i], out_face[i] = best_t, best_f
        out_uv[i, 0], out_uv[i, 1] = bv, bw
    return n * tris.shape[0]
