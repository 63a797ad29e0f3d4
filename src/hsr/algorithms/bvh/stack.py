"""A walk's stack of boxes still to enter, nearest first, as the int32 keys of
:func:`hsr.algorithms.simd.box_keys8`, pruned by the best hit found since they were
pushed (:func:`bound_key`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import float_bits
from .boxes import above32
from .layout import LANES, nowrap

__all__ = ["stack_size", "walk_stack", "bound_key", "next_box"]


@njit(cache=True, nogil=True, inline="always")
def stack_size(wide_depth):
    """Slots of one walk's stack: each of the ``wide_depth + 1`` wide levels a walk
    passes through leaves at most LANES - 1 siblings behind, which
    ``(LANES - 1) * wide_depth + 2 * LANES`` covers with room to spare."""
    return (LANES - 1) * wide_depth + 2 * LANES


@njit(cache=True, nogil=True)
def walk_stack(wide_depth, walks):
    """(references, counts, entry keys (int32)) of the stacks of ``walks`` walks, each
    :func:`stack_size` slots, one after another. Sized once per walk: an array re-bound
    inside the loop (grown on demand) costs reference counting at every step, more than
    doubling the walk's time."""
    size = walks * stack_size(wide_depth)
    return (np.empty(size, dtype=np.int64), np.empty(size, dtype=np.int64),
            np.empty(size, dtype=np.int32))


@njit(cache=True, nogil=True, inline="always")
def bound_key(bound):
    """The key a box's key is compared with to be kept under ``bound`` (>= 0, or -0.0):
    the bits of a float32 at least the bound (:func:`hsr.algorithms.bvh.boxes.above32`)
    with the three low bits set. A box whose exact entry is at most the bound has a key
    whose entry part (``key & ~7``) is at most the bound's float32, whatever its lane
    bits, so it passes; the bits of the bound itself failed the keys of lanes 1 to 7
    entered at 0 when a hit at t = 0 (a ray from a vertex) had made the bound 0."""
    return float_bits(above32(bound)) | 7


@njit(cache=True, nogil=True, inline="always")
def next_box(stack_ref, stack_count, stack_t, top, limit, bottom):
    """The next box still worth entering from the stack (slots ``bottom .. top - 1``;
    one array can hold several rays' stacks): ``(ref, n, top, found)``;
    boxes entered beyond the walk's bound (a hit nearer than them has been found since
    they were pushed) are dropped: those whose key is above ``limit``, the bound's
    :func:`bound_key`. The stack holds entries as keys of
    :func:`hsr.algorithms.simd.sort_keys8`, each at most the box's exact entry (the box
    tests make them so)."""
    while top > bottom:
        top -= 1
        up = nowrap(top)  # (no negative-index wraparound)
        if stack_t[up] <= limit:
            return np.int64(stack_ref[up]), np.int64(stack_count[up]), top, True
    return np.int64(0), np.int64(0), top, False
