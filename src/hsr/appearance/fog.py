"""Depth cueing (fog), as OpenGL's fixed-function fog computes it (OpenGL 2.1 spec,
section 3.10): a blend factor ``f`` from the eye-space distance ``c`` of the fragment,

    linear: f = (end - c) / (end - start)
    exp:    f = exp(-density * c)
    exp2:   f = exp(-(density * c) ** 2)

clamped to [0, 1], then ``colour = f * colour + (1 - f) * fog_colour``. ``c`` is the
Euclidean distance from the eye (``distance="radial"``, what the spec defines) or
``|z_eye|`` (``distance="plane"``, the approximation most GL implementations used).
The background (clear colour) is not fogged, as in OpenGL.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import RenderError, check_choice, check_rgb

__all__ = ["Fog", "MODES", "parse_fog"]

MODES = ("linear", "exp", "exp2")
DISTANCES = ("radial", "plane")


@dataclass(frozen=True)
class Fog:
    """OpenGL 2.1 fixed-function fog: ``mode`` linear | exp | exp2 with ``start``/``end``
    (linear) or ``density``, ``color`` (0..255), ``distance`` radial | plane.

    Raises :class:`~hsr.errors.RenderError` for an unknown mode or distance, or parameters
    that are not finite, negative, or an empty linear range.
    """

    mode: str = "linear"
    start: float = 0.0
    end: float = 1.0
    density: float = 1.0
    color: tuple = (128, 128, 128)
    distance: str = "radial"

    def __post_init__(self):
        check_choice(self.mode, MODES, "fog mode")
        check_choice(self.distance, DISTANCES, "fog distance")
        for name in ("start", "end", "density"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value):
                raise RenderError(f"fog {name} must be a finite number, got {value!r}")
        if self.mode == "linear" and self.end == self.start:
            raise RenderError("linear fog needs end != start")
        if self.mode != "linear" and self.density < 0:
            raise RenderError(f"fog density must be >= 0, got {self.density}")
        object.__setattr__(self, "color", check_rgb(self.color, "fog colour"))

    def factor(self, distance: np.ndarray) -> np.ndarray:
        """Blend factor ``f`` in [0, 1] (1 = no fog) for eye-space distances."""
        c = np.asarray(distance, dtype=np.float64)
        if self.mode == "linear":  # halved, so that end - start cannot overflow
            f = (self.end / 2 - c / 2) / (self.end / 2 - self.start / 2)
        else:
            # A product past the largest double is +inf, whose exp(-inf) = 0 is the
            # limit the formula means: no warning for it.
            with np.errstate(over="ignore"):
                f = (np.exp(-self.density * c) if self.mode == "exp"
                     else np.exp(-(self.density * c) ** 2))
        return np.clip(f, 0.0, 1.0)

    def apply(self, rgb: np.ndarray, pos_eye: np.ndarray) -> np.ndarray:
        """Fogged (K, 3) float colours for fragments at (K, 3) eye-space positions."""
        if self.distance == "radial":
            c = np.sqrt(np.einsum("ij,ij->i", pos_eye, pos_eye))
        else:
            c = np.abs(pos_eye[:, 2])
        f = self.factor(c)[:, None]
        return f * rgb + (1.0 - f) * np.asarray(self.color, dtype=np.float64)


def parse_fog(text: str, color=(128, 128, 128), distance: str = "radial") -> Fog:
    """``linear:START,END``, ``exp:DENSITY`` or ``exp2:DENSITY``."""
    mode, _, params = text.partition(":")
    mode = mode.strip().lower()
    if mode not in MODES or not params:
        raise RenderError(f"fog must look like linear:START,END, exp:DENSITY or exp2:DENSITY; "
                          f"got {text!r}")
    try:
        values = [float(p) for p in params.split(",")]
    except ValueError:
        raise RenderError(f"fog parameters must be numbers, got {params!r}") from None
    if mode == "linear":
        if len(values) != 2:
            raise RenderError(f"linear fog needs START,END; got {params!r}")
        return Fog("linear", start=values[0], end=values[1], color=color, distance=distance)
    if len(values) != 1:
        raise RenderError(f"{mode} fog needs one DENSITY; got {params!r}")
    return Fog(mode, density=values[0], color=color, distance=distance)
