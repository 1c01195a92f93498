"""The subproblem of the compiled least-squares level solver (:mod:`wbc.compiled.lsq`) updated
instead of solved again: after the dual active set method adds bounds to a set whose
subproblem was solved (the *base*, its QR of ``A_Fᵀ``, its ``(B_F Q)ᵀ`` and its reduced
Hessian's Cholesky factor still in the work space), the bounds added since are equalities
``c_sᵀ z = β_s`` on the base's null-space coordinates z (``c_s = Zᵀ e_s``), met through the
Schur complement ``S = Cᵀ H⁻¹ C`` of the reduced Hessian ``H = MᵀM + ridge·I`` (q × q, q the
bounds added): ``S ν = b_S − x_S``, ``z = z₀ + H⁻¹ C ν``, and ν are the added bounds'
multipliers. Only for the normal form (p ≥ d) and while every base bound is still held; a
bound whose ``c_s`` is (nearly) in the span of the others' (holding it would drop the rank of
``A_F``) or more bounds than d return False: the caller solves the subproblem afresh.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from ._cache import refresh
from .lsq_linalg import (
    _FAST,
    _I_FIXED,
    _I_FREE,
    _V_E,
    _V_LAM,
    _V_TAU,
    _V_W2,
    _axpy,
    _cholesky_solve,
    _dot,
    _r11_solve,
)
from .lsq_subproblem import _fixed_multiplier

# U's rows: the base's x, its residual e, y₀ = (Qᵀ x_F)[:k], a work vector, then Qᵀ e_s (the
# added bounds', n rows) and H⁻¹ c_s (n rows)
_U_X, _U_E, _U_Y, _U_WORK, _U_Q = 0, 1, 2, 3, 4
_C_MIN = 1e-12  # ‖c_s‖² (‖Qᵀ e_s‖ = 1) at most this: e_s is in the row space of A_F
_PIVOT_RTOL = 1e-8  # a Schur pivot ≤ _PIVOT_RTOL × its diagonal: the bound depends on the others


@njit(cache=True, fastmath=_FAST, inline="always")
def _reflect(W, j, nf, tj, U, row):
    """U[row, :nf] ← (I − tj v vᵀ) U[row, :nf] (reflector j, as ``_reflect_vector``: inlined
    here, the rows of U being variables where the subproblem's are constants)."""
    s = tj * (U[row, j] + _dot(W, j, U, row, j + 1, nf))
    U[row, j] -= s
    _axpy(-s, W, j, U, row, j + 1, nf)


@njit(cache=True, fastmath=_FAST)
def _updated(A, B, ridge, lower, upper, x, W, T, N, V, ind, U, S, base, k, first):
    """The subproblem of the set in ``ind[_I_FIXED]`` from the base's (fixed set ``base``,
    rank k; its factors in W, T, N, V and its free list in ``ind[_I_FREE]``), as
    :func:`~wbc.compiled.lsq_subproblem._subproblem` leaves it (x, ``V[_V_MU]``,
    ``V[_V_MU_TOL]``, ``V[_V_E]``). ``first``: the base's solution is still in x and
    ``V[_V_E]`` (kept into U). False (nothing written but U) if the update does not apply."""
    n = A.shape[1]
    p = B.shape[0]
    pp = (p + 3) & ~3
    nf = np.int64(0)
    for i in range(n):
        if base[i] == 0:
            nf += 1
        elif ind[_I_FIXED, i] != base[i]:
            return False  # a base bound released or moved: not an update
    d = nf - k
    if first:
        for i in range(n):
            U[_U_X, i] = x[i]
        for i in range(pp):
            U[_U_E, i] = V[_V_E, i]
        for c in range(nf):
            U[_U_Y, c] = x[ind[_I_FREE, c]]
        for j in range(k):
            if V[_V_TAU, j] != 0.0:
                _reflect(W, j, nf, V[_V_TAU, j], U, _U_Y)
    # the bounds added since the base: u_s = Qᵀ e_s, h_s = H⁻¹ c_s, S = Cᵀ H⁻¹ C (Cholesky)
    q = np.int64(0)
    for c in range(nf):
        v = ind[_I_FREE, c]
        if ind[_I_FIXED, v] == 0:
            continue
        if q >= d:
            return False
        u = np.int64(_U_Q) + q
        for j in range(nf):
            U[u, j] = 0.0
        U[u, c] = 1.0
        for j in range(k):
            if V[_V_TAU, j] != 0.0:
                _reflect(W, j, nf, V[_V_TAU, j], U, u)
        cc = 0.0
        for j in range(d):
            V[_V_W2, j] = U[u, k + j]
            cc += U[u, k + j] * U[u, k + j]
        if not cc > _C_MIN:  # e_s (nearly) in the row space of A_F: holding it drops the rank
            return False
        _cholesky_solve(N, d, V, np.int64(_V_W2))
        hrow = _U_Q + n + q
        for j in range(d):
            U[hrow, j] = V[_V_W2, j]
        for t in range(q + 1):  # S[q, t] = c_qᵀ H⁻¹ c_t
            s = 0.0
            for j in range(d):
                s += U[_U_Q + n + t, j] * U[u, k + j]
            S[q, t] = s
        # the new row of S's Cholesky factor (lower), and its pivot
        diag = S[q, q]
        for t in range(q):
            s = S[q, t]
            for j in range(t):
                s -= S[q, j] * S[t, j]
            S[q, t] = s / S[t, t]
        piv = diag
        for j in range(q):
            piv -= S[q, j] * S[q, j]
        if not piv > _PIVOT_RTOL * diag:
            return False
        S[q, q] = np.sqrt(piv)
        S[q, n] = c  # (its position in the base's free list)
        q += 1
    # ν from S ν = b_S − x_S (the base's), into V[_V_W2]
    for t in range(q):
        v = ind[_I_FREE, np.int64(S[t, n])]
        b = lower[v] if ind[_I_FIXED, v] < 0 else upper[v]
        s = b - U[_U_X, v]
        for j in range(t):
            s -= S[t, j] * V[_V_W2, j]
        V[_V_W2, t] = s / S[t, t]
    for t in range(q - 1, -1, -1):
        s = V[_V_W2, t]
        for j in range(t + 1, q):
            s -= S[j, t] * V[_V_W2, j]
        V[_V_W2, t] = s / S[t, t]
    # Δz = Σ ν_t h_t (in U[_U_WORK, k:nf], zeros before), e = e₀ + M Δz, x_F = x₀ + Q (0, Δz)
    for j in range(nf):
        U[_U_WORK, j] = 0.0
    for t in range(q):
        _axpy(V[_V_W2, t], U, _U_Q + n + t, U, _U_WORK, 0, d)
    for j in range(d - 1, -1, -1):
        U[_U_WORK, k + j] = U[_U_WORK, j]
    for j in range(min(k, d)):
        U[_U_WORK, j] = 0.0
    for i in range(pp):
        V[_V_E, i] = U[_U_E, i]
    for c in range(d):
        _axpy(U[_U_WORK, k + c], T, k + c, V, _V_E, 0, pp)
    for j in range(k - 1, -1, -1):
        if V[_V_TAU, j] != 0.0:
            _reflect(W, j, nf, V[_V_TAU, j], U, _U_WORK)
    for i in range(n):
        x[i] = U[_U_X, i]
    for c in range(nf):
        v = ind[_I_FREE, c]
        if ind[_I_FIXED, v] == 0:
            x[v] += U[_U_WORK, c]
        else:
            x[v] = lower[v] if ind[_I_FIXED, v] < 0 else upper[v]
    # λ' (permuted, basic): R11 λ' = −(Qᵀ (g_F − Σ ν_s e_s))[:k]
    for j in range(k):
        s = _dot(T, j, V, _V_E, 0, pp) + ridge * U[_U_Y, j]
        for t in range(q):
            s -= V[_V_W2, t] * U[_U_Q + t, j]
        V[_V_LAM, j] = -s
    _r11_solve(W, k, V, _V_LAM, _V_LAM)
    # reduced gradients of the fixed variables, as the subproblem's: μ = B_iᵀ e + ridge x_i + A_iᵀ λ
    for i in range(n):
        if ind[_I_FIXED, i] != 0:
            _fixed_multiplier(A, B, ridge, x, V, ind, i, p, k)
    return True


# numba caches these on this file alone: flush them when the kernels they call change
_HERE = Path(__file__).parent
refresh([_reflect, _updated], [_HERE / "lsq_linalg.py", _HERE / "lsq_subproblem.py"])
