"""The equalities' multipliers at a stationary point, from the pivoted QR of the compiled
least-squares level solver (:mod:`wbc.compiled.lsq_linalg`): the hierarchy's hard rows'
multipliers (:func:`wbc.compiled.ticks._hard_multipliers`) and their certificate."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from ._cache import refresh
from .lsq_linalg import (
    _I_FREE,
    _I_PERM,
    _N_IVEC,
    _N_VEC,
    _V_LAM,
    _V_T,
    _V_TAU,
    _pivoted_qr_rows,
    _r11_solve,
    _reflect_vector,
)


@njit(cache=True)
def equality_multipliers(A, state, g, lam, rank_rtol=1e-9) -> bool:
    """λ with ``A_Fᵀ λ = −g_F`` on the free variables F (``state == 0``): the multipliers of
    the equalities A x = a at a point whose gradient is g, a basic solution from the pivoted
    QR of A_Fᵀ (rows found dependent get λ = 0), into ``lam`` (m). False if the system has no
    solution (residual above 1e-7·(1 + ‖g_F‖)): the point is not stationary."""
    m, n = A.shape
    size = max(m, n, _N_VEC)
    work = np.empty((2, size, max(m, n)))
    ind = np.empty((_N_IVEC, max(m, n)), dtype=np.int64)
    return equality_multipliers_in(A, state, g, lam, rank_rtol, work[0], work[1], ind)


@njit(cache=True)
def equality_multipliers_in(A, state, g, lam, rank_rtol, W, V, ind) -> bool:
    """:func:`equality_multipliers` in work arrays W, V (at least max(m, n, 16) × max(m, n))
    and ind (6 × max(m, n), int64): no allocation."""
    m, n = A.shape
    nf = np.int64(0)
    for j in range(n):
        if state[j] == 0:
            ind[_I_FREE, nf] = j
            nf += 1
    for row in range(m):
        ind[_I_PERM, row] = row
        for c in range(nf):
            W[row, c] = A[row, ind[_I_FREE, c]]
    k = _pivoted_qr_rows(W, m, nf, V, ind, rank_rtol) if m > 0 and nf > 0 else 0
    norm = 0.0
    for c in range(nf):  # u = Qᵀ (−g_F), the reflectors in order
        V[_V_T, c] = -g[ind[_I_FREE, c]]
        norm += V[_V_T, c] * V[_V_T, c]
    for j in range(k):
        if V[_V_TAU, j] != 0.0:
            _reflect_vector(W, j, nf, V[_V_TAU, j], V, _V_T)
    miss = 0.0
    for c in range(k, nf):
        miss += V[_V_T, c] * V[_V_T, c]
    if np.sqrt(miss) > 1e-7 * (1.0 + np.sqrt(norm)):
        return False
    _r11_solve(W, k, V, _V_T, _V_LAM)  # R11 λ'' = u[:k]
    for i in range(m):
        lam[i] = 0.0
    for j in range(k):
        lam[ind[_I_PERM, j]] = V[_V_LAM, j]
    return True


# numba caches these on this file alone: flush them when the kernels they call change
refresh(
    [equality_multipliers, equality_multipliers_in], [Path(__file__).with_name("lsq_linalg.py")]
)
