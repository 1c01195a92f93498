"""The subproblem of the compiled least-squares level solver (:mod:`wbc.compiled.lsq`) for a
guessed active set: the equality-constrained least squares of the free variables in the null
space of their equality rows, with the bounds' multipliers; and the rank tests of the dual
active set method (does a bound depend on the active ones and the equalities)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from ._cache import refresh
from .lsq_linalg import (
    _FAST,
    _I_FIX,
    _I_FIXED,
    _I_FREE,
    _I_PERM,
    _V_CVEC,
    _V_E,
    _V_LAM,
    _V_MU,
    _V_MU_TOL,
    _V_NU,
    _V_RP,
    _V_T,
    _V_TAU,
    _V_W,
    _axpy,
    _cholesky,
    _cholesky_solve,
    _dot,
    _gram,
    _pivoted_qr_rows,
    _r11_solve,
    _reflect_columns,
    _reflect_columns2,
    _reflect_vector,
)

_MU_TOL = 1e-9  # a multiplier has the wrong sign when by more than _MU_TOL × its terms' size
_EQ_TOL = 1e-9  # equalities are inconsistent when ‖residual‖ > _EQ_TOL·(1 + ‖a‖ + ‖A_X x_X‖)

_SUB_OK, _SUB_INCONSISTENT, _SUB_SINGULAR = 0, 1, 2


@njit(cache=True, fastmath=_FAST)
def _subproblem(A, a, B, r, ridge, lower, upper, x, rank_rtol, W, T, N, V, ind, factored):
    """Solve the equality-constrained subproblem for the fixed set ``ind[_I_FIXED]`` (-1/+1 = at
    the lower/upper bound).

    Writes x, and for fixed i the multiplier ``V[_V_MU, i]`` with its tolerance
    ``V[_V_MU_TOL, i]``. Returns (_SUB_OK, _SUB_INCONSISTENT or _SUB_SINGULAR; the rank of A_F).
    ``factored`` > 0: the work space holds this set's factors already (the QR of A_F of rank
    ``factored − 1`` in W, ``V[_V_TAU]`` and ``ind[_I_PERM]``, T, the Cholesky factor in N and
    ``V[_V_DINV]``: the last subproblem solved here, of the same A, B and ridge, was of this
    set and consistent); only the right-hand sides (a, r, the bounds) are solved again, with
    the same arithmetic as a fresh solve, so the same answer.
    """
    m, n = A.shape
    p = B.shape[0]
    pp = (p + 3) & ~3
    nf = np.int64(0)
    nx = 0
    for i in range(n):
        if ind[_I_FIXED, i] == 0:
            ind[_I_FREE, nf] = i
            nf += 1
        else:
            x[i] = lower[i] if ind[_I_FIXED, i] < 0 else upper[i]
            ind[_I_FIX, nx] = i
            nx += 1
    # equalities restricted to F: A_F x_F = a − A_X x_X
    a_norm = 0.0
    ax_norm = 0.0
    if factored > 0:  # (A_F's QR kept: the right-hand side only)
        for i in range(m):
            s = _fixed_part(A, x, ind, i, nx)
            V[_V_CVEC, i] = a[i] - s
            a_norm += a[i] * a[i]
            ax_norm += s * s
        k = factored - 1
    else:
        for i in range(m):
            s = _fixed_part(A, x, ind, i, nx)
            V[_V_CVEC, i] = a[i] - s
            a_norm += a[i] * a[i]
            ax_norm += s * s
            ind[_I_PERM, i] = i
            for c in range(nf):
                W[i, c] = A[i, ind[_I_FREE, c]]
        k = _pivoted_qr_rows(W, m, nf, V, ind, rank_rtol)
    # y₀ from R11ᵀ y₀ = (Πᵀ c)[:k]; the dependent rows must agree
    for i in range(k):
        V[_V_T, i] = (V[_V_CVEC, ind[_I_PERM, i]] - _dot(W, i, V, _V_T, 0, i)) / W[i, i]
    res = 0.0
    for i in range(k, m):
        d_i = V[_V_CVEC, ind[_I_PERM, i]] - _dot(W, i, V, _V_T, 0, k)
        res += d_i * d_i
    if np.sqrt(res) > _EQ_TOL * (1.0 + np.sqrt(a_norm) + np.sqrt(ax_norm)):
        return _SUB_INCONSISTENT, k
    d = nf - k
    # T = (B_F Q)ᵀ = Qᵀ B_Fᵀ = H_{k−1} ⋯ H_0 B_Fᵀ: rows 0…k−1 are (B_F Y)ᵀ, rows k…nf−1 are Mᵀ
    if factored == 0:
        _reflected(B, W, T, V, ind, nf, k, p, pp)
    # r' = r − B x₀, x₀ = (x_X, Y y₀)
    for i in range(p):
        s = 0.0
        for c in range(nx):
            s += B[i, ind[_I_FIX, c]] * x[ind[_I_FIX, c]]
        V[_V_RP, i] = r[i] - s
    for i in range(p, pp):
        V[_V_RP, i] = 0.0
    for j in range(k):
        _axpy(-V[_V_T, j], T, j, V, _V_RP, 0, pp)
    # null-space least squares for z (into t[k:nf]), and the residual e = B x − r
    if d > 0 and p >= d:  # normal form: (MᵀM + ridge·I) z = Mᵀ r'
        if factored == 0:
            _gram(T, k, d, pp, N)
            for c in range(d):
                N[c, c] += ridge
                V[_V_W, c] = _dot(T, k + c, V, _V_RP, 0, pp)
            if not _cholesky(N, d, ridge, V):
                return _SUB_SINGULAR, k
        else:  # (its Cholesky factor kept)
            for c in range(d):
                V[_V_W, c] = _dot(T, k + c, V, _V_RP, 0, pp)
        _cholesky_solve(N, d, V, np.int64(_V_W))
        for i in range(pp):  # e = M z − r'
            V[_V_E, i] = -V[_V_RP, i]
        for c in range(d):
            V[_V_T, k + c] = V[_V_W, c]
            _axpy(V[_V_W, c], T, k + c, V, _V_E, 0, pp)
    elif d > 0:  # row form: z = Mᵀ (M Mᵀ + ridge·I)⁻¹ r'
        if factored == 0:
            for i in range(p):
                for i2 in range(i + 1):
                    N[i, i2] = 0.0
            for c in range(d):
                for i in range(p):
                    _axpy(T[k + c, i], T, k + c, N, i, 0, i + 1)
            for i in range(p):
                N[i, i] += ridge
                V[_V_E, i] = V[_V_RP, i]
            if not _cholesky(N, p, ridge, V):
                return _SUB_SINGULAR, k
        else:  # (its Cholesky factor kept)
            for i in range(p):
                V[_V_E, i] = V[_V_RP, i]
        _cholesky_solve(N, p, V, np.int64(_V_E))  # w = (M Mᵀ + ridge I)⁻¹ r'
        for i in range(p, pp):
            V[_V_E, i] = 0.0
        for c in range(d):
            V[_V_T, k + c] = _dot(T, k + c, V, _V_E, 0, pp)  # z = Mᵀ w
        for i in range(p):  # e = M z − r' = −ridge·w, without the cancellation
            V[_V_E, i] *= -ridge
    else:
        for i in range(pp):
            V[_V_E, i] = -V[_V_RP, i]
    if nx > 0:  # λ' (permuted, basic): R11 λ' = −(Qᵀ g_F)[:k], (Qᵀ g_F)_j = T_j·e + ridge·y₀_j
        for j in range(k):
            V[_V_LAM, j] = -(_dot(T, j, V, _V_E, 0, pp) + ridge * V[_V_T, j])
        _r11_solve(W, k, V, _V_LAM, _V_LAM)
    # x_F = Q (y₀, z): the reflectors in reverse order
    for j in range(k - 1, -1, -1):
        if V[_V_TAU, j] != 0.0:
            _reflect_vector(W, j, nf, V[_V_TAU, j], V, _V_T)
    for c in range(nf):
        x[ind[_I_FREE, c]] = V[_V_T, c]
    # reduced gradients of the fixed variables: μ = B_iᵀ e + ridge x_i + A_iᵀ λ
    for c in range(nx):
        _fixed_multiplier(A, B, ridge, x, V, ind, ind[_I_FIX, c], p, k)
    return _SUB_OK, k


@njit(cache=True, fastmath=_FAST, inline="always")
def _fixed_part(A, x, ind, i, nx):
    """A_X x_X of row i (the fixed variables' part)."""
    s = 0.0
    for c in range(nx):
        s += A[i, ind[_I_FIX, c]] * x[ind[_I_FIX, c]]
    return s


@njit(cache=True, fastmath=_FAST, inline="always")
def _reflected(B, W, T, V, ind, nf, k, p, pp):
    """T = (B_F Q)ᵀ = Qᵀ B_Fᵀ from the reflectors of the QR of A_F in W (the first k)."""
    i = 0
    while i + 4 <= p:  # (four rows of B at a time: a quarter of the loop overhead)
        for c in range(nf):
            fc = ind[_I_FREE, c]
            T[c, i] = B[i, fc]
            T[c, i + 1] = B[i + 1, fc]
            T[c, i + 2] = B[i + 2, fc]
            T[c, i + 3] = B[i + 3, fc]
        i += 4
    while i < p:
        for c in range(nf):
            T[c, i] = B[i, ind[_I_FREE, c]]
        i += 1
    for c in range(nf):
        for i in range(p, pp):
            T[c, i] = 0.0
    for j in range(0, k - 1, 2):
        _reflect_columns2(T, W, j, nf, V[_V_TAU, j], V[_V_TAU, j + 1], V, pp)
    if k % 2 == 1 and V[_V_TAU, k - 1] != 0.0:
        _reflect_columns(T, W, k - 1, nf, V[_V_TAU, k - 1], V, pp)


@njit(cache=True, fastmath=_FAST, inline="always")
def _fixed_multiplier(A, B, ridge, x, V, ind, i, p, k):
    """The fixed variable i's multiplier μ_i = B_iᵀ e + ridge x_i + A_iᵀ λ into V[_V_MU, i],
    and its tolerance (_MU_TOL × the terms' magnitudes) into V[_V_MU_TOL, i]."""
    g = 0.0
    for j in range(p):
        g += B[j, i] * V[_V_E, j]
    size = abs(g) + ridge * abs(x[i])
    s = g + ridge * x[i]
    for j in range(k):
        term = V[_V_LAM, j] * A[ind[_I_PERM, j], i]
        s += term
        size += abs(term)
    V[_V_MU, i] = s
    V[_V_MU_TOL, i] = _MU_TOL * size


@njit(cache=True, fastmath=_FAST)
def _dependency(A, i, rank_rtol, W, V, ind):
    """ν with e_i = Aᵀλ' + Σ_X ν_j e_j, for a free i whose bound depends on the active ones.

    λ' solves A_Fᵀ λ' = e_i restricted to F (basic solution from the pivoted QR of A_Fᵀ; F and
    X from ``ind[_I_FIXED]``), and ν_j = −(Aᵀλ')_j on the fixed variables (0 elsewhere), into
    ``V[_V_NU]``. The rest of the work space is shared with :func:`_subproblem`.
    """
    m, n = A.shape
    nf = np.int64(0)
    pos = np.int64(-1)
    for j in range(n):
        V[_V_NU, j] = 0.0
        if ind[_I_FIXED, j] == 0:
            if j == i:
                pos = nf
            ind[_I_FREE, nf] = j
            nf += 1
    for row in range(m):
        ind[_I_PERM, row] = row
        for c in range(nf):
            W[row, c] = A[row, ind[_I_FREE, c]]
    k = _pivoted_qr_rows(W, m, nf, V, ind, rank_rtol)
    for c in range(nf):  # u = Qᵀ e_pos (reflectors in order)
        V[_V_T, c] = 0.0
    V[_V_T, pos] = 1.0
    for j in range(k):
        if V[_V_TAU, j] != 0.0:
            _reflect_vector(W, j, nf, V[_V_TAU, j], V, _V_T)
    _r11_solve(W, k, V, _V_T, _V_LAM)  # R11 λ'' = u[:k]
    for j in range(n):
        if ind[_I_FIXED, j] != 0:
            s = 0.0
            for row in range(k):
                s += V[_V_LAM, row] * A[ind[_I_PERM, row], j]
            V[_V_NU, j] = -s


@njit(cache=True, fastmath=_FAST)
def _rank_with(A, i, rank_rtol, W, V, ind):
    """Numerical rank of A restricted to the free variables and variable i (W, V and ind are
    work space, as in :func:`_dependency`)."""
    m, n = A.shape
    nf = np.int64(0)
    for j in range(n):
        if ind[_I_FIXED, j] == 0 or j == i:
            ind[_I_FREE, nf] = j
            nf += 1
    for row in range(m):
        ind[_I_PERM, row] = row
        for c in range(nf):
            W[row, c] = A[row, ind[_I_FREE, c]]
    return _pivoted_qr_rows(W, m, nf, V, ind, rank_rtol)


# numba caches these on this file alone: flush them when the kernels they call change
refresh([_subproblem, _dependency, _rank_with], [Path(__file__).with_name("lsq_linalg.py")])
