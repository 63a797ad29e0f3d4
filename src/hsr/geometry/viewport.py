"""The viewport: which image sizes a render accepts."""

from __future__ import annotations

import numpy as np

from ..errors import RenderError
from ..scene.camera import MAX_IMAGE_SIDE

__all__ = ["MAX_SIZE", "BYTES_PER_PIXEL", "check_size", "check_memory", "available_memory"]

# Largest image side (see hsr.scene.camera.MAX_IMAGE_SIDE).
MAX_SIZE = MAX_IMAGE_SIDE
# What a render holds per pixel at its peak, rounded up: colour (3), depth (4), face id (4),
# object id (4), the fill's and the shading's per-pixel temporaries (row and column
# indices, barycentrics, colours in float64).
BYTES_PER_PIXEL = 64
# Frames needing less than this are not checked against the memory available.
_ALWAYS_FITS = 256 << 20


def check_size(width, height) -> None:
    """Raise :class:`RenderError` unless ``width`` and ``height`` are integers in
    1..:data:`MAX_SIZE`."""
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise RenderError(f"{name} must be an integer, got {value!r}")
        if not 0 < value <= MAX_SIZE:
            raise RenderError(f"{name} must be in 1..{MAX_SIZE}, got {value}")


def available_memory() -> int | None:
    """Bytes of memory available to new allocations (Linux: MemAvailable), or None when
    the system does not say."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        import os

        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(width: int, height: int, bytes_per_pixel: int = BYTES_PER_PIXEL,
                 what: str = "render") -> None:
    """Refuse, before anything is allocated, an image whose buffers cannot fit in the
    memory available now (:class:`RenderError` with both sizes)."""
    need = width * height * bytes_per_pixel
    if need <= _ALWAYS_FITS:
        return  # no need to ask the system on every small render
    have = available_memory()
    if have is not None and need > have:
        raise RenderError(f"a {width}x{height} {what} needs about {need / 2**30:.1f} GiB "
                          f"({bytes_per_pixel} bytes a pixel); {have / 2**30:.1f} GiB "
                          f"are available")
