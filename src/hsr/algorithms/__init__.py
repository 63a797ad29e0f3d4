"""The visibility algorithms. Each module has ``NAME``, ``DESCRIPTION``, ``OPTIONS`` (the
keys it accepts from ``render(..., options=...)``), ``check(state, needs)`` (raises
:class:`~hsr.errors.RenderError` for a request it cannot honour exactly) and
``resolve(screen, state, ...) -> Fragments``; :data:`ALGORITHMS` is the registry the API
and the CLI read. The data structures live beside their algorithm: the BVH
(:mod:`.bvh`) next to the ray caster, the BSP tree (:mod:`.bsp_tree`) next to its walk,
hierarchical-z occlusion culling (:mod:`.hiz`) next to the z-buffer."""

from __future__ import annotations

import numpy as np

from ..errors import RenderError, check_choice
from . import bsp, newell, painter, raycast, scanline, zbuffer
from .support import Needs

ALGORITHMS = {module.NAME: module for module in (zbuffer, scanline, raycast, painter, newell,
                                                 bsp)}

__all__ = ["ALGORITHMS", "Needs", "check", "check_option"]


def check(name: str, options: dict, state, needs: Needs) -> None:
    """Raise :class:`RenderError` unless algorithm ``name`` exists, accepts every key of
    ``options`` and honours ``state`` with ``needs`` exactly."""
    if not isinstance(name, str) or name not in ALGORITHMS:
        raise RenderError(
            f"unknown algorithm {name!r}; choose from {', '.join(sorted(ALGORITHMS))}")
    if not isinstance(options, dict):
        raise RenderError(f"options must be a dict, got {type(options).__name__}")
    module = ALGORITHMS[name]
    unknown = sorted(set(options) - set(module.OPTIONS))
    if unknown:
        accepted = ", ".join(module.OPTIONS) or "none"
        raise RenderError(f"{name} has no option {', '.join(unknown)} (accepted: {accepted})")
    for key, value in options.items():
        check_option(name, key, value, module.OPTIONS[key])
    module.check(state, needs)


def check_option(name: str, key: str, value, kind) -> None:
    """``kind`` is what an algorithm's option takes: ``bool``, ``int`` (>= 0), a tuple of
    allowed strings, or a class whose instances it accepts (a prebuilt BVH or BSP tree)."""
    if kind is bool:
        ok, wanted = isinstance(value, (bool, np.bool_)), "true or false"
    elif kind is int:
        ok = bool(isinstance(value, (int, np.integer)) and not isinstance(value, bool)
                  and value >= 0)
        wanted = "an integer >= 0"
    elif isinstance(kind, tuple):
        check_choice(value, kind, f"{name} option {key}")
        return
    else:
        ok, wanted = isinstance(value, kind), f"an {kind.__module__.split('.')[0]}." \
            f"{kind.__name__}"
    if not ok:
        raise RenderError(f"{name} option {key} must be {wanted}, got {value!r}")
