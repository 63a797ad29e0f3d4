"""The ray caster's depth ranking, which its walks apply at each hit: a hit is ranked by
the window depth the rasterizer would give it (float32, glDepthRange [0, 1]), so the ray
caster keeps the face the z-buffer keeps, ties included (:func:`window_ranking`,
:func:`tie_reach`; the walks call :func:`t_bound`, :func:`depth32`,
:func:`ranks_before`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import next_float32

__all__ = ["window_ranking", "DEPTH_TIE", "REACH_MAX", "tie_reach", "clip_zw", "depth32",
           "t_bound", "ranks_before"]


def window_ranking(view_proj, depth_range) -> tuple:
    """The ray caster's ranking (``raster[3]`` of :func:`trace_range`) for the rays of
    pixels (NDC x, y in [-1, 1]) to the far plane (t = 1), from the near plane (t = 0)
    or from the eye (the near plane at t = near / far; :func:`tie_reach` holds for both),
    11 floats: rows 2 and 3 of ``view_proj`` (the ray's clip z and w), the scale and offset that
    take NDC depth to window depth for glDepthRange ``depth_range`` (near, far), and
    the rays' tie reach (:func:`tie_reach`)."""
    near, far = depth_range
    scale = 0.5 * (far - near)
    # A tuple of floats, not an array: a walk that binds an array from its ``raster``
    # tuple, or hands one to an inlined helper, counts a reference to it each time, two
    # atomic instructions; once a hit, they were 5-6% of the 1M-face terrain's filling
    # frame in a profile (one thread).
    return tuple(float(x) for x in np.concatenate([
        np.asarray(view_proj, dtype=np.float64)[2:4].ravel(),
        [scale, 0.5 * (far + near), tie_reach(view_proj, scale)]]))

# Window depths (float32, in [0, 1] between the near and far planes) that round to
# the same float32, or the wrong way round, are less than one float32 step apart (at
# most 2**-23 in [0, 1]) plus the float64 rounding of computing them (~1e-15): four
# steps bound that with room to spare.
DEPTH_TIE = 2.0 ** -21

# The largest tie reach used (far / near beyond about 100): past it, solving for the
# next float32 depth at each hit prunes boxes better.
REACH_MAX = 1e-4


def tie_reach(view_proj, depth_scale) -> float:
    """How far past a hit (in t, on [0, 1]) another hit of the same pixel ray can still
    rank before it or tie (window depths within :data:`DEPTH_TIE`), for every pixel ray
    of ``view_proj``; NaN when that bound does not hold or exceeds :data:`REACH_MAX`
    (then :func:`t_bound` solves at each hit).

    A pixel ray runs from NDC (x, y, -1) to (x, y, 1): in clip space from l0 (x, y, -1, 1)
    to l1 (x, y, 1, 1), l0 and l1 its clip w at the two planes, so along it clip w is
    W(t) = l0 + t (l1 - l0) and clip z Z(t) = -l0 + t (l1 + l0): two of its points
    differ in window depth ``scale Z / W + offset`` by ``scale (t' - t) K / (W(t)
    W(t'))`` with K = W(0) Z' - Z(0) W' = 2 l0 l1 (Z' and W' the slopes).
    A step D solves to ``t' - t = a W(t) / (1 - a (l1 - l0))``, ``a = D W(t) / (scale
    K)``; with ``a |l1 - l0| <= 1/2`` that is at most ``2 a W(t)``, so at most
    ``D / scale * max(l0, l1) / min(l0, l1)`` (``a |l1 - l0|`` is at most half of that,
    far below 1/2 for any reach kept). The ratio l1 / l0 is a ratio of affine
    functions of (x, y) (1 / l is row 3 of the inverse of ``view_proj`` times the NDC
    point), so its largest value either way is at a corner of the image. A perspective
    ray from the eye instead (the ray caster's) reaches the near plane at t0 = near /
    far, and the point at t above lies at t0 + (1 - t0) t on it: the same depth step
    spans less of it, and the reach holds."""
    if not depth_scale > 0.0:
        return np.nan
    try:
        inverse_w = np.linalg.inv(np.asarray(view_proj, dtype=np.float64))[3]
    except np.linalg.LinAlgError:
        return np.nan
    corners = np.array([[x, y] for x in (-1.0, 1.0) for y in (-1.0, 1.0)])
    near_w = 1.0 / (corners @ inverse_w[:2] - inverse_w[2] + inverse_w[3])
    far_w = 1.0 / (corners @ inverse_w[:2] + inverse_w[2] + inverse_w[3])
    if not (np.all(near_w > 0.0) and np.all(far_w > 0.0) and np.all(np.isfinite(near_w))
            and np.all(np.isfinite(far_w))):
        return np.nan
    ratio = float(np.max(np.maximum(far_w / near_w, near_w / far_w)))
    # (1 + 1e-6): the walk's clip w and z come from the rays as made, to float64 rounding.
    reach = DEPTH_TIE / depth_scale * ratio * (1.0 + 1e-6) + 1e-12
    return reach if reach <= REACH_MAX else np.nan


@njit(cache=True, nogil=True, inline="always")
def clip_zw(rank, ox, oy, oz, dx, dy, dz):
    """(zc0, zc1, wc0, wc1): clip z and w along the ray are zc0 + t zc1 and wc0 + t wc1
    (both linear in t)."""
    zc0 = rank[0] * ox + rank[1] * oy + rank[2] * oz + rank[3]
    zc1 = rank[0] * dx + rank[1] * dy + rank[2] * dz
    wc0 = rank[4] * ox + rank[5] * oy + rank[6] * oz + rank[7]
    wc1 = rank[4] * dx + rank[5] * dy + rank[6] * dz
    return zc0, zc1, wc0, wc1


@njit(cache=True, nogil=True, inline="always")
def depth32(t, zc0, zc1, wc0, wc1, depth_scale, depth_offset):
    """float32 window depth of the point at parameter t of the ray."""
    return np.float32((zc0 + t * zc1) / (wc0 + t * wc1) * depth_scale + depth_offset)


@njit(cache=True, nogil=True, inline="always")
def t_bound(t, z, zc0, zc1, wc0, wc1, rank):
    """The ray parameter past which no hit can rank before the hit at ``t`` (float32
    window depth ``z``) nor tie with it (window depth grows monotonically along the
    ray): ``t`` plus the rays' tie reach (:func:`tie_reach`, ``rank[10]``), else past
    the next float32 above ``z``. With the reach only an add waits on the hit, where
    solving takes two divisions after the depth's own, and the walk's next step waits
    on the bound (measurements: docs/history.md, "Ray core")."""
    reach, depth_scale, depth_offset = rank[10], rank[8], rank[9]
    if reach == reach:
        return min(1.0, t * (1.0 + 1e-9) + reach)
    if depth_scale == 0.0:
        return 1.0
    # next_float32, not np.nextafter, which calls libm: the same float32 for every
    # finite z.
    z_next = next_float32(z, True)
    zn = (np.float64(z_next) - depth_offset) / depth_scale
    denom = zn * wc1 - zc1
    if denom == 0.0:
        return 1.0
    solved = (zc0 - zn * wc0) / denom
    # Past the far plane (z rounded up to the far plane's depth when far / near is
    # large) the solution can cross the pole of the depth map and come out before the
    # hit; NaN for a degenerate ray: no pruning then.
    return min(1.0, solved * (1.0 + 1e-9) + 1e-12) if solved >= t else 1.0


@njit(cache=True, nogil=True, inline="always")
def ranks_before(z, f, best_z, best_f, lequal):
    """Whether a hit of window depth ``z`` on face ``f`` beats the best so far as the
    z-buffer decides (no best yet: ``best_f`` < 0): nearer, or as near and drawn later
    under GL_LEQUAL (earlier under GL_LESS, where the first drawn stays)."""
    return best_f < 0 or z < best_z or (z == best_z and (f > best_f if lequal else f < best_f))
