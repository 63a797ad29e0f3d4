"""``hsr.render``: validate, run the geometry stage, ask the chosen algorithm what is
visible, shade, and hand back a :class:`Frame`."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .algorithms import ALGORITHMS
from .camera import Camera
from .errors import RenderError
from .fog import Fog
from .fragments import Fragments
from .lines import HiddenLine, hidden_line_pass, polygon_edges
from .mesh import as_scene, instance_of
from .occlusion import object_bounds
from .parallel import Workers
from .pipeline import prepare
from .shading import (Look, ShadeContext, face_colors, paint_faces, shade_depth,
                      shade_fragments, to_uint8)
from .state import RenderState
from .transparency import transparent_pass

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
        fragments tested / written, milliseconds per stage; the plain z-buffer classifies
        and sets up faces as it fills, so its "geometry" time is the vertex transform and
        the rest counts as "visibility").
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
            object_id = instance_of(offsets, self.face_id).astype(np.int32)
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
           look: Look | None = None, fog: Fog | None = None, textures: bool = True,
           texture_filter: str = "bilinear", texture_wrap: str = "repeat",
           hidden_line: HiddenLine | bool | None = None, transparency: str = "object",
           **state_fields) -> Frame:
    """Render ``scene`` (a Mesh, Scene, trimesh.Trimesh or (vertices, faces)) seen by
    ``camera`` into a ``width`` x ``height`` Frame.

    ``state`` (or keyword fields of :class:`RenderState`, e.g. ``cull="back"``,
    ``depth_func="lequal"``, ``polygon_mode="line"``, ``polygon_offset=(1, 1)``) sets the
    OpenGL depth, culling and polygon state. ``counts=True``
    also records per-pixel fragment counts (overdraw). ``into=frame`` draws on top of an
    earlier frame without clearing it (its depth buffer, colours and ids are kept where
    this draw writes nothing), like a second draw call in OpenGL. ``threads`` sets how
    many threads run the kernels (default: numba's thread count); results never depend
    on it. ``occlusion_cull=True`` (z-buffer, depth func less or lequal) draws the scene's
    objects front to back and skips those hidden behind what is already drawn; the
    result is identical, ``stats`` counts objects tested and culled. ``options`` go to the
    algorithm (e.g. ``{"accel": "none"}`` or ``{"bvh": tree}`` for ``raycast``).

    Appearance (after visibility, the same for every algorithm): ``shading`` (see
    :data:`hsr.shading.SHADING_MODES`), ``textures`` (use mesh textures), ``texture_filter``
    (nearest | bilinear), ``texture_wrap`` (repeat | clamp), ``fog`` (:class:`hsr.fog.Fog`),
    or all of them as one :class:`hsr.shading.Look`. ``hidden_line=True`` (or a
    :class:`hsr.lines.HiddenLine`) draws only the visible edges over the filled depth
    buffer. Instances with ``opacity < 1`` are blended after the opaque ones, sorted back
    to front per object (``transparency="object"``) or per fragment (``"exact"``).
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
    if look is None:
        look = Look(shading, textures, texture_filter, texture_wrap, fog)
    elif not isinstance(look, Look):
        raise RenderError(f"look must be an hsr.shading.Look, got {type(look).__name__}")
    if hidden_line is True:
        hidden_line = HiddenLine()
    elif hidden_line is False:
        hidden_line = None
    elif hidden_line is not None and not isinstance(hidden_line, HiddenLine):
        raise RenderError("hidden_line must be True, False or an hsr.lines.HiddenLine")
    try:
        bg = np.asarray(background, dtype=np.float64)
    except (TypeError, ValueError):
        bg = np.zeros(0)
    if bg.shape != (3,) or not np.all((bg >= 0) & (bg <= 255)):
        raise RenderError(f"background must be three numbers in 0..255, got {background!r}")
    if transparency not in ("object", "exact"):
        raise RenderError(f"transparency must be object or exact, got {transparency!r}")
    if into is not None and (into.width, into.height) != (width, height):
        raise RenderError("into= frame has a different size")
    scene = as_scene(scene)
    _check_combination(scene, algorithm, state, hidden_line, occlusion_cull, counts, into)

    stats: dict = {"algorithm": algorithm, "width": width, "height": height}
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    with Workers(threads) as workers:
        return _render(scene, camera, width, height, algorithm, state, look, background,
                       counts, into, stats, t_start, view_proj, workers, occlusion_cull,
                       dict(options or {}), hidden_line, transparency)


# Algorithms that fill through the shared raster code (and so honour polygon offset and
# can draw a subset of the scene's triangles).
_RASTER_FILLS = ("zbuffer", "painter", "newell")


def _check_combination(scene, algorithm, state, hidden_line, occlusion_cull, counts, into):
    transparent = any(inst.opacity < 1.0 for inst in scene.instances)
    if occlusion_cull:
        if algorithm != "zbuffer":
            raise RenderError("occlusion culling works with the zbuffer algorithm")
        if counts:
            raise RenderError("occlusion culling does not record per-pixel counts")
        if state.polygon_offset != (0.0, 0.0) or hidden_line is not None or transparent:
            raise RenderError("occlusion culling does not combine with polygon offset, "
                              "hidden lines or transparency")
    if into is not None and algorithm != "zbuffer":
        raise RenderError("into= (drawing without a clear) needs the zbuffer algorithm")
    if state.polygon_mode != "fill":
        if algorithm != "zbuffer":
            raise RenderError(f"polygon mode {state.polygon_mode.value} draws lines or points "
                              f"with the z-buffer; {algorithm} only fills")
        if hidden_line is not None or transparent or into is not None or counts:
            raise RenderError(f"polygon mode {state.polygon_mode.value} does not combine with "
                              f"hidden lines, transparency, into= or counts")
    offset = state.polygon_offset != (0.0, 0.0) or hidden_line is not None
    if offset and algorithm not in _RASTER_FILLS + ("bsp",):
        raise RenderError(f"polygon offset (and hidden lines) need a raster fill: "
                          f"{', '.join(_RASTER_FILLS + ('bsp',))}, not {algorithm}")
    if transparent and algorithm not in _RASTER_FILLS:
        raise RenderError(f"transparency draws the opaque objects with one of "
                          f"{', '.join(_RASTER_FILLS)}, not {algorithm}")


def _render(scene, camera, width, height, algorithm, state, look, background, counts,
            into, stats, t_start, view_proj, workers, occlusion_cull, options, hidden_line,
            transparency):
    background = np.asarray(background, dtype=np.uint8)
    transparent = np.array([inst.opacity < 1.0 for inst in scene.instances])
    # The plain z-buffer streams faces from clip space into its fill (classification and
    # set-up then count as visibility time); everything else works on screen triangles.
    streamed = (algorithm == "zbuffer" and not occlusion_cull and not transparent.any()
                and state.polygon_mode == "fill")
    screen = prepare(scene, view_proj, width, height, state, stats, workers, deferred=streamed)
    t_geometry = time.perf_counter()

    fill_state = state
    if hidden_line is not None and state.polygon_offset == (0.0, 0.0):
        fill_state = state.with_(polygon_offset=hidden_line.polygon_offset)
    opaque_screen = screen
    if transparent.any():
        is_transparent = transparent[scene.instance_of(screen.face_id)]
        opaque_screen = screen.subset(~is_transparent)

    module = ALGORITHMS[algorithm]
    if state.polygon_mode != "fill":
        face_id, depth, line_stats = polygon_edges(scene, screen, view_proj, state)
        fragments = Fragments(face_id, depth, screen, line_stats)
    else:
        extra = dict(options, view=View(scene, camera, view_proj, width, height))
        if occlusion_cull:
            extra["occlusion"] = object_bounds(scene, view_proj)
        if into is not None:
            fragments = module.resolve(opaque_screen, fill_state, depth_buffer=into.depth.copy(),
                                       counts=counts, workers=workers, **extra)
        else:
            fragments = module.resolve(opaque_screen, fill_state, counts=counts,
                                       workers=workers, **extra)
        fragments.screen = screen
    t_visibility = time.perf_counter()

    face_id = fragments.face_id
    color = np.empty((height, width, 3), dtype=np.uint8)
    ctx = ShadeContext(scene, camera, screen, look, workers)
    if state.polygon_mode != "fill" or not ctx.per_pixel:
        mode = look.shading if state.polygon_mode == "fill" else (
            look.shading if look.shading in ("flat", "normal", "random") else "flat")
        covered = paint_faces(workers, face_id, face_colors(mode, scene, camera, workers,
                                                            face_id), background, color)
        if look.shading == "depth" and state.polygon_mode == "fill":
            shade_depth(color, face_id, fragments.depth, camera, state.depth_range)
    else:
        covered = paint_faces(workers, face_id, np.zeros((0, 3), np.uint8), background, color)
        rows, cols = np.nonzero(face_id >= 0)
        if len(rows):
            color[rows, cols] = to_uint8(shade_fragments(
                ctx, rows, cols, face_id[rows, cols], fragments.depth[rows, cols]))
    if into is not None:
        drawn = face_id >= 0
        color = np.where(drawn[..., None], color, into.color)
        face_id = np.where(drawn, face_id, into.face_id).astype(np.int32)
        covered = int(np.count_nonzero(face_id >= 0))
    if transparent.any():
        stats.update(transparent_pass(ctx, screen.subset(is_transparent), fragments.depth,
                                      state, color, order=transparency))
    if hidden_line is not None:
        if hidden_line.fill == "background":
            color[:] = background
        line_face, line_stats = hidden_line_pass(scene, camera, screen, view_proj,
                                                 fragments.depth.copy(), hidden_line,
                                                 state.depth_range)
        color[line_face >= 0] = np.asarray(hidden_line.line_color(background), dtype=np.uint8)
        fragments.buffers["lines"] = line_face
        stats.update(line_stats)
        stats["line_pixels"] = int(np.count_nonzero(line_face >= 0))
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
