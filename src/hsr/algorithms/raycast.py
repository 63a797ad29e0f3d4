"""Ray casting: one primary ray per pixel centre through the camera, nearest hit wins
(seed 004). ``accel="bvh"`` (default) walks a bounding volume hierarchy; ``accel="none"``
is the literal O(pixels x triangles) loop, for small scenes and teaching."""

from __future__ import annotations

from ..errors import RenderError
from ..geometry.stage import ScreenTriangles
from ..geometry.state import RenderState
from ..parallel import Workers
from .bvh import BVH, build, cast
from .fragments import Fragments
from .support import Needs, refuse_unless_nearest_wins, refuse_unsupported

NAME = "raycast"
# Accepted keys of render(..., options=...) and what each takes.
OPTIONS = {"accel": ("bvh", "none"), "bvh": BVH, "force": bool, "buffers": bool}
DESCRIPTION = "one ray per pixel in world space; BVH (binned SAH) or naive; watertight test"
NAIVE_LIMIT = 2_000_000_000  # ray-triangle tests allowed for accel="none" without force


def check(state: RenderState, needs: Needs) -> None:
    """Raise :class:`RenderError` for a request raycast cannot honour exactly."""
    refuse_unless_nearest_wins(NAME, state)
    if needs.counts:
        raise RenderError("raycast does not record per-pixel fragment counts")
    refuse_unsupported(NAME, state, needs)


def resolve(screen: ScreenTriangles, state: RenderState, workers: Workers | None = None,
            counts: bool = False, view=None, accel: str = "bvh", bvh: BVH | None = None,
            force: bool = False, buffers: bool = False, **_) -> Fragments:
    """``buffers=True`` also returns per-pixel ray ``distance`` (from the eye, or the eye
    plane for orthographic cameras) and ``barycentrics`` in ``fragments.buffers``."""
    if view is None:
        raise RenderError("raycast needs the scene and camera (call it through hsr.render)")
    if accel not in ("bvh", "none"):
        raise RenderError(f"raycast accel must be 'bvh' or 'none', got {accel!r}")
    workers = workers or Workers()
    width, height = screen.width, screen.height
    stats: dict = {"accel": accel}
    if accel == "none":
        triangles = view.scene.world_triangles()
        if width * height * len(triangles) > NAIVE_LIMIT and not force:
            raise RenderError(
                f"naive ray casting would run {width * height * len(triangles):.2e} ray-triangle "
                f"tests (limit {NAIVE_LIMIT:.0e}); use accel='bvh' or force=True")
        used = None
    else:
        if bvh is None:
            bvh = build(view.scene, workers.threads)
        elif not isinstance(bvh, BVH):
            raise RenderError(f"raycast option bvh must be an hsr.raycast.BVH (from "
                              f"hsr.raycast.build), got {type(bvh).__name__}")
        elif bvh.n_faces != view.scene.n_faces:
            raise RenderError("the BVH was built for another scene")
        triangles = None
        used = bvh
        stats.update(bvh_nodes=bvh.n_nodes, bvh_build_ms=bvh.build_ms)
    face, depth, distance, bary, tests = cast(triangles, view.camera, width, height, state,
                                              workers, used, extras=buffers)
    stats["ray_triangle_tests"] = tests
    fragments = Fragments(face, depth, screen, stats)
    if buffers:
        fragments.buffers = {"distance": distance, "barycentrics": bary}
    return fragments
