"""The subproblem of the compiled least-squares level solver (:mod:`wbc.compiled.lsq`) updated
instead of solved again: after the active set methods add bounds to a set whose subproblem
was solved (the *base*, its QR of ``A_Fᵀ``, its ``(B_F Q)ᵀ`` and its reduced Hessian's
Cholesky factor still in the work space), the bounds added since are equalities
``c_sᵀ z = β_s`` on the base's null-space coordinates z (``c_s = Zᵀ e_s``), met through the
Schur complement ``S = Cᵀ H⁻¹ C`` of the reduced Hessian ``H = MᵀM + ridge·I`` (q × q, q the
bounds added): ``S ν = b_S − x_S``, ``z = z₀ + H⁻¹ C ν``, and ν are the added bounds'
multipliers. Base bounds released since (PDAS's exchanges, the dual method's drops) border
that system with one variable each (the released x_j − b_j, the free variables following
along the direction that keeps the equalities); a base bound moved to its other side is such
a variable whose value is known (``FLIPS``: its terms go to the right-hand side, the free set
and the factors the same). Only for the normal form (p ≥ d); a bound whose ``c_s`` is
(nearly) in the span of the others'
(holding it would drop the rank of ``A_F``), more added bounds than d, or a released
variable whose column ``A_j`` is not in the range of ``A_F`` (releasing it would raise the
rank) decline: the caller solves the subproblem afresh. Equality rows joined since the base
(A's rows from the base's m on: a continued call, ``lsq.solve_level_in``) are equalities
``c_gᵀ z + d_gᵀ w = β_g`` like the added bounds (``c_g = Zᵀ g_F``); one that depends on
the others declines with ``_ROW_DEPENDS``, unless it reaches released variables: then the
bordered system is solved with w eliminated first (``WFIRST``: S may be singular there).
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
    _I_PERM,
    _V_E,
    _V_LAM,
    _V_MU,
    _V_MU_TOL,
    _V_NRM,
    _V_TAU,
    _V_W,
    _V_W2,
    _axpy,
    _cholesky_solve,
    _dot,
    _r11_solve,
)
from .lsq_subproblem import _MU_TOL, _fixed_multiplier

# U's rows: the base's x, its residual e, y₀ = (Qᵀ x_F)[:k], a work vector, then Qᵀ e_s (the
# added bounds', n rows) and H⁻¹ c_s (n rows)
_U_X, _U_E, _U_Y, _U_WORK, _U_Q = 0, 1, 2, 3, 4
# ... then for the released bounds (n rows each): u_t = (Qᵀ g_F)[:k], P_t, MᵀP_t, H⁻¹MᵀP_t and
# S⁻¹F[t]: U has _U_Q + _U_ROWS·n rows
_U_ROWS = 7
_C_MIN = 1e-12  # ‖c_s‖² (‖Qᵀ e_s‖ = 1) at most this: e_s is in the row space of A_F
_PIVOT_RTOL = 1e-8  # a Schur pivot ≤ _PIVOT_RTOL × its diagonal: the bound depends on the others
_RANGE_TOL = 1e-10  # a released variable's column A_j misses the range of A_F by more: declined
#: base bounds released since the base are updated too (the bordered system); False (edit it;
#: the kernels then compile again): a release solves the subproblem afresh, as before
RELEASES = True
#: equality rows joined since the base (the hierarchy's rows joining its last level, each a
#: new ``solve_level`` call on the last call's factors: ``lsq.solve_level_in``) are updated
#: too; False (edit it; the kernels then compile again): a joined row solves afresh, as before
JOINS = True
#: True (edit it; the kernels then compile again): a base bound moved to its other side since
#: the base (a joint from one speed bound to the other: the free set the same, only x_j's value
#: changed) is updated too, as a released bound whose w_j is known (the bound's distance to
#: the other), where it declined and the set was solved afresh. Exact (walk_strict's captures:
#: Δq within 3.1e-15, walk10's fresh subproblems 610 -> 575), but not faster: the update from
#: a base 4-6 bounds away costs about the fresh solve it saves, and the later updates carry
#: the older base (the 34 walk10 solves where it acts 33.3 -> 32.9 µs replayed, turn's 8
#: 33.3 -> 33.5; benchmarks/self_collision.md, eighteenth session): off
FLIPS = False
#: a joined row with (nearly) no part in the base's null space (``c_g ≈ 0``: on the base's
#: free variables a combination of its rows) that reaches released variables: w eliminated
#: before ν (``(S + Fᵀ E⁻¹ F) ν = β − Fᵀ E⁻¹ γ``, the Schur complement in ν of the bordered
#: system, nonsingular while the row is independent of the others on the set's free
#: variables), where z-then-ν needs S nonsingular; on ``walk_strict``'s double-support ticks
#: with a row active, each joining row then took a fresh subproblem after its bounds were
#: released. False (edit it; the kernels then compile again): such a row declines
#: (``_ROW_DEPENDS``) and is solved afresh, as before
WFIRST = True
#: a joined row's part in the base's null space is measured against the row's size on every
#: variable, held ones too: a row on held variables only but for rounding on the free ones
#: (walk_strict's self-collision rows, ~1e-20 on joints outside the pair's chains) was measured
#: against that rounding, passed as independent, and its update moved x by ~β/S with S ~ its
#: square (15 of 24 bounds violated, then 2 fresh subproblems; or the active set cycling to its
#: budget, ~200 µs a tick); now it depends (``_ROW_DEPENDS``: the warm set's bounds in the row
#: released first, as a fresh subproblem finds it). False (edit it; the kernels then compile
#: again): measured on the free variables, as before
ROW_FULL_SIZE = True
#: what :func:`_updated` returns: the subproblem updated; declined (solve it afresh); declined
#: because a joined row depends on the base's rows and the set's bounds (as an inconsistent
#: warm start: the caller may release the row's bounds first, as after a fresh solve)
_DECLINED, _UPDATED, _ROW_DEPENDS = 0, 1, 2
#: a released variable's reduced curvature E_tt at most this × its curvature before the free
#: variables' share is removed: the update declines (on random ill-conditioned levels, ridge
#: 1e-6 and p = 9 < n, x was 1e-9 from the subproblem solved afresh without it)
_BORDER_RTOL = 1e-2
#: ... or whose bordered system's Cholesky diagonal, or S's, spans more than this (as the
#: base's H: on those random levels 1e-10 from it without, 2e-15 with)
_K_SPAN = 1e2


@njit(cache=True, inline="always")
def _cholesky_row(M: np.ndarray, t: int) -> bool:
    """Row ``t`` of the lower Cholesky factor of M, in place: M[t, :t+1] holds the matrix's
    row, M[:t, :t] its factor's rows already; L[t, i] = (M[t, i] − Σ_j<i L[t, j] L[i, j]) /
    L[i, i], L[t, t] = √(M[t, t] − Σ_j<t L[t, j]²). False when that pivot is ≤ _PIVOT_RTOL of
    M[t, t] (the row depends on the others)."""
    diag = M[t, t]
    for i in range(t):
        s = M[t, i]
        for j in range(i):
            s -= M[t, j] * M[i, j]
        M[t, i] = s / M[i, i]
    piv = diag
    for j in range(t):
        piv -= M[t, j] * M[t, j]
    if not piv > _PIVOT_RTOL * diag:
        return False
    M[t, t] = np.sqrt(piv)
    return True


@njit(cache=True, inline="always")
def _cholesky_spanned(M: np.ndarray, r: int) -> bool:
    """Rows ``0..r-1`` of M's lower Cholesky factor, in place (:func:`_cholesky_row`); False
    when a row depends on the others or the factor's diagonal spans more than
    :data:`_K_SPAN` (ill-conditioned: the answer would lose its digits)."""
    lmin = np.inf
    lmax = 0.0
    for t in range(r):
        if not _cholesky_row(M, t):
            return False
        lmin = min(lmin, M[t, t])
        lmax = max(lmax, M[t, t])
    return not lmax > _K_SPAN * lmin


@njit(cache=True, fastmath=_FAST, inline="always")
def _reflect(W, j, nf, tj, U, row):
    """U[row, :nf] ← (I − tj v vᵀ) U[row, :nf] (reflector j, as ``_reflect_vector``: inlined
    here, the rows of U being variables where the subproblem's are constants)."""
    s = tj * (U[row, j] + _dot(W, j, U, row, j + 1, nf))
    U[row, j] -= s
    _axpy(-s, W, j, U, row, j + 1, nf)


@njit(cache=True, fastmath=_FAST)
def _updated(A, a, B, ridge, lower, upper, x, W, T, N, V, ind, U, S, K, base, k, first, m, wf=True):
    """The subproblem of the set in ``ind[_I_FIXED]`` from the base's (fixed set ``base``,
    rank k; its factors in W, T, N, V and its free list in ``ind[_I_FREE]``), as
    :func:`~wbc.compiled.lsq_subproblem._subproblem` leaves it (x, ``V[_V_MU]``,
    ``V[_V_MU_TOL]``, ``V[_V_E]``). ``first``: the base's solution is still in x and
    ``V[_V_E]`` (kept into U). False (nothing written but U, S, K) if the update does not
    apply. ``wf``: a joined row without a part in the base's null space may be met on the
    released variables (:func:`_w_first`); else it declines (``_ROW_DEPENDS``).

    Bounds added since the base are equalities ``c_sᵀ z + d_sᵀ w = β_s``; base bounds released
    since are variables w (x_j = b_j + w_j, the free variables following along ``g_j``, the
    base's particular solution moved by A_F g_F = −A_j: ``u_j = (Qᵀ g_F)[:k]``). With
    ``P = B G`` and γ the gradient in w at the base's solution, the KKT system
    ``[H, MᵀP, −C; PᵀM, E₀, −D; Cᵀ, Dᵀ, 0]`` is solved by eliminating z with H's factor, then
    ν with S's (the added bounds' Schur complement): ``(E + F S⁻¹ Fᵀ) w = −γ − F S⁻¹ β`` with
    ``E = PᵀP + ridge(UᵀU + I) − PᵀM H⁻¹ MᵀP`` and ``F = PᵀM H⁻¹ C − D``.
    """
    m_all, n = A.shape
    p = B.shape[0]
    pp = (p + 3) & ~3
    nf = np.int64(0)
    r_ = np.int64(0)  # base bounds released since
    flips = np.int64(0)  # ... and moved to their other side (after the released, in K)
    for i in range(n):
        if base[i] == 0:
            nf += 1
        elif ind[_I_FIXED, i] == 0:
            if not RELEASES:
                return _DECLINED
            K[r_, 2 * n] = i
            r_ += 1
        elif ind[_I_FIXED, i] != base[i]:
            if not FLIPS:
                return _DECLINED  # a base bound moved to its other side: not an update
            flips += 1
    r_u = r_  # (the released: w_t unknown; the moved: w_t their bounds' distance)
    if flips > 0:
        for i in range(n):
            side = ind[_I_FIXED, i]
            if base[i] != 0 and side != 0 and side != base[i]:
                K[r_, 2 * n] = i
                K[r_, 2 * n + 2] = (upper[i] - lower[i]) if side > 0 else (lower[i] - upper[i])
                r_ += 1
    d = nf - k
    if first:
        _keep_base(x, W, V, ind, U, nf, k, pp)
    # the equality rows joined since the base (A's rows from m on: ``c_g = Zᵀ g_F``), then the
    # bounds added since the base (``c_s = Zᵀ e_s``): u_s = Qᵀ g_s, h_s = H⁻¹ c_s, S = Cᵀ H⁻¹ C
    # (Cholesky); S[s, n]: a bound's position in the base's free list, or −1 − a row's index
    q = np.int64(0)
    wfirst = False  # (a joined row whose c_g is ≈ 0, or S's pivot: ν after w, WFIRST)
    for c in range(nf + m_all - m):
        row = np.int64(-1)
        if c >= nf:
            if not JOINS:
                return _DECLINED
            row = m + c - nf
        elif ind[_I_FIXED, ind[_I_FREE, c]] == 0:
            continue
        if q >= d:
            return _DECLINED if row < 0 else _ROW_DEPENDS
        u = np.int64(_U_Q) + q
        size = 1.0
        if row >= 0:
            size = 0.0
            for j in range(nf):
                U[u, j] = A[row, ind[_I_FREE, j]]
            if ROW_FULL_SIZE:  # (its held variables' terms too: see ROW_FULL_SIZE)
                for j in range(n):
                    size += A[row, j] * A[row, j]
            else:
                for j in range(nf):
                    size += U[u, j] * U[u, j]
        else:
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
        if not cc > _C_MIN * size:  # g_s (nearly) in the row space of A_F: the rank drops
            if row < 0 or r_u == 0 or not (WFIRST and wf):  # (... unless released ones lift it)
                return _DECLINED if row < 0 else _ROW_DEPENDS
            wfirst = True
            V[_V_W, q] = 0.0  # (its reach on the released variables is checked: _w_first)
        else:
            V[_V_W, q] = -1.0
        _cholesky_solve(N, d, V, np.int64(_V_W2))
        hrow = _U_Q + n + q
        for j in range(d):
            U[hrow, j] = V[_V_W2, j]
        for t in range(q + 1):  # S[q, t] = c_qᵀ H⁻¹ c_t
            s = 0.0
            for j in range(d):
                s += U[_U_Q + n + t, j] * U[u, k + j]
            S[q, t] = s
        if not wfirst and not _cholesky_row(S, q):  # the new row of S's Cholesky factor
            if row < 0 or r_u == 0 or not (WFIRST and wf):
                return _DECLINED if row < 0 else _ROW_DEPENDS
            wfirst = True
            V[_V_W, q] = 0.0
        S[q, n] = c if row < 0 else -1 - row
        q += 1
    # the released bounds: u_t, P_t = B_F Y u_t + B_j, MᵀP_t, H⁻¹MᵀP_t, γ_t; E and F into K
    for t in range(r_):
        j = np.int64(K[t, 2 * n])
        ru = _U_Q + 2 * n + t
        rp = _U_Q + 3 * n + t
        rm = _U_Q + 4 * n + t
        rh = _U_Q + 5 * n + t
        for i in range(k):  # R11ᵀ u = −(Πᵀ A_j)[:k]
            U[ru, i] = (-A[ind[_I_PERM, i], j] - _dot(W, i, U, ru, 0, i)) / W[i, i]
        res = 0.0
        an = 0.0
        for i in range(m):
            an += A[i, j] * A[i, j]
        for i in range(k, m):  # A_j in the range of A_F, else releasing it changes the rank
            di = -A[ind[_I_PERM, i], j] - _dot(W, i, U, ru, 0, k)
            res += di * di
        if np.sqrt(res) > _RANGE_TOL * (1.0 + np.sqrt(an)):
            return _DECLINED
        for i in range(p):
            U[rp, i] = B[i, j]
        for i in range(p, pp):
            U[rp, i] = 0.0
        for i in range(k):
            _axpy(U[ru, i], T, i, U, rp, 0, pp)
        for c in range(d):
            V[_V_W2, c] = _dot(T, k + c, U, rp, 0, pp)
            U[rm, c] = V[_V_W2, c]
        _cholesky_solve(N, d, V, np.int64(_V_W2))
        for c in range(d):
            U[rh, c] = V[_V_W2, c]
        # γ_t = P_t·e₀ + ridge (u_t·y₀ + b_j)
        K[t, 2 * n + 1] = _dot(U, rp, U, _U_E, 0, pp) + ridge * (
            _dot(U, ru, U, _U_Y, 0, k) + U[_U_X, j]
        )
        for t2 in range(t + 1):
            e = _dot(U, rp, U, _U_Q + 3 * n + t2, 0, pp) + ridge * _dot(
                U, ru, U, _U_Q + 2 * n + t2, 0, k
            )
            if t2 == t:
                e += ridge
                full = e
            e -= _dot(U, rm, U, _U_Q + 5 * n + t2, 0, d)
            if t2 == t and not e > _BORDER_RTOL * full:
                return _DECLINED  # (E's diagonal cancels: its digits are lost)
            K[t, t2] = e
        for s_ in range(q):  # F[t, s] = (MᵀP_t)·H⁻¹c_s − (Qᵀg_s)[:k]·u_t (− g_j for a row)
            f1 = _dot(U, rm, U, _U_Q + n + s_, 0, d)
            f2 = _dot(U, _U_Q + s_, U, ru, 0, k)
            f3 = A[np.int64(-1 - S[s_, n]), j] if S[s_, n] < 0 else 0.0
            K[t, n + s_] = f1 - f2 - f3
            if wfirst and V[_V_W, s_] >= 0.0:  # (the terms' size, for _w_first's check)
                V[_V_W, s_] += (abs(f1) + abs(f2) + abs(f3)) ** 2
    # ν₀ = S⁻¹ β (β = b_S − x_S, the base's), into V[_V_W2]
    for t in range(q):
        if S[t, n] < 0:  # a row: β = a_g − g·x
            row = np.int64(-1 - S[t, n])
            V[_V_W2, t] = a[row] - _dot(A, row, U, _U_X, 0, n)
        else:
            v = ind[_I_FREE, np.int64(S[t, n])]
            b = lower[v] if ind[_I_FIXED, v] < 0 else upper[v]
            V[_V_W2, t] = b - U[_U_X, v]
    # the moved bounds' known w into the released ones' γ (E_rf w_f) and into β (F_fᵀ w_f)
    for t2 in range(r_u, r_):
        w = K[t2, 2 * n + 2]
        for t in range(r_u):
            K[t, 2 * n + 1] += K[t2, t] * w
        for s_ in range(q):
            V[_V_W2, s_] += K[t2, n + s_] * w
    if wfirst:
        if not _w_first(S, K, U, V, q, r_u, n, d, k):
            return _ROW_DEPENDS
    else:
        _chol_solve_small(S, q, V, np.int64(_V_W2))
    if r_u > 0 and not wfirst:
        # K' = E + F S⁻¹ Fᵀ (X_t = S⁻¹ F[t] into U's rows), rhs −γ − F ν₀ (into K[:, 2n + 1])
        for t in range(r_):
            rx = _U_Q + 6 * n + t
            for s_ in range(q):
                U[rx, s_] = K[t, n + s_]
            _chol_solve_small(S, q, U, np.int64(rx))
            K[t, 2 * n + 1] = -K[t, 2 * n + 1]
            s = 0.0
            for s_ in range(q):
                s += K[t, n + s_] * V[_V_W2, s_]
            K[t, 2 * n + 1] -= s
        for t in range(r_):
            for t2 in range(t + 1):
                s = 0.0
                for s_ in range(q):
                    s += K[t, n + s_] * U[_U_Q + 6 * n + t2, s_]
                K[t, t2] += s
        # its Cholesky factor (lower, in place), then w into K[:, 2n + 2]
        lmin = np.inf
        lmax = 0.0
        for t in range(q):  # (S⁻¹ enters K: S must be as well conditioned as K)
            lmin = min(lmin, S[t, t])
            lmax = max(lmax, S[t, t])
        if lmax > _K_SPAN * lmin:
            return _DECLINED
        if not _cholesky_spanned(K, r_u):
            return _DECLINED
        for t in range(r_u):
            s = K[t, 2 * n + 1]
            for j in range(t):
                s -= K[t, j] * K[j, 2 * n + 2]
            K[t, 2 * n + 2] = s / K[t, t]
        for t in range(r_u - 1, -1, -1):
            s = K[t, 2 * n + 2]
            for j in range(t + 1, r_u):
                s -= K[j, t] * K[j, 2 * n + 2]
            K[t, 2 * n + 2] = s / K[t, t]
        for t in range(r_u):  # ν = ν₀ + Σ w_t X_t (the moved bounds' terms in ν₀: β)
            _axpy(K[t, 2 * n + 2], U, _U_Q + 6 * n + t, V, _V_W2, 0, q)
    # Δz = Σ ν_s h_s − Σ w_t H⁻¹MᵀP_t, Δy = Σ w_t u_t (U[_U_WORK], the base's Q coordinates)
    for j in range(nf):
        U[_U_WORK, j] = 0.0
    for t in range(q):
        _axpy(V[_V_W2, t], U, _U_Q + n + t, U, _U_WORK, 0, d)
    for t in range(r_):
        _axpy(-K[t, 2 * n + 2], U, _U_Q + 5 * n + t, U, _U_WORK, 0, d)
    for j in range(d - 1, -1, -1):
        U[_U_WORK, k + j] = U[_U_WORK, j]
    for j in range(min(k, d)):
        U[_U_WORK, j] = 0.0
    for t in range(r_):
        _axpy(K[t, 2 * n + 2], U, _U_Q + 2 * n + t, U, _U_WORK, 0, k)
    # e = e₀ + M Δz + Σ w_t P_t; λ needs y = y₀ + Δy before Δ is reflected back
    for i in range(pp):
        V[_V_E, i] = U[_U_E, i]
    for c in range(d):
        _axpy(U[_U_WORK, k + c], T, k + c, V, _V_E, 0, pp)
    for t in range(r_):
        _axpy(K[t, 2 * n + 2], U, _U_Q + 3 * n + t, V, _V_E, 0, pp)
    # λ' (permuted, basic): R11 λ' = −(Qᵀ (g_F − Σ ν_s e_s))[:k]
    for j in range(k):
        s = _dot(T, j, V, _V_E, 0, pp) + ridge * (U[_U_Y, j] + U[_U_WORK, j])
        for t in range(q):
            s -= V[_V_W2, t] * U[_U_Q + t, j]
        V[_V_LAM, j] = -s
    _r11_solve(W, k, V, _V_LAM, _V_LAM)
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
    for t in range(r_u):
        x[np.int64(K[t, 2 * n])] += K[t, 2 * n + 2]
    for t in range(r_u, r_):  # (a moved bound's x exactly on it)
        v = np.int64(K[t, 2 * n])
        x[v] = lower[v] if ind[_I_FIXED, v] < 0 else upper[v]
    # reduced gradients of the fixed variables, as the subproblem's: μ = B_iᵀ e + ridge x_i + A_iᵀ λ
    for i in range(n):
        if ind[_I_FIXED, i] != 0:
            _fixed_multiplier(A, B, ridge, x, V, ind, i, p, k)
    for t in range(q):  # ... and the joined rows' (their multipliers −ν)
        if S[t, n] < 0:
            row = np.int64(-1 - S[t, n])
            for i in range(n):
                if ind[_I_FIXED, i] != 0:
                    term = V[_V_W2, t] * A[row, i]
                    V[_V_MU, i] -= term
                    V[_V_MU_TOL, i] += _MU_TOL * abs(term)
    return _UPDATED


@njit(cache=True, fastmath=_FAST)
def _w_first(S, K, U, V, q, r_, n, d, k) -> bool:
    """ν and w of the bordered system ``E w + F ν = −γ``, ``Fᵀ w − S ν = −β`` with w
    eliminated first (S may be singular: a joined row with no part in the base's null space):
    ``(S + Fᵀ E⁻¹ F) ν = β − Fᵀ E⁻¹ γ``, ``w = −E⁻¹(γ + F ν)``. E (K[:r_, :r_], lower), F
    (K[:r_, n:n + q]) and γ (K[:r_, 2n + 1]) as :func:`_updated` leaves them, β in
    ``V[_V_W2, :q]``; S again from c_s = U[_U_Q + s, k:k + d] and H⁻¹c_s = U[_U_Q + n + s, :d]
    (its factor's rows were begun in place). ν into ``V[_V_W2]``, w into K[:r_, 2n + 2],
    E⁻¹F into U's rows _U_Q + 6n + t. False if E or the Schur complement is singular or
    spans more than _K_SPAN on its Cholesky diagonal (the row depends on the others)."""
    for s1 in range(q):
        for t in range(s1 + 1):
            s = 0.0
            for j in range(d):
                s += U[_U_Q + n + t, j] * U[_U_Q + s1, k + j]
            S[s1, t] = s
    for s1 in range(q):  # a row without a part in the null space must reach the released
        if V[_V_W, s1] >= 0.0:  # variables by more than its terms' roundoff
            f = 0.0
            for t in range(r_):
                f += K[t, n + s1] * K[t, n + s1]
            if not f > _C_MIN * V[_V_W, s1]:
                return False
    if not _cholesky_spanned(K, r_):  # E's factor
        return False
    for s1 in range(q + 1):  # E⁻¹F's columns, then E⁻¹γ (into K[:, 2n + 2])
        for t in range(r_):  # (V's row of the QR's column norms: free)
            V[_V_NRM, t] = K[t, 2 * n + 1] if s1 == q else K[t, n + s1]
        _chol_solve_small(K, r_, V, np.int64(_V_NRM))
        for t in range(r_):
            if s1 == q:
                K[t, 2 * n + 2] = V[_V_NRM, t]
            else:
                U[_U_Q + 6 * n + t, s1] = V[_V_NRM, t]
    for s1 in range(q):  # S + Fᵀ E⁻¹ F, and β − Fᵀ E⁻¹ γ
        for t2 in range(s1 + 1):
            s = 0.0
            for t in range(r_):
                s += K[t, n + s1] * U[_U_Q + 6 * n + t, t2]
            S[s1, t2] += s
        s = 0.0
        for t in range(r_):
            s += K[t, n + s1] * K[t, 2 * n + 2]
        V[_V_W2, s1] -= s
    if not _cholesky_spanned(S, q):
        return False
    _chol_solve_small(S, q, V, np.int64(_V_W2))
    for t in range(r_):  # w = −E⁻¹γ − E⁻¹F ν
        s = K[t, 2 * n + 2]
        for s1 in range(q):
            s += U[_U_Q + 6 * n + t, s1] * V[_V_W2, s1]
        K[t, 2 * n + 2] = -s
    return True


@njit(cache=True, fastmath=_FAST)
def _keep_base(x, W, V, ind, U, nf, k, pp):
    """The base's solution into U (its x, its residual e and y₀ = (Qᵀ x_F)[:k]), from x and
    ``V[_V_E]`` as the subproblem solved afresh leaves them."""
    for i in range(x.shape[0]):
        U[_U_X, i] = x[i]
    for i in range(pp):
        U[_U_E, i] = V[_V_E, i]
    for c in range(nf):
        U[_U_Y, c] = x[ind[_I_FREE, c]]
    for j in range(k):
        if V[_V_TAU, j] != 0.0:
            _reflect(W, j, nf, V[_V_TAU, j], U, _U_Y)


@njit(cache=True, fastmath=_FAST, inline="always")
def _chol_solve_small(S, q, V, row):
    """Solve L Lᵀ w = V[row, :q] in place (L: the lower triangle of S[:q, :q], its diagonal
    the factor's own)."""
    for t in range(q):
        s = V[row, t]
        for j in range(t):
            s -= S[t, j] * V[row, j]
        V[row, t] = s / S[t, t]
    for t in range(q - 1, -1, -1):
        s = V[row, t]
        for j in range(t + 1, q):
            s -= S[j, t] * V[row, j]
        V[row, t] = s / S[t, t]


# numba caches these on this file alone: flush them when the kernels they call change
_HERE = Path(__file__).parent
refresh(
    [_reflect, _updated, _w_first, _keep_base, _chol_solve_small],
    [_HERE / "lsq_linalg.py", _HERE / "lsq_subproblem.py"],
)
