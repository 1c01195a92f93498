"""Compiled solver for one least-squares level with equalities and box bounds.

One call solves::

    minimise   ½‖B x − r‖² + ½·ridge·‖x‖²
    subject to A x = a            (rows may be linearly dependent, m may be 0)
               lower ≤ x ≤ upper  (entries may be ±inf; lower == upper pins x_i)

with an active set on the bounds. For a guessed active set the variables split into fixed ones
X (held at a bound) and free ones F, and the equality-constrained least-squares subproblem is
solved in the null space of ``A_F``:

* pivoted Householder QR ``A_Fᵀ Π = Q [R; 0]``, rank k where ``|R_jj| > rank_rtol·|R_00|``,
  ``Q = [Y Z]``; the minimum-norm particular solution ``x_F = Y y₀`` solves the k independent
  rows, and the dependent rows must agree with it (else the equalities are inconsistent);
* ``x_F = Y y₀ + Z z`` with ``M = B_F Z``, ``r' = r − B_X x_X − B_F Y y₀``:
  ``(MᵀM + ridge·I) z = Mᵀ r'`` (normal form, p ≥ d = dim z) or
  ``z = Mᵀ (M Mᵀ + ridge·I)⁻¹ r'`` (row form, p < d: accurate for a tiny ridge when M has full
  row rank), by Cholesky; ``ridge·‖z‖²`` is the ridge on all of x_F since Y ⟂ Z. Z is never
  formed: ``(B_F Q)ᵀ = Qᵀ B_Fᵀ`` comes from the reflectors, applied two at a time (compact
  WY with blocks of two) to ``B_Fᵀ``, stored with its rows padded to a multiple of 4;
* multipliers ``A_Fᵀ λ = −g_F`` (g the gradient, same QR) and the bounds' reduced gradients
  ``μ_X = g_X + A_Xᵀ λ``: a variable at its upper bound is optimal iff μ ≤ 0, at its lower
  bound iff μ ≥ 0.

The active set is first updated by the primal-dual active set method (PDAS,
Hintermüller–Ito–Kunisch; block principal pivoting): a free variable beyond a bound is fixed at
it and a fixed one with the wrong multiplier sign is released, all at once. PDAS converges in a
few steps when the reduced Hessian is close to an M-matrix but can cycle otherwise (typically
p < d with a small ridge). When the number of infeasibilities stops falling (on a damped level:
after ``ties`` such steps, :data:`PDAS_TIES` where a stack sets it), or an exchange makes
the equalities inconsistent, the solver switches to a dual active set method (Goldfarb–Idnani
on the bounds): from the set PDAS met with the fewest infeasibilities (its subproblem's x and
multipliers kept, not solved again: on the hierarchy's last level with self-collision rows,
whose re-solves start from the set of the problem with one row less, PDAS's first exchange
mostly overshoots — 1487 → 1343 subproblems along walk10), less its wrong-signed
bounds (released one at a time, the largest multiplier first: a dual feasible point; on the
walk's hierarchy, 14 subproblems → 8 on the ticks where PDAS stalls), it adds the most
violated bound, moving along the subproblem's solution, which is affine in the
value the added variable is held at, and releasing a bound whose multiplier reaches zero on the
way; when the added bound depends on the active ones and the equalities (holding it drops the
rank of A_F), a pure dual step releases one of those instead, or, if none can go and the
variable meets its bound already to roundoff (a degenerate vertex), the bound is held with a
zero multiplier. Each completed addition strictly raises the dual objective of a strictly
convex problem, so the method is finite.

``state`` is an int8 array (any integer dtype compiles too): -1 = at the lower bound, 0 = free,
+1 = at the upper bound. It is the warm start on input and the final active set on output; a
value pointing at an infinite bound counts as 0. A warm start whose equalities are
inconsistent (an equality row that joined since depends on the variables it holds) starts
cold; with a ridge (one minimiser, whatever the start) it first releases only the bounds of
the variables in the rows found dependent (on the hierarchy's last level with self-collision
rows the set it is released from was mostly one variable from the answer: walk10's
``walk_strict``, the last level's subproblems 2075 → 1972, p99 23 → 20 a tick). Pinned
variables (lower == upper) are always fixed and reported as -1 or +1 after the sign of their
multiplier.

Tolerances: the equalities are inconsistent when the dependent rows miss by more than
1e-9·(1 + ‖a‖ + ‖A_X x_X‖); a free variable is beyond a bound b by more than 1e-12·(1 + |b|)
(a returned solution is then clipped onto the box exactly); a multiplier has the wrong sign by
more than 1e-9 × the sum of the magnitudes of its terms.

Limits: ``max_iter`` counts subproblem solves (about 3.5 µs each at n = 24, m = 6, p = 30).
From a cold start PDAS needs 2–7 of them on well-conditioned levels; levels with p < d, a tiny
ridge and many active bounds can need 10–30 or more (that is where the dual method takes
over); a warm start from the previous tick's active set usually needs 1. With ridge = 0 the
problem must be strictly convex on the visited faces (B_F Z of full column rank): a singular
normal form returns NUMERICAL, and with p < d the row form returns the minimum-norm z, for
which the active set iteration is not guaranteed to settle (MAX_ITER). Pass float64
C-contiguous arrays: other layouts or dtypes compile another specialisation (~15 s, cached
afterwards).

Continued calls (:func:`solve_level_in`, in a work space from :func:`level_space`): a level
solved again with equality rows appended (the hierarchy's inequality rows joining a level, one
call each) starts from the last call's final subproblem's factors: the joined rows are
equalities on its null-space coordinates, updated as added bounds are
(:mod:`wbc.compiled.lsq_update`, ``JOINS``), and a joined row that depends on the warm set
(on variables it holds: an inconsistent warm start) releases those bounds at once (the
rows joined since the last call's: the rows before met its set), as a fresh solve does
after finding the set inconsistent — first only those its miss at the last call's answer
pushes inwards (:data:`INWARD_RELEASE`), the others if it still depends —, and is then an
update on the released variables
(``lsq_update.WFIRST``); where the update declines, the subproblem is solved afresh as
before.

The linear algebra lives in :mod:`wbc.compiled.lsq_linalg` (Householder QR, Cholesky, the
work space), the subproblem of a guessed active set in :mod:`wbc.compiled.lsq_subproblem`;
this module holds the active set methods and the entry points.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from ._cache import refresh
from .lsq_linalg import (
    _I_FIXED,
    _I_PERM,
    _I_PINNED,
    _I_PREV,
    _N_IVEC,
    _N_VEC,
    _V_MU,
    _V_MU0,
    _V_MU_TOL,
    _V_NU,
    _V_X0,
    _fill,
)
from .lsq_subproblem import (
    _SUB_INCONSISTENT,
    _SUB_OK,
    _SUB_SINGULAR,
    _dependency,
    _rank_with,
    _subproblem,
)
from .lsq_update import (
    _DECLINED,
    _ROW_DEPENDS,
    _U_Q,
    _U_ROWS,
    _U_X,
    _UPDATED,
    FLIPS,
    _keep_base,
    _updated,
)

OK, MAX_ITER, INCONSISTENT, NUMERICAL = 0, 1, 2, 3

_X_TOL = 1e-12  # a free x_i is beyond a bound b when by more than _X_TOL·(1 + |b|)

_PDAS, _DUAL_START, _DUAL_ADD = 0, 1, 2

#: the subproblem of a set that adds bounds to the last one solved afresh (its base) or
#: releases some of the base's is updated from the base's factors
#: (:mod:`wbc.compiled.lsq_update`; releases: ``lsq_update.RELEASES``) instead of solved again;
#: False (edit it; the kernels then compile again): every subproblem solved afresh, as before
UPDATES = True
#: on a damped level (ridge > 0: one minimiser, whatever the path), PDAS may go on through
#: ``ties`` steps that do not lower its number of infeasibilities (raising it by PDAS_RISE at
#: most) before the dual method takes over from the set with the fewest (0: at the first such
#: step). PDAS_TIES is the value of a hierarchy whose stack sets ``pdas_ties`` (the stacks with
#: self-collision rows; ``cascade_solve``'s ``params[4]``, else 0). On walk_strict's slowest
#: ticks the last level's set from the last tick PDAS had two bounds to fix, then two others
#: (a tie), which the dual method took one at a time: with 2 (and PDAS_RISE 1) 6 subproblems
#: -> 3, the replayed walk10 p99 48.6 -> 44.7 µs. The weighted QP passes 0: on it the other
#: path changed the rounding, and the thesis's ill-posed qp-* controllers' runs (their null
#: space left to drift) went elsewhere from there (up to 0.4 rad; benchmarks/self_collision.md,
#: sixteenth pass)
PDAS_TIES = 2
PDAS_RISE = 1
#: a joined row that depends on the warm set (``lsq_update._ROW_DEPENDS``) releases first only
#: the bounds its miss at the last call's answer pushes inwards (x_j held at its upper bound
#: where the row falls with x_j, or at its lower where it rises) and whose multiplier there is
#: small against the row's pull, |μ_j / A_rj| at most :data:`INWARD_RATIO` × the smallest of
#: them (the answer and μ kept in the work space by :func:`_carry`, whatever x the caller
#: passes); the others kept; if none is, or the row still depends, every bound in it. On
#: walk_strict's walk10 touch-downs a row then takes 1 update where PDAS fixed most of the
#: released bounds again in 4 (the answers bit for bit the same: the updates are of the same
#: base); on random levels' held and lifted rows fewer subproblems in sum for each kind
#: (benchmarks/self_collision.md, nineteenth session). False (edit it; the kernels then
#: compile again): every bound in the row at once
INWARD_RELEASE = True
#: (the bound whose multiplier the row's pull overcomes first is released with those within
#: this factor of it: the others' multipliers hold them; random levels' continued calls with
#: held and lifted rows 2767 subproblems with every bound released, 2102 with every inward
#: one, 1914 with this 10)
INWARD_RATIO = 10.0
#: a subproblem of the set whose factors (A_F's QR, T, the Cholesky factor) are in the work
#: space already — the last solved afresh there, of the same A, B and ridge: in one call, or
#: the last call's with ``_solve``'s ``same`` (the proximal steps) — solves only its
#: right-hand sides again (``lsq_subproblem._subproblem``'s ``factored``), the same
#: arithmetic (the same answers, bit for bit); False (edit it; the kernels then compile
#: again): every subproblem factored afresh, as before
_FACTORED = True
#: ... but not from a base whose reduced Hessian's Cholesky diagonal spans more than this
#: (its condition number beyond about its square)
_COND_MAX_SQRT = 1e2


@njit(cache=True, inline="always")
def _wrong_sign(side, mu, tol):
    """True when the multiplier ``mu`` of a bound on ``side`` (±1) has the wrong sign."""
    if side > 0:
        return mu > tol
    return mu < -tol


@njit(cache=True, inline="always")
def _violation(xi, lo, up):
    """How far xi lies beyond [lo, up] relative to 1 + |bound| (0 inside, or within _X_TOL)."""
    if xi > up + _X_TOL * (1.0 + abs(up)):
        return (xi - up) / (1.0 + abs(up))
    if xi < lo - _X_TOL * (1.0 + abs(lo)):
        return (lo - xi) / (1.0 + abs(lo))
    return 0.0


@njit(cache=True)
def _finish(x, lower, upper, V, mu_row, ind, state, clip):
    """Write the active set into state; with ``clip``, put the free variables (within _X_TOL of
    the box at a solution) exactly on it. Pinned variables report the sign of their multiplier
    (``V[mu_row]``)."""
    for i in range(x.shape[0]):
        if ind[_I_PINNED, i]:
            state[i] = -1 if V[mu_row, i] >= 0.0 else 1
        else:
            state[i] = ind[_I_FIXED, i]
            if clip and ind[_I_FIXED, i] == 0:
                x[i] = min(max(x[i], lower[i]), upper[i])


@njit(cache=True, inline="always")
def _released(base, ind):
    """True if a bound of the base (fixed set ``base``) is released in ``ind[_I_FIXED]``, or
    (``lsq_update.FLIPS``) moved to its other side."""
    for i in range(base.shape[0]):
        if base[i] != 0 and ind[_I_FIXED, i] != base[i]:
            if ind[_I_FIXED, i] == 0 or FLIPS:
                return True
    return False


@njit(cache=True)
def level_space(m: int, n: int, p: int) -> tuple:
    """A work space for :func:`solve_level_in` on levels of at most m equality rows, n
    variables and p least-squares rows (the subproblem's factors, the update's, the active
    set's vectors; and what a following call on the same level continues from)."""
    pp = (p + 3) & ~3
    return (
        np.empty((4, max(m, n, _N_VEC), max(m, n, pp))),
        np.empty((_N_IVEC, max(m, n)), dtype=np.int64),
        # (the update's rows for released bounds, in U and K, only once a release comes: on
        # the walks' ticks that never update, the larger work space cost 0.1-0.3 µs a call)
        np.empty((2 * n + _U_Q, max(n, pp))),
        np.empty((n, n + 1)),
        np.empty((0, 2 * n + 3)),
        np.empty((3, n)),
        np.zeros(n, dtype=np.int64),
        # the base a following call may continue from: [valid, its rows of A, its rank, its
        # solution only in U's first row, the rows of A of the call that kept it, its rank + 1
        # while its factors are in the work space (:data:`_FACTORED`; else 0)]
        np.zeros(6, dtype=np.int64),
        np.int64(m),
        np.int64(p),
    )


@njit(cache=True)
def _carry(carry, base, base_ok, base_first, base_m, base_k, x, W, V, ind, U, U0, pp, m, last):
    """At an optimal set: the base for a following call (:func:`solve_level_in` with
    ``cont``); if the base was the last subproblem, its x into U (its y₀ and residual are
    kept there by the call that continues: most calls are not continued); the answer x and
    its multipliers into ``last`` (2 × n: a joined row's miss and the bounds' multipliers,
    :data:`INWARD_RELEASE`, whatever x the caller passes next)."""
    if not base_ok:
        return
    for i in range(x.shape[0]):
        last[0, i] = x[i]
        last[1, i] = V[_V_MU, i]
    if base_first:  # (its x now: the rest of it, if a following call continues)
        for i in range(x.shape[0]):
            U[_U_X, i] = x[i]
    if U.shape[0] != U0.shape[0]:  # (grown in this call: its first rows into the space's)
        U0[:_U_Q] = U[:_U_Q]
    carry[3] = 1 if base_first else 0
    carry[0] = 1
    carry[1] = base_m
    carry[2] = base_k
    carry[4] = m


@njit(cache=True)
def _solve(
    A, a, B, r, ridge, lower, upper, state, x, rank_rtol, max_iter, space, cont, keep, ties, same
):  # fmt: skip
    """The solver behind :func:`solve_level` and :func:`solve_level_in` (compiled once for
    float ridge/rank_rtol, an integer max_iter and a bool ``cont``, however the public
    functions are called); ``ties``: PDAS's budget of steps that do not lower its count
    (see :data:`PDAS_TIES`). ``same``: A, B and ridge are the last call's in ``space`` (only
    a, r and the bounds changed: :mod:`wbc.compiled.proximal`'s steps), so a first
    subproblem of the set that call solved last afresh takes its factors
    (:data:`_FACTORED`)."""
    m, n = A.shape
    p = B.shape[0]
    work, ind, U0, S, K, saved, base, carry, m_max, p_max = space
    U = U0
    if m > m_max or p > p_max or base.shape[0] != n:
        raise ValueError("solve_level_in: the work space is for other shapes")
    if a.shape[0] != m:
        raise ValueError("solve_level: a must have one entry per row of A")
    if B.shape[1] != n:
        raise ValueError("solve_level: B must have as many columns as A")
    if r.shape[0] != p:
        raise ValueError("solve_level: r must have one entry per row of B")
    if lower.shape[0] != n or upper.shape[0] != n or state.shape[0] != n or x.shape[0] != n:
        raise ValueError("solve_level: lower, upper, state and x must have n entries")
    if not ridge >= 0.0:
        raise ValueError("solve_level: ridge must be >= 0")
    pp = (p + 3) & ~3
    W = work[0]
    T = work[1]
    N = work[2]
    V = work[3]
    # (the vectors are used as rows of V and ind: a view per vector costs reference counting)
    warm = False
    for i in range(n):
        if not lower[i] <= upper[i] or lower[i] == np.inf or upper[i] == -np.inf:
            raise ValueError("solve_level: need lower <= upper, no NaN, and finite if equal")
        V[_V_MU, i] = 0.0
        ind[_I_PINNED, i] = 0
        ind[_I_FIXED, i] = 0
        if lower[i] == upper[i]:
            ind[_I_PINNED, i] = 1
            ind[_I_FIXED, i] = -1
        elif state[i] > 0 and upper[i] < np.inf:
            ind[_I_FIXED, i] = 1
            warm = True
        elif state[i] < 0 and lower[i] > -np.inf:
            ind[_I_FIXED, i] = -1
            warm = True
    # phases: PDAS; then, if it stalls, the dual active set method (Goldfarb–Idnani on the
    # bounds), which first releases wrong-signed bounds (DUAL_START) and then adds violated
    # bounds one at a time along the path of the subproblem's solution (DUAL_ADD). One call
    # site of _subproblem keeps the compiled code (and the compile time) small.
    phase = _PDAS
    best = n + 1  # fewest PDAS infeasibilities so far
    tied = 0  # PDAS steps that did not lower the count (at most ``ties``)
    # x, μ and their tolerances of the set with the fewest (the set PDAS falls back to)
    kept = False
    # the bounds of an inconsistent warm start's dependent rows released: 0 not yet, 1 those
    # a joined row's miss pushes inwards (INWARD_RELEASE), 2 every one in the rows
    released = 0
    rank = 0
    # the rank of A_F for the set now in ind (-1: not known), the set PDAS falls back to's, and
    # that of the free set with i_add, known when i_add joined the set of the last subproblem
    # (the dual method's rank test then needs no QR of its own)
    rank_now = np.int64(-1)
    saved_rank = np.int64(-1)
    rank_with = np.int64(-1)
    # the base of the updates (lsq_update): the fixed set of the last subproblem solved in the
    # normal form, while its factors are in the work space, its rank and its rows of A (U, S,
    # K: the update's work space); with ``cont``, the last call's (A's rows from its m on
    # joined since, as equalities)
    base_ok = cont and carry[0] == 1 and carry[1] <= m
    base_first = np.bool_(False)
    base_k = carry[2]
    base_m = carry[1]
    joined = max(carry[1], carry[4])  # (A's rows from here on joined since the last call)
    if base_ok and carry[3] == 1:  # (the rest of the base's solution into U)
        nf = np.int64(0)
        for i in range(n):
            nf += base[i] == 0
        _keep_base(U[_U_X], W, V, ind, U, nf, base_k, pp)
    carry[0] = 0
    # (the factors of the set ``base`` in the work space, for a subproblem of that set again:
    # this call's, or with ``same`` the last call's; carry[5] is its rank + 1, else 0)
    factors_ok = same and _FACTORED
    count = 0
    i_add = np.int64(-1)
    side = 0
    while True:
        if count >= max_iter:
            if phase == _DUAL_ADD:  # the last point on the path meets the equalities
                for i in range(n):
                    x[i] = V[_V_X0, i]
                    V[_V_MU, i] = V[_V_MU0, i]
            _finish(x, lower, upper, V, np.int64(_V_MU), ind, state, np.bool_(False))
            return MAX_ITER, count
        if UPDATES and base_ok and not kept and K.shape[0] == 0 and _released(base, ind):
            # U's and K's rows for the released bounds (U's first rows kept: the base's
            # solution may be in them)
            grown = np.empty((_U_ROWS * n + _U_Q, U.shape[1]))
            grown[:_U_Q] = U[:_U_Q]
            U = grown
            K = np.empty((n, 2 * n + 3))
        code = _DECLINED
        if UPDATES and base_ok and not kept:
            # (a joined row that depends on the warm set releases its bounds first, below: from
            # there fewer subproblems than met on the base's released variables at once — the
            # replayed walk_strict turn's first double-support ticks 31 against 42 µs at most)
            first_try = count == 0 and warm and released == 0 and ridge > 0.0
            code = _updated(
                A, a, B, ridge, lower, upper, x, W, T, N, V, ind, U, S, K, base, base_k,
                base_first, base_m, np.bool_(not first_try),
            )  # fmt: skip
        if kept:  # (the set PDAS falls back to: its subproblem's x and multipliers kept)
            kept = False
            sub = _SUB_OK
            for i in range(n):
                x[i] = saved[0, i]
                V[_V_MU, i] = saved[1, i]
                V[_V_MU_TOL, i] = saved[2, i]
            rank_now = saved_rank
            # (the base's factors are still in the work space: only a base whose own solution
            # was in x and is not kept in U yet is lost)
            base_ok = base_ok and not base_first
        elif code == _UPDATED:
            count += 1
            base_first = np.bool_(False)
            sub = _SUB_OK
            rank = base_k + m - base_m  # (no bound added or row joined depends on the others)
            rank_now = rank
            rank_with = rank
        elif code == _ROW_DEPENDS and count == 0 and warm and released < 2 and ridge > 0.0:
            # a row joined since the last call depends on the warm set (its variables held at
            # their bounds): the warm start is inconsistent, and its bounds in the joined rows
            # are released as a fresh solve would after finding it so (below); then on
            # (INWARD_RELEASE: first only the bounds the row's miss pushes inwards; if
            # the row still depends on the set, every bound in it, as before)
            inward = INWARD_RELEASE and released == 0
            for _ in range(2):  # (a second sweep, every bound, if none was pushed inwards)
                freed = 0
                for row in range(joined, m):  # (the last call's set met the rows before)
                    miss = -a[row]
                    pull = np.inf  # (the smallest |μ_j / A_rj| of the bounds pushed inwards)
                    if inward:  # (at the last call's answer, its μ: saved[:2], by _carry)
                        for j in range(n):
                            miss += A[row, j] * saved[0, j]
                        for j in range(n):
                            side_j = ind[_I_FIXED, j]
                            if side_j != 0 and not ind[_I_PINNED, j] and A[row, j] != 0.0:
                                if side_j * miss * A[row, j] > 0.0:
                                    pull = min(pull, abs(saved[1, j] / A[row, j]))
                    for j in range(n):
                        side_j = ind[_I_FIXED, j]
                        if side_j != 0 and not ind[_I_PINNED, j] and A[row, j] != 0.0:
                            if not inward or (
                                side_j * miss * A[row, j] > 0.0
                                and abs(saved[1, j] / A[row, j]) <= INWARD_RATIO * pull
                            ):
                                ind[_I_FIXED, j] = 0
                                freed += 1
                if freed > 0 or not inward:
                    break
                inward = False
            released = 1 if inward else 2
            continue
        else:
            count += 1
            factored = np.int64(0)
            if factors_ok and carry[5] > 0:
                factored = carry[5]
                for i in range(n):
                    if base[i] != ind[_I_FIXED, i]:
                        factored = 0
            carry[5] = 0
            sub, rank = _subproblem(
                A, a, B, r, ridge, lower, upper, x, rank_rtol, W, T, N, V, ind, factored
            )  # fmt: skip
            if sub == _SUB_OK:
                carry[5] = rank + 1
            factors_ok = _FACTORED
            rank_now = rank
            nf = 0
            for i in range(n):
                base[i] = ind[_I_FIXED, i]
                if ind[_I_FIXED, i] == 0:
                    nf += 1
            base_ok = sub == _SUB_OK and p >= nf - rank > 0
            if base_ok:  # (a Schur complement on an ill-conditioned H loses its accuracy)
                lmin = np.inf
                lmax = 0.0
                for j in range(nf - rank):
                    lmin = min(lmin, N[j, j])
                    lmax = max(lmax, N[j, j])
                base_ok = lmax <= _COND_MAX_SQRT * lmin
            base_first = np.bool_(True)
            base_k = rank
            base_m = np.int64(m)
        if sub == _SUB_SINGULAR:
            _fill(x, np.nan)
            return NUMERICAL, count
        r_with = rank_with  # (for this pass's rank test only)
        rank_with = -1
        if phase == _DUAL_ADD and sub != _SUB_INCONSISTENT and r_with < 0:
            r_with = _rank_with(A, i_add, rank_rtol, W, V, ind)
            carry[5] = 0  # (its QR took the work space)
            base_ok = False  # (its QR took the work space)
        if phase == _PDAS:
            if sub == _SUB_INCONSISTENT:
                if warm and best > n:  # the warm start is inconsistent
                    if released < 2 and ridge > 0.0:
                        # release the bounds in the rows found dependent (an equality row that
                        # joined since, on the variables the warm set holds), then on; a
                        # strictly convex level's answer is the same whatever the start
                        released = 2
                        freed = 0
                        for t in range(rank, m):
                            row = ind[_I_PERM, t]
                            for j in range(n):
                                if ind[_I_FIXED, j] != 0 and not ind[_I_PINNED, j]:
                                    if A[row, j] != 0.0:
                                        ind[_I_FIXED, j] = 0
                                        freed += 1
                        if freed > 0:
                            max_iter += 1
                            continue
                    warm = False  # retry from a cold start
                    max_iter += 1
                    for i in range(n):
                        ind[_I_FIXED, i] = -1 if ind[_I_PINNED, i] else 0
                    continue
                if best > n:  # even the cold start is inconsistent
                    _fill(x, np.nan)
                    for i in range(n):
                        state[i] = -1 if ind[_I_PINNED, i] else 0
                    return INCONSISTENT, count
                # the last exchange fixed too many variables: back to the previous set (which
                # was consistent), and on with the dual method
                for i in range(n):
                    ind[_I_FIXED, i] = ind[_I_PREV, i]
                phase = _DUAL_START
                kept = True
                continue
            n_inf = 0
            for i in range(n):
                if ind[_I_PINNED, i]:
                    continue
                if ind[_I_FIXED, i] == 0:
                    n_inf += _violation(x[i], lower[i], upper[i]) > 0.0
                else:
                    n_inf += _wrong_sign(ind[_I_FIXED, i], V[_V_MU, i], V[_V_MU_TOL, i])
            if n_inf == 0:
                if keep:
                    _carry(
                        carry, base, base_ok, base_first, base_m, base_k, x, W, V, ind, U, U0,
                        pp, m, saved,
                    )  # fmt: skip
                _finish(x, lower, upper, V, np.int64(_V_MU), ind, state, np.bool_(True))
                return OK, count
            improved = n_inf < best
            if improved or (ridge > 0.0 and tied < ties and n_inf <= best + PDAS_RISE):
                # (a step that does not lower the count: on with PDAS, the set with the fewest
                # kept as the one to fall back to; a damped level only, whose minimiser is
                # unique whatever the path)
                if improved:
                    best = n_inf
                    saved_rank = rank
                    for i in range(n):
                        saved[0, i] = x[i]
                        saved[1, i] = V[_V_MU, i]
                        saved[2, i] = V[_V_MU_TOL, i]
                        ind[_I_PREV, i] = ind[_I_FIXED, i]
                else:
                    tied += 1
                for i in range(n):
                    if ind[_I_PINNED, i]:
                        continue
                    if ind[_I_FIXED, i] == 0:
                        if _violation(x[i], lower[i], upper[i]) > 0.0:
                            ind[_I_FIXED, i] = 1 if x[i] > upper[i] else -1
                    elif _wrong_sign(ind[_I_FIXED, i], V[_V_MU, i], V[_V_MU_TOL, i]):
                        ind[_I_FIXED, i] = 0
                continue
            # PDAS is not making progress (it may cycle): the dual method, from the set with
            # the fewest infeasibilities (the last exchange made things worse)
            phase = _DUAL_START
            for i in range(n):
                ind[_I_FIXED, i] = ind[_I_PREV, i]
            kept = True  # (that set's subproblem is the one kept: not solved again)
            continue
        if phase == _DUAL_START:
            if sub == _SUB_INCONSISTENT:  # cannot happen: only releases since a consistent set
                _finish(x, lower, upper, V, np.int64(_V_MU), ind, state, np.bool_(False))
                return MAX_ITER, count
            # a dual feasible start: no bound with the wrong multiplier sign. The most wrong
            # one is released at a time (the others' signs may change with it)
            i_worst = -1
            worst_mu = 0.0
            for i in range(n):
                side_i = ind[_I_FIXED, i]
                if side_i != 0 and not ind[_I_PINNED, i]:
                    if _wrong_sign(side_i, V[_V_MU, i], V[_V_MU_TOL, i]):
                        if abs(V[_V_MU, i]) > worst_mu:
                            worst_mu = abs(V[_V_MU, i])
                            i_worst = i
            if i_worst >= 0:
                ind[_I_FIXED, i_worst] = 0
                continue
            for i in range(n):
                V[_V_X0, i] = x[i]
                V[_V_MU0, i] = V[_V_MU, i]
            phase = _DUAL_ADD
        elif sub == _SUB_INCONSISTENT or rank < r_with:
            # the bound being added is a combination e_i = Aᵀλ' + Σ_X ν_j e_j of the equalities
            # and the active bounds (holding x_i at it drops the rank of A_F; the subproblem is
            # inconsistent, or consistent only because x_i is at the bound to roundoff already,
            # and then its multipliers are not unique), so x cannot move: a pure dual step
            # instead. Raising the added multiplier by s·τ (s its right sign) shifts μ_j by
            # −s·τ·ν_j; the first active bound whose multiplier reaches zero is released
            ind[_I_FIXED, i_add] = 0
            _dependency(A, i_add, rank_rtol, W, V, ind)
            carry[5] = 0
            base_ok = False
            sgn = -side
            tau_min = np.inf
            j_drop = -1
            for j in range(n):
                side_j = ind[_I_FIXED, j]
                if side_j == 0 or ind[_I_PINNED, j]:
                    continue
                nu_j = V[_V_NU, j]
                rate = side_j * sgn * nu_j  # d(−fixed_j μ_j)/dτ
                if rate < -1e-12 * (1.0 + abs(nu_j)):
                    tj = max(-side_j * V[_V_MU0, j], 0.0) / -rate
                    if tj < tau_min:
                        tau_min = tj
                        j_drop = j
            if j_drop >= 0:
                for j in range(n):
                    if ind[_I_FIXED, j] != 0:
                        V[_V_MU0, j] -= sgn * tau_min * V[_V_NU, j]
                V[_V_MU0, i_add] += sgn * tau_min
                ind[_I_FIXED, j_drop] = 0
                ind[_I_FIXED, i_add] = side
                continue
            if sub == _SUB_INCONSISTENT:  # the bounds and the equalities have no common point
                for i in range(n):
                    x[i] = V[_V_X0, i]
                _finish(x, lower, upper, V, np.int64(_V_MU0), ind, state, np.bool_(False))
                return MAX_ITER, count
            # x_i meets its bound already (to roundoff): hold it there, with μ_i = 0
            ind[_I_FIXED, i_add] = side
            V[_V_MU0, i_add] = 0.0
            for i in range(n):
                V[_V_X0, i] = x[i]
        else:
            # x, mu solve the problem with i_add on its bound; the segment from (x0, mu0) to
            # them is the path as x_i moves to the bound. Stop where a multiplier first
            # reaches zero (the bound is released there), else take the whole step
            theta = 1.0
            j_drop = -1
            for j in range(n):
                side_j = ind[_I_FIXED, j]
                if side_j == 0 or ind[_I_PINNED, j] or j == i_add:
                    continue
                if _wrong_sign(side_j, V[_V_MU, j], V[_V_MU_TOL, j]):
                    # margins of the right sign (−fixed·μ ≥ 0), at the start and at the end
                    m0 = max(-side_j * V[_V_MU0, j], 0.0)
                    m1 = -side_j * V[_V_MU, j]
                    th = m0 / (m0 - m1)
                    if th < theta:
                        theta = th
                        j_drop = j
            if j_drop >= 0:
                for j in range(n):
                    V[_V_X0, j] += theta * (x[j] - V[_V_X0, j])
                    V[_V_MU0, j] += theta * (V[_V_MU, j] - V[_V_MU0, j])
                ind[_I_FIXED, j_drop] = 0
                continue
            for i in range(n):
                V[_V_X0, i] = x[i]
                V[_V_MU0, i] = V[_V_MU, i]
        # (DUAL_ADD) x0, mu0 solve the current set with the right signs: add the bound farthest
        # beyond (relative to 1 + |bound|), or stop
        i_add = np.int64(-1)
        worst = 0.0
        for i in range(n):
            if ind[_I_FIXED, i] == 0:
                v = _violation(V[_V_X0, i], lower[i], upper[i])
                if v > worst:
                    worst = v
                    i_add = i
        if i_add < 0:
            wrong = False  # (guards against roundoff: the dual method keeps the signs right)
            for i in range(n):
                side_i = ind[_I_FIXED, i]
                if side_i != 0 and not ind[_I_PINNED, i]:
                    if _wrong_sign(side_i, V[_V_MU0, i], V[_V_MU_TOL, i]):
                        ind[_I_FIXED, i] = 0
                        wrong = True
            if wrong:
                phase = _DUAL_START
                continue
            for i in range(n):
                x[i] = V[_V_X0, i]
                V[_V_MU, i] = V[_V_MU0, i]
            if keep:
                _carry(
                    carry, base, base_ok, base_first, base_m, base_k, x, W, V, ind, U, U0, pp, m,
                    saved,
                )  # fmt: skip
            _finish(x, lower, upper, V, np.int64(_V_MU), ind, state, np.bool_(True))
            return OK, count
        side = 1 if V[_V_X0, i_add] > upper[i_add] else -1
        rank_with = rank_now  # (the set of the last subproblem, or the kept one's, is in ind)
        ind[_I_FIXED, i_add] = side
        V[_V_MU0, i_add] = 0.0


@njit(cache=True)
def solve_level_iterations(
    A, a, B, r, ridge, lower, upper, state, x, rank_rtol=1e-9, max_iter=30, ties=0
):  # fmt: skip
    """:func:`solve_level` that also returns how many subproblems it solved: (status, count).

    A warm start from the final active set of the same problem takes one subproblem.
    """
    m, n = A.shape
    space = level_space(m, n, B.shape[0])
    return _solve(
        A, a, B, r, float(ridge), lower, upper, state, x, float(rank_rtol), int(max_iter), space,
        np.bool_(False), np.bool_(False), int(ties), np.bool_(False),
    )  # fmt: skip


@njit(cache=True)
def solve_level(
    A, a, B, r, ridge, lower, upper, state, x, rank_rtol=1e-9, max_iter=30, ties=0
):  # fmt: skip
    """Solve one least-squares level with equalities and box bounds (see the module docstring).

    Writes the minimiser into ``x`` (n,) and the final active set into ``state`` (n,) int8
    (-1 at lower, 0 free, +1 at upper; read as the warm start). Returns OK, MAX_ITER (no
    optimal active set within ``max_iter`` subproblem solves, or the bounds and equalities have
    no common point; x is the last iterate, which meets the equalities but maybe not the
    bounds: fall back to a general QP solver), INCONSISTENT (the equalities cannot be met with
    the pinned variables, even from a cold start; x is NaN) or NUMERICAL (a singular
    subproblem, possible only with ridge = 0; x is NaN). A, a, B, r, lower, upper are not
    modified. ``ties``: on a damped level, PDAS's budget of steps that do not lower its count
    of infeasibilities before the dual method takes over (:data:`PDAS_TIES`; 0: at the first).
    """
    m, n = A.shape
    space = level_space(m, n, B.shape[0])
    status, _ = _solve(
        A, a, B, r, float(ridge), lower, upper, state, x, float(rank_rtol), int(max_iter), space,
        np.bool_(False), np.bool_(False), int(ties), np.bool_(False),
    )  # fmt: skip
    return status


@njit(cache=True)
def solve_level_in(
    A, a, B, r, ridge, lower, upper, state, x, rank_rtol, max_iter, space, cont, ties
):  # fmt: skip
    """:func:`solve_level` in a work space from :func:`level_space` (no allocation), returning
    (status, subproblems solved). ``cont``: this level is the last call's in ``space`` with
    equality rows appended (A's and a's first rows, B, r, ridge and the bounds unchanged):
    its final subproblem's factors are updated with the joined rows (``lsq_update.JOINS``)
    instead of solved afresh, where that applies. ``ties``: as :func:`solve_level`'s."""
    return _solve(
        A, a, B, r, float(ridge), lower, upper, state, x, float(rank_rtol), int(max_iter), space,
        np.bool_(cont), np.bool_(True), int(ties), np.bool_(False),
    )  # fmt: skip


# numba caches these on this file alone: flush them when the kernels they call change
_HERE = Path(__file__).parent
refresh(
    [
        level_space,
        _released,
        _carry,
        solve_level_in,
        _wrong_sign,
        _violation,
        _finish,
        _solve,
        solve_level_iterations,
        solve_level,
    ],
    [_HERE / "lsq_linalg.py", _HERE / "lsq_subproblem.py", _HERE / "lsq_update.py"],
)
