"""The viewport: which image sizes a render accepts."""

from __future__ import annotations

import numpy as np

from ..errors import RenderError

__all__ = ["MAX_SIZE", "check_size"]

# Largest image side: keeps snapped window coordinates well inside int64 edge arithmetic
# and buffers of a sane size.
MAX_SIZE = 32768


def check_size(width, height) -> None:
    """Raise :class:`RenderError` unless ``width`` and ``height`` are integers in
    1..:data:`MAX_SIZE`."""
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise RenderError(f"{name} must be an integer, got {value!r}")
        if not 0 < value <= MAX_SIZE:
            raise RenderError(f"{name} must be in 1..{MAX_SIZE}, got {value}")
