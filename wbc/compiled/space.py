"""The compiled cascade's work space: two buffers a solver allocates once, viewed in place.

:func:`wbc.compiled.ticks.cascade_solve` took its work arrays from the allocator at every
call (the level solver's space, each level's copies, the inequality rows' working matrices and
their multipliers' QR: 21–41 allocations a tick on ``walk_strict``) at addresses the allocator
chose. With the space (a float64 and an int64 buffer of the solver's plans,
:class:`wbc.solvers.plan.CascadePlan`) it carves them as views of those buffers, densely and
sized by the tick's own rows, from the same addresses at every tick: nothing is allocated,
and a tick that comes after other work finds less of it evicted. The views have the shapes
and types the allocations had, so the arithmetic is the same to the bit. A buffer too small
for a tick (a caller without one: the weighted QP, the numpy path) is allocated in the call.

Layout: the level solver's space (:func:`level_space_at`, :func:`wbc.compiled.lsq.level_space`'s
arrays), each level's vectors (its entry Δq, its solution without its rows, a copy for the
proximal steps; its bounds' sets), then the inequality rows' working arrays
(:func:`inequality_work`) and, after them, their multipliers' QR (:func:`multiplier_work`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from ._cache import refresh
from .lsq_linalg import _N_IVEC, _N_VEC
from .lsq_update import _U_Q, _U_ROWS

#: the level solver's space holds this many inequality rows joining a level (more: a larger
#: one, allocated then)
SPACE_ROWS = 8
#: the vectors of a level (floats: its entry Δq, its solution without its rows, the proximal
#: steps' start; integers: its bounds' set kept, and that of its solution without its rows)
LEVEL_FLOATS = 3
LEVEL_INTS = 2


@njit(cache=True)
def level_space_size(m: int, n: int, p: int) -> tuple:
    """The floats and integers of :func:`level_space_at` (m, n, p: as ``level_space``'s)."""
    pp = (p + 3) & ~3
    rows = max(m, n, _N_VEC)
    cols = max(m, n, pp)
    floats = 4 * rows * cols + (_U_ROWS * n + _U_Q) * max(n, pp) + n * (n + 1)
    floats += n * (2 * n + 3) + 3 * n
    return floats, _N_IVEC * max(m, n) + n + 6


@njit(cache=True)
def level_space_at(fw, iw, m, n, p) -> tuple:
    """:func:`wbc.compiled.lsq.level_space`'s arrays as views of fw (float64) and iw (int64)
    from their starts (:func:`level_space_size` of each), the update's rows for released
    bounds (U's, K) at their full size (so that a call allocates none); the base's and
    carry's entries zeroed as there."""
    pp = (p + 3) & ~3
    rows = max(m, n, _N_VEC)
    cols = max(m, n, pp)
    o = 4 * rows * cols
    work = fw[:o].reshape((4, rows, cols))
    u = (_U_ROWS * n + _U_Q) * max(n, pp)
    U = fw[o : o + u].reshape((_U_ROWS * n + _U_Q, max(n, pp)))
    o += u
    S = fw[o : o + n * (n + 1)].reshape((n, n + 1))
    o += n * (n + 1)
    K = fw[o : o + n * (2 * n + 3)].reshape((n, 2 * n + 3))
    o += n * (2 * n + 3)
    saved = fw[o : o + 3 * n].reshape((3, n))
    k = _N_IVEC * max(m, n)
    ind = iw[:k].reshape((_N_IVEC, max(m, n)))
    base = iw[k : k + n]
    carry = iw[k + n : k + n + 6]
    base[:] = 0
    carry[:] = 0
    return (work, ind, U, S, K, saved, base, carry, np.int64(m), np.int64(p))


@njit(cache=True)
def inequality_size(m0: int, p0: int, p: int, n: int) -> tuple:
    """The floats and integers of :func:`inequality_work` (without the multipliers')."""
    return (m0 + p) * (n + 2) + (p0 + p) * (n + 1) + 2 * n, 2 * p


@njit(cache=True)
def inequality_work(fw, iw, m0, p0, p, n) -> tuple:
    """The working arrays of :func:`wbc.compiled.ticks.solve_with_inequalities` (A0's rows and
    the hard rows, B0's and the soft ones, their right sides, the multipliers, the feasible
    point, the proximal steps' start; the working rows in order and their drops, zeroed) as
    views of fw and iw from their starts."""
    m = m0 + p
    q = p0 + p
    A = fw[: m * n].reshape((m, n))
    o = m * n
    B = fw[o : o + q * n].reshape((q, n))
    o += q * n
    a = fw[o : o + m]
    lam = fw[o + m : o + 2 * m]
    r = fw[o + 2 * m : o + 2 * m + q]
    o += 2 * m + q
    xc = fw[o : o + n]
    previous = fw[o + n : o + 2 * n]
    rows = iw[:p]
    drops = iw[p : 2 * p]
    drops[:] = 0
    return A, a, B, r, lam, xc, previous, rows, drops


@njit(cache=True)
def multiplier_size(m: int, n: int) -> tuple:
    """The floats and integers of :func:`multiplier_work` for m rows of n variables."""
    return n + 2 * max(m, n, _N_VEC) * max(m, n), _N_IVEC * max(m, n)


@njit(cache=True)
def multiplier_work(fw, iw, m, n) -> tuple:
    """:func:`wbc.compiled.lsq_multipliers.equality_multipliers`' work arrays (its gradient,
    zeroed; W, V and ind) as views of fw and iw from their starts."""
    rows = max(m, n, _N_VEC)
    cols = max(m, n)
    grad = fw[:n]
    grad[:] = 0.0
    work = fw[n : n + 2 * rows * cols].reshape((2, rows, cols))
    ind = iw[: _N_IVEC * cols].reshape((_N_IVEC, cols))
    return grad, work[0], work[1], ind


@njit(cache=True)
def keep_size(levels: int, n: int, p: int) -> int:
    """The integers of the sets :func:`wbc.compiled.ticks.cascade_solve` keeps for its fallback
    (a flag, up to levels + 2 bounds' sets of n, the levels' working sets of p rows)."""
    return 1 + (levels + 2) * n + levels * p


@njit(cache=True)
def cascade_space_size(level_rows, n: int, p: int) -> tuple:
    """The floats and integers of the space of :func:`wbc.compiled.ticks.cascade_solve` for
    levels ``level_rows`` (boundaries), n variables and p inequality rows: the level solver's
    space, the levels' vectors, then the inequality rows' arrays with room for the
    multipliers of :data:`SPACE_ROWS` hard rows joining the last level, and at the end the
    sets kept for the fallback (:func:`keep_size`)."""
    levels = level_rows.shape[0] - 1
    above = level_rows[max(levels - 1, 0)]
    widest = np.int64(0)  # (not a literal 0: inequality_size compiled for int64 once)
    for k in range(levels):
        widest = max(widest, level_rows[k + 1] - level_rows[k])
    f0, i0 = level_space_size(above + SPACE_ROWS, n, widest + SPACE_ROWS)
    f1, i1 = inequality_size(above, widest, p, n)
    f2, i2 = multiplier_size(above + min(p, SPACE_ROWS), n)
    return f0 + LEVEL_FLOATS * n + f1 + f2, i0 + LEVEL_INTS * n + i1 + i2 + keep_size(levels, n, p)


# numba caches these on this file alone: flush them when the layout constants change
_HERE = Path(__file__).parent
refresh(
    [
        level_space_size,
        level_space_at,
        inequality_size,
        inequality_work,
        multiplier_size,
        multiplier_work,
        keep_size,
        cascade_space_size,
    ],
    [_HERE / "lsq_linalg.py", _HERE / "lsq_update.py"],
)
