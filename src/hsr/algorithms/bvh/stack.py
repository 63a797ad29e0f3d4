"""A walk's stack of boxes still to enter, nearest first, as keys of
:func:`hsr.algorithms.simd.sort_keys8`, pruned by the best hit found since they were
pushed."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..simd import float_bits
from .layout import LANES

__all__ = ["stack_size", "walk_stack", "next_box"]


@njit(cache=True, nogil=True, inline="always")
def stack_size(wide_depth):
    """Slots of one walk's stack: each of the ``wide_depth + 1`` wide levels a walk
    passes through leaves at most LANES - 1 siblings behind, which
    ``(LANES - 1) * wide_depth + 2 * LANES`` covers with room to spare."""
    return (LANES - 1) * wide_depth + 2 * LANES


@njit(cache=True, nogil=True)
def walk_stack(wide_depth, walks):
    """(references, counts, entry keys) of the stacks of ``walks`` walks, each
    :func:`stack_size` slots, one after another. Sized once per walk: an array re-bound
    inside the loop (grown on demand) costs reference counting at every step, more than
    doubling the walk's time."""
    size = walks * stack_size(wide_depth)
    return (np.empty(size, dtype=np.int64), np.empty(size, dtype=np.int64),
            np.empty(size, dtype=np.int64))


@njit(cache=True, nogil=True, inline="always")
def next_box(stack_ref, stack_count, stack_t, top, bound, bottom):
    """The next box still worth entering from the stack (slots ``bottom .. top - 1``;
    one array can hold several rays' stacks): ``(ref, n, top, found)``;
    boxes entered beyond ``bound`` (a hit nearer than them has been found since they
    were pushed) are dropped. The stack holds entries as keys of
    :func:`hsr.algorithms.simd.sort_keys8`, each at most the box's exact entry (the box
    tests make them so), compared with the bound's bits (bound + 0.0 makes a bound of
    -0.0 the +0.0 whose bits are the least)."""
    bound_key = float_bits(bound + 0.0)
    while top > bottom:
        top -= 1
        if stack_t[top] <= bound_key:
            return np.int64(stack_ref[top]), np.int64(stack_count[top]), top, True
    return np.int64(0), np.int64(0), top, False
