"""What a render asks of a visibility algorithm, and the shared rules by which an algorithm
honours a request exactly or refuses it with a :class:`RenderError` naming what it cannot do
(never a silently different picture)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import RenderError
from ..geometry.state import DepthFunc, RenderState

__all__ = ["Needs", "refuse_unsupported", "refuse_unless_nearest_wins", "apply_clear_depth"]


@dataclass(frozen=True)
class Needs:
    """What a render asks of its visibility algorithm besides the render state.

    counts : per-pixel fragment counts (overdraw).
    into : drawing over an earlier frame's depth buffer (no clear).
    occlusion : occlusion culling of whole objects.
    subset : drawing only some of the scene's faces (the opaque ones, under transparency).
    """

    counts: bool = False
    into: bool = False
    occlusion: bool = False
    subset: bool = False


_WHAT = {
    "counts": "per-pixel fragment counts (counts=True)",
    "into": "drawing over an earlier frame (into=)",
    "occlusion": "occlusion culling",
    "subset": "drawing the opaque part of a scene with transparent objects",
    "offset": "polygon offset (hidden lines fill with it)",
}


def refuse_unsupported(name: str, state: RenderState, needs: Needs, allowed=()) -> None:
    """Raise :class:`RenderError` for the first request of ``needs`` (and polygon offset in
    ``state``) that algorithm ``name`` does not list in ``allowed``."""
    asked = {"counts": needs.counts, "into": needs.into, "occlusion": needs.occlusion,
             "subset": needs.subset, "offset": state.polygon_offset != (0.0, 0.0)}
    for key, on in asked.items():
        if on and key not in allowed:
            raise RenderError(f"{name} does not support {_WHAT[key]}")


def refuse_unless_nearest_wins(name: str, state: RenderState) -> None:
    """Scan-line, ray casting and the depth-sorting algorithms (painter's, Newell, BSP)
    find the *nearest* surface at each pixel. OpenGL's picture is that surface exactly
    when the depth test is on with func less or lequal, depth writes are on, and the depth
    range runs from near to far (n < f: with n > f the farthest surface wins, with n = f
    all depths tie and submission order decides). Any other state is refused, naming it.
    (The clear depth is honoured afterwards: :func:`apply_clear_depth`.)"""
    why = f"{name} draws the nearest surface at each pixel; use zbuffer for"
    if not state.depth_test:
        raise RenderError(f"{why} depth_test=False (last submitted wins)")
    if state.depth_func not in (DepthFunc.LESS, DepthFunc.LEQUAL):
        raise RenderError(f"{why} depth_func {state.depth_func.value}")
    if not state.depth_mask:
        raise RenderError(f"{why} depth_mask=False (each fragment is tested against the "
                          f"clear depth only)")
    near, far = state.depth_range
    if not near < far:
        raise RenderError(f"{why} depth_range ({near:g}, {far:g}): "
                          + ("reversed, the farthest surface wins" if near > far else
                             "every depth ties, submission order decides"))


def apply_clear_depth(face: np.ndarray, depth: np.ndarray, state: RenderState) -> int:
    """The clear depth for an algorithm that drew the nearest surface of every pixel: in
    OpenGL that surface is kept only if it passes the depth test against the clear value
    (everything farther failed against it too). Clears, in place, the pixels where it
    does not pass; returns how many."""
    clear = np.float32(state.clear_depth)
    drawn = face >= 0
    passes = depth < clear if state.depth_func == DepthFunc.LESS else depth <= clear
    dropped = drawn & ~passes
    n = int(np.count_nonzero(dropped))
    if n:
        face[dropped] = -1
        depth[dropped] = clear
    return n
