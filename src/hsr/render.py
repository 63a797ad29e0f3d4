"""``hsr.render``: the data path in one function. Validate, then geometry
(:mod:`hsr.geometry`), visibility (:mod:`hsr.algorithms`, or :mod:`hsr.lines` for polygon
modes), appearance (:mod:`hsr.appearance`), then the optional passes (drawing over an
earlier frame, transparency, hidden lines), and hand back a :class:`Frame`."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from .algorithms import ALGORITHMS, Needs
from .algorithms import check as check_algorithm
from .algorithms.fragments import Fragments
from .algorithms.hiz import object_bounds
from .appearance import buffers
from .appearance.fog import Fog
from .appearance.shading import (
    Look,
    ShadeContext,
    as_look,
    check_background,
    paint_faces,
    shade_visible,
)
from .appearance.transparency import check_order, transparent_mask, transparent_pass
from .appearance.viewpoint import first_look
from .choices import Algorithm, Light, Shading, TextureFilter, TextureWrap, Transparency
from .errors import RenderError
from .geometry.stage import prepare
from .geometry.state import RenderState
from .geometry.viewport import MAX_SIZE, check_memory, check_size
from .lines.raster import HiddenLine, as_hidden_line, draw_hidden_lines, fill_state, polygon_edges
from .lines.raster import check as check_lines
from .parallel import (
    Workspace,
    check_threads,
    default_workspace,
    release_default_workspace,
)
from .scene.camera import Camera
from .scene.load import scene_of
from .scene.mesh import SceneLike, instance_of

__all__ = ["Frame", "View", "render", "MAX_SIZE"]

NO_COLORS = np.zeros((0, 3), dtype=np.uint8)  # paint_faces: the background only


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

    color : (H, W, 3) uint8 (the background everywhere after ``render(..., color=False)``).
    depth : (H, W) float32 window depth (the state's clear depth where nothing was drawn).
    face_id : (H, W) int32 index of the visible triangle in the scene's global face list,
        -1 for background.
    object_id : (H, W) int32 index of the visible instance in the scene, -1 for background.
    stats : counts and timings (triangles in / culled / clipped / degenerate / outside,
        fragments tested / written, milliseconds per stage; the plain z-buffer classifies
        and sets up faces as it fills, so its "geometry" time is the vertex transform and
        the rest counts as "visibility"). The ray caster runs no raster geometry stage:
        its counts are the triangles in, the degenerate ones and its own (the walked
        8-wide BVH's nodes, rays cast, ray-triangle tests, the walk).
    fragments : the algorithm's raw output (screen triangles, per-pixel triangle index).
    eye_depth, distance, normals : derived on first use (see the properties).
    """

    color: np.ndarray
    depth: np.ndarray
    face_id: np.ndarray
    stats: dict = field(default_factory=dict)
    fragments: Fragments | None = None
    face_offsets: np.ndarray | None = field(default=None, repr=False)
    scene: object = field(default=None, repr=False)
    camera: Camera | None = field(default=None, repr=False)
    look: Look | None = field(default=None, repr=False)

    def __repr__(self) -> str:
        s = self.stats
        triangles = f"{s['triangles_in']} triangles, " if "triangles_in" in s else ""
        return (f"Frame({self.width}x{self.height}, {s.get('algorithm', '?')}, {triangles}"
                f"{s.get('pixels_covered', int(np.count_nonzero(self.face_id >= 0)))} pixels "
                f"covered, {s.get('timings_ms', {}).get('total', float('nan')):.1f} ms)")

    def _repr_png_(self) -> bytes:
        """The colour image as PNG, for notebooks."""
        import io

        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(self.color).save(buf, format="PNG")
        return buf.getvalue()

    def _derived(self, name, compute):
        """Buffer ``name`` from ``compute(surface)``, on first use; the surface points of
        the covered pixels are found once for all the derived buffers."""
        cache = self.__dict__.setdefault("_buffers", {})
        if name not in cache:
            if self.scene is None or self.camera is None or self.fragments is None:
                raise RenderError(f"frame.{name} needs the frame of an hsr.render call")
            if "surface" not in cache:
                # Pixels drawn by an earlier frame (into=) are not this scene's faces: only
                # this draw's pixels are derived.
                cache["surface"] = buffers.surface_points(self.scene, self.fragments.screen,
                                                          self.fragments.face_id)
            cache[name] = compute(cache["surface"])
        return cache[name]

    @property
    def eye_depth(self) -> np.ndarray:
        """(H, W) float32 distance along the viewing axis in world units (the z of OpenCV's
        camera frame), +inf where nothing is drawn; exact in float64 from the visible face,
        not from the float32 depth buffer."""
        return self._derived("eye_depth", lambda surface: buffers.eye_depth(
            self.camera, surface, self.face_id.shape))

    @property
    def distance(self) -> np.ndarray:
        """(H, W) float32 Euclidean distance from the eye (orthographic: the eye depth),
        +inf where nothing is drawn."""
        return self._derived("distance", lambda surface: buffers.distance(
            self.camera, surface, self.face_id.shape))

    @property
    def normals(self) -> np.ndarray:
        """(H, W, 3) float32 world-space unit normals, 0 where nothing is drawn: the face
        normal as wound, or interpolated corner normals when the frame was Gouraud shaded."""
        smooth = self.look is not None and self.look.shading == "gouraud"

        def compute(surface):
            ctx = ShadeContext(self.scene, self.camera, self.fragments.screen,
                               self.look or Look(), None)
            return buffers.normals(self.scene, surface, self.face_id.shape, smooth,
                                   ctx.corner_normals)

        return self._derived("normals", compute)

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

    def save(self, path: str | os.PathLike) -> None:
        """Write the colour image (PNG or any format Pillow knows).

        Raises :class:`~hsr.errors.OutputError` for a missing folder or an unknown extension.
        """
        from .scene.files import save_image

        save_image(self.color, path)

    def save_depth(self, path: str | os.PathLike) -> None:
        """Write the depth buffer: ``.npy`` float32, or 16-bit PNG (depth * 65535).

        Raises :class:`~hsr.errors.OutputError` for a missing folder or another extension.
        """
        from .scene.files import save_depth

        save_depth(self.depth, path)

    def save_ids(self, path: str | os.PathLike) -> None:
        """Write the face-id buffer as ``.npy`` int32.

        Raises :class:`~hsr.errors.OutputError` for a missing folder or another extension.
        """
        from .scene.files import save_ids

        save_ids(self.face_id, path)


def render(scene: SceneLike, camera: Camera | None = None, width: int = 800, height: int = 600, *,
           algorithm: Algorithm = "zbuffer", state: RenderState | None = None,
           shading: Shading = "auto", background: ArrayLike = (0, 0, 0), counts: bool = False,
           into: Frame | None = None, threads: int | None = None,
           occlusion_cull: bool = False, options: dict | None = None,
           look: Look | None = None, fog: Fog | None = None, textures: bool = True,
           texture_filter: TextureFilter = "bilinear", texture_wrap: TextureWrap = "repeat",
           light: Light | None = None,
           hidden_line: HiddenLine | bool | None = None, transparency: Transparency = "object",
           color: bool = True, workspace: Workspace | None = None,
           **state_fields) -> Frame:
    """Render ``scene`` (a Mesh, Scene, trimesh.Trimesh or (vertices, faces), a path or a
    list of them) seen by ``camera`` into a ``width`` x ``height`` Frame (800 x 600 by
    default, as ``hsr render``). Without a camera: the first look of
    ``hsr render MODEL`` (:func:`hsr.first_look`: the model framed tight from the side
    that shows the most of its shape, and the studio light unless ``light`` says
    otherwise).

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
    :data:`hsr.appearance.shading.SHADING_MODES`), ``textures`` (use mesh textures),
    ``texture_filter`` (nearest | bilinear), ``texture_wrap`` (repeat | clamp), ``fog``
    (:class:`hsr.Fog`), ``light`` (``headlight``, the default with a camera: one light
    along the view, the textbooks'; ``studio``: key and fill lights, shapes read better),
    or all of them as one :class:`hsr.Look`. ``hidden_line=True`` (or a
    :class:`hsr.HiddenLine`) draws only the visible edges over the filled depth buffer.
    Instances with ``opacity < 1`` are blended after the opaque ones, sorted back to front
    per object (``transparency="object"``) or per fragment (``"exact"``).
    ``color=False`` skips the appearance stage when only the buffers are wanted (face ids,
    depth, the derived eye depth and normals; e.g. visibility counts over many views):
    ``Frame.color`` is the background everywhere. ``workspace`` (an
    :class:`hsr.Workspace`) keeps threads and scratch buffers from one render to the next
    (faster for many renders in a row; the result is the same); ``threads`` is then the
    workspace's. Without one, each calling thread keeps a workspace of its own for its
    plain calls (scratch up to :data:`hsr.parallel.DEFAULT_KEEP_BYTES` kept;
    :func:`hsr.parallel.release_default_workspace` drops it), so repeated renders are as
    fast as through a Workspace. A frame's colour, depth and face ids are the caller's;
    once it drops every view of them, the workspace keeps their memory (up to
    :data:`hsr.parallel.OUTPUT_KEEP_BYTES`) for a later frame of the same size
    (:class:`hsr.parallel.OutputPool`), so a loop of renders does not fault fresh pages in
    each time.

    Raises :class:`~hsr.errors.MeshError` for a scene that is not a valid mesh or scene,
    :class:`~hsr.errors.CameraError` for an invalid camera and
    :class:`~hsr.errors.RenderError` for invalid arguments or a combination an algorithm
    cannot honour exactly.
    """
    t_start = time.perf_counter()
    check_size(width, height)
    check_memory(width, height)
    scene = scene_of(scene)  # paths and lists of them load here, as one scene
    if camera is None:
        # The first look, as ``hsr render MODEL`` draws it.
        camera = first_look(scene, width / height)
        light = "studio" if light is None else light
    if not isinstance(camera, Camera):
        raise RenderError(f"camera must be an hsr.Camera, got {type(camera).__name__}")
    camera.validate()
    light = "headlight" if light is None else light
    fields = RenderState.__dataclass_fields__
    unknown = sorted(set(state_fields) - set(fields))
    if unknown:
        raise RenderError(f"render() has no argument {', '.join(unknown)} (render state "
                          f"fields: {', '.join(fields)})")
    if state is not None and not isinstance(state, RenderState):
        raise RenderError(f"state must be an hsr.RenderState, got {type(state).__name__}")
    if state is None:
        state = RenderState(**state_fields)
    elif state_fields:
        state = state.with_(**state_fields)
    look = as_look(look, shading, textures, texture_filter, texture_wrap, fog, light)
    background = check_background(background)
    check_order(transparency)
    hidden_line = as_hidden_line(hidden_line)
    for name, value in (("counts", counts), ("occlusion_cull", occlusion_cull),
                        ("textures", textures), ("color", color)):
        if not isinstance(value, (bool, np.bool_)):
            raise RenderError(f"{name} must be True or False, got {value!r}")
    check_threads(threads)
    if workspace is not None and not isinstance(workspace, Workspace):
        raise RenderError(f"workspace must be an hsr.Workspace, got {type(workspace).__name__}")
    if workspace is not None and threads is not None and threads != workspace.threads:
        raise RenderError(f"threads={threads} differs from the workspace's {workspace.threads}")
    if into is not None and not isinstance(into, Frame):
        raise RenderError(f"into must be an hsr.Frame, got {type(into).__name__}")
    if into is not None and (into.width, into.height) != (width, height):
        raise RenderError("into= frame has a different size")
    if options is not None and not isinstance(options, dict):
        raise RenderError(f"options must be a dict, got {type(options).__name__}")
    options = dict(options or {})
    transparent = transparent_mask(scene)
    if not color and (into is not None or hidden_line is not None or transparent.any()):
        raise RenderError("color=False draws no colour: it does not combine with into=, "
                          "hidden lines or transparent instances")
    # Each stage states what it cannot combine: the line stage (polygon modes), then the
    # algorithm, asked for exactly what this render needs of it.
    check_lines(state, hidden_line, algorithm, transparent=bool(transparent.any()),
                into=into is not None, counts=counts)
    check_algorithm(algorithm, options, fill_state(state, hidden_line),
                    Needs(counts=counts, into=into is not None, occlusion=occlusion_cull,
                          subset=bool(transparent.any())))

    stats: dict = {"algorithm": algorithm, "width": width, "height": height}
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    if workspace is not None:
        release_default_workspace()  # an explicit workspace takes over from the default
    with (default_workspace(threads) if workspace is None else workspace.claim()) as workers:
        return _render(scene, camera, width, height, algorithm, state, look, background,
                       counts, into, stats, t_start, view_proj, workers, occlusion_cull,
                       options, hidden_line, transparency, transparent, color)


def _render(scene, camera, width, height, algorithm, state, look, background, counts,
            into, stats, t_start, view_proj, workers, occlusion_cull, options, hidden_line,
            transparency, transparent, shade=True):
    # 1. Geometry: world -> clip -> window space. The plain z-buffer streams faces from
    # clip space into its fill (classification and set-up then count as visibility time);
    # the ray caster walks world space and reads neither screen triangles nor clip-space
    # vertices, so they are made only if a later pass asks (a 1M-face terrain: 12 + 4 ms
    # a frame saved); everything else works on the stored screen triangles.
    streamed = (algorithm == "zbuffer" and not occlusion_cull and not transparent.any()
                and state.polygon_mode == "fill")
    screen = prepare(scene, view_proj, width, height, state, stats, workers,
                     deferred=streamed, lazy=algorithm == "raycast")
    if algorithm == "raycast":  # the counts it has without classifying faces
        stats.update(triangles_in=scene.n_faces, degenerate=sum(
            int(np.count_nonzero(inst.mesh.degenerate_mask())) for inst in scene.instances))
    t_geometry = time.perf_counter()

    # 2. Visibility: the chosen algorithm (or the line stage, for polygon modes) decides
    # the face and depth of every pixel.
    fragments = _visibility(scene, camera, screen, width, height, algorithm, state, counts,
                            into, view_proj, workers, occlusion_cull, options, hidden_line,
                            transparent)
    t_visibility = time.perf_counter()

    # 3. Appearance: colour from the visible face of each pixel.
    if shade:
        ctx = ShadeContext(scene, camera, screen, look, workers)
        color, covered = shade_visible(ctx, fragments, state, background)
    elif not background.any():  # black: zeroed pages from the system cost nothing here
        color = np.zeros((height, width, 3), dtype=np.uint8)
        covered = int(np.count_nonzero(fragments.face_id >= 0))
    else:
        color = workers.output((height, width, 3), np.uint8)
        covered = paint_faces(workers, fragments.face_id, NO_COLORS, background, color)
    face_id = fragments.face_id
    # 4. Optional passes, each a call into its stage.
    if into is not None:
        drawn = face_id >= 0
        color = np.where(drawn[..., None], color, into.color)
        face_id = np.where(drawn, face_id, into.face_id).astype(np.int32)
        covered = int(np.count_nonzero(face_id >= 0))
    if transparent.any():
        is_transparent = transparent[scene.instance_of(screen.face_id)]
        stats.update(transparent_pass(ctx, screen.subset(is_transparent), fragments.depth,
                                      state, color, order=transparency))
    if hidden_line is not None:
        stats.update(draw_hidden_lines(scene, camera, screen, view_proj, fragments,
                                       hidden_line, state, background, color))
    t_end = time.perf_counter()

    stats.update(fragments.stats)
    stats["pixels_covered"] = int(covered)
    stats["timings_ms"] = {
        "geometry": 1e3 * (t_geometry - t_start),
        "visibility": 1e3 * (t_visibility - t_geometry),
        "shading": 1e3 * (t_end - t_visibility),
        "total": 1e3 * (t_end - t_start),
    }
    return Frame(color, fragments.depth, face_id, stats, fragments, scene.face_offsets(),
                 scene, camera, look)


def _visibility(scene, camera, screen, width, height, algorithm, state, counts, into,
                view_proj, workers, occlusion_cull, options, hidden_line, transparent):
    """Fragments of the opaque faces: polygon modes draw edges or corners; otherwise the
    algorithm fills (pushed back by the hidden lines' polygon offset, over ``into``'s
    depth buffer when given)."""
    if state.polygon_mode != "fill":
        face_id, depth, line_stats = polygon_edges(scene, screen, view_proj, state)
        return Fragments(face_id, depth, screen, line_stats)
    opaque_screen = screen
    if transparent.any():
        opaque_screen = screen.subset(~transparent[scene.instance_of(screen.face_id)])
    extra = dict(options, view=View(scene, camera, view_proj, width, height))
    if occlusion_cull:
        extra["occlusion"] = object_bounds(scene, view_proj)
    if into is not None:
        extra["depth_buffer"] = into.depth.copy()
    fragments = ALGORITHMS[algorithm].resolve(opaque_screen, fill_state(state, hidden_line),
                                              counts=counts, workers=workers, **extra)
    fragments.screen = screen
    return fragments
