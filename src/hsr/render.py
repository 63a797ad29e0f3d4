"""``hsr.render``: validate, run the geometry stage, ask the chosen algorithm what is
visible, shade, and hand back a :class:`Frame`."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .algorithms import ALGORITHMS
from .camera import Camera
from .errors import RenderError
from .fragments import Fragments
from .mesh import as_scene
from .occlusion import object_bounds
from .parallel import Workers
from .pipeline import prepare
from .shading import SHADING_MODES, face_colors, paint_faces, shade_depth
from .state import RenderState

__all__ = ["Frame", "View", "render", "MAX_SIZE"]

# Largest image side: keeps snapped window coordinates well inside int64 edge arithmetic
# and buffers of a sane size.
MAX_SIZE = 32768


@dataclass
class View:
    """What an algorithm that works in world space (ray casting, BSP) needs besides the
    screen triangles."""

    scene: object
    camera: Camera
    view_proj: np.ndarray
    width: int
    height: int


@dataclass
class Frame:
    """The result of a render. Row 0 of every array is the top of the image.

    color : (H, W, 3) uint8.
    depth : (H, W) float32 window depth (the state's clear depth where nothing was drawn).
    face_id : (H, W) int32 index of the visible triangle in the scene's global face list,
        -1 for background.
    object_id : (H, W) int32 index of the visible instance in the scene, -1 for background.
    stats : counts and timings (triangles in / culled / clipped / degenerate / outside,
        fragments tested / written, milliseconds per stage).
    fragments : the algorithm's raw output (screen triangles, per-pixel triangle index).
    """

    color: np.ndarray
    depth: np.ndarray
    face_id: np.ndarray
    stats: dict = field(default_factory=dict)
    fragments: Fragments | None = None
    face_offsets: np.ndarray | None = field(default=None, repr=False)

    @property
    def object_id(self) -> np.ndarray:
        """(H, W) int32 instance index of the visible face, -1 for background (derived
        from ``face_id`` on first use)."""
        if getattr(self, "_object_id", None) is None:
            offsets = self.face_offsets if self.face_offsets is not None else np.array([0])
            object_id = np.searchsorted(offsets, self.face_id, side="right").astype(np.int32) - 1
            object_id[self.face_id < 0] = -1
            self._object_id = object_id
        return self._object_id

    @property
    def width(self) -> int:
        return self.color.shape[1]

    @property
    def height(self) -> int:
        return self.color.shape[0]

    def save(self, path) -> None:
        """Write the colour image (PNG or any format Pillow knows)."""
        from .io import save_image

        save_image(self.color, path)

    def save_depth(self, path) -> None:
        """Write the depth buffer: ``.npy`` float32, or 16-bit PNG (depth * 65535)."""
        from .io import save_depth

        save_depth(self.depth, path)

    def save_ids(self, path) -> None:
        """Write the face-id buffer as ``.npy`` int32."""
        from .io import save_ids

        save_ids(self.face_id, path)


def _check_size(width, height):
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise RenderError(f"{name} must be an integer, got {value!r}")
        if not 0 < value <= MAX_SIZE:
            raise RenderError(f"{name} must be in 1..{MAX_SIZE}, got {value}")


def render(scene, camera: Camera, width: int = 640, height: int = 480, *,
           algorithm: str = "zbuffer", state: RenderState | None = None,
           shading: str = "flat", background=(0, 0, 0), counts: bool = False,
           into: Frame | None = None, threads: int | None = None,
           occlusion_cull: bool = False, options: dict | None = None,
           **state_fields) -> Frame:
    """Render ``scene`` (a Mesh, Scene, trimesh.Trimesh or (vertices, faces)) seen by
    ``camera`` into a ``width`` x ``height`` Frame.

    ``state`` (or keyword fields of :class:`RenderState`, e.g. ``cull="back"``,
    ``depth_func="lequal"``) sets the OpenGL depth and culling state. ``counts=True``
    also records per-pixel fragment counts (overdraw). ``into=frame`` draws on top of an
    earlier frame without clearing it (its depth buffer, colours and ids are kept where
    this draw writes nothing), like a second draw call in OpenGL. ``threads`` sets how
    many threads run the kernels (default: numba's thread count); results never depend
    on it. ``occlusion_cull=True`` (z-buffer, depth func less or lequal) draws the scene's
    objects front to back and skips those hidden behind what is already drawn; the
    result is identical, ``stats`` counts objects tested and culled. ``options`` go to the
    algorithm (e.g. ``{"accel": "none"}`` or ``{"bvh": tree}`` for ``raycast``).
    """
    t_start = time.perf_counter()
    _check_size(width, height)
    if not isinstance(camera, Camera):
        raise RenderError(f"camera must be an hsr.Camera, got {type(camera).__name__}")
    camera.validate()
    if state is None:
        state = RenderState(**state_fields)
    elif state_fields:
        state = state.with_(**state_fields)
    if algorithm not in ALGORITHMS:
        raise RenderError(
            f"unknown algorithm {algorithm!r}; choose from {', '.join(sorted(ALGORITHMS))}")
    unknown = sorted(set(options or {}) - set(ALGORITHMS[algorithm].OPTIONS))
    if unknown:
        accepted = ", ".join(ALGORITHMS[algorithm].OPTIONS) or "none"
        raise RenderError(f"{algorithm} has no option {', '.join(unknown)} (accepted: {accepted})")
    if shading not in SHADING_MODES:
        raise RenderError(f"shading must be one of {', '.join(SHADING_MODES)}; got {shading!r}")
    if into is not None and (into.width, into.height) != (width, height):
        raise RenderError("into= frame has a different size")
    scene = as_scene(scene)

    stats: dict = {"algorithm": algorithm, "width": width, "height": height}
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    with Workers(threads) as workers:
        return _render(scene, camera, width, height, algorithm, state, shading, background,
                       counts, into, stats, t_start, view_proj, workers, occlusion_cull,
                       dict(options or {}))


def _render(scene, camera, width, height, algorithm, state, shading, background, counts,
            into, stats, t_start, view_proj, workers, occlusion_cull, options):
    screen = prepare(scene, view_proj, width, height, state, stats, workers)
    t_geometry = time.perf_counter()

    module = ALGORITHMS[algorithm]
    extra = dict(options, view=View(scene, camera, view_proj, width, height))
    if occlusion_cull:
        if algorithm != "zbuffer":
            raise RenderError("occlusion culling works with the zbuffer algorithm")
        if counts:
            raise RenderError("occlusion culling does not record per-pixel counts")
        extra["occlusion"] = object_bounds(scene, view_proj)
    if into is not None:
        if algorithm != "zbuffer":
            raise RenderError("into= (drawing without a clear) needs the zbuffer algorithm")
        fragments = module.resolve(screen, state, depth_buffer=into.depth.copy(), counts=counts,
                                   workers=workers, **extra)
    else:
        fragments = module.resolve(screen, state, counts=counts, workers=workers, **extra)
    t_visibility = time.perf_counter()

    face_id = fragments.face_id
    color = np.empty((height, width, 3), dtype=np.uint8)
    covered = paint_faces(workers, face_id, face_colors(shading, scene, camera, workers, face_id),
                          np.asarray(background, dtype=np.uint8), color)
    if shading == "depth":
        shade_depth(color, face_id, fragments.depth, camera, state.depth_range)
    if into is not None:
        drawn = face_id >= 0
        color = np.where(drawn[..., None], color, into.color)
        face_id = np.where(drawn, face_id, into.face_id).astype(np.int32)
        covered = int(np.count_nonzero(face_id >= 0))
    t_end = time.perf_counter()

    stats.update(fragments.stats)
    stats["pixels_covered"] = int(covered)
    stats["timings_ms"] = {
        "geometry": 1e3 * (t_geometry - t_start),
        "visibility": 1e3 * (t_visibility - t_geometry),
        "shading": 1e3 * (t_end - t_visibility),
        "total": 1e3 * (t_end - t_start),
    }
    return Frame(color, fragments.depth, face_id, stats, fragments, scene.face_offsets())
