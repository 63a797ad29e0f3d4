"""The client side of a batch: start (or use) a Dask cluster, plan each model on a worker,
send groups of views as tasks, collect the manifest rows as they finish, and write the
manifest. The scheduling, retries after a lost worker and data movement are Dask's
(``dask.distributed``); hsr only says what each task is."""

from __future__ import annotations

import json
import os
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

from ..errors import OutputError
from ..parallel import progress_bar
from ..scene.outputs import check_outside, check_store_target
from ..scene.partitioned import is_partitioned, open_partitioned, store_kind
from .plan import (
    FORMATS,
    OUTPUT_ARRAYS,
    BatchError,
    check_outputs,
    check_size,
    group_views,
    job_targets,
    model_stems,
    output_complete,
    output_path,
    parse_views,
    probe_options,
)

__all__ = ["render_views", "BatchResult", "local_cluster", "STORE_KIND"]

# The kind written into a batch's Zarr store, by which a later run recognises its own.
STORE_KIND = "hsr-batch-views"


@dataclass
class BatchResult:
    """What a batch did: one manifest row per view (``model``, ``view``, ``status`` ok /
    failed / skipped, ``error``, ``ms``), where the manifest is, and the wall time."""

    rows: list = field(default_factory=list)
    manifest: str = ""
    seconds: float = 0.0
    task_seconds: float = 0.0  # time inside the tasks (loads, cameras, views), all workers

    @property
    def failed(self) -> int:
        return sum(r["status"] == "failed" for r in self.rows)

    @property
    def rendered(self) -> int:
        return sum(r["status"] == "ok" for r in self.rows)

    @property
    def skipped(self) -> int:
        return sum(r["status"] == "skipped" for r in self.rows)

    @property
    def views_per_second(self) -> float:
        return self.rendered / self.seconds if self.seconds > 0 else 0.0

    def summary(self) -> str:
        total = len(self.rows)
        text = (f"{self.rendered:,} of {total:,} views rendered in {self.seconds:.1f} s "
                f"({self.views_per_second:.1f} views/s)")
        if self.skipped:
            text += f", {self.skipped:,} already done"
        if self.failed:
            text += f"; {self.failed:,} of {total:,} views failed; see {self.manifest}"
        return text


# Views of at least this many pixels run on threads of one in-process worker by default;
# smaller ones on one single-threaded worker process per core (benchmarks/bench_batch.py).
THREADED_PIXELS = 512 * 512


def local_cluster(workers: int | None = None, pixels: int = 0):
    """A Dask cluster on this machine for views of ``pixels`` pixels, with ``workers``
    (default one per core) threads or processes. Measured on 2 cores
    (benchmarks/bench_batch.py): a small view is mostly Python (camera, buffers, file
    creation) and holds the GIL, so one single-threaded worker process per core is 1.4 to
    1.8x a plain loop where threads in one process are not faster than it; a large view is
    mostly compiled kernels and PNG compression, which release the GIL, so threads of one
    worker inside this process do as well as processes and start seconds sooner (no
    processes to spawn, Numba's kernels and the model already at hand): the bunny at
    512 x 512, orbit:128 from cold, 4.8 s against 8.4 s. Processes listen on 127.0.0.1
    only; the in-process worker uses no socket; the dashboard binds 127.0.0.1."""
    from distributed import LocalCluster

    cores = os.cpu_count() or 1
    n = cores if workers is None else workers
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= 1024:
        raise BatchError(f"workers must be an integer in 1..1024, got {workers!r}")
    if pixels >= THREADED_PIXELS:
        return LocalCluster(n_workers=1, threads_per_worker=n, processes=False,
                            dashboard_address="127.0.0.1:0", silence_logs=40)
    return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                        dashboard_address="127.0.0.1:0", silence_logs=40)


def render_views(models, views, size=(512, 512), outputs=("color",), out="batch",
                 client=None, *, format="files", resume=False, workers=None,
                 progress=None, near=None, far=None, views_per_task=None, force=False,
                 up_axis=None, **render_options) -> BatchResult:
    """Render every model from every view, on a Dask cluster, writing the outputs to
    ``out`` (see docs/guide/batch.md for the layout).

    ``models``: paths every worker can read (each is loaded once per worker). ``views``:
    ``orbit:N[:ELEVATION]``, ``sphere:N``, ``hemisphere:N``, a transforms.json or COLMAP
    folder, ``per-model:FILE``, a list of :class:`hsr.Camera` or a dict of them per
    model (see :func:`hsr.batch.plan.parse_views`). ``outputs``: names from
    :data:`hsr.batch.plan.OUTPUTS`. ``client``: any ``distributed.Client``; without one a
    local cluster of ``workers`` (default one per core) runs the job and is closed after
    it (see :func:`local_cluster`).
    ``format``: ``files`` or ``zarr``. ``resume``: skip views whose outputs all exist.
    ``force``: replace a model's Zarr store (``OUT/<stem>.zarr``) that a batch wrote
    before; a store is never written where another folder or a file is (see
    :mod:`hsr.scene.outputs`), and no input is, or lies inside, what the job writes.
    ``views_per_task``: views in one task (default: about 4 M pixels, at least four tasks
    per worker thread). ``near`` / ``far``: the planes of cameras from files; a file that
    names none has them fitted to each model (:meth:`hsr.Camera.fitted`). ``up_axis``:
    ``y`` or ``z`` for the view sets, None for each model's own (:func:`hsr.load`).
    ``render_options`` go to :func:`hsr.render` (algorithm, cull, shading, light, ...).
    Results are bit for bit ``hsr.render``'s with the same camera and options.

    Raises :class:`~hsr.batch.plan.BatchError` for malformed views, outputs, models or
    format, :class:`~hsr.errors.CameraError` for a bad camera file,
    :class:`~hsr.errors.RenderError` for render options ``hsr.render`` refuses, and
    :class:`~hsr.errors.OutputError` when ``out`` cannot be written. A model or view that
    fails is a ``failed`` row of the manifest, never an exception.
    """
    models = [os.fspath(m) for m in ([models] if isinstance(models, (str, os.PathLike))
                                     else models)]
    if not models:
        raise BatchError("no models given")
    for m in models:  # a folder is a store: opened (and checked) here, or refused here
        if os.path.isdir(m) and not is_partitioned(m):
            open_partitioned(m, check_parts=False)
    partitioned = [m for m in models if is_partitioned(m)]
    if partitioned and len(models) > 1:
        raise BatchError(f"a partitioned scene ({partitioned[0]}) renders on its own: give "
                         f"it as the only model")
    width, height = check_size(size)
    outputs = check_outputs(outputs)
    if format not in FORMATS:
        raise BatchError(f"format must be one of {', '.join(FORMATS)}, got {format!r}")
    stems = model_stems(models)
    if views_per_task is not None and (isinstance(views_per_task, bool) or not isinstance(
            views_per_task, int) or not 1 <= views_per_task <= 100_000):
        raise BatchError(f"views_per_task must be an integer in 1..100000, got "
                         f"{views_per_task!r}")
    spec = parse_views(views, models, near, far, up_axis=up_axis)
    probe_options(render_options)
    out = os.fspath(out)
    _check_targets(models, views, stems, out, format, force or resume)
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"cannot write to {out}: {exc}") from None
    if progress is None:
        progress = sys.stderr.isatty()

    if partitioned:
        # Without a client: --workers N local processes share the parts, else part
        # after part in this process.
        with _client_for(client, workers, 0, own=workers is not None) as job_client:
            return _run_partitioned(job_client, models[0], stems, spec, (width, height),
                                    outputs, out, render_options, views_per_task, progress,
                                    format, resume)
    start = time.perf_counter()
    with _client_for(client, workers, width * height, own=True) as job_client:
        rows, task_seconds = _run(job_client, models, stems, spec, (width, height), outputs,
                                  out, format, resume, render_options, progress,
                                  views_per_task)
    result = BatchResult(rows, os.path.join(out, "manifest.json"), time.perf_counter() - start,
                         task_seconds)
    _write_manifest(result, spec, (width, height), outputs, format, render_options)
    return result


def _check_targets(models, views, stems, out, fmt, replace) -> None:
    """Before any work: no input (a model, a camera file) is or lies inside what the job
    writes, and each Zarr store is written only where nothing, an empty folder or (with
    ``replace``: --force or --resume) a batch store is."""
    inputs = list(models)
    if isinstance(views, (str, os.PathLike)):
        spec = os.fspath(views)
        spec = spec[len("per-model:"):] if spec.startswith("per-model:") else spec
        if os.path.lexists(spec):
            inputs.append(spec)
    for model in models:
        target = os.path.abspath(os.path.join(out, f"{stems[model]}.zarr"))
        if fmt == "zarr" and is_partitioned(model) and target == os.path.abspath(model):
            raise BatchError(f"--format zarr would write {target}, the partitioned scene "
                             f"itself: choose another --out")
        check_outside(inputs, job_targets(out, stems[model], fmt))
        if fmt == "zarr":
            check_store_target(target, replace, lambda p: store_kind(p) == STORE_KIND,
                               "--out", "batch store")


@contextmanager
def _client_for(client, workers, pixels: int, own: bool):
    """``client`` when given; else, when ``own``, a client of a local cluster for views of
    ``pixels`` pixels (:func:`local_cluster`), closed with its cluster after the job;
    else None."""
    if client is not None or not own:
        yield client
        return
    from distributed import Client

    cluster = local_cluster(workers, pixels)
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def _run(client, models, stems, spec, size, outputs, out, fmt, resume, options, progress,
         views_per_task) -> tuple:
    """(manifest rows, seconds spent inside the tasks). Every task is sent at once: the
    views still to do are known on the client (the count comes from the spec, resume
    looks at the files), and each task places its
    model's cameras itself from the spec (on every worker the same function of the same
    bounds gives the same cameras), so no task waits for another and each worker loads a
    model at most once. One task per model also returns all the cameras, for the
    transforms.json (and the zarr attributes)."""
    from distributed import as_completed

    from .tasks import MeshCache, render_task

    client.register_plugin(MeshCache())
    n_workers = max(1, sum(w.get("nthreads", 1) for w in
                           client.scheduler_info().get("workers", {}).values()))
    job_views = sum(spec.count_for(m) for m in models)
    bar = progress_bar(progress, job_views, "hsr batch")
    rows, tasks, busy = [], {}, 0.0  # tasks: task -> (model, the views it renders)
    for model in models:
        count = spec.count_for(model)
        todo = _todo(out, stems[model], count, size, outputs, fmt, resume)
        skipped = sorted(set(range(count)) - set(todo))
        rows += [{"model": model, "view": v, "status": "skipped", "error": None, "ms": 0.0}
                 for v in skipped]
        bar.update(len(skipped))
        given = (spec.per_model[model] if spec.kind == "per-model"
                 else spec.cameras if spec.kind == "cameras" else None)
        groups = group_views(todo, size[0], size[1], n_workers, job_views, views_per_task,
                             _size_of(model))
        for k, group in enumerate(groups or [[]]):
            # Given cameras travel with their views only (the describing task: all of
            # them), never the whole job's.
            placement = (_set_of(spec) if given is None else ("all", list(given)) if k == 0
                         else ("these", [given[v] for v in group]))
            task = client.submit(render_task, model, stems[model], group, placement, k == 0,
                                 size, outputs, out, fmt, options, pure=False)
            tasks[task] = (model, group)
    for future in as_completed(list(tasks)):
        model, group = tasks.pop(future)
        done = _outcome(future)
        if "error" in done:  # the model, or the task itself (e.g. its worker kept dying)
            done = {"rows": [{"model": model, "view": v, "status": "failed",
                              "error": done["error"], "ms": 0.0} for v in group]}
        if "cameras" in done:
            _describe(out, stems[model], done["cameras"], size, outputs, fmt)
        rows += done["rows"]
        busy += done.get("task_ms", 0.0) / 1000.0
        bar.update(len(done["rows"]))
    bar.close()
    if fmt == "files":
        _remove_stale_temporaries(out, [stems[m] for m in models], outputs)
    order = {model: k for k, model in enumerate(models)}
    rows.sort(key=lambda r: (order[r["model"]], r["view"]))
    return rows, busy


def _set_of(spec) -> tuple:
    """The placement of a view set: framed round each model on its worker."""
    return ("set", spec.kind, spec.count, spec.elevation, spec.up_axis)


def _run_partitioned(client, store_path, stems, spec, size, outputs, out, options,
                     views_per_task, progress, fmt, resume) -> BatchResult:
    """``render_views`` of one partitioned scene: sort-last on ``client`` (or here without
    one, part after part), the composited frames written on the client as a plain
    model's would be; each view's manifest row names the parts its task group rendered,
    the faces they loaded and their milliseconds."""
    from .sortlast import OUTPUTS as COMPOSITED
    from .sortlast import each_partitioned
    from .tasks import buffers, place_cameras, write_files, write_zarr

    start = time.perf_counter()
    store = open_partitioned(store_path)
    stem = stems[store_path]
    given = (spec.per_model[store_path] if spec.kind == "per-model"
             else spec.cameras if spec.kind == "cameras" else None)
    placement = _set_of(spec) if given is None else ("all", list(given))
    cameras = place_cameras(store, placement, size)
    per_task = views_per_task or max(1, (4 << 20) // (size[0] * size[1]))
    todo = _todo(out, stem, len(cameras), size, outputs, fmt, resume)
    rows = [{"model": store_path, "view": v, "status": "skipped", "error": None, "ms": 0.0}
            for v in sorted(set(range(len(cameras))) - set(todo))]
    busy = 0.0
    if fmt == "files":
        for name in outputs:
            os.makedirs(os.path.dirname(output_path(out, stem, name, 0)), exist_ok=True)
    zarr_store = os.path.join(out, f"{stem}.zarr")
    # Each group is written as it is composited and dropped: the client holds a group.
    groups = each_partitioned(store, [cameras[v] for v in todo], size[0], size[1],
                              outputs=tuple(o for o in outputs if o in COMPOSITED),
                              client=client, views_per_task=per_task, progress=progress,
                              **options) if todo else ()
    for first, frames in groups:
        busy += sum(s["ms"] for s in frames[0].stats) / 1000.0
        for k, frame in enumerate(frames, first):
            view = todo[k]
            arrays = buffers(frame, outputs)  # a CompositeFrame has hsr.Frame's names
            if fmt == "files":
                write_files(out, stem, view, arrays)
            else:
                write_zarr(zarr_store, view, arrays)
            rows.append({"model": store_path, "view": view, "status": "ok", "error": None,
                         # the view's share of its group's part renders
                         "ms": round(sum(s["ms"] / s["views"] for s in frame.stats), 3),
                         "parts": [s["part"] for s in frame.stats],
                         "faces_loaded": [s["faces_loaded"] for s in frame.stats]})
    rows.sort(key=lambda r: r["view"])
    _describe(out, stem, cameras, size, outputs, fmt)
    if fmt == "files":
        _remove_stale_temporaries(out, [stem], outputs)
    result = BatchResult(rows, os.path.join(out, "manifest.json"),
                         time.perf_counter() - start, busy)
    _write_manifest(result, spec, size, outputs, fmt, options)
    return result


def _size_of(model) -> int:
    """The model file's size, or 0 where the client cannot see it (the workers can)."""
    try:
        return os.path.getsize(model)
    except OSError:
        return 0


def _remove_stale_temporaries(out, stems, outputs) -> None:
    """Every task is finished: a temporary file still in an output folder was left by a
    worker killed while writing it (its task ran again elsewhere), so it goes."""
    for stem in stems:
        for name in outputs:
            folder = os.path.dirname(output_path(out, stem, name, 0))
            if not os.path.isdir(folder):
                continue
            for entry in os.scandir(folder):
                if entry.name.startswith(".") and entry.name.endswith(".tmp") \
                        and entry.is_file(follow_symlinks=False):
                    os.remove(entry.path)


def _outcome(future) -> dict:
    """The task's result, or ``{"error": one line}`` when the task raised or Dask gave it
    up (a worker lost too often): one task's failure never stops the job."""
    from .tasks import one_line

    try:
        return future.result()
    except Exception as exc:  # noqa: BLE001 - recorded in the manifest
        return {"error": one_line(exc)}


def _todo(out, stem, count, size, outputs, fmt, resume) -> list:
    """The views still to render (all of them unless ``resume``); for zarr, creates the
    model's store when it is not resumed."""
    if fmt == "zarr":
        return _prepare_zarr(out, stem, count, size, outputs, resume)
    if not resume:
        return list(range(count))
    return [v for v in range(count)
            if not all(output_complete(output_path(out, stem, o, v), o, size) for o in outputs)]


def _describe(out, stem, cameras, size, outputs, fmt) -> None:
    """The model's cameras beside its outputs: transforms.json (NeRF convention, the
    path of each view's first output), and for zarr the OpenGL matrices in the store's
    attributes."""
    import numpy as np

    from ..scene.camera_files import write_transforms

    folder = os.path.join(out, stem)
    os.makedirs(folder, exist_ok=True)
    width, height = size
    first = "color" if "color" in outputs else outputs[0]
    if not any(c.is_orthographic for c in cameras):
        write_transforms(os.path.join(folder, "transforms.json"), cameras, width, height,
                         [os.path.relpath(output_path(out, stem, first, v), folder)
                          for v in range(len(cameras))])
    if fmt == "zarr":
        import zarr

        group = zarr.open_group(os.path.join(out, f"{stem}.zarr"), mode="r+")
        aspect = width / height
        group.attrs["cameras"] = [{"view_matrix": c.view_matrix.tolist(),
                                   "projection_matrix": np.asarray(
                                       c.projection_matrix(aspect)).tolist()}
                                  for c in cameras]


def _prepare_zarr(out, stem, count, size, outputs, resume) -> list:
    """One Zarr v3 store per model: an array per output, (views, H, W[, C]) with one view
    per chunk, a ``done`` mark per view (the cameras are added by :func:`_describe`).
    ``resume`` keeps a matching store and returns the views not marked done, and those
    marked done whose chunks do not all read back (a chunk cut short or removed: every
    chunk is written, background ones too, so a missing one is a loss)."""
    import zarr

    width, height = size
    path = os.path.join(out, f"{stem}.zarr")
    n = count  # views
    if resume and os.path.isdir(path):
        try:
            return _zarr_todo(path, zarr.open_group(path, mode="r"), n, size, outputs)
        except Exception:  # noqa: BLE001 - a store that does not open is started afresh
            pass
    group = zarr.open_group(path, mode="w", zarr_format=3)
    for name in outputs:
        dtype, extra = OUTPUT_ARRAYS[name]
        fill = {"ids": -1, "object_ids": -1}.get(name, 0)
        group.create_array(name, shape=(n, height, width) + extra,
                           chunks=(1, height, width) + extra, dtype=dtype, fill_value=fill)
    group.create_array("done", shape=(n,), chunks=(1,), dtype="uint8", fill_value=0)
    group.attrs["size"] = [width, height]
    group.attrs["hsr"] = {"kind": STORE_KIND, "version": 1}  # how a later run knows it
    return list(range(n))


def _zarr_todo(store, group, n, size, outputs) -> list:
    """The views of a resumed store still to render (see :func:`_prepare_zarr`); raises
    when the store is not the one this job writes (then it is made anew)."""
    width, height = size
    if "done" not in group or group["done"].shape != (n,) or not all(
            o in group and group[o].shape == (n, height, width) + OUTPUT_ARRAYS[o][1]
            for o in outputs):
        raise BatchError("a different store")
    done = group["done"][:]
    todo = []
    for v in range(n):
        if done[v] and all(_chunk_reads(store, group[o], o, v) for o in outputs):
            continue
        todo.append(v)
    return todo


def _chunk_reads(store: str, array, name: str, view: int) -> bool:
    """Whether view ``view``'s chunk of the output array ``name`` (``array``) in the
    store folder ``store`` is there as a file and decodes."""
    key = array.metadata.encode_chunk_key((view,) + (0,) * (array.ndim - 1))
    if not os.path.isfile(os.path.join(store, name, *key.split("/"))):
        return False
    try:
        array[view]
    except Exception:  # noqa: BLE001 - a codec error of a cut chunk
        return False
    return True


def _write_manifest(result, spec, size, outputs, fmt, options) -> None:
    from importlib.metadata import PackageNotFoundError, version

    from ..scene.outputs import write_atomic

    try:
        hsr_version = version("hsr")
    except PackageNotFoundError:  # run from a source tree that is not installed
        hsr_version = "unknown"
    doc = {"hsr": hsr_version, "views": spec.text, "size": list(size),
           "outputs": list(outputs), "format": fmt,
           "render_options": {k: v if isinstance(v, (str, int, float, bool)) or v is None
                              else repr(v) for k, v in options.items()},
           "summary": {"views": len(result.rows), "rendered": result.rendered,
                       "skipped": result.skipped, "failed": result.failed,
                       "seconds": round(result.seconds, 3)},
           "tasks": result.rows}
    text = json.dumps(doc, indent=1).encode()
    write_atomic(result.manifest, lambda f: f.write(text))
