"""OpenGL-style render state: depth test, depth function, depth mask, clear depth,
depth range, face culling and winding, polygon mode and polygon offset. Names follow the
GL calls they mirror."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import Enum

import numpy as np

from ..errors import RenderError

__all__ = ["DepthFunc", "CullMode", "FrontFace", "PolygonMode", "RenderState"]


class DepthFunc(str, Enum):
    """glDepthFunc. The fragment passes when ``fragment_depth OP stored_depth``."""

    NEVER = "never"
    LESS = "less"
    EQUAL = "equal"
    LEQUAL = "lequal"
    GREATER = "greater"
    NOTEQUAL = "notequal"
    GEQUAL = "gequal"
    ALWAYS = "always"

    @property
    def code(self) -> int:
        """Integer code used by the compiled kernels (order of GL_NEVER..GL_ALWAYS)."""
        return list(DepthFunc).index(self)


class CullMode(str, Enum):
    """glCullFace, with NONE meaning glDisable(GL_CULL_FACE)."""

    NONE = "none"
    BACK = "back"
    FRONT = "front"
    FRONT_AND_BACK = "front_and_back"


class FrontFace(str, Enum):
    """glFrontFace: which window-space winding is front-facing."""

    CCW = "ccw"
    CW = "cw"


class PolygonMode(str, Enum):
    """glPolygonMode: fill the triangles, draw their edges as lines, or their corners as
    points."""

    FILL = "fill"
    LINE = "line"
    POINT = "point"


def _enum(cls, value, what):
    if isinstance(value, cls):
        return value
    try:
        return cls(str(value).lower().replace("-", "_"))
    except ValueError:
        choices = ", ".join(m.value for m in cls)
        raise RenderError(f"{what} must be one of {choices}; got {value!r}") from None


@dataclass(frozen=True)
class RenderState:
    """The depth and culling state a draw runs with (OpenGL defaults, except that the
    depth test is enabled, since hidden-surface removal is the point).

    Raises :class:`~hsr.errors.RenderError` for an unknown enum value or a depth value
    outside [0, 1].
    """

    depth_test: bool = True
    depth_func: DepthFunc = DepthFunc.LESS
    depth_mask: bool = True
    clear_depth: float = 1.0
    depth_range: tuple = (0.0, 1.0)
    cull: CullMode = CullMode.NONE
    front_face: FrontFace = FrontFace.CCW
    polygon_mode: PolygonMode = PolygonMode.FILL
    # glPolygonOffset(factor, units) with GL_POLYGON_OFFSET_FILL; (0, 0) = disabled.
    polygon_offset: tuple = (0.0, 0.0)

    def __post_init__(self):
        for name in ("depth_test", "depth_mask"):
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise RenderError(f"{name} must be True or False, got {value!r}")
            object.__setattr__(self, name, bool(value))
        object.__setattr__(self, "polygon_mode",
                           _enum(PolygonMode, self.polygon_mode, "polygon mode"))
        try:
            factor, units = (float(v) for v in self.polygon_offset)
        except (TypeError, ValueError):
            raise RenderError(f"polygon offset must be two numbers (factor, units), got "
                              f"{self.polygon_offset!r}") from None
        if not (math.isfinite(factor) and math.isfinite(units)):
            raise RenderError(f"polygon offset must be finite, got {self.polygon_offset!r}")
        object.__setattr__(self, "polygon_offset", (factor, units))
        object.__setattr__(self, "depth_func", _enum(DepthFunc, self.depth_func, "depth func"))
        object.__setattr__(self, "cull", _enum(CullMode, self.cull, "cull mode"))
        object.__setattr__(self, "front_face", _enum(FrontFace, self.front_face, "front face"))
        try:
            near, far = (float(v) for v in self.depth_range)
        except (TypeError, ValueError):
            raise RenderError(f"depth range must be two numbers, got "
                              f"{self.depth_range!r}") from None
        for v in (near, far):
            if not (math.isfinite(v) and 0.0 <= v <= 1.0):
                raise RenderError(f"depth range values must be in [0, 1], got {self.depth_range!r}")
        object.__setattr__(self, "depth_range", (near, far))
        try:
            clear = float(self.clear_depth)
        except (TypeError, ValueError):
            raise RenderError(f"clear depth must be a number, got {self.clear_depth!r}") from None
        if not math.isfinite(clear):
            raise RenderError(f"clear depth must be finite, got {self.clear_depth!r}")
        # glClearDepth clamps to [0, 1].
        object.__setattr__(self, "clear_depth", min(max(clear, 0.0), 1.0))

    def with_(self, **changes) -> RenderState:
        """A copy with some fields changed."""
        return replace(self, **changes)
