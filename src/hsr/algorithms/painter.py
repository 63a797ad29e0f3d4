"""The painter's algorithm (seed 000, 001, 003): sort triangles by depth, farthest first,
and paint them in that order with no depth test, so nearer ones cover farther ones.

It is *expected* to be wrong where no back-to-front order of whole triangles exists
(cyclic overlap, penetration) or where the sort key misorders two overlapping triangles;
``stats["pixels_wrong"]`` counts the pixels where it differs from the z-buffer, and
:func:`hsr.explain.compare.difference_map` draws them.
"""

from __future__ import annotations

import numpy as np

from ..errors import RenderError
from ..geometry.state import DepthFunc, RenderState
from ..parallel import Workers
from ..raster.fill import rasterize
from . import zbuffer
from .fragments import Fragments
from .support import Needs, apply_clear_depth, refuse_unless_nearest_wins, refuse_unsupported

NAME = "painter"
KEYS = ("max", "centroid", "min")
# Accepted keys of render(..., options=...) and what each takes.
OPTIONS = {"key": KEYS, "check": bool}
DESCRIPTION = "depth sort (max / centroid / min key), paint far to near; fails on cycles"


def sort_far_to_near(depth_window: np.ndarray, key: str) -> np.ndarray:
    """Indices farthest first by the key depth (window depth grows with distance);
    stable, so equal keys keep submission order."""
    if key == "max":
        k = depth_window.max(axis=1)
    elif key == "min":
        k = depth_window.min(axis=1)
    elif key == "centroid":
        k = depth_window.mean(axis=1)
    else:
        raise RenderError(f"painter key must be one of {', '.join(KEYS)}; got {key!r}")
    return np.argsort(-k, kind="stable")


def check(state: RenderState, needs: Needs) -> None:
    """Raise :class:`RenderError` for a request painter cannot honour exactly."""
    refuse_unless_nearest_wins(NAME, state)
    refuse_unsupported(NAME, state, needs, allowed=("counts", "subset", "offset"))


def resolve(screen, state: RenderState, workers: Workers | None = None,
            counts: bool = False, key: str = "max", check: bool = True, **_) -> Fragments:
    """Painter's algorithm. ``key`` picks the sort depth; ``check`` also runs the
    z-buffer to count the pixels where painting got it wrong."""
    workers = workers or Workers()
    order = sort_far_to_near(screen.depth_window, key)
    # Paint each triangle over whatever is there (ALWAYS, depth written, so the depth
    # buffer keeps the depth of the last painted fragment).
    face, depth, _, tested, written, c_tested, c_written = rasterize(
        screen.xy_window[order], screen.depth_window[order], screen.face_id[order],
        screen.width, screen.height, state, workers, depth_test=True,
        depth_func=DepthFunc.ALWAYS.code, depth_write=True, counts=counts)
    stats = {"key": key, "fragments_tested": int(tested), "fragments_written": int(written),
             "cleared_by_clear_depth": apply_clear_depth(face, depth, state)}
    fragments = Fragments(face, depth, screen, stats, c_tested, c_written)
    if check:
        truth = zbuffer.resolve(screen, state, workers=workers)
        wrong = face != truth.face_id
        stats["pixels_wrong"] = int(np.count_nonzero(wrong))
        fragments.buffers["wrong"] = wrong
    return fragments
