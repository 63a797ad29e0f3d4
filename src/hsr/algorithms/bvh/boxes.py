"""Slab tests of a node's eight child boxes for one ray or a packet, the careful versions
(a ray parallel to a slab, or a bound the float32 boxes must not cut short); the fast
eight-lane test is :func:`hsr.algorithms.simd.box_keys8`."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import SLACK, SLACK_ABS, float_bits
from .layout import LANES

__all__ = ["inverse_direction", "careful_keys8", "careful_packet_keys8", "open_slabs"]


@njit(cache=True, nogil=True, inline="always")
def inverse_direction(dx, dy, dz):
    """(1 / dx, 1 / dy, 1 / dz, careful) for the slab tests: +inf for a zero component,
    and ``careful`` when there is one (0 * inf is NaN there; see :func:`open_slabs`)."""
    return (1.0 / dx if dx != 0.0 else np.inf, 1.0 / dy if dy != 0.0 else np.inf,
            1.0 / dz if dz != 0.0 else np.inf, dx == 0.0 or dy == 0.0 or dz == 0.0)


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
    return t_in if t_in <= t_out * SLACK + SLACK_ABS and t_in <= bound else np.inf


@njit(cache=True, nogil=True, inline="always")
def careful_keys8(box, w, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound, keys):
    """:func:`hsr.algorithms.simd.box_keys8` lane by lane with the NaN care of
    :func:`_careful_entry`, for rays with a zero direction component."""
    mask = 0
    for lane in range(LANES):
        e = _careful_entry(box, w, lane, ox, oy, oz, inv_dx, inv_dy, inv_dz, bound)
        keys[lane] = float_bits(e) & ~7 | lane
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
