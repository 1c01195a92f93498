"""The box of a stack's limits on Δq: each box limit's own (their bound kernels fill them: the
joint position and velocity limits, any other) folded into one, the first kept and each other
intersected in turn. One definition for every path: the compiled tick folds each box as its
kernel writes it (:mod:`wbc.compiled.template`), the self-collision rows' speed box
(:mod:`wbc.limits.collision_packed`) and :func:`wbc.limits.box_bounds` call these."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def fold_box(lower: np.ndarray, upper: np.ndarray, b_lo: np.ndarray, b_hi: np.ndarray) -> None:
    """Intersect the box [b_lo, b_hi] into [lower, upper] (what the limits before it leave);
    where it leaves no room, it wins, moved as far towards [lower, upper] as it allows (a
    joint outside its range comes back at the servo's speed, never further out)."""
    for i in range(lower.shape[0]):
        lo = lower[i]
        hi = upper[i]
        new_lo = max(lo, b_lo[i])
        new_hi = min(hi, b_hi[i])
        if new_lo > new_hi:
            new_lo = min(max(lo, b_lo[i]), b_hi[i])
            new_hi = max(min(hi, b_hi[i]), b_lo[i])
        lower[i] = new_lo
        upper[i] = new_hi


@njit(cache=True)
def fold_boxes(boxes: np.ndarray, n: int, lower: np.ndarray, upper: np.ndarray) -> None:
    """The box of a stack's limits from each limit's own (``boxes[i]``: lower, upper; the
    first ``n``, the joint position limit first): the first, then each of the others folded
    in turn by :func:`fold_box`. One definition for every path (the compiled tick folds each
    box as its kernel writes it; :func:`wbc.limits.box_bounds` calls this)."""
    for i in range(lower.shape[0]):
        lower[i] = boxes[0, 0, i]
        upper[i] = boxes[0, 1, i]
    for k in range(1, n):
        fold_box(lower, upper, boxes[k, 0], boxes[k, 1])
