"""What a render asks of a visibility algorithm, and the shared rules by which an algorithm
honours a request exactly or refuses it with a :class:`RenderError` naming what it cannot do
(never a silently different picture)."""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import RenderError
from ..geometry.state import RenderState

__all__ = ["Needs", "refuse_unsupported"]


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
