"""What the viewer draws: the scenes it may show (the models named on its command line,
loaded once, and the built-in scenes), one request rendered into the chosen buffer as an
image with its stats, a pixel picked, an explanation view, and the command line and
Python call that reproduce a view."""

from __future__ import annotations

import io
import math
import os
import shlex
import threading
import time

import numpy as np

from .params import ViewRequest, orbit_camera

__all__ = ["Library", "render_request", "pick", "explain_image", "encode", "reproduce",
           "pixel_camera", "id_colors"]


class Library:
    """The scenes a viewer serves, by name: each MODEL file (named by its file name,
    loaded now, so a bad file fails at start) and each built-in scene (built on first
    use). Nothing else can be named: no path ever comes from a request."""

    def __init__(self, models=(), builtin=True, up_axis="auto"):
        from ..scene import builtin as scenes
        from ..scene.load import load_scene

        self._scenes, self._paths, self._lock = {}, {}, threading.Lock()
        self._bounds, self._cameras = {}, {}
        for path in models:
            name = os.path.basename(os.fspath(path))
            if name in self._scenes:
                name = os.fspath(path)
            self._scenes[name] = load_scene(path, up_axis=up_axis)
            self._paths[name] = os.fspath(path)
        self._builtin = dict(scenes.SCENES) if builtin else {}
        self.names = list(self._scenes) + [n for n in self._builtin if n not in self._scenes]

    def get(self, name: str):
        with self._lock:
            if name not in self._scenes:
                self._scenes[name], self._cameras[name] = self._builtin[name]()
            return self._scenes[name]

    def initial(self, name: str) -> dict:
        """The orbit controls a scene opens with: a built-in scene's own camera (the
        seeds' view of it), else a model's first look, from the side that shows the most
        of its shape (:func:`hsr.best_view`, as ``hsr render MODEL`` draws it), found
        once per model."""
        from ..appearance.viewpoint import best_view
        from .params import orbit_of

        if name in self._paths:
            scene = self.get(name)
            with self._lock:
                if name not in self._cameras:
                    az, el = best_view(scene)
                    self._cameras[name] = {"az": float(az), "el": float(el)}
                return dict(self._cameras[name])
        if name not in self._builtin:
            return {}
        bounds = self.bounds(name)
        return orbit_of(bounds, self._cameras[name])

    def bounds(self, name: str):
        """The scene's bounding box, computed once (the camera orbits its sphere)."""
        scene = self.get(name)
        with self._lock:
            if name not in self._bounds:
                self._bounds[name] = scene.bounds()
            return self._bounds[name]

    def path(self, name: str) -> str | None:
        """The file a model was loaded from (None for a built-in scene)."""
        return self._paths.get(name)


def _fog(bounds, camera, request: ViewRequest):
    from ..appearance.fog import Fog

    if request.fog == "none":
        return None
    lo, hi = bounds
    centre, radius = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-9)
    d = float(np.linalg.norm(np.asarray(camera.eye) - centre))
    if request.fog == "linear":
        return Fog("linear", start=max(d - radius, 0.0), end=d + radius)
    return Fog(request.fog, density=request.fog_density / radius)


def _options(bounds, camera, request: ViewRequest) -> dict:
    return dict(algorithm=request.algorithm, shading=request.shading,
                light=request.light, fog=_fog(bounds, camera, request),
                hidden_line=request.hidden_lines or None,
                occlusion_cull=request.occlusion_cull, transparency=request.transparency,
                **request.state_fields())


def render_request(scene, request: ViewRequest, bounds=None) -> tuple:
    """``(frame, image (H, W, 3) uint8, stats)`` of ``request`` on ``scene``. Raises what
    :func:`hsr.render` raises for a state the algorithm cannot honour."""
    from ..explain.compare import difference_map
    from ..explain.views import heat
    from ..render import render

    start = time.perf_counter()
    bounds = scene.bounds() if bounds is None else bounds
    camera = orbit_camera(bounds, request, scene.up_axis())
    w, h = request.w, request.h
    options = _options(bounds, camera, request)
    buffer = request.buffer
    extra: dict = {}
    image: np.ndarray | None
    if buffer == "overdraw":
        frame = render(scene, camera, w, h, counts=True, **options)
        tested: np.ndarray = frame.fragments.count_tested  # type: ignore[union-attr,assignment]
        image = heat(tested, max(int(tested.max()), 1))
        extra["max_fragments_per_pixel"] = int(tested.max())
    else:
        if buffer == "painter_error":
            options["algorithm"] = "painter"
        frame = render(scene, camera, w, h, **options)
        image = None if buffer in ("painter_error", "zbuffer_diff") else \
            _buffer_image(frame, buffer)
        if options["algorithm"] != "zbuffer":
            # Every other algorithm is measured against the z-buffer, live: painter's
            # failures are counted and shown, never hidden.
            reference = render(scene, camera, w, h, **dict(options, algorithm="zbuffer"))
            covered = (frame.face_id >= 0) | (reference.face_id >= 0)
            extra["pixels_differing_from_zbuffer"] = int(
                np.count_nonzero((frame.face_id != reference.face_id) & covered))
            if image is None:
                image = difference_map(frame, reference)
        if image is None:  # the z-buffer against itself: no pixel differs
            image = difference_map(frame, frame)
            extra["pixels_differing_from_zbuffer"] = 0
    stats = _plain(dict(frame.stats, **extra))
    stats["algorithm"] = options["algorithm"]
    stats["server_ms"] = 1e3 * (time.perf_counter() - start)
    return frame, image, stats


def id_colors(ids: np.ndarray) -> np.ndarray:
    """A distinct colour per id (a multiplicative hash), black for -1."""
    x = (ids.astype(np.int64) + 1) * 2654435761 % (1 << 32)
    out = np.stack([(x >> 16) & 255, (x >> 8) & 255, x & 255], axis=-1).astype(np.uint8)
    out |= 64
    out[ids < 0] = 0
    return out


def _buffer_image(frame, buffer: str) -> np.ndarray:
    from ..explain.views import gray

    covered = frame.face_id >= 0
    if buffer == "color":
        return frame.color
    if buffer == "window_depth":
        return gray(frame.depth, covered)
    if buffer == "eye_depth":
        return gray(frame.eye_depth, covered)
    if buffer == "face_ids":
        return id_colors(frame.face_id)
    normals = frame.normals
    out = np.zeros(normals.shape, np.uint8)
    out[covered] = np.round((normals[covered] + 1.0) * 127.5).clip(0, 255).astype(np.uint8)
    return out


def _plain(value):
    """Stats as JSON-able Python values."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def encode(image: np.ndarray, fmt: str, quality: int = 85) -> bytes:
    """PNG (lossless; fast compression: the page asks for it when the view is still) or
    JPEG bytes."""
    from PIL import Image

    buffer = io.BytesIO()
    if fmt == "png":
        Image.fromarray(image).save(buffer, format="PNG", compress_level=1)
    else:
        Image.fromarray(image).save(buffer, format="JPEG", quality=quality)
    return buffer.getvalue()


def pixel_camera(camera, width, height, x, y):
    """A camera whose one-pixel image samples exactly the centre of pixel (x, y) of a
    ``width`` x ``height`` image of ``camera`` (the frustum narrowed to that pixel)."""
    from ..scene.camera import Camera

    proj = camera.projection_matrix(width / height).copy()
    cx, cy = (x + 0.5) / width * 2 - 1, 1 - (y + 0.5) / height * 2
    # x' = W (x_ndc - cx): with w = -z_eye the shift goes into the z column.
    w_row = proj[3].copy()
    proj[0] = width * proj[0] - width * cx * w_row
    proj[1] = height * proj[1] - height * cy * w_row
    return Camera.from_matrices(camera.view_matrix, proj)


def pick(scene, request: ViewRequest, names, bounds=None) -> dict:
    """What is at pixel (x, y) of the view: face id, object (node) name, window and eye
    depth, and the face each algorithm shows at that pixel's centre (each rendered
    through a one-pixel frustum, so even Newell's and the BSP tree's answer quickly; an
    algorithm that refuses the state says why)."""
    from ..errors import HsrError
    from ..render import render

    bounds = scene.bounds() if bounds is None else bounds
    camera = orbit_camera(bounds, request, scene.up_axis())
    options = _options(bounds, camera, request)
    frame = render(scene, camera, request.w, request.h, **options)
    x, y = request.x, request.y
    face = int(frame.face_id[y, x])
    result = {"x": x, "y": y, "face_id": face, "object_id": None, "object": None,
              "window_depth": float(frame.depth[y, x]), "eye_depth": None}
    if face >= 0:
        obj = int(frame.object_id[y, x])
        result.update(object_id=obj, object=scene.instances[obj].name,
                      eye_depth=float(frame.eye_depth[y, x]))
    one = pixel_camera(camera, request.w, request.h, x, y)
    agree: dict = {}
    for name in names:
        try:
            got = int(render(scene, one, 1, 1, **dict(options, algorithm=name,
                                                       occlusion_cull=False)).face_id[0, 0])
            agree[name] = {"face_id": got, "agrees": got == face}
        except HsrError as exc:
            agree[name] = {"refused": str(exc)}
    result["algorithms"] = agree
    return result


def explain_image(scene, request: ViewRequest, bounds=None) -> np.ndarray:
    """The explanation view ``request.view`` (:mod:`hsr.explain.views`) of this view."""
    from ..explain.views import explain
    from ..geometry.state import RenderState

    bounds = scene.bounds() if bounds is None else bounds
    camera = orbit_camera(bounds, request, scene.up_axis())
    return explain(request.view, scene, camera, min(request.w, 480), min(request.h, 360),
                   RenderState(**request.state_fields())).image


def reproduce(scene, request: ViewRequest, path: str | None, bounds=None) -> dict:
    """``{"command": ..., "python": ...}``: the ``hsr render`` line and the Python call
    that draw the current view (colour; the other buffers have their own options:
    ``--depth-out``, ``--ids-out``, ``--normals-out``)."""
    bounds = scene.bounds() if bounds is None else bounds
    camera = orbit_camera(bounds, request, scene.up_axis())
    # Shortest round-trip reprs: the command draws exactly this view.
    eye = ",".join(repr(float(v)) for v in camera.eye)
    target = ",".join(repr(float(v)) for v in camera.target)
    source = shlex.quote(path) if path else None
    args = ["hsr", "render"] + ([source] if source else ["--scene", request.scene])
    args += ["--size", f"{request.w}x{request.h}", "--eye", eye, "--target", target,
             "--fov", repr(float(request.fov)), "--near", repr(float(camera.near)), "--far",
             repr(float(camera.far))]
    if scene.up_axis() == "z":  # the command's camera up, as the page's
        args += ["--up-axis", "z"]
    flags = {"algorithm": "zbuffer", "cull": "none", "front_face": "ccw",
             "depth_func": "less", "polygon_mode": "fill", "shading": "auto",
             "transparency": "object"}
    for name, default in flags.items():
        if request.values[name] != default:
            args += [f"--{name.replace('_', '-')}", request.values[name]]
    args += ["--light", request.light]
    if not request.depth_test:
        args.append("--no-depth-test")
    if not request.depth_write:
        args.append("--no-depth-write")
    if request.clear_depth != 1.0:
        args += ["--clear-depth", f"{request.clear_depth:g}"]
    if (request.depth_near, request.depth_far) != (0.0, 1.0):
        args += ["--depth-range", f"{request.depth_near:g},{request.depth_far:g}"]
    if (request.offset_factor, request.offset_units) != (0.0, 0.0):
        args += ["--polygon-offset", f"{request.offset_factor:g},{request.offset_units:g}"]
    if request.occlusion_cull:
        args.append("--occlusion-cull")
    if request.hidden_lines:
        args.append("--hidden-line")
    fog = _fog(bounds, camera, request)
    if fog is not None:
        args += ["--fog", f"linear:{fog.start!r},{fog.end!r}" if fog.mode == "linear"
                 else f"{fog.mode}:{fog.density!r}"]
    args += ["-o", "view.png"]
    load = (f"hsr.load_scene({path!r})" if path else f"hsr.scenes.get({request.scene!r})[0]")
    state = ", ".join(f"{k}={v!r}" for k, v in request.state_fields().items())
    python = (f"import hsr\nscene = {load}\ncamera = hsr.Camera.look_at(({eye}), ({target}), "
              f"fov_y={float(request.fov)!r}, near={float(camera.near)!r}, "
              f"far={float(camera.far)!r})\n"
              f"frame = hsr.render(scene, camera, {request.w}, {request.h}, "
              f"algorithm={request.algorithm!r}, shading={request.shading!r}, "
              f"light={request.light!r}, {state}"
              + (f", fog=hsr.Fog({fog.mode!r}, start={fog.start!r}, end={fog.end!r}, "
                 f"density={fog.density!r})" if fog is not None else "")
              + (", hidden_line=True" if request.hidden_lines else "")
              + (", occlusion_cull=True" if request.occlusion_cull else "")
              + (f", transparency={request.transparency!r}"
                 if request.transparency != "object" else "") + ")")
    return {"command": " ".join(args), "python": python}
