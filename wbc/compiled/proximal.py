"""Proximal steps on an intermediate level of the hierarchy (no ridge) whose exact
least-squares solve failed (:func:`wbc.compiled.ticks.cascade_solve`'s levels)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from ._cache import refresh
from .lsq import OK, _solve

#: ridge of a proximal step on an intermediate level, relative to its mean squared row norm
PROXIMAL_RIDGE = 1e-8
#: at most this many proximal steps (the residual's bias shrinks by ε/(σ² + ε) per step)
PROXIMAL_STEPS = 12


@njit(cache=True)
def proximal_level(A, a, B, r, lower, upper, state, x, max_iter, ties, space) -> int:
    """min ‖B x − r‖² s.t. A x = a and the bounds, from a feasible x, by proximal steps:
    y = argmin ‖B (x + y) − r‖² + ε‖y‖² (same constraints), x += y, until y vanishes.

    Each step is strictly convex (the active set settles), and the ridge only pulls towards
    the last iterate, so the steps converge to the exact least-squares optimum (closest to
    the start among the optima) instead of leaving a ridge's bias on the level's residual.
    ε is relative to the rows' mean squared norm. ``ties``: the steps' PDAS budget
    (:func:`~wbc.compiled.lsq.solve_level`'s). The steps are solved in ``space``
    (:func:`~wbc.compiled.lsq.level_space`, the level's: no work space allocated a step —
    24 steps on the lateral walk's slowest ticks; the same arithmetic, so the same answers),
    kept by no step (a following call on it does not continue from them).
    """
    m, n = B.shape
    scale = 0.0
    for i in range(m):
        for j in range(n):
            scale += B[i, j] * B[i, j]
    ridge = PROXIMAL_RIDGE * max(1.0, scale / max(m, 1))
    a_s = np.empty(a.shape[0])
    r_s = np.empty(m)
    lo = np.empty(n)
    hi = np.empty(n)
    y = np.zeros(n)
    status = OK
    for step in range(PROXIMAL_STEPS):
        for i in range(a.shape[0]):
            a_s[i] = a[i] - np.dot(A[i], x)
        for i in range(m):
            r_s[i] = r[i] - np.dot(B[i], x)
        for j in range(n):
            lo[j] = lower[j] - x[j]
            hi[j] = upper[j] - x[j]
        # (solve_level_in's value types: one specialisation of _solve)
        status, _ = _solve(
            A, a_s, B, r_s, float(ridge), lo, hi, state, y, 1e-9, int(max_iter), space,
            np.bool_(False), np.bool_(False), int(ties), np.bool_(step > 0),
        )  # fmt: skip
        if status != OK:
            return status
        moved = 0.0
        for j in range(n):
            x[j] = min(max(x[j] + y[j], lower[j]), upper[j])
            moved = max(moved, abs(y[j]))
        if moved <= 1e-13:
            break
    return status


# numba caches these on this file alone: flush them when the kernels they call change
_HERE = Path(__file__).parent
refresh(
    [proximal_level],
    [_HERE / f for f in ("lsq.py", "lsq_subproblem.py", "lsq_update.py", "lsq_linalg.py")],
)
