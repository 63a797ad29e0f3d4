"""The visibility algorithms. Each module has ``NAME``, ``DESCRIPTION``, ``OPTIONS`` (the
keys it accepts from ``render(..., options=...)``) and
``resolve(screen, state, ...) -> Fragments``; :data:`ALGORITHMS` is the registry the API
and the CLI read."""

from __future__ import annotations

from . import bsp, newell, painter, raycast, scanline, zbuffer

ALGORITHMS = {module.NAME: module for module in (zbuffer, scanline, raycast, painter, newell,
                                                 bsp)}

__all__ = ["ALGORITHMS"]
