"""What runs on a Dask worker: load a model once per worker (a worker plugin keeps the
loaded scenes), place its cameras, render a group of views and write each output under a
temporary name, renamed into place when complete (so an interrupted run never leaves a
half-written file under a final name). Every function returns small rows for the
manifest; no image travels back to the client."""

from __future__ import annotations

import os
import threading
import time
from collections import OrderedDict

import numpy as np
from distributed import WorkerPlugin

from ..scene.outputs import check_outside, write_atomic
from .plan import OUTPUTS, job_targets, output_path

__all__ = ["MeshCache", "PLUGIN_NAME", "place_cameras", "render_task", "render_group",
           "write_atomic"]

PLUGIN_NAME = "hsr-mesh-cache"


class MeshCache(WorkerPlugin):
    """A Dask worker plugin holding the scenes
    this worker has loaded, least recently used first out, up to ``max_faces`` faces in
    all (so a worker that sees thousands of models keeps a bounded amount). A model is
    keyed by its path, size and modification time: an edited file is loaded again."""

    name = PLUGIN_NAME

    def __init__(self, max_faces: int = 20_000_000):
        self.max_faces = max_faces
        self.scenes: OrderedDict = OrderedDict()
        self.lock = threading.Lock()

    def setup(self, worker=None):
        self.scenes = OrderedDict()

    def teardown(self, worker=None):
        self.scenes.clear()

    def get(self, path: str):
        """The scene of ``path``, loaded on first use. A worker with several threads runs
        tasks at once: one lock guards the cache, and a model is loaded once even when
        two tasks ask for it together."""
        from ..scene.load import load_scene

        stat = os.stat(path)
        key = (os.path.abspath(path), stat.st_size, stat.st_mtime_ns)
        with self.lock:
            if key in self.scenes:
                self.scenes.move_to_end(key)
                return self.scenes[key]
            scene = load_scene(path)
            self.scenes[key] = scene
            while len(self.scenes) > 1 and sum(s.n_faces for s in self.scenes.values()) \
                    > self.max_faces:
                self.scenes.popitem(last=False)
            return scene

    def __getstate__(self):  # sent to the workers empty, without its lock
        return {"max_faces": self.max_faces}

    def __setstate__(self, state):
        self.__init__(state["max_faces"])


def _cache() -> MeshCache:
    """This worker's cache (a plain one outside a worker: the tasks also run inline)."""
    try:
        from distributed import get_worker

        return get_worker().plugins[PLUGIN_NAME]  # type: ignore[return-value]
    except (ImportError, ValueError, KeyError):
        return MeshCache()


def one_line(exc: BaseException) -> str:
    """An exception as one line of at most 300 characters; anything but an
    :class:`~hsr.errors.HsrError` (an hsr bug, a worker lost) is named by its type."""
    from ..errors import HsrError

    text = " ".join(str(exc).split())
    if not isinstance(exc, (HsrError, OSError)) or not text:
        text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def place_cameras(scene, placement, size, views=None) -> list:
    """The cameras of a model: ``("set", kind, count, elevation, up_axis)`` frames a view
    set around the scene, turning about ``up_axis`` (None: the scene's own), the same
    cameras on every worker (the same function of the same bounds; only ``views``, when
    given, are framed); ``("all", cameras)`` / ``("these", cameras)`` are cameras as
    given, those from a file without planes fitted to the scene
    (:class:`~hsr.batch.plan.Unfitted`). Returns the cameras of ``views`` (default all)."""
    from ..scene import views as view_sets
    from .plan import Unfitted, placed

    if placement[0] in ("all", "these"):
        chosen = list(placement[1])
        if placement[0] == "all" and views is not None:
            chosen = [chosen[v] for v in views]
        bounds = scene.bounds() if any(isinstance(c, Unfitted) for c in chosen) else None
        return [placed(c, bounds) for c in chosen]
    _, kind, count, elevation, *up_axis = placement
    up = view_sets.model_up(scene, up_axis[0] if up_axis else None)
    dirs = view_sets.directions(kind, count, elevation, up_axis=up)
    bounds = scene.bounds()
    return [view_sets.framed(bounds, dirs[v], size[0] / size[1], up_axis=up)
            for v in (range(count) if views is None else views)]


def render_task(path: str, stem: str, views: list, placement, describe: bool, size,
                outputs, out_dir: str, fmt: str, options: dict) -> dict:
    """Load the model (once per worker), place its cameras, render ``views`` and write
    their outputs: ``{"rows": [...]}`` (one manifest row per view: status ``ok`` or
    ``failed`` with a one-line error, milliseconds), with ``"cameras"`` (all of the
    model's) when ``describe``; ``{"error": one line}`` when the model cannot be loaded or
    its cameras placed."""
    start = time.perf_counter()
    try:
        scene = _cache().get(path)
        # The files the model was read from (.mtl, textures, buffers) stay outside what
        # this job writes (the model itself was checked where the job started).
        check_outside(scene.sources(), job_targets(out_dir, stem, fmt))
        # ("these", cameras): just this task's views' cameras, in order.
        cameras = place_cameras(scene, placement, size) if describe else None
        mine = (place_cameras(scene, placement, size) if placement[0] == "these"
                else [cameras[v] for v in views] if cameras is not None
                else place_cameras(scene, placement, size, views))
    except Exception as exc:  # noqa: BLE001 - any failure of one model is its manifest row
        return {"error": one_line(exc)}
    done: dict = {"rows": render_group(scene, path, stem, views, mine, size, outputs, out_dir,
                                 fmt, options)}
    if describe:
        done["cameras"] = cameras
    done["task_ms"] = (time.perf_counter() - start) * 1000.0  # load, cameras, views
    return done


def buffers(frame, outputs):
    """Output name -> array of a frame."""
    source = {"color": lambda: frame.color, "window_depth": lambda: frame.depth,
              "eye_depth": lambda: frame.eye_depth, "distance": lambda: frame.distance,
              "normals": lambda: frame.normals, "ids": lambda: frame.face_id,
              "object_ids": lambda: frame.object_id}
    return {name: source[name]() for name in outputs}


def write_files(out_dir, stem, view, arrays) -> None:
    """Each output of one view as its own file (the folders exist: see render_group)."""
    from PIL import Image

    for name, array in arrays.items():
        path = output_path(out_dir, stem, name, view)
        if OUTPUTS[name][0] == ".png":
            write_atomic(path, lambda f, a=array: Image.fromarray(a).save(f, format="PNG"))
        else:
            write_atomic(path, lambda f, a=array: np.save(f, a))


def write_zarr(store, view, arrays) -> None:
    """Each output's chunk of this view, then the view's ``done`` mark: a view without its
    mark is redone by ``resume`` (zarr writes a chunk as one file, but the mark makes the
    whole view one unit)."""
    import zarr

    group = zarr.open_group(store, mode="r+")
    for name, array in arrays.items():
        # Every chunk is written, one of background alone too (zarr skips chunks equal to
        # the fill value by default), so that a resumed run can tell a lost chunk.
        group[name].with_config(  # type: ignore[union-attr]  # an array, made by plan
            {"write_empty_chunks": True})[view] = array
    group["done"][view] = 1


def render_group(scene, path: str, stem: str, views: list, cameras: list, size, outputs,
                 out_dir: str, fmt: str, options: dict) -> list:
    """Render ``views`` (indices, with their ``cameras``) of one loaded model and write the
    outputs; one manifest row per view. Each render runs single-threaded: the parallelism
    is Dask's, a worker thread per core (a multithreaded render in each of several worker
    threads oversubscribed the cores and, for small views, spent more on thread hand-offs
    than on the view)."""
    from ..parallel import Workspace
    from ..render import render

    rows = []
    width, height = size
    store = os.path.join(out_dir, f"{stem}.zarr") if fmt == "zarr" else None
    if store is None:
        for name in outputs:
            os.makedirs(os.path.dirname(output_path(out_dir, stem, name, 0)), exist_ok=True)
    with Workspace(1) as workspace:  # scratch kept from view to view
        for view, camera in zip(views, cameras):
            rows.append(_render_view(render, scene, path, stem, view, camera, width, height,
                                     outputs, out_dir, store, options, workspace))
    return rows


def _render_view(render, scene, path, stem, view, camera, width, height, outputs, out_dir,
                 store, options, workspace) -> dict:
    """One view of :func:`render_group`, rendered and written: its manifest row."""
    start = time.perf_counter()
    try:
        frame = render(scene, camera, width, height, threads=1, workspace=workspace,
                       **options)
        arrays = buffers(frame, outputs)
        if store is None:
            write_files(out_dir, stem, view, arrays)
        else:
            write_zarr(store, view, arrays)
        return {"model": path, "view": view, "status": "ok", "error": None,
                "ms": round((time.perf_counter() - start) * 1000.0, 3)}
    except Exception as exc:  # noqa: BLE001 - one view's failure is its manifest row
        return {"model": path, "view": view, "status": "failed", "error": one_line(exc),
                "ms": round((time.perf_counter() - start) * 1000.0, 3)}
