"""Compiled calls around a tick that were several calls, one each.

In a 50 Hz loop every tick finds its code cold, and pays for each distinct piece of code it
runs: a numba entry point 1–3 µs, numpy's first call ~10 µs (benchmarks/self_collision.md).
So the checks and resets that a tick makes besides its rows and its solve are one compiled
call each here:

- :func:`configuration_check`: a configuration's base-quaternion defect
  (:func:`~wbc.compiled.checks.quaternion_defect`) and whether a joint is outside its range
  (:func:`~wbc.compiled.checks.outside`) at once (:meth:`wbc.model.Kinematics.update`; the
  solver reads the second after its solve instead of asking again);
- :func:`forget_sets`: a compiled plan's warm sets started afresh before its tick (its bounds'
  active sets above a level, every inequality row's working flag), what two numpy ``fill``
  calls did; :func:`gather_forget`: the same after the plan's constraints' parameters
  gathered (:func:`~wbc.compiled.checks.gather`), the call before it in a tick (a numba entry
  point ~5 µs at the end of a cold tick: benchmarks/self_collision.md).

numba caches a kernel on its own file only: :func:`refresh` flushes these when
:mod:`wbc.compiled.checks` changed.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from numba import njit, types

from ._cache import refresh
from .checks import gather, outside, quaternion_defect


@njit(cache=True)
def configuration_check(q: np.ndarray, q_min: np.ndarray, q_max: np.ndarray) -> tuple:
    """(|‖q[3:7]‖² − 1| or +inf if an entry of q is not finite, True if a joint of q is outside
    [q_min, q_max]): :func:`~wbc.compiled.checks.quaternion_defect` and
    :func:`~wbc.compiled.checks.outside` in one call."""
    return quaternion_defect(q), outside(q, q_min, q_max)


@njit(cache=True)
def forget_sets(states: np.ndarray, upto: int, working: np.ndarray) -> None:
    """``states[:upto]`` (the bounds' active sets of the levels above ``upto``) set to 0 and
    every flag of ``working`` (the inequality rows' working sets) to False."""
    for k in range(min(upto, states.shape[0])):
        for j in range(states.shape[1]):
            states[k, j] = 0
    for k in range(working.shape[0]):
        for j in range(working.shape[1]):
            working[k, j] = False


@njit(cache=True)
def gather_forget(
    addresses: np.ndarray,
    sizes: np.ndarray,
    out: np.ndarray,
    states: np.ndarray,
    upto: int,
    working: np.ndarray,
) -> None:
    """:func:`~wbc.compiled.checks.gather` (``addresses``, ``sizes`` into ``out``; no q), then
    :func:`forget_sets` (``states``, ``upto``, ``working``): one call."""
    empty = np.empty(0)
    gather(addresses, sizes, out, empty, empty)
    forget_sets(states, upto, working)


def configuration_entry() -> Callable[..., tuple[float, bool]]:
    """:func:`configuration_check`'s entry point for float64 vectors of any strides (as
    :func:`~wbc.compiled.checks.outside`'s own: an entry point checks no argument's layout)."""
    vector = types.float64[:]
    signature = (vector, vector, vector)
    configuration_check.compile(signature)
    return configuration_check.overloads[signature].entry_point


refresh([configuration_check, forget_sets, gather_forget], [Path(__file__).with_name("checks.py")])
