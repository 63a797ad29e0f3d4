"""What a batch will do, decided on the client before anything runs: which cameras each
model gets (a view-set spec, camera files, or cameras given in Python), which outputs are
written where, how views are grouped into tasks, and which views a resumed run skips.
Nothing here loads a mesh or renders."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import HsrError, RenderError
from ..scene.camera import Camera

__all__ = ["OUTPUTS", "FORMATS", "BatchError", "ViewSpec", "parse_views", "output_path",
           "group_views", "model_stems"]


class BatchError(HsrError):
    """A batch job is malformed (views, outputs, models, output folder)."""


# Output name -> (file extension, what it holds).
OUTPUTS = {
    "color": (".png", "(H, W, 3) uint8 colour image"),
    "window_depth": (".npy", "(H, W) float32 window depth, the clear depth on background"),
    "eye_depth": (".npy", "(H, W) float32 depth along the view axis, +inf on background"),
    "distance": (".npy", "(H, W) float32 distance from the eye, +inf on background"),
    "normals": (".npy", "(H, W, 3) float32 world-space unit normals, 0 on background"),
    "ids": (".npy", "(H, W) int32 face ids, -1 on background"),
    "object_ids": (".npy", "(H, W) int32 instance (node) index, -1 on background"),
}
FORMATS = ("files", "zarr")
_SETS = ("orbit", "sphere", "hemisphere")
MAX_VIEWS = 1_000_000


@dataclass(frozen=True)
class Unfitted:
    """A camera read from a file that names no planes (and none given to the call): each
    model's worker fits its near and far to that model (:meth:`hsr.Camera.fitted`), as
    ``--view`` framing does, so a millimetre scan and a kilometre terrain both show."""

    camera: Camera

    def on(self, bounds) -> Camera:
        return self.camera.fitted(bounds)


def file_cameras(cameras, fit, bounds) -> tuple:
    """Cameras read from a file: fitted to ``bounds`` where ``fit`` says so, or, with no
    bounds known yet (a batch job's models load on the workers), marked :class:`Unfitted`."""
    from ..scene.camera_files import fitted_where

    if bounds is not None:
        return tuple(fitted_where(cameras, fit, bounds))
    return tuple(Unfitted(c) if f else c for c, f in zip(cameras, fit))


def placed(camera, bounds) -> Camera:
    """A view's camera for a model of box ``bounds`` (an :class:`Unfitted` one fitted)."""
    return camera.on(bounds) if isinstance(camera, Unfitted) else camera


@dataclass(frozen=True)
class ViewSpec:
    """Views for every model: a view set computed from each model's bounds (``kind`` one
    of orbit / sphere / hemisphere, ``count``, ``elevation`` for orbit), or fixed
    ``cameras`` (the same for every model), or ``per_model`` cameras keyed by model path;
    ``size``: the image size a camera file gives (its first camera's), else None."""

    kind: str
    count: int = 0
    elevation: float = 20.0
    cameras: tuple = ()
    per_model: dict | None = None
    text: str = ""
    size: tuple | None = None
    up_axis: str | None = None

    def count_for(self, model: str) -> int:
        if self.kind in _SETS:
            return self.count
        if self.kind == "per-model":
            return len(self.per_model[model])  # type: ignore[index]  # set with the kind
        return len(self.cameras)


def parse_views(views: Any, models: list, near: float | None = None,
                far: float | None = None, bounds: Any = None,
                up_axis: str | None = None) -> ViewSpec:
    """A :class:`ViewSpec` from ``orbit:N[:ELEVATION]``, ``sphere:N``, ``hemisphere:N``,
    a transforms.json or COLMAP folder (the same cameras for every model),
    ``per-model:FILE`` (a JSON object from each model's path or file name to a
    transforms.json or COLMAP folder, relative to FILE), a list of :class:`hsr.Camera`,
    or a dict from model path to such a list. Raises :class:`BatchError` for anything
    else, and :class:`~hsr.errors.CameraError` for a bad camera file or bad ``near`` /
    ``far`` (the planes of cameras read from files, None for the file's own or, where it
    has none, fitted to the box ``bounds`` when given, else to each model; checked
    whatever the views); ``up_axis`` (``y``, ``z`` or None for each model's own) orients
    a view set."""
    from ..scene.camera import check_perspective_planes
    from ..scene.camera_files import colmap_cameras, transforms_cameras
    from ..scene.views import check_up_axis

    check_perspective_planes(near, far)
    if up_axis is not None:
        check_up_axis(up_axis)

    if isinstance(views, dict):
        return ViewSpec("per-model", per_model=_per_model(views, models), text="per-model")
    if isinstance(views, (list, tuple)):
        return ViewSpec("cameras", cameras=_cameras(views, "views"), text="cameras")
    if not isinstance(views, str) or not views:
        raise BatchError(f"views must be a spec string, a list of cameras or a dict of them, "
                         f"got {type(views).__name__}")
    head, _, rest = views.partition(":")
    if head in _SETS:
        parts = rest.split(":") if rest else []
        if not parts or len(parts) > (2 if head == "orbit" else 1):
            raise BatchError(f"views {views!r}: use {head}:N" + ("[:ELEVATION]"
                                                                if head == "orbit" else ""))
        count = _int(parts[0], f"views {views!r}: N")
        if not 1 <= count <= MAX_VIEWS:
            raise BatchError(f"views {views!r}: N must be in 1..{MAX_VIEWS}")
        elevation = 20.0
        if len(parts) == 2:
            elevation = _float(parts[1], f"views {views!r}: ELEVATION")
            if not -90.0 <= elevation <= 90.0:
                raise BatchError(f"views {views!r}: ELEVATION must be in -90..90 degrees")
        return ViewSpec(head, count, elevation, text=views, up_axis=up_axis)
    if head == "per-model":
        return ViewSpec("per-model", per_model=_per_model_file(rest, models, near, far),
                        text=views)
    if os.path.isdir(views):
        cameras, _, sizes, fit = colmap_cameras(views, near, far)
        return ViewSpec("cameras", cameras=file_cameras(cameras, fit, bounds), text=views,
                        size=sizes[0])
    if os.path.exists(views):
        cameras, _, size, fit = transforms_cameras(views, near, far)
        return ViewSpec("cameras", cameras=file_cameras(cameras, fit, bounds), text=views,
                        size=size)
    raise BatchError(f"views {views!r}: not orbit:N[:EL], sphere:N, hemisphere:N, "
                     f"per-model:FILE, nor an existing transforms.json or COLMAP folder")


def _int(text, what) -> int:
    try:
        return int(text)
    except ValueError:
        raise BatchError(f"{what} must be an integer, got {text!r}") from None


def _float(text, what) -> float:
    try:
        value = float(text)
    except ValueError:
        raise BatchError(f"{what} must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise BatchError(f"{what} must be finite, got {text!r}")
    return value


def _cameras(items, what) -> tuple:
    items = tuple(items)
    if not items or not all(isinstance(c, (Camera, Unfitted)) for c in items):
        raise BatchError(f"{what}: a non-empty list of hsr.Camera is needed")
    for cam in items:
        (cam.camera if isinstance(cam, Unfitted) else cam).validate()
    return items


def _per_model(mapping, models) -> dict:
    out = {}
    for model in models:
        keys = [k for k in (model, os.path.basename(model)) if k in mapping]
        if not keys:
            raise BatchError(f"views: no cameras for model {model!r}")
        out[model] = _cameras(mapping[keys[0]], f"views for {model!r}")
    return out


def _per_model_file(path, models, near, far) -> dict:
    from ..scene.camera_files import colmap_cameras, transforms_cameras
    from ..scene.files import read_regular

    try:
        doc = json.loads(read_regular(path, "per-model views file", 64 << 20, BatchError))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise BatchError(f"{path}: not JSON ({exc})") from None
    if not isinstance(doc, dict) or not all(isinstance(v, str) for v in doc.values()):
        raise BatchError(f"{path}: must be a JSON object from model to a transforms.json or "
                         f"COLMAP folder")
    folder = os.path.dirname(os.path.abspath(path))
    mapping = {}
    for key, target in doc.items():
        target = os.path.join(folder, target)
        read = colmap_cameras if os.path.isdir(target) else transforms_cameras
        cameras, _, _, fit = read(target, near, far)
        mapping[key] = file_cameras(cameras, fit, None)
    return _per_model(mapping, models)


def check_outputs(outputs) -> tuple:
    """The output names, checked (at least one, no repeats, each known)."""
    if isinstance(outputs, str):
        outputs = [o for o in outputs.split(",") if o]
    try:
        outputs = tuple(outputs)
    except TypeError:
        raise BatchError(f"outputs must be names from {', '.join(OUTPUTS)} (a list or a "
                         f"comma-separated string), got {outputs!r}") from None
    unknown = [o for o in outputs if o not in OUTPUTS]
    if not outputs or unknown or len(set(outputs)) != len(outputs):
        raise BatchError(f"outputs must be distinct names from {', '.join(OUTPUTS)}; "
                         f"got {', '.join(map(str, outputs)) or 'none'}")
    return outputs


def model_stems(models) -> dict:
    """Model path -> its folder name under the output folder (the file's stem); two models
    with one stem are refused rather than written over each other."""
    stems: dict = {}
    for model in models:
        stem = os.path.splitext(os.path.basename(os.fspath(model)))[0] or "model"
        if stem in stems.values():
            other = next(m for m, s in stems.items() if s == stem)
            raise BatchError(f"models {other!r} and {model!r} would both write to "
                             f"{stem}/: rename one")
        stems[model] = stem
    return stems


def job_targets(out_dir, stem, fmt) -> list:
    """What a job writes for the model ``stem``: its folder (``OUT/<stem>``: the files,
    transforms.json), its store for zarr (``OUT/<stem>.zarr``) and the manifest. No input
    may be or lie inside any of them."""
    targets = [os.path.join(out_dir, stem), os.path.join(out_dir, "manifest.json")]
    return targets + ([os.path.join(out_dir, f"{stem}.zarr")] if fmt == "zarr" else [])


def output_path(out_dir, stem, output, view) -> str:
    """``OUT/<stem>/<output>/<view:04d><ext>``."""
    return os.path.join(out_dir, stem, output, f"{view:04d}{OUTPUTS[output][0]}")


# What each output holds: (dtype, trailing shape) of its array.
OUTPUT_ARRAYS = {"color": ("uint8", (3,)), "window_depth": ("float32", ()),
                 "eye_depth": ("float32", ()), "distance": ("float32", ()),
                 "normals": ("float32", (3,)), "ids": ("int32", ()),
                 "object_ids": ("int32", ())}


_PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def output_complete(path: str, output: str, size) -> bool:
    """Whether the file ``path`` is a whole ``output`` of a ``size`` view, as a resumed
    batch must know before it skips the view: a PNG that decodes to the size in RGB, an
    NPY whose header gives the shape and dtype and whose data is all there. A file cut
    short by a killed process, of another size, or not of its kind is not complete
    (writes are atomic, so this only happens to files changed by something else)."""
    width, height = size
    dtype, trailing = OUTPUT_ARRAYS[output]
    try:
        if not os.path.isfile(path):
            return False
        if OUTPUTS[output][0] == ".png":
            from PIL import Image

            with open(path, "rb") as fh:  # a PNG ends with its IEND chunk (PNG spec 5.6)
                fh.seek(max(0, os.path.getsize(path) - len(_PNG_END)))
                if fh.read() != _PNG_END:
                    return False
            with Image.open(path) as img:
                if img.size != (width, height) or img.mode != "RGB":
                    return False
                img.load()  # the whole stream: a cut file fails here
            return True
        array = np.load(path, mmap_mode="r", allow_pickle=False)  # fails on short data
        return array.shape == (height, width) + trailing and array.dtype == np.dtype(dtype)
    except (OSError, ValueError, SyntaxError, EOFError):  # unreadable: render it again
        return False


# Rough costs on one core of this project's machine, for sizing tasks only (ratios matter,
# not the values): a view costs about 30 ns a pixel (the bunny at 1024 x 1024: 21 ms to
# render, about 9 ms to write ids and eye depth; smaller views cost more a pixel, which
# only makes tasks larger than this rule needs, and the spread rule caps them), and an OBJ
# loads at about 8 MB/s (the bunny's 2.4 MB in 0.31 s; binary glTF is faster).
VIEW_SECONDS_PER_PIXEL = 3e-8
LOAD_SECONDS_PER_BYTE = 1.25e-7
LOAD_SHARE = 0.1  # a task renders views worth at least ten times its model's load


def group_views(views, width, height, workers, job_views=None, per_task=None,
                model_bytes=0) -> list:
    """Views (indices) of one model in tasks. A task renders about 4 M pixels (a 512 x
    512 view takes milliseconds; a task costs the scheduler about a millisecond), at most
    64 views, and at least enough views that loading its model (``model_bytes``, once on
    each worker that runs one of its tasks) stays under a tenth of the task: on a large
    cluster a model's tasks land on as many workers as there are tasks, each loading it.
    Over the whole job (``job_views``, default these views) there are still at least four
    tasks per worker, so every worker has work and a lost worker costs little; that rule
    wins when they disagree. ``per_task`` overrides all of it."""
    views = list(views)
    if not views:
        return []
    if per_task is None:
        pixels = max(1, width * height)
        by_pixels = min(64, max(1, (4 << 20) // pixels))
        view_s = pixels * VIEW_SECONDS_PER_PIXEL
        by_load = math.ceil(model_bytes * LOAD_SECONDS_PER_BYTE / (LOAD_SHARE * view_s))
        total = len(views) if job_views is None else max(job_views, len(views))
        by_spread = max(1, math.ceil(total / (4 * max(1, workers))))
        per_task = max(1, min(by_spread, max(by_pixels, by_load)))
    return [views[k:k + per_task] for k in range(0, len(views), per_task)]


def check_size(size) -> tuple:
    from ..geometry.viewport import check_size as check_image

    try:
        width, height = (int(v) for v in size)
    except (TypeError, ValueError):
        raise BatchError(f"size must be (width, height), got {size!r}") from None
    check_image(width, height)
    return width, height


def probe_options(options: dict) -> None:
    """Refuse render options ``hsr.render`` refuses (a typo, a bad value) before any
    work is sent out: one render of one triangle at 1 x 1 pixel with them."""
    from ..render import render
    from ..scene.mesh import Mesh

    for name in ("threads", "into", "counts", "workspace"):
        if name in options:
            raise RenderError(f"{name} is not a batch render option")
    tri = Mesh(np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]]),
               np.array([[0, 1, 2]]))
    render(tri, Camera.look_at((0, 0, 3), (0, 0, 0)), 1, 1, threads=1, **options)
