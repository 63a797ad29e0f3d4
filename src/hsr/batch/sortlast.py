"""Sort-last rendering of a partitioned scene: each part rendered on its own, the partial
frames composited by depth (Molnar, Cox, Ellsworth and Fuchs 1994, "A sorting
classification of parallel rendering"; IceT's reduction in ParaView and VisIt).

Why it is exact: with the depth test on and depth writes on, the z-buffer leaves at each
pixel the fragment that is best under the depth function (nearest for ``less`` /
``lequal``, farthest for ``greater`` / ``gequal``); among equally good fragments ``less``
and ``greater`` keep the first drawn and ``lequal`` / ``gequal`` the last, and
``always`` keeps the last drawn whatever its depth. A part keeps its faces in global
(submission) order, so its own render holds, at each pixel, the best of *its* fragments
with the same tie rule; the best of the parts' bests, ties broken by the global face id
(lower for first-drawn-wins, higher for last-drawn-wins), is then the whole scene's
winner, and compositing is associative and commutative, so any reduction tree gives the
same frame. Every fragment's window depth is computed from its own face's vertices with
the original instance's matrix, so the depths compared are the very float32 values the
whole scene's render would compare.

Colour, eye depth, distance and normals depend only on the winning face and the pixel, and
a part's winner at a pixel is the whole scene's winner there whenever that face wins the
composite, so each part's render carries them and compositing keeps the winner's: the
result equals a single :func:`hsr.render` of the whole scene bit for bit (tested).
Depth functions whose result depends on the order of every fragment (``equal``,
``notequal``, ``never``), a disabled depth mask, transparency, hidden lines, overdraw
counts and ``shading="depth"`` / ``"random"`` (which look at the whole image or at face
ids) are refused.

Traffic: a partial frame is W x H x (4 bytes depth + 8 bytes id + the outputs' bytes);
a tree over K parts moves K - 1 of them per view, in ceil(log2 K) levels.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..geometry.state import RenderState
from ..parallel import progress_bar
from ..render import render
from ..scene.camera import Camera
from ..scene.mesh import instance_of
from ..scene.partitioned import PartitionedScene, PartitionError, open_partitioned

__all__ = ["CompositeFrame", "render_partitioned", "each_partitioned", "composite", "OUTPUTS"]

# Outputs a sort-last render can return, beside the face ids and window depth it always has.
OUTPUTS = ("color", "eye_depth", "distance", "normals")
# What every composited frame holds whether asked or not (hsr batch's names for them):
# taken in outputs= and ignored, as the command line takes them.
ALWAYS = ("ids", "window_depth", "object_ids")
# Depth functions that order fragments (best first), and whether the last-drawn of equally
# good fragments wins.
_ORDERING = {"less": (np.less, False), "lequal": (np.less, True),
             "greater": (np.greater, False), "gequal": (np.greater, True),
             "always": (None, True)}
_REFUSED_OPTIONS = ("counts", "into", "hidden_line", "workspace")


@dataclass
class CompositeFrame:
    """One view of a sort-last render: the buffers of :class:`hsr.Frame` that were asked
    for, equal to those of :func:`hsr.render` on the whole scene. ``face_id`` (H, W)
    global ids (-1 background; int32, as hsr.Frame's, below 2**31 faces), ``depth``
    (H, W) float32 window depth, ``object_id`` (H, W) int32 instance index; ``color``,
    ``eye_depth``, ``distance``, ``normals`` as in :class:`hsr.Frame` or None when not
    asked for; ``stats``: per part rendered, its faces loaded, views and milliseconds."""

    face_id: np.ndarray
    depth: np.ndarray
    object_id: np.ndarray
    color: np.ndarray | None = None
    eye_depth: np.ndarray | None = None
    distance: np.ndarray | None = None
    normals: np.ndarray | None = None
    stats: list = field(default_factory=list)


def _check(options: dict, outputs: tuple) -> RenderState:
    """The render state the options describe, refusing what compositing cannot honour."""
    for name in _REFUSED_OPTIONS:
        if options.get(name) not in (None, False):
            raise PartitionError(f"sort-last rendering does not take {name}=")
    if options.get("algorithm", "zbuffer") != "zbuffer":
        raise PartitionError(f"sort-last rendering composites z-buffers: algorithm must be "
                             f"zbuffer, got {options['algorithm']!r}")
    unknown = sorted(set(outputs) - set(OUTPUTS) - set(ALWAYS))
    if unknown:
        raise PartitionError(f"unknown output(s) {', '.join(unknown)}; choose from "
                             f"{', '.join(OUTPUTS)} (face ids and depth always come)")
    if options.get("shading", "flat") in ("depth", "random"):
        raise PartitionError(f"shading={options['shading']!r} looks at the whole image or "
                             f"at face ids: not composited part by part")
    state_fields = {k: v for k, v in options.items() if k in RenderState.__dataclass_fields__}
    given = options.get("state")
    state: RenderState = given if isinstance(given, RenderState) else RenderState(**state_fields)
    func = state.depth_func.value
    if not state.depth_test or not state.depth_mask or func not in _ORDERING:
        raise PartitionError(f"sort-last compositing needs the depth test on with depth "
                             f"writes and a depth function that orders fragments (less, "
                             f"lequal, greater, gequal, always); got depth_test="
                             f"{state.depth_test}, depth_mask={state.depth_mask}, "
                             f"depth_func={func}")
    if state.polygon_mode.value != "fill":
        raise PartitionError("sort-last rendering draws filled polygons only")
    return state


def composite(a: dict, b: dict, depth_func: str) -> dict:
    """Partial frames ``a`` and ``b`` (dicts of (V, H, W[, C]) arrays: ``face_id`` global
    ids with -1 for none, ``depth`` and any other buffer) composited pixel by pixel: the
    better fragment under ``depth_func``, ties to the lower face id where the first drawn
    wins and to the higher where the last drawn wins (see the module). Pure; neither input
    is changed."""
    better, last_wins = _ORDERING[depth_func]
    ids_a, ids_b = a["face_id"], b["face_id"]
    covered_b = ids_b >= 0
    later = ids_b > ids_a
    if better is None:  # always: the last drawn covering face
        take_b = covered_b & ((ids_a < 0) | later)
    else:
        tie = b["depth"] == a["depth"]
        by_order = later if last_wins else ~later
        take_b = covered_b & ((ids_a < 0) | better(b["depth"], a["depth"]) | (tie & by_order))
    out = {}
    for name, value in a.items():
        mask = take_b.reshape(take_b.shape + (1,) * (value.ndim - take_b.ndim))
        out[name] = np.where(mask, b[name], value)
    return out


def render_part(store: PartitionedScene | str, p: int, cameras: list, width: int,
                height: int, outputs: tuple, options: dict) -> dict:
    """Render part ``p`` of ``store`` from every camera: ``{"frames": dict of (V, H, W[,
    C]) arrays (``face_id`` global, ``depth`` and ``outputs``), "stats": [part, faces
    loaded, views, ms]}``."""
    path = store.path if isinstance(store, PartitionedScene) else store
    return _render_loaded(_load(path, p), cameras, width, height, outputs, options)


def _merge(a: dict, b: dict, depth_func: str) -> dict:
    return {"frames": composite(a["frames"], b["frames"], depth_func),
            "stats": a["stats"] + b["stats"]}


def render_partitioned(store: PartitionedScene | str, cameras: list, width: int,
                       height: int, outputs: tuple = ("color",), client: Any = None,
                       views_per_task: int = 8, progress: bool | None = None,
                       **options) -> list:
    """Sort-last render of the partitioned scene ``store`` (a path or an opened
    :class:`PartitionedScene`) from each of ``cameras``: a list of
    :class:`CompositeFrame`, each equal to :func:`hsr.render` of the whole scene with the
    same options. ``outputs``: any of :data:`OUTPUTS`. ``options``: :func:`hsr.render`'s
    keyword arguments (state fields, shading, light, background, ...).

    With a Dask ``client``, each part is loaded once into a worker's memory (a future per
    part, so every task of that part runs where it is), each task renders one part for
    ``views_per_task`` views, and the partial frames are composited in a binary tree on
    the workers; only the final frames come back. Without one, the same runs here, part
    after part. A progress bar shows on a terminal (``progress``: force it on or off).
    Raises :class:`~hsr.scene.partitioned.PartitionError` for options that
    compositing cannot honour (see the module) and :class:`~hsr.errors.CameraError` for
    cameras that are not hsr Cameras."""
    done = sorted(each_partitioned(store, cameras, width, height, outputs, client,
                                   views_per_task, progress, **options),
                  key=lambda item: item[0])
    return [frame for _, frames in done for frame in frames]


def each_partitioned(store: PartitionedScene | str, cameras: list, width: int, height: int,
                     outputs: tuple = ("color",), client: Any = None,
                     views_per_task: int = 8, progress: bool | None = None,
                     **options) -> Iterator[tuple]:
    """:func:`render_partitioned`, group by group as each is composited: yields
    ``(index of the group's first camera, [CompositeFrame, ...])``, in the order the
    groups finish (on a Dask client; here, all at the end, since parts go one after
    another). A caller that writes each group and drops it holds a group of frames, not
    the job's. Raises what :func:`render_partitioned` raises, before any work."""
    from ..errors import CameraError
    from ..geometry.viewport import check_size

    if not isinstance(store, PartitionedScene):
        store = open_partitioned(store)
    check_size(width, height)
    state = _check(options, tuple(outputs))
    outputs = tuple(o for o in outputs if o not in ALWAYS)
    if any(inst["opacity"] < 1.0 for inst in store.instances):
        raise PartitionError("the scene has transparent instances, which blend in depth "
                             "order across parts: not composited")
    cameras = list(cameras)
    if not cameras or not all(isinstance(c, Camera) for c in cameras):
        raise CameraError("cameras must be a non-empty list of hsr.Camera")
    if isinstance(views_per_task, bool) or not isinstance(views_per_task, int) \
            or views_per_task < 1:
        raise PartitionError(f"views_per_task must be a positive integer, got "
                             f"{views_per_task!r}")
    func = state.depth_func.value
    groups = [cameras[k:k + views_per_task] for k in range(0, len(cameras), views_per_task)]
    if progress is None:
        progress = sys.stderr.isatty()
    return _each(store, groups, width, height, outputs, options, func, client,
                 progress_bar(progress, store.parts * len(cameras), "sort-last",
                              unit="part-view"), views_per_task)


def _each(store, groups, width, height, outputs, options, func, client, bar,
          per_task) -> Iterator[tuple]:
    """The generator behind :func:`each_partitioned` (the checks ran before it starts)."""
    with bar:
        if client is None:
            # Part by part, each read once and dropped before the next: one part in memory.
            merged: list = [None] * len(groups)
            for p in range(store.parts):
                loaded = _load(store.path, p)
                for g, group in enumerate(groups):
                    part = _render_loaded(loaded, group, width, height, outputs, options)
                    merged[g] = part if merged[g] is None else _merge(merged[g], part, func)
                    bar.update(len(group))
                del loaded
            for g, group in enumerate(merged):
                yield g * per_task, _frames(store, group)
        else:
            for g, group in _on_dask(client, store, groups, width, height, outputs, options,
                                     func, bar):
                yield g * per_task, _frames(store, group)


def _on_dask(client, store, groups, width, height, outputs, options, func,
             bar) -> Iterator[tuple]:
    """One load future per part (its scene stays in that worker's memory), a task per
    (part, group of views) that depends on it, a binary reduction tree per group; yields
    ``(group index, composited group)`` as each root finishes, then lets it go."""
    from distributed import as_completed

    loaded = [client.submit(_load, store.path, p, pure=False) for p in range(store.parts)]
    finals = []
    for group in groups:
        level = [client.submit(_render_loaded, part, group, width, height, outputs, options,
                               pure=False) for part in loaded]
        while len(level) > 1:
            pairs = [client.submit(_merge, level[k], level[k + 1], func, pure=False)
                     for k in range(0, len(level) - 1, 2)]
            level = pairs + ([level[-1]] if len(level) % 2 else [])
        finals.append(level[0])
        del level  # only the tree's root is held: partial frames go once merged
    index = {future.key: g for g, future in enumerate(finals)}
    for future, result in as_completed(finals, with_results=True):
        g = index[future.key]
        bar.update(store.parts * len(groups[g]))
        yield g, result
        future.release()  # the workers may drop the frames now
    del loaded  # the parts leave the workers' memory with their futures


def _load(path: str, p: int) -> tuple:
    """On a worker: part ``p`` read once, kept as long as its future lives."""
    store = open_partitioned(path, check_parts=False)  # checked where the job started
    scene, face_id = store.part(p)
    return p, scene, face_id


def _render_loaded(loaded: tuple, cameras, width, height, outputs, options) -> dict:
    start = time.perf_counter()
    p, scene, face_id = loaded
    # Shading is only for the colour output (face ids, depth and the derived buffers come
    # from visibility): counting and depth-only jobs skip it, as face_visibility does.
    options = dict(options, color="color" in outputs)
    frames = [render(scene, cam, width, height, **options) for cam in cameras]
    local = np.stack([f.face_id for f in frames])
    result = {"face_id": np.where(local >= 0, face_id[np.maximum(local, 0)], -1),
              "depth": np.stack([f.depth for f in frames])}
    for name in outputs:
        result[name] = np.stack([getattr(f, name) for f in frames])
    stats = {"part": int(p), "faces_loaded": int(len(face_id)), "views": len(cameras),
             "ms": (time.perf_counter() - start) * 1000.0}
    return {"frames": result, "stats": [stats]}


def _frames(store: PartitionedScene, group: dict) -> list:
    frames = group["frames"]
    offsets = store.face_offsets()
    id_type = np.int32 if store.n_faces < 2 ** 31 else np.int64  # as hsr.Frame's
    out = []
    for v in range(len(frames["face_id"])):
        ids = frames["face_id"][v].astype(id_type)
        object_id = instance_of(offsets, ids).astype(np.int32)
        object_id[ids < 0] = -1
        extra = {name: frames[name][v] for name in OUTPUTS if name in frames}
        out.append(CompositeFrame(ids, frames["depth"][v], object_id, stats=group["stats"],
                                  **extra))
    return out
