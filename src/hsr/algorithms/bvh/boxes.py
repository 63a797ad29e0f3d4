"""Slab tests of a node's eight child boxes: the ray made ready for the fast float32
eight-lane test of one ray (:func:`box_frame`, :func:`box_bound`; the test is
:func:`hsr.algorithms.simd.box_keys8`), and the careful float64 versions for one ray or
a packet (a ray parallel to a slab, or one float32 cannot hold)."""

from __future__ import annotations

import sys

import numpy as np
from numba import njit

from ..simd import SLACK, SLACK_ABS, float_bits
from .layout import LANES

__all__ = ["inverse_direction", "box_reach", "box_frame", "box_bound", "slack_bound",
           "below32", "above32", "careful_keys8", "careful_packet_keys8", "open_slabs"]

# float32's unit roundoff.
_U32 = 2.0**-24

# A ray whose box distances could reach this (or whose inverse direction is below its
# inverse) takes the careful float64 test: float32 then keeps them normal and finite.
FIT32 = 2.0**100

# The largest float64.
_FLOAT_MAX = sys.float_info.max

# The largest float32: a bound above it would let a missed box (entered at +inf) pass.
FLOAT32_MAX = 3.4028234663852886e38

# float32's least normal number: below it float32 rounds by an absolute 2**-150.
_TINY32 = 2.0**-126


@njit(cache=True, nogil=True, inline="always")
def inverse_direction(dx, dy, dz):
    """(1 / dx, 1 / dy, 1 / dz, careful) for the slab tests: +inf for a zero component,
    and ``careful`` when there is one (0 * inf is NaN there; see :func:`open_slabs`)."""
    return (1.0 / dx if dx != 0.0 else np.inf, 1.0 / dy if dy != 0.0 else np.inf,
            1.0 / dz if dz != 0.0 else np.inf, dx == 0.0 or dy == 0.0 or dz == 0.0)


@njit(cache=True, nogil=True)
def box_reach(box, w):
    """The largest magnitude of the finite bounds of wide node ``w``'s boxes: at the
    root, of every box in the tree (each lies inside its parent's lane)."""
    reach = 0.0
    for q in range(6 * LANES):
        v = abs(np.float64(box[w, q]))
        if v < np.inf:
            reach = max(reach, v)
    return reach


@njit(cache=True, nogil=True, inline="always")
def box_frame(ox, oy, oz, inv_dx, inv_dy, inv_dz, reach):
    """The ray as :func:`hsr.algorithms.simd.box_keys8` takes it: ``(ox, oy, oz, inv_dx,
    inv_dy, inv_dz, pad)`` in float32, then ``pad`` in float64 (for :func:`box_bound`)
    and whether the ray fits float32 (if not, it takes :func:`careful_keys8`).
    ``reach``: :func:`box_reach` of the root.

    Why the pad keeps the test conservative (Ize 2013, "Robust BVH ray traversal", for
    float32): with u = 2**-24, a box's float32 bound p (|p| <= reach = M), the origin o
    rounded to o32 (off by at most u |o|) and the float64 inverse rounded to inv32
    (relative error below 1.0000001 u), the computed distance fl(fl(p - o32) inv32) has
    three relative roundings and the origin's error, so it lies within E = 4.01 u (M +
    |o|) |inv| <= 4.01 u T of the exact (p - o) / d, T = (M + max |o|) max |inv|. So a
    box the exact ray enters (t_in <= t_out) has computed distances with t_in' <= t_out'
    + 2 E, and the test's ``t_in' <= fl(t_out' + pad)`` holds when pad (1 - u) >= 2 E +
    u T', which pad = 12 u T (T' <= T (1 + 5u) bounds the computed distances) gives with
    room. The key fl(t_in' - pad) is then at most the exact entry. ``fits``: T <= 2**100
    and every |inv| >= 2**-100 keep every value normal and finite (a subtraction whose
    result is subnormal is exact; pad's floor of 2**-100 covers a product that
    underflows)."""
    t_scale = (reach + max(abs(ox), abs(oy), abs(oz))) * max(abs(inv_dx), abs(inv_dy),
                                                              abs(inv_dz))
    fits = (t_scale <= FIT32) & (min(abs(inv_dx), abs(inv_dy), abs(inv_dz)) >= 1.0 / FIT32)
    pad = max(12.0 * _U32 * t_scale, 1.0 / FIT32) * (1.0 + 2.0**-20)
    return (np.float32(ox), np.float32(oy), np.float32(oz), np.float32(inv_dx),
            np.float32(inv_dy), np.float32(inv_dz), _up32(pad), pad, fits)


@njit(cache=True, nogil=True, inline="always")
def _up32(x):
    """A float32 >= x for x in float32's normal range (x (1 + 4u) rounds to nearest no
    lower than x), at most the largest float32 (rounding a larger value could give
    +inf), without the coin-flip branch of rounding to the next float32 exactly
    (:func:`hsr.algorithms.bvh.layout.up32`), which cost ~20 ns a ray."""
    return np.float32(min(x * (1.0 + 4.0 * _U32), FLOAT32_MAX))


@njit(cache=True, nogil=True, inline="always")
def box_bound(bound, pad):
    """The walk's bound (float64) for :func:`hsr.algorithms.simd.box_keys8`: bound + pad
    (the most a computed entry exceeds the exact one; :func:`box_frame`) rounded up to
    float32, at most the largest float32 so that a missed box (entered at +inf) fails
    it."""
    return _up32(bound + pad)


@njit(cache=True, nogil=True, inline="always")
def below32(x):
    """A float32 at most ``x`` (>= 0, or +inf, which stays +inf), at most the largest
    float32: ``x`` lowered by a relative 4u and by float32's least normal before it is
    rounded to nearest, so neither the relative rounding of the normal range (u) nor the
    absolute one below it (2**-150) can take it above ``x``."""
    low = np.float32(min(max(x * (1.0 - 4.0 * _U32) - _TINY32, 0.0), FLOAT32_MAX))
    return low if x < np.inf else np.float32(np.inf)


@njit(cache=True, nogil=True, inline="always")
def above32(x):
    """A float32 at least ``x`` (>= 0, or -0.0) unless ``x`` is above the largest float32,
    which it then is: :func:`_up32` of ``x`` raised by float32's least normal, so that the
    rounding below it (absolute) cannot take it under ``x`` either."""
    return _up32(x + _TINY32)


@njit(cache=True, nogil=True, inline="always")
def slack_bound(bound):
    """The bound the float64 tests compare a computed entry with: ``bound`` with the slack
    of the exit distance (:data:`hsr.algorithms.simd.SLACK`), at most the largest float.
    A computed entry may lie a few roundings above the exact one, and a box entered
    exactly at the bound (the distance of a hit found) may hold an equal hit of a lower
    face id, which the answer must not depend on the walk to find."""
    return min(bound * SLACK + SLACK_ABS, _FLOAT_MAX)


@njit(cache=True, nogil=True, inline="always")
def _lane_slabs(box, w, lane, ox, oy, oz, inv_dx, inv_dy, inv_dz):
    """The ray parameters (t0x, t1x, t0y, t1y, t0z, t1z) where the ray crosses the low
    and high planes of lane ``lane``'s box of wide node ``w``, in float64."""
    return ((np.float64(box[w, lane]) - ox) * inv_dx,
            (np.float64(box[w, 3 * LANES + lane]) - ox) * inv_dx,
            (np.float64(box[w, LANES + lane]) - oy) * inv_dy,
            (np.float64(box[w, 4 * LANES + lane]) - oy) * inv_dy,
            (np.float64(box[w, 2 * LANES + lane]) - oz) * inv_dz,
            (np.float64(box[w, 5 * LANES + lane]) - oz) * inv_dz)


@njit(cache=True, nogil=True, inline="always")
def _careful_entry(box, w, lane, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound):
    """Where the ray enters lane ``lane``'s box of wide node ``w`` (+inf: missed, or
    entered beyond ``bound``), for a ray with a zero direction component: 0 * inf (the
    ray in a slab's plane) is NaN, and the closed slab holds such a ray for every t
    (see :func:`open_slabs`)."""
    t0x, t1x, t0y, t1y, t0z, t1z = _lane_slabs(box, w, lane, ox, oy, oz, inv_dx, inv_dy,
                                               inv_dz)
    t0x, t1x, t0y, t1y, t0z, t1z = open_slabs(t0x, t1x, t0y, t1y, t0z, t1z)
    t_in = max(min(t0x, t1x), min(t0y, t1y), min(t0z, t1z), 0.0)
    t_out = min(max(t0x, t1x), max(t0y, t1y), max(t0z, t1z))
    # The slack is that of hsr.algorithms.simd (see SLACK there).
    return t_in if t_in <= t_out * SLACK + SLACK_ABS and t_in <= slack_bound(bound) else np.inf


@njit(cache=True, nogil=True, inline="always")
def careful_keys8(box, w, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound, keys):
    """:func:`hsr.algorithms.simd.box_keys8` lane by lane in float64 with the NaN care
    of :func:`_careful_entry`, for rays with a zero direction component or which float32
    cannot hold; each key (int32, as the fast test's) lowered by the slack and rounded
    down to float32, so that it is at most the exact entry."""
    mask = 0
    for lane in range(LANES):
        e = _careful_entry(box, w, lane, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound)
        # The key at most the exact entry (the walk prunes by it; e may be a few
        # roundings above). An entry beyond float32's range keeps the largest float32,
        # still before the missed lanes' +inf.
        keys[lane] = float_bits(below32(max((e - SLACK_ABS) / SLACK, 0.0))) & ~7 | lane
        mask |= (e < np.inf) << lane
    return mask


@njit(cache=True, nogil=True, inline="always")
def careful_packet_keys8(box, w, rays, bound, active, out, keys):
    """:func:`hsr.algorithms.simd.packet_keys8` ray by ray with the NaN care of
    :func:`_careful_entry`, for a packet holding a ray with a zero direction
    component."""
    mask = 0
    for k in range(LANES):
        nearest = np.inf
        for r in range(4):
            e = _careful_entry(box, w, k, rays[0, r], rays[1, r], rays[2, r], rays[3, r],
                               rays[4, r], rays[5, r], bound[r])
            out[r, k] = e
            if (active >> r) & 1 and e < np.inf:
                mask |= 1 << (4 * k + r)
                nearest = min(nearest, e)
        keys[k] = float_bits(nearest) & ~7 | k
    return mask


@njit(cache=True, nogil=True, inline="always")
def open_slabs(t0x, t1x, t0y, t1y, t0z, t1z):
    """The six slab distances with each NaN made the bound that keeps its slab open
    (-inf for a low plane, +inf for a high one). 0 * inf is NaN: a ray parallel to a
    slab (inv = inf) whose origin lies on one of its planes; the box is closed, so the
    ray lies inside that slab for every t, and min and max would pass the NaN on or
    drop it depending on argument order (a box beside the origin of an axis-aligned ray
    was missed)."""
    return (-np.inf if t0x != t0x else t0x, np.inf if t1x != t1x else t1x,
            -np.inf if t0y != t0y else t0y, np.inf if t1y != t1y else t1y,
            -np.inf if t0z != t0z else t0z, np.inf if t1z != t1z else t1z)
