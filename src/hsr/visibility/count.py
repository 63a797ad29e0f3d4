"""Per-face visibility from many views: render each view's face ids (any algorithm; the
z-buffer by default) and count, for every face, the pixels where it is the visible
surface, summed over the views. Runs in this process (the kernels' threads) or on a Dask
client, one task per group of views with the scene sent to each worker once.

What "visible" means here is exactly what the renderer shows: a pixel belongs to the face
whose id the frame holds at the pixel's centre. Faces that tie in depth are decided by the
render state's depth function in submission order, as OpenGL does (with ``less``, the
default, the earlier face keeps a tied pixel, so a later coplanar duplicate is never
visible).
"""

from __future__ import annotations

import math
import os
import sys
import threading
from typing import Any

import numpy as np
from numba import njit

from ..choices import Algorithm
from ..errors import HsrError
from ..parallel import progress_bar
from ..scene.camera import Camera
from ..scene.mesh import Scene, SceneLike, as_scene

__all__ = ["VisibilityError", "face_visibility", "object_visibility", "cameras_for",
           "check_size"]

# A group of views in one Dask task: enough to make the scene's transfer and the task's
# cost small against the renders, few enough that every worker gets several groups.
VIEWS_PER_TASK = 16


class VisibilityError(HsrError):
    """A visibility or pruning job is malformed (views, size, scene, thresholds)."""


def check_size(size) -> tuple:
    """(width, height) from ``R`` (square) or ``(W, H)``."""
    from ..geometry.viewport import check_size as check_image

    if isinstance(size, (int, np.integer)) and not isinstance(size, bool):
        width = height = int(size)
    else:
        try:
            width, height = (int(v) for v in size)
        except (TypeError, ValueError):
            raise VisibilityError(f"size must be R or (width, height), got {size!r}") from None
    check_image(width, height)
    return width, height


def cameras_for(scene: Scene, views: Any, aspect: float, near: float | None = None,
                far: float | None = None, up_axis: str | None = None) -> list:
    """The cameras of ``views``: a spec (``sphere:N``, ``hemisphere:N``,
    ``orbit:N[:ELEVATION]``: framed outside the scene's bounding sphere, as
    :mod:`hsr.views`), a transforms.json or COLMAP folder (interior viewpoints are
    welcome; their planes ``near`` / ``far`` when given, else the file's, else fitted to
    the scene), a :class:`hsr.Camera`, or a list mixing any of these (every set is used).
    View sets turn about ``up_axis`` (``y``, ``z``, or None: the scene's own,
    :meth:`hsr.Scene.up_axis`). Raises :class:`VisibilityError` for anything else."""
    from ..batch.plan import BatchError, parse_views
    from ..scene import views as view_sets

    items = list(views) if isinstance(views, (list, tuple)) else [views]
    if not items:
        raise VisibilityError("no views given")
    cameras, bounds = [], None
    for item in items:
        if isinstance(item, Camera):
            item.validate()
            cameras.append(item)
            continue
        if isinstance(item, (list, tuple)):
            cameras += cameras_for(scene, item, aspect, near, far, up_axis)
            continue
        if isinstance(item, str) and item.startswith("per-model:"):
            raise VisibilityError("views: per-model is for hsr batch; give the cameras")
        try:
            is_file = isinstance(item, str) and os.path.exists(item)
            if is_file and bounds is None:
                bounds = scene.bounds()
            spec = parse_views(item, [], near, far, bounds if is_file else None)
        except BatchError as exc:
            raise VisibilityError(str(exc)) from None
        if spec.kind == "cameras":
            cameras += list(spec.cameras)
        else:
            bounds = scene.bounds() if bounds is None else bounds
            up = view_sets.model_up(scene, up_axis)
            dirs = view_sets.directions(spec.kind, spec.count, spec.elevation, up_axis=up)
            cameras += [view_sets.framed(bounds, d, aspect, up_axis=up) for d in dirs]
    return cameras


def face_visibility(scene: SceneLike, views: Any, size: int | tuple = 512, *,
                    client: Any = None, algorithm: Algorithm = "zbuffer",
                    threads: int | None = None, near: float | None = None,
                    far: float | None = None,
                    progress: bool | None = None, cull_objects: bool | str = True,
                    exact: bool = False, **render_options) -> np.ndarray:
    """(n_faces,) int64: for each face of ``scene`` (global face ids, submission order),
    the number of pixels where it is visible, summed over ``views`` (see
    :func:`cameras_for`) rendered at ``size`` (``R`` or ``(W, H)``) with ``algorithm``
    and ``render_options`` (:func:`hsr.render`'s: cull, depth_func, ...). ``client``: a
    ``distributed.Client`` to spread the views over its workers; without one the views
    render here, ``threads`` at a time (one view per thread). A progress bar shows on a
    terminal.
    ``cull_objects``: with the z-buffer and a depth test where the nearest surface wins,
    skip the objects a view cannot show where that pays (``"always"``: wherever it can;
    :func:`count_view_culled`: the counts are the same, faster when parts are hidden).
    ``exact=True``: (n_faces,) float64 visible areas in px^2 instead, from
    :func:`hsr.visible_regions` (every face with a visible part counts, however small;
    ``render_options`` are its depth state: cull, front_face, depth_func).

    A partitioned scene (:func:`hsr.partition`'s store, or its path) is rendered sort-last
    (:func:`hsr.batch.render_partitioned`, on ``client`` when given) and counted after
    compositing; the counts equal the whole scene's.

    Raises :class:`VisibilityError` for bad views or size and for a scene with
    transparent instances (whether a face is seen through one is not a face id), and
    what :func:`hsr.render` raises for bad render options."""
    from ..scene.load import load_scene
    from ..scene.partitioned import PartitionedScene

    if isinstance(scene, (str, os.PathLike)):
        scene = load_scene(scene)
    if isinstance(scene, PartitionedScene):
        return _partitioned_counts(scene, views, size, client, near, far,
                                   dict(render_options, algorithm=algorithm, threads=threads))
    scene = as_scene(scene)
    check_opaque(scene)
    width, height = check_size(size)
    cameras = cameras_for(scene, views, width / height, near, far)
    if exact:
        if algorithm != "zbuffer":
            raise VisibilityError("exact=True computes visible regions: it takes no "
                                  "algorithm")
        return exact_areas(scene, cameras, width, height, render_options, client, threads,
                           progress)
    options = dict(render_options, algorithm=algorithm)
    if not (isinstance(cull_objects, (bool, np.bool_)) or cull_objects == "always"):
        raise VisibilityError(f"cull_objects must be True, False or 'always', got "
                              f"{cull_objects!r}")
    for name in ("into", "counts", "hidden_line", "color", "workspace"):
        if name in options:
            raise VisibilityError(f"{name} is not an option of face_visibility")
    # Refuse bad options before the work is spread out: one 1 x 1 render.
    from ..render import render

    render(scene, cameras[0], 1, 1, threads=1, **options)
    if progress is None:
        progress = sys.stderr.isatty()
    if client is not None:
        return _on_dask(client, scene, cameras, width, height, options, progress)
    cull = bool(cull_objects) and len(scene) > 1 and can_cull_objects(options)
    boxes = [inst.mesh.bounds() for inst in scene.instances] if cull else None
    with progress_bar(progress, len(cameras), "visibility") as bar:
        return _count_here(scene, cameras, width, height, threads, options, bar, boxes,
                           cull_objects == "always")


def _count_here(scene, cameras, width, height, threads, options, bar, boxes, always):
    """The views rendered in this process: one view per thread at a time, each drawn on
    one thread into its thread's own counts (a view's set-up and Python glue then overlap
    another view's fill, instead of every view being cut into bands), summed at the end.
    ``boxes``: per-instance bounds to skip hidden objects (:func:`count_view_culled`),
    or None."""
    from concurrent.futures import ThreadPoolExecutor

    from ..parallel import Workers, Workspace

    lanes = min(Workers(threads).threads, len(cameras))
    view_threads = 1 if lanes > 1 else threads
    totals = np.zeros((lanes, scene.n_faces), dtype=np.int64)
    local = threading.local()
    lock = threading.Lock()
    taken = []
    subsets = SubsetScenes(scene) if boxes is not None else None

    def one(camera):
        if not hasattr(local, "total"):
            with lock:
                local.total = totals[len(taken)]
                # Each lane renders one view at a time: its own scratch, kept (Workspace).
                local.options = {**options, "workspace": Workspace(view_threads)}
                taken.append(local.options["workspace"])
        if boxes is not None:
            # Which objects earlier views saw only steers the speed (any set gives the
            # same counts), so a slightly stale sum over the lanes is fine.
            seen = per_object(scene, totals.sum(axis=0)) > 0
            count_view_culled(scene, camera, width, height, view_threads, local.options,
                              local.total, seen, boxes, always=always, subsets=subsets)
        else:
            count_view(scene, camera, width, height, view_threads, local.options,
                       local.total)

    try:
        if lanes == 1:
            for camera in cameras:
                one(camera)
                bar.update(1)
            return totals[0]
        pool = ThreadPoolExecutor(lanes)
        try:
            for future in [pool.submit(one, camera) for camera in cameras]:
                future.result()
                bar.update(1)
        finally:  # after an error (or Ctrl-C) the views not started are dropped
            pool.shutdown(cancel_futures=True)
        return totals.sum(axis=0)
    finally:
        for workspace in taken:
            workspace.close()


def object_visibility(scene: SceneLike, views: Any, size: int | tuple = 512,
                      **options) -> np.ndarray:
    """(n_instances,) int64: the visible pixels of each instance summed over the views
    (:func:`face_visibility` summed over each instance's faces)."""
    scene = as_scene(scene)
    return per_object(scene, face_visibility(scene, views, size, **options))


def per_object(scene: Scene, face_counts: np.ndarray) -> np.ndarray:
    """Face counts summed per instance (int64; float64 for exact areas)."""
    sums = np.add.reduceat(face_counts, scene.face_offsets()[:-1])
    return sums if np.issubdtype(sums.dtype, np.floating) else sums.astype(np.int64)


@njit(cache=True, nogil=True)
def add_pixels_through(face_id, global_id, total):
    """:func:`add_pixels` for a draw of part of the scene: its face ``f`` is face
    ``global_id[f]`` of the whole."""
    flat = face_id.ravel()
    for k in range(flat.size):
        f = flat[k]
        if f >= 0:
            total[global_id[f]] += 1


@njit(cache=True, nogil=True)
def add_pixels(face_id, total):
    """``total[f] += `` the pixels of ``face_id`` (an image of face ids, -1 background)
    that show face ``f``: a histogram without the temporary arrays of a mask and a
    bincount (a 1024 x 1024 view: about 1 ms instead of 6)."""
    flat = face_id.ravel()
    for k in range(flat.size):
        f = flat[k]
        if f >= 0:
            total[f] += 1


def count_view(scene, camera, width, height, threads, options, total) -> None:
    """Add one view's visible pixels per face to ``total``."""
    from ..render import render

    face_id = render(scene, camera, width, height, threads=threads, color=False,
                     **options).face_id
    add_pixels(np.ascontiguousarray(face_id), total)


# Window depth by which a hidden object's box must lie behind what is drawn (about 16
# float32 steps at depth 1: the rasterizer interpolates depth in float32).
CULL_MARGIN = 1e-6
# The faces whose set-up and fill cost what testing one object's box costs (about
# 0.2 ms / 140 ns).
CULL_OBJECT_FACES = 1400
# How far (in pixels at its far side) an object's box is grown before the test: the
# rasterizer snaps vertices to 1/256 pixel, so a face may cover a pixel centre just
# outside the exact box's image.
CULL_GROW_PIXELS = 2.0


@njit(cache=True, nogil=True)
def box_hidden(depth, x0, x1, r0, r1, clip_to_model, model_to_clip, lo, hi, scale, offset,
               margin):
    """True when, at every pixel centre of columns x0..x1 and rows r0..r1 whose ray meets
    the model-space box [lo, hi], the box's nearest point on that ray lies behind the
    depth buffer by more than ``margin`` (window depth): then nothing inside the box can
    pass a less / lequal depth test there, and at the other pixels nothing inside it
    lies on the ray at all. An occlusion query of the box, answered by casting each
    pixel's ray through it (slab test, Kay and Kajiya 1986)."""
    height, width = depth.shape
    a = np.empty(4)
    b = np.empty(4)
    p = np.empty(4)
    for r in range(r0, r1 + 1):
        y = 1.0 - (r + 0.5) / height * 2.0
        for c in range(x0, x1 + 1):
            x = (c + 0.5) / width * 2.0 - 1.0
            # The pixel's ray from the near plane (t = 0) to the far plane (t = 1).
            for i in range(4):
                a[i] = clip_to_model[i, 0] * x + clip_to_model[i, 1] * y \
                    - clip_to_model[i, 2] + clip_to_model[i, 3]
                b[i] = clip_to_model[i, 0] * x + clip_to_model[i, 1] * y \
                    + clip_to_model[i, 2] + clip_to_model[i, 3]
            t0, t1 = 0.0, 1.0
            hit = True
            for i in range(3):
                pa, pb = a[i] / a[3], b[i] / b[3]
                d = pb - pa
                if d == 0.0:
                    if pa < lo[i] or pa > hi[i]:
                        hit = False
                        break
                    continue
                ta, tb = (lo[i] - pa) / d, (hi[i] - pa) / d
                t0 = max(t0, min(ta, tb))
                t1 = min(t1, max(ta, tb))
                if t0 > t1:
                    hit = False
                    break
            if not hit:
                continue
            for i in range(3):
                p[i] = a[i] / a[3] + t0 * (b[i] / b[3] - a[i] / a[3])
            p[3] = 1.0
            z = 0.0
            w = 0.0
            for j in range(4):
                z += model_to_clip[2, j] * p[j]
                w += model_to_clip[3, j] * p[j]
            if not (w > 0.0 and (z / w) * scale + offset > depth[r, c] + margin):
                return False
    return True


def hidden_instances(scene, candidates, camera, width, height, depth, depth_range,
                     boxes) -> list:
    """The instances among ``candidates`` that cannot show a pixel over ``depth`` (a
    depth buffer of this view, less / lequal test): see :func:`box_hidden`. ``boxes``:
    each instance's model-space bounds."""
    from ..algorithms.hiz import box_corners, screen_box

    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    low, high = depth_range
    scale, offset = 0.5 * (high - low), 0.5 * (high + low)
    eye = np.asarray(camera.eye, dtype=np.float64)
    pixel = 2.0 * math.tan(math.radians(camera.fov_y) / 2.0) / height \
        if not camera.is_orthographic and camera.intrinsics is None else None
    hidden = []
    for k in candidates:
        inst = scene.instances[k]
        lo, hi = boxes[k]
        model_to_clip = view_proj @ inst.model
        world = box_corners(lo, hi) @ inst.model.T
        if pixel is None:  # orthographic or from intrinsics: a generous fixed growth
            grow_world = 1e-3 * float(np.linalg.norm(world[:, :3].max(0) - world[:, :3].min(0)))
        else:
            far = float(np.linalg.norm(world[:, :3] - eye, axis=1).max())
            grow_world = CULL_GROW_PIXELS * pixel * far
        # In model units, at least grow_world in every direction.
        smallest = float(np.linalg.svd(inst.model[:3, :3], compute_uv=False).min())
        grow = grow_world / max(smallest, 1e-300) + 1e-9 * float(np.abs(hi - lo).max())
        lo_g, hi_g = lo - grow, hi + grow
        x0, x1, r0, r1, _, ok = screen_box(box_corners(lo_g, hi_g) @ model_to_clip.T, width,
                                           height, scale, offset)
        if not ok:
            continue  # reaches the near plane: treated as visible
        if x0 > x1 or r0 > r1 or box_hidden(depth, x0, x1, r0, r1,
                                            np.linalg.inv(model_to_clip), model_to_clip,
                                            lo_g, hi_g, scale, offset, CULL_MARGIN):
            hidden.append(k)
    return hidden


def can_cull_objects(options) -> bool:
    """Whether the renders of ``options`` let :func:`count_view_culled` skip hidden objects
    exactly: the z-buffer filling with the depth test and depth writes on, depth func
    less or lequal and the depth range not reversed (the nearest surface wins), no
    polygon offset, no state object."""
    from ..geometry.state import RenderState

    if options.get("algorithm") != "zbuffer" or "state" in options or options.get("options"):
        return False
    fields = {k: options[k] for k in RenderState.__dataclass_fields__ if k in options}
    state = RenderState(**fields)
    return bool(state.depth_test and state.depth_mask and state.polygon_mode.value == "fill"
                and state.depth_func.value in ("less", "lequal")
                and state.depth_range[0] <= state.depth_range[1]
                and tuple(state.polygon_offset) == (0.0, 0.0))


class SubsetScenes:
    """The scenes of instance subsets drawn by :func:`count_view_culled`, the same Scene
    object for the same subset over the views (views mostly draw the same few sets, and
    a Scene keeps its joined arrays between renders: :meth:`Scene.assembled`). Holds the
    ``keep`` most recent sets (each as large as its meshes); safe to share by threads."""

    def __init__(self, scene: Scene, keep: int = 4):
        self.scene, self.keep = scene, keep
        self._scenes: dict = {}
        self._lock = threading.Lock()

    def get(self, drawn: np.ndarray) -> Scene:
        """The Scene of the instances ``drawn`` (ascending indices)."""
        key = tuple(int(k) for k in drawn)
        with self._lock:
            found = self._scenes.pop(key, None)
            if found is None:
                found = Scene([self.scene.instances[k] for k in key])
            while len(self._scenes) >= self.keep:
                self._scenes.pop(next(iter(self._scenes)))  # least recently used
            self._scenes[key] = found
            return found


def count_view_culled(scene, camera, width, height, threads, options, total, seen, boxes,
                      always=False, subsets=None) -> int:
    """:func:`count_view` that skips the objects this view cannot show. ``seen`` (per
    instance, True once an earlier view showed it) names the likely occluders: they are
    drawn first, alone; an unseen object whose bounding box (``boxes``: model-space
    bounds per instance) lies behind that depth buffer at every pixel its box covers
    (:func:`hidden_instances`) cannot win a pixel in the full draw either, whatever else
    is drawn (more geometry only brings the depth nearer). If every unseen object is
    hidden, the occluders' draw is the view; otherwise the scene without the hidden
    objects is drawn in submission order. Either way ties resolve exactly as in the full
    draw and the counts are the same. Object-level occlusion culling (Greene, Kass and
    Miller 1993) with the occluders taken from earlier views. Unless ``always``, the
    plain draw is used where the extra pass cannot pay. ``subsets``: a
    :class:`SubsetScenes` of ``scene`` kept over the views. Returns how many objects were
    skipped."""
    from ..render import render

    offsets = scene.face_offsets()
    unseen_faces = int(np.diff(offsets)[~seen].sum())
    # Worth a try only when skipping the unseen objects saves more than a second draw
    # and the box tests may cost: a frame's clear, fill and shading take about 10 ns a
    # pixel, a face's set-up and fill about 140 ns (measured on the bunny at 1024 x
    # 1024), the test of one object's box about 0.2 ms (mostly Python; measured on the
    # CAD-like assembly of benchmarks/bench_prune.py, where four hidden objects of 6k
    # faces saved nothing at 256 x 256).
    if not seen.any() or seen.all() or (not always and unseen_faces <= width * height // 14
                                        + CULL_OBJECT_FACES * int((~seen).sum())):
        count_view(scene, camera, width, height, threads, options, total)
        return 0
    drawn = np.flatnonzero(seen)
    subsets = subsets or SubsetScenes(scene)
    frame = render(subsets.get(drawn), camera, width, height, threads=threads, color=False,
                   **options)
    unseen = np.flatnonzero(~seen)
    hidden = hidden_instances(scene, unseen, camera, width, height, frame.depth,
                              options.get("depth_range", (0.0, 1.0)), boxes)
    face_id = frame.face_id
    if len(hidden) < len(unseen):  # some may show: draw all but the hidden, in order
        drawn = np.setdiff1d(np.arange(len(scene)), hidden)
        face_id = render(subsets.get(drawn), camera, width, height, threads=threads,
                         color=False, **options).face_id
    global_id = np.concatenate([np.arange(offsets[k], offsets[k + 1]) for k in drawn])
    add_pixels_through(np.ascontiguousarray(face_id), global_id, total)
    return len(hidden)


def count_views(scene, cameras, width, height, options) -> np.ndarray:
    """A Dask task: the summed counts of a group of views (one thread each: the
    parallelism is the cluster's)."""
    from ..parallel import Workspace

    total = np.zeros(scene.n_faces, dtype=np.int64)
    with Workspace(1) as workspace:  # scratch kept from view to view
        for camera in cameras:
            count_view(scene, camera, width, height, 1, {**options, "workspace": workspace},
                       total)
    return total


def _on_dask(client, scene, cameras, width, height, options, progress) -> np.ndarray:
    """Groups of views as tasks; only the (n_faces,) sums come back, added as they
    arrive."""
    total = np.zeros(scene.n_faces, dtype=np.int64)

    def take(_, counts):
        total[:] += counts
        return None

    with progress_bar(progress, len(cameras), "visibility") as bar:
        spread_views(client, count_views, scene, cameras, (width, height, options), take, bar)
    return total


def exact_areas(scene, cameras, width, height, state, client=None, threads=None,
                progress=None) -> np.ndarray:
    """(n_faces,) float64: visible areas (px^2) summed over ``cameras``
    (:func:`hsr.visible_regions` with the depth ``state`` fields), here or on ``client``."""
    state = exact_state(scene, cameras[0], state)
    total = np.zeros(scene.n_faces)
    if progress is None:
        progress = sys.stderr.isatty()
    with progress_bar(progress, len(cameras), "visibility") as bar:
        if client is not None:
            def take(_, areas):
                total[:] += areas

            spread_views(client, area_views, scene, cameras, (width, height, state, 1), take,
                         bar)
            return total
        for camera in cameras:
            total += area_views(scene, [camera], width, height, state, threads)
            bar.update(1)
    return total


def exact_state(scene, camera, state: dict) -> dict:
    """The depth state ``state`` (render options) of an exact (regions) count, checked now
    (one 1 x 1 view): no algorithm and no appearance option, only the fields
    :func:`hsr.visible_regions` takes."""
    from .regions import visible_regions

    state = {k: v for k, v in state.items() if not (k == "algorithm" and v == "zbuffer")}
    allowed = {"cull", "front_face", "depth_func", "depth_test", "depth_mask",
               "clear_depth", "polygon_mode", "polygon_offset", "depth_range"}
    unknown = sorted(set(state) - allowed)
    if unknown:
        raise VisibilityError(f"exact=True computes visible regions: it takes no "
                              f"{', '.join(unknown)}")
    visible_regions(scene, camera, 1, 1, threads=1, **state)
    return state


def area_views(scene, cameras, width, height, state, threads=1) -> np.ndarray:
    """A Dask task (or a loop here): the summed visible areas of a group of views."""
    total = np.zeros(scene.n_faces)
    for ids, areas in region_columns(scene, cameras, width, height, state, threads=threads):
        np.add.at(total, ids, areas)
    return total


def region_columns(scene, cameras, width, height, state, quality=False,
                   threads=1) -> list:
    """A Dask task: (face ids, areas[, cosine sums, distance sums]) of each view's
    visible regions, the sums weighted by area (so the matrix's division by the areas
    gives the means)."""
    from .regions import visible_regions

    out: list = []
    for camera in cameras:
        regions = visible_regions(scene, camera, width, height, threads=threads, **state)
        if quality:
            cosine, distance = regions.quality(scene, camera)
            out.append((regions.face_id, regions.area, cosine * regions.area,
                        distance * regions.area))
        else:
            out.append((regions.face_id, regions.area))
    return out


def spread_views(client, task, scene, cameras, args, take, bar) -> None:
    """``task(scene, group, *args)`` for groups of ``cameras`` as Dask tasks: the scene
    goes to every worker once (scattered), a group is at most VIEWS_PER_TASK views and
    every worker gets about four groups; ``take(first_view, result)`` runs on the client
    as each result arrives, and ``bar`` advances by the group's views."""
    from distributed import as_completed

    shared = client.scatter(scene, broadcast=True, hash=False)
    workers = max(1, sum(w.get("nthreads", 1) for w in
                         client.scheduler_info().get("workers", {}).values()))
    per_task = max(1, min(VIEWS_PER_TASK, math.ceil(len(cameras) / (4 * workers))))
    futures = {client.submit(task, shared, cameras[k:k + per_task], *args, pure=False): k
               for k in range(0, len(cameras), per_task)}
    for future in as_completed(list(futures)):
        k = futures.pop(future)
        take(k, future.result())
        bar.update(len(cameras[k:k + per_task]))
        future.release()


def _partitioned_counts(store, views, size, client, near, far, options) -> np.ndarray:
    """face_visibility of a partitioned scene: sort-last frames, counted on the client."""
    from ..batch.sortlast import render_partitioned

    width, height = check_size(size)
    cameras = cameras_for(store, views, width / height, near, far)
    counts = np.zeros(store.n_faces, dtype=np.int64)
    for frame in render_partitioned(store, cameras, width, height, outputs=(), client=client,
                                    **options):
        shown = frame.face_id[frame.face_id >= 0]
        counts += np.bincount(shown, minlength=store.n_faces)
    return counts


def check_opaque(scene: Scene) -> None:
    for inst in scene.instances:
        if inst.opacity < 1.0:
            raise VisibilityError(
                f"instance {inst.name!r} has opacity {inst.opacity}: visibility counts the "
                f"opaque surface at each pixel; make every instance opaque first")


