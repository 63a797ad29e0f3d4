"""The z-buffer (Catmull 1974): for every fragment, keep it if it passes the depth test
against what is stored. Follows OpenGL's depth state exactly, in submission order."""

from __future__ import annotations

import itertools

import numpy as np

from ..errors import RenderError
from ..geometry.setup import covers_pixels, estimate_row_work, setup_records, setup_triangles
from ..geometry.stage import (
    CULLED,
    NEEDS_CLIP,
    SIMPLE,
    Geometry,
    ScreenTriangles,
    classify_setup_range,
    clip_and_project,
    geometry_counts,
    status_counts,
)
from ..geometry.state import DepthFunc, RenderState
from ..parallel import Workers, split_range
from ..raster.fill import band_split, fill_bands, fill_kernel, fill_targets, rasterize
from .fragments import Fragments
from .hiz import BLOCK, ObjectBounds, rect_hidden, screen_box, update_hzb
from .support import Needs

NAME = "zbuffer"
OPTIONS: dict = {}  # accepted keys of render(..., options=...): none
DESCRIPTION = "depth buffer with OpenGL depth state (test, func, mask, clear, range)"
_NO_COUNTS = np.zeros((1, 1), dtype=np.int32)
_BY_FACE = np.zeros(0, dtype=np.int64)  # fill_band: records laid out by face
# Faces per streamed chunk (about): its set-up records (99 bytes a face) stay in the L3
# cache between the set-up and the fill, and no per-face array of the whole mesh is written.
STREAM_CHUNK = 1 << 16
# Faces per set-up part (see _SetupParts): a part costs about half a millisecond.
SETUP_PART = 8192


def check(state: RenderState, needs: Needs) -> None:
    """The z-buffer honours every depth state; occlusion culling needs the nearest surface
    to win and no per-pixel counts, polygon offset or transparency."""
    if needs.occlusion:
        if not (state.depth_test and state.depth_mask
                and state.depth_func in (DepthFunc.LESS, DepthFunc.LEQUAL)):
            raise RenderError("occlusion culling needs the depth test and depth writes on and "
                              "depth func less or lequal")
        if needs.counts:
            raise RenderError("occlusion culling does not record per-pixel counts")
        if state.polygon_offset != (0.0, 0.0) or needs.subset:
            raise RenderError("occlusion culling does not combine with polygon offset, "
                              "hidden lines or transparency")


def resolve(screen: ScreenTriangles, state: RenderState, depth_buffer: np.ndarray | None = None,
            counts: bool = False, workers: Workers | None = None,
            occlusion: ObjectBounds | None = None, **_) -> Fragments:
    """Z-buffer visibility of ``screen``. The depth buffer starts cleared to
    ``state.clear_depth``, or is ``depth_buffer`` ((H, W) float32, updated in place: draws
    accumulate as in OpenGL without glClear). ``face_id`` marks what this draw wrote.
    With ``occlusion`` (the scene's object bounds) objects are drawn front to back and
    those hidden behind what is drawn are skipped (:mod:`hsr.algorithms.hiz`)."""
    workers = workers or Workers()
    if occlusion is not None:
        return _resolve_with_occlusion(screen, state, depth_buffer, workers, occlusion)
    if screen.pending:
        return _resolve_streamed(screen, state, depth_buffer, counts, workers)
    face, depth, bbox, tested, written, count_tested, count_written = rasterize(
        screen.xy_window, screen.depth_window, screen.face_id, screen.width, screen.height,
        state, workers, counts=counts, depth_buffer=depth_buffer)
    stats = {
        "triangles_rasterized": int(np.count_nonzero(covers_pixels(bbox))),
        "fragments_tested": int(tested),
        "fragments_written": int(written),
    }
    return Fragments(face, depth, screen, stats, count_tested, count_written)


def _resolve_with_occlusion(screen, state, depth_buffer, workers, occlusion):
    width, height = screen.width, screen.height
    if depth_buffer is None:
        depth = np.full((height, width), state.clear_depth, dtype=np.float32)
    else:
        depth = depth_buffer
    face = np.full((height, width), -1, dtype=np.int32)
    z_lo, z_hi = min(state.depth_range), max(state.depth_range)
    near, far = state.depth_range
    depth_scale, depth_offset = 0.5 * (far - near), 0.5 * (far + near)
    # Screen triangles are in face order, so each object's triangles are one slice.
    tri_start = np.searchsorted(screen.face_id, occlusion.face_offsets)
    hzb = np.empty((-(-height // BLOCK), -(-width // BLOCK)), dtype=np.float32)
    update_hzb(depth, hzb, 0, width - 1, 0, height - 1)
    boxes = [screen_box(c, width, height, depth_scale, depth_offset)
             for c in occlusion.corners_clip]
    order = np.argsort([b[4] for b in boxes], kind="stable")  # nearest first
    tested = written = n_tested = n_culled = n_rasterized = 0
    for obj in order:
        t0, t1 = tri_start[obj], tri_start[obj + 1]
        if t0 == t1:
            continue
        n_tested += 1
        x0, x1, r0, r1, z_min, ok = boxes[obj]
        if ok and rect_hidden(hzb, x0, x1, r0, r1, z_min):
            n_culled += 1
            continue
        # Set up only what is drawn: culled objects cost nothing past the geometry stage.
        vert_fixed, edge_bias, bbox, zplane, row_work = setup_triangles(
            screen.xy_window[t0:t1], screen.depth_window[t0:t1], width, height, workers)
        bands = band_split(row_work, workers.threads)
        t, w, _ = fill_bands(
            workers, bands, vert_fixed, edge_bias, bbox, zplane, screen.face_id[t0:t1], width,
            height, True, state.depth_func.code, True, z_lo, z_hi, np.nan, depth, face,
            _NO_COUNTS, _NO_COUNTS, False, True)
        tested, written = tested + t, written + w
        drawn = bbox[covers_pixels(bbox)]
        n_rasterized += len(drawn)
        if len(drawn):
            update_hzb(depth, hzb, int(drawn[:, 0].min()), int(drawn[:, 1].max()),
                       height - 1 - int(drawn[:, 3].max()), height - 1 - int(drawn[:, 2].min()))
    stats = {
        "triangles_rasterized": n_rasterized,
        "fragments_tested": int(tested),
        "fragments_written": int(written),
        "objects_tested": n_tested,
        "objects_culled": n_culled,
    }
    return Fragments(face, depth, screen, stats)


def _resolve_streamed(screen: ScreenTriangles, state: RenderState, depth_buffer, counts,
                      workers) -> Fragments:
    """The z-buffer straight from the vertices, in chunks of faces: each chunk is classified
    and set up in one pass (no window-space copy of the triangles is stored), then filled, all
    on ``workers``. Chunks go in submission order and every band keeps triangle order, so
    the result equals filling the prepared screen triangles.

    The chunks are pipelined: each thread fills its band of chunk k, then sets up parts
    of chunk k + 1 (into the other of two record buffers) until none are left, in one
    hand-off. With a hand-off for each (every one waits for the slowest thread) a
    1M-face terrain at 1080p spent 15 of its ~90 ms waiting; pipelined, 10."""
    geometry: Geometry = screen.geometry  # type: ignore[assignment]  # deferred: kept
    width, height, n_faces = geometry.width, geometry.height, len(geometry.faces)
    # Fresh buffers are cleared by the first chunk's fill.
    depth, face, clear, count_tested, count_written = fill_targets(
        width, height, state, workers, depth_buffer, counts)
    z_lo, z_hi = min(state.depth_range), max(state.depth_range)
    keep_ccw, keep_cw = geometry.keep_by_facing()
    factor, units = (float(v) for v in state.polygon_offset)
    status = workers.scratch("status", n_faces, dtype=np.int8)
    # Chunks of about STREAM_CHUNK faces, none much smaller: a small last chunk (the
    # bunny's 69k faces made one of 4k) costs its own hand-offs and walks.
    size = max(1, -(-n_faces // max(1, round(n_faces / STREAM_CHUNK))))
    n_chunks = max(1, -(-n_faces // size))  # rounding up the size may leave fewer
    records = [setup_records(size, workers, slot) for slot in range(min(n_chunks, 2))]
    fill = fill_kernel(state.depth_test, state.depth_func.code, counts)
    setup_args = (geometry.degenerate, geometry.window(workers), geometry.codes,
                  geometry.faces, width, height, keep_ccw, keep_cw, factor, units, status)

    def chunk_of(k):
        c0 = k * size
        c1 = min(c0 + size, n_faces)
        return c0, c1, tuple(r[:c1 - c0] for r in records[k % 2])

    def set_up(k):
        """Chunk k's set-up, cut into parts of about SETUP_PART faces that the threads
        take as they come free (see :class:`_SetupParts`)."""
        c0, c1, chunk = chunk_of(k)
        n_parts = max(1, round((c1 - c0) / SETUP_PART))  # split_range keeps parts <= faces
        return _SetupParts(c0 + split_range(c1 - c0, n_parts), (c0, *setup_args, *chunk),
                           height)

    parts = set_up(0)
    # No more threads than parts: a mesh of one part (under SETUP_PART faces) is set up
    # by the calling thread alone, without waking another for nothing.
    workers.run(_set_up_parts, np.arange(min(workers.threads, len(parts.done)) + 1), parts)
    done, delta = parts.done, parts.delta
    tested = written = binned = rasterized = pieces_kept = clip_culled = 0
    for k in range(n_chunks):
        c0, c1, chunk = chunk_of(k)
        work = estimate_row_work(delta, [widest for widest, _ in done])
        rasterized += sum(covering for _, covering in done)
        clip_at, piece_off = _BY_FACE, np.zeros(1, dtype=np.int64)
        clip_local = np.flatnonzero(status[c0:c1] == NEEDS_CLIP)
        if len(clip_local):
            p_xy, p_depth, p_face, _, n_culled = clip_and_project(geometry, c0 + clip_local)
            clip_culled += n_culled
            if len(p_face):
                *p_records, p_row_work = setup_triangles(p_xy, p_depth, width, height,
                                                         workers, state.polygon_offset)
                chunk = tuple(np.concatenate([a, b]) for a, b in zip(chunk, p_records))
                work = work + p_row_work
                clip_at, n_pieces = np.unique(p_face - c0, return_counts=True)
                piece_off = np.concatenate([[0], np.cumsum(n_pieces)]).astype(np.int64)
                pieces_kept += len(p_face)
                rasterized += int(np.count_nonzero(covers_pixels(p_records[2])))
        bands = band_split(work, workers.threads)
        fill_args = (*chunk, _BY_FACE, c0, clip_at, piece_off, width, height,
                     state.depth_test, state.depth_func.code, state.depth_mask, z_lo, z_hi,
                     clear, depth, face, count_tested, count_written, counts, False)
        # Step i: band i of this chunk, then parts of the next as they come.
        parts = set_up(k + 1) if k + 1 < n_chunks else None
        results = workers.run(_fill_band_then_set_up, bands, fill, fill_args, parts)
        for t, w, b in results:
            tested, written, binned = tested + t, written + w, binned + b
        if parts is not None:
            done, delta = parts.done, parts.delta
        clear = np.nan
    geometry.release_window()  # the frame keeps the geometry; see release_window
    by_status = status_counts(status)
    stats = geometry_counts(n_faces, by_status, by_status[CULLED] + clip_culled,
                            by_status[SIMPLE] + pieces_kept)
    geometry.stats.update(stats)
    stats.update({"triangles_rasterized": rasterized, "fragments_tested": int(tested),
                  "fragments_written": int(written), "chunks": n_chunks,
                  "bands": len(bands) - 1, "band_triangles": int(binned)})
    return Fragments(face, depth, screen, stats, count_tested if counts else None,
                     count_written if counts else None)


class _SetupParts:
    """The set-up of one chunk cut into parts (face bounds ``bounds``), taken by the
    threads in turn as each comes free, so that a thread whose band filled quickly sets up
    more (equal shares left the threads of the 1M-face terrain waiting for each other
    about 5 of its 60 ms). Each part adds to its own row of ``delta`` and leaves its
    (widest, covering) in ``done``: the result does not depend on who ran what."""

    def __init__(self, bounds, args, height):
        self.bounds, self.args = bounds, args
        self.delta = np.zeros((len(bounds) - 1, height + 1))
        self.done = [None] * (len(bounds) - 1)
        self._next = itertools.count()  # next() is atomic under the GIL

    def run(self):
        while (i := next(self._next)) < len(self.done):
            self.done[i] = classify_setup_range(int(self.bounds[i]), int(self.bounds[i + 1]),
                                                *self.args, self.delta[i])


def _set_up_parts(_, __, parts):
    parts.run()


def _fill_band_then_set_up(band_lo, band_end, fill, fill_args, parts):
    """One thread's step of the pipeline: fill its band of this chunk, then take parts of
    the next chunk's set-up (``parts``, or None after the last chunk) until none are left.
    Returns the fill's counts."""
    counts = fill(band_lo, band_end, *fill_args)
    if parts is not None:
        parts.run()
    return counts
