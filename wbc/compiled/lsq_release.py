"""The damped last level's speed-bound set carried to the next tick, its weakly held bounds
marked to be released at the start (an option: ``HierarchicalQP.release_small``).

The hierarchy's last level is first solved without its inequality rows, from the set that
solve ended with at the last tick (``states[L]`` of :func:`wbc.compiled.ticks.cascade_solve`).
When a bound the last tick held with a small multiplier is not held any more, PDAS's first
exchange releases it beside fixing others it should not, overshoots, and the dual method walks
back one bound at a time (walk_strict's slowest ticks: 8-10 subproblems where the answer's set
is one exchange away). A bound held with |μ_j| < ratio · max_i |μ_i| (the largest multiplier of
the bounds that solve held, pinned variables aside) is written into ``states[L]`` as ±2 instead
of ±1 (:func:`mark_weak`); the next tick's solve starts with it released
(:func:`release_marked`). Any start reaches the same minimiser (the level is strictly convex),
on another path: the same Δq up to rounding, not bit for bit. A solver that reads ±2 as ±1
(every other reader of ``states``: ``lsq._solve`` takes the sign) sees the last tick's set.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from ._cache import refresh
from .lsq_linalg import _V_MU

#: the mark of a weakly held bound in a carried set (the sign: the side it was held at)
WEAK = 2


@njit(cache=True)
def release_marked(state: np.ndarray) -> int:
    """The bounds marked weak (±:data:`WEAK`) in ``state`` set free (0); how many."""
    freed = 0
    for j in range(state.shape[0]):
        if state[j] == WEAK or state[j] == -WEAK:
            state[j] = 0
            freed += 1
    return freed


@njit(cache=True)
def mark_weak(
    state: np.ndarray, V: np.ndarray, lower: np.ndarray, upper: np.ndarray, ratio: float
) -> int:
    """Mark (±:data:`WEAK`) each bound ``state`` holds (±1, not a pinned variable: lower <
    upper) whose multiplier (``V``'s row of them, :mod:`wbc.compiled.lsq_linalg`, as the
    solve that wrote ``state`` left it) is below ``ratio`` × the largest of those; how many."""
    largest = 0.0
    for j in range(state.shape[0]):
        if state[j] != 0 and lower[j] < upper[j]:
            largest = max(largest, abs(V[_V_MU, j]))
    marked = 0
    for j in range(state.shape[0]):
        if state[j] != 0 and lower[j] < upper[j] and abs(V[_V_MU, j]) < ratio * largest:
            state[j] = WEAK if state[j] > 0 else -WEAK
            marked += 1
    return marked


# numba caches these on this file alone: flush them when the kernels they call change
refresh([release_marked, mark_weak], [Path(__file__).with_name("lsq_linalg.py")])
