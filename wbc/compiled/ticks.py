"""The compiled solve of a tick, once the rows and the bounds are filled: the QP(s), integration.

* (the box of a stack's limits, which the tick's bound kernels fill before these:
  :mod:`wbc.compiled.boxes`);
* :func:`weighted_solve` — the weighted QP: soft rows in least squares (damping μ‖Δq‖²), hard
  rows as equalities, inequality rows, the bounds;
* :func:`cascade_solve` — the lexicographic QP: level k in least squares subject to the bounds
  and to every level above kept at its achieved values (``J_i Δq = J_i Δq_i``, the exact
  optimal set of a least-squares level) and its inequality rows at their bounds plus the
  slacks it kept, the last level damped by μ‖Δq‖² as the weighted QP.

Both solve each least-squares problem by :func:`wbc.compiled.lsq.solve_level` (an active set on
the bounds) and the inequality rows by a primal active set around it
(:func:`solve_with_inequalities`), which costs nothing while the rows are inactive. They are
the one algorithm of both solvers on every path (the numpy assembly calls them too).
Both return a status; anything but :data:`~wbc.compiled.lsq.OK` sends the caller back to the
numpy path, which handles (and names) infeasible problems. The tick itself (rows and bounds,
then one of these) is generated per set of kernels by :mod:`wbc.compiled.dispatch`.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit

from ._cache import refresh
from .integrate import integrate
from .lsq import (
    MAX_ITER,
    NUMERICAL,
    OK,
    level_space,
    solve_level_in,
)
from .lsq_multipliers import equality_multipliers_in
from .lsq_release import mark_weak, release_marked
from .proximal import proximal_level
from .space import (
    LEVEL_FLOATS,
    LEVEL_INTS,
    SPACE_ROWS,
    cascade_space_size,
    inequality_size,
    inequality_work,
    keep_size,
    level_space_at,
    level_space_size,
    multiplier_size,
    multiplier_work,
)

#: the hard rows of the last solve missed their targets by more than the caller's tolerance
HARD_MISSED = 100
#: the solution is not finite (a non-finite target or row): never returned as solved
NOT_FINITE = 101
#: a soft level deferred to the next level's solve cannot be met exactly (internal: the
#: cascade then solves it; never returned by :func:`cascade_solve`)
DEFERRAL_FAILED = 102
#: a deferred soft level counts as met when each row is within this × (1 + |b_i|)
DEFERRED_TOL = 1e-9
#: at most this many subproblem solves of an intermediate level without a ridge (a warm
#: start takes 1 or 2; beyond a few, the active set is cycling on the level's flat directions
#: and proximal steps take over)
EXACT_MAX_ITER = 6
#: at most this many subproblem solves of a damped level (many active bounds and working
#: rows can take the dual active set method beyond the 30 that the plain levels need)
LEVEL_MAX_ITER = 100
#: a row that leaves the working set more often than this: the active set is cycling
MAX_DROPS = 2
#: with the rows joining the deferred solve (``params[0]`` = 2), its answer is degenerate when a
#: hard row outside its working set is within this × (1 + |h_i|) of its bound: then the levels
#: are solved one by one, as without the rows joining (:func:`_degenerate`)
DEGENERATE_ROW = 1e-8
#: the damped last level takes its rows most violated first (``_cascade``'s ``direct``) only
#: while the level above holds fewer of its hard rows than this at their bounds
DIRECT_HELD_ROWS = 2


@njit(cache=True)
def _violated(G, h, p, x, tol) -> bool:
    """True if one of the first p rows of G x <= h is violated by more than tol."""
    for i in range(p):
        s = -h[i]
        for j in range(x.shape[0]):
            s += G[i, j] * x[j]
        if s > tol:
            return True
    return False


@njit(cache=True)
def _any(flags, p) -> bool:
    """True if one of the first p flags is set."""
    for i in range(p):
        if flags[i]:
            return True
    return False


@njit(cache=True)
def weighted_solve(
    soft_J, soft_b, hard_J, hard_b, G, h, g_rows, q, q_min, q_max, params, lower, upper, state,
    working, dq, q_next,
) -> int:  # fmt: skip
    """With the rows and the bounds filled: min ‖soft_J Δq − soft_b‖² + μ‖Δq‖² subject to
    hard_J Δq = hard_b, G Δq <= h (its first ``g_rows[1]`` rows) and the bounds; Δq into
    ``dq``, q ⊕ Δq into ``q_next`` (see :func:`integrate`). ``params``: [(unused), μ,
    (unused), tolerance of the inequality rows]; ``working``: the inequality rows' working set
    (the last tick's: a warm start; updated). Without a warm start the inequality rows cost
    nothing while the solution without them meets them; else, and with one,
    :func:`solve_with_inequalities`."""
    mu = params[1]
    tol = params[3]
    p = g_rows[1]
    status = OK
    space = level_space(hard_J.shape[0] + SPACE_ROWS, dq.shape[0], soft_J.shape[0])
    for _ in range(2):  # a warm start that fails: once more, cold
        warm = _any(working, p)  # a working set from the last tick: straight to the rows
        status = OK
        if not warm:
            status, _ = solve_level_in(
                hard_J,
                hard_b,
                soft_J,
                soft_b,
                mu,
                lower,
                upper,
                state,
                dq,
                1e-9,
                np.int64(30),
                space,
                np.bool_(False),
                np.int64(0),
            )  # fmt: skip  (solve_level's defaults, as values: one specialisation, see _level)
        if status == OK and (warm or _violated(G, h, p, dq, tol)):
            status, _ = solve_with_inequalities(
                hard_J, hard_b, soft_J, soft_b, mu, np.bool_(False), lower, upper, state, dq,
                G[:p], h[:p], p, tol, working[:p], dq, np.bool_(False), space,
                np.bool_(not warm), np.int64(0), np.empty(0), np.empty(0, np.int64),
            )  # fmt: skip
        if status == OK or not warm:
            break
        working[:] = False
        state[:] = 0
    if status == OK and not _finite(dq):
        status = NOT_FINITE
    if status == OK:
        integrate(q, dq, lower, upper, q_min, q_max, q_next)
    return status


@njit(cache=True)
def _count(flags, p) -> int:
    """How many of the first p flags are set."""
    c = 0
    for i in range(p):
        if flags[i]:
            c += 1
    return c


@njit(cache=True)
def _finite(x) -> bool:
    """True if every entry of x is finite (x·x is, unless one is not or it overflows)."""
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i] * x[i]
    if math.isfinite(s):
        return True
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]):
            return False
    return True


@njit(cache=True)
def _level(A, a, B, r, ridge, exact, lower, upper, state, x, space, cont, ties, previous) -> int:
    """One least-squares level by :func:`~wbc.compiled.lsq.solve_level`: with ``ridge``
    (the weighted QP, the last level of the hierarchy); or, ``exact``, without (an
    intermediate level of the hierarchy): exact least squares when the level's rows are
    independent in the remaining freedom, else, or when the active set cycles on the flat
    directions of the unregularised problem, proximal steps from x
    (:func:`~wbc.compiled.proximal.proximal_level`). In ``space``
    (:func:`~wbc.compiled.lsq.level_space`); ``cont``: the last call's level in it with
    equality rows joined (:func:`~wbc.compiled.lsq.solve_level_in`); ``ties``: its PDAS
    budget (the stack's, ``params[4]`` of :func:`cascade_solve`; the weighted QP's 0);
    ``previous``: n floats of work (x before the exact solve)."""
    if not exact:
        status, _ = solve_level_in(
            A, a, B, r, ridge, lower, upper, state, x, 1e-9, np.int64(LEVEL_MAX_ITER), space, cont,
            ties,
        )  # fmt: skip
        return status
    previous[:] = x
    status, _ = solve_level_in(
        A, a, B, r, 0.0, lower, upper, state, x, 1e-9, np.int64(EXACT_MAX_ITER), space, cont,
        ties,
    )  # fmt: skip
    if status == NUMERICAL or status == MAX_ITER:
        x[:] = previous
        status = proximal_level(A, a, B, r, lower, upper, state, x, LEVEL_MAX_ITER, ties, space)
    return status


@njit(cache=True)
def _hard_multipliers(A, mh, B, ps, r, ridge, exact, state, x, lam, fw, iw):
    """Multipliers of the equalities A[:mh] at x from the stationarity on the free variables,
    ``A_Fᵀ λ = −∇f_F`` with ∇f = Bᵀ(B x − r) (+ ridge·x unless ``exact``), in least squares
    (:func:`~wbc.compiled.lsq_multipliers.equality_multipliers`: a basic solution if the rows are
    dependent), into ``lam``; False if it has no solution (no certificate). Its work in fw, iw
    (:func:`~wbc.compiled.space.multiplier_work`; allocated if they are too small)."""
    n = x.shape[0]
    f, i_ = multiplier_size(mh, n)
    if fw.shape[0] < f or iw.shape[0] < i_:
        fw, iw = np.empty(f), np.empty(i_, np.int64)
    grad, W, V, ind = multiplier_work(fw, iw, mh, n)
    for i in range(ps):
        e = -r[i]
        for j in range(n):
            e += B[i, j] * x[j]
        for j in range(n):
            grad[j] += B[i, j] * e
    if not exact:
        for j in range(n):
            grad[j] += ridge * x[j]
    return equality_multipliers_in(A[:mh], state, grad, lam[:mh], 1e-9, W, V, ind)


@njit(cache=True, inline="always")
def _row(G, h, i, x):
    """G_i x − h_i."""
    v = -h[i]
    for j in range(x.shape[0]):
        v += G[i, j] * x[j]
    return v


@njit(cache=True)
def solve_with_inequalities(
    A0, a0, B0, r0, ridge, exact, lower, upper, state, x, G, h, soft_from, tol, working, start,
    from_start, space, cont, ties, fw, iw,
) -> int:  # fmt: skip
    """min ‖B0 x − r0‖² + ridge‖x‖² + Σ_{i ≥ soft_from} max(G_i x − h_i, 0)² subject to
    A0 x = a0, G_i x <= h_i (i < soft_from) and the bounds: a primal active set on the G
    rows around :func:`_level` (``exact``: no ridge, an intermediate level of the hierarchy).

    A hard row of the working set is an equality; a soft row is a least-squares row
    (G_i x ≈ h_i: the slack s_i = G_i x − h_i of min ‖s‖² s.t. G_i x − s_i <= h_i, whose
    multiplier is s_i itself). From a feasible point x_c (``start`` with ``from_start``, if it
    meets A0, the bounds and the hard rows and lies on the hard rows of the warm working set,
    else the first solution that meets every row),
    each solution x is approached along the segment from x_c, and the first hard row that
    blocks it joins (so the working set stays consistent); without one, the most violated
    row joins. Once every row holds to ``tol``, the working rows' multipliers are checked —
    a soft row's is its slack, a hard row's comes from the stationarity on the free variables
    (:func:`_hard_multipliers`) — and the most negative leaves (below −tol, relative for the
    hard ones), else x is optimal. ``working`` (p bools): the working set to start from (the
    last tick's: a warm start, whose rows join at once); on
    OK the final one, else cleared. Returns (status, near): OK (x optimal, ``state`` its
    bounds' active set), NUMERICAL (the stationarity has no solution: no certificate),
    MAX_ITER (also when a row leaves more than :data:`MAX_DROPS` times: cycling, on degenerate
    or dependent rows) or the status of a failed level solve; ``near``: with OK, whether x is
    degenerate (:func:`_degenerate` on its hard rows, from the values its last scan computed).
    A lone hard row joined from the damped level's minimiser without rows keeps its place
    without its multiplier computed (it is ≥ 0). ``space``: the level solver's work space
    (:func:`~wbc.compiled.lsq.level_space`); ``cont``: its last call solved this level
    without the rows (x its solution, ``state`` its set): hard rows joining since are then
    updates of that call's factors, as after each solve here that only hard rows followed.
    ``ties``: :func:`_level`'s. fw, iw: its work (:func:`~wbc.compiled.space.inequality_work`,
    then the multipliers'; allocated if they are too small).
    """
    m0, n = A0.shape
    p0 = B0.shape[0]
    p = G.shape[0]
    f, i_ = inequality_size(m0, p0, p, n)
    if fw.shape[0] < f or iw.shape[0] < i_:
        fw, iw = np.empty(f), np.empty(i_, np.int64)
    A, a, B, r, lam, xc, previous, rows, drops = inequality_work(fw, iw, m0, p0, p, n)
    A[:m0] = A0
    a[:m0] = a0
    B[:p0] = B0
    r[:p0] = r0
    solve = _any(working, p)  # a warm start is solved first (x: a solution without the rows)
    # a lone hard row joined at x, the damped level's minimiser without rows, which violates
    # it: its multiplier λ = −v'(h) ≥ 0 (v(t) = min{f : A0 x = a0, bounds, G_i x = t} is
    # convex, least at G_i x > h_i), so it cannot leave: no multipliers to compute (3-5 µs)
    lone = not solve and not exact and ridge > 0.0
    feasible = from_start
    if feasible:
        for j in range(n):
            if start[j] < lower[j] - tol or start[j] > upper[j] + tol:
                feasible = False
        for i in range(soft_from):
            if _row(G, h, i, start) > tol:
                feasible = False
        for i in range(soft_from):  # x_c must lie on the hard rows of the working set
            if working[i] and _row(G, h, i, start) < -tol:
                feasible = False
    if feasible:
        xc[:] = start
    # rows: the working set, in the order its rows joined; drops: how often each row left it
    nw = 0
    for i in range(p):
        if working[i]:
            rows[nw] = i
            nw += 1
    mh = m0
    ps = p0
    for _ in range(2 * p + 4):
        if solve:
            mh = m0
            ps = p0
            for w in range(nw):
                i = rows[w]
                if i < soft_from:
                    A[mh] = G[i]
                    a[mh] = h[i]
                    mh += 1
                else:
                    B[ps] = G[i]
                    r[ps] = h[i]
                    ps += 1
            if mh > space[8] or ps > space[9]:  # (more rows than it was made for)
                space = level_space(m0 + p, n, p0 + p)
                cont = False
            status = _level(
                A[:mh], a[:mh], B[:ps], r[:ps], ridge, exact, lower, upper, state, x, space, cont,
                ties, previous,
            )  # fmt: skip
            if status != OK:
                working[:] = False
                return status, False
            cont = True  # (until a soft row joins, changing B, or a row leaves)
        solve = True
        k = -1
        # (a hard row outside the working set within DEGENERATE_ROW of its bound at x:
        # :func:`_degenerate` at the answer, from the rows' values the scans below compute)
        near = False
        if feasible:  # the first hard row that blocks the step from x_c to x joins
            t_min = 1.0
            for i in range(soft_from):
                if not working[i]:
                    vn = _row(G, h, i, x)
                    near = near or vn > -DEGENERATE_ROW * (1.0 + abs(h[i]))
                    if vn > tol:
                        vc = min(_row(G, h, i, xc), 0.0)
                        t = -vc / (vn - vc)
                        if t < t_min:
                            t_min = t
                            k = i
            if k >= 0:
                for j in range(n):
                    xc[j] += t_min * (x[j] - xc[j])
            else:
                xc[:] = x
        if k < 0:  # the most violated row joins (when x_c is kept: a soft one)
            worst = tol
            for i in range(soft_from if feasible else 0, p):
                if not working[i]:
                    v = _row(G, h, i, x)
                    if i < soft_from:
                        near = near or v > -DEGENERATE_ROW * (1.0 + abs(h[i]))
                    if v > worst:
                        worst = v
                        k = i
        if k >= 0:
            rows[nw] = k
            working[k] = True
            nw += 1
            cont = cont and k < soft_from
            continue
        if not feasible:  # x meets every row: from here on, the feasible point
            feasible = True
            xc[:] = x
        if lone and nw == 1 and mh == m0 + 1:
            return OK, near
        if mh > m0 and not _hard_multipliers(
            A, mh, B, ps, r, ridge, exact, state, x, lam, fw[f:], iw[i_:]
        ):
            working[:] = False
            return NUMERICAL, False
        scale = 0.0
        for c in range(m0, mh):
            scale = max(scale, abs(lam[c]))
        drop = -1
        lowest = 0.0
        c = m0
        for w in range(nw):
            i = rows[w]
            if i < soft_from:
                mult = lam[c]
                c += 1
                limit = -tol * (1.0 + scale)
            else:
                mult = _row(G, h, i, x)
                limit = -tol
            if mult < limit and mult < lowest:
                lowest = mult
                drop = w
        if drop < 0:
            return OK, near
        lone = False
        drops[rows[drop]] += 1
        if drops[rows[drop]] > MAX_DROPS:  # cycling (degenerate or dependent rows): give up
            working[:] = False
            return MAX_ITER, False
        working[rows[drop]] = False
        for w in range(drop, nw - 1):
            rows[w] = rows[w + 1]
        nw -= 1
        cont = False
    working[:] = False
    return MAX_ITER, False


@njit(cache=True)
def _degenerate(G, h, hard, working, x) -> bool:
    """Whether a hard row G_i x <= h_i (i < ``hard``) outside the working set is within
    :data:`DEGENERATE_ROW` of its bound at x: then x is at a vertex of more rows than it
    holds, and which of them a path holds (each answer within the rows' tolerance of them)
    moves Δq by up to ~1e-8 (the OP3's walk_strict walk10, ticks 308–311)."""
    for i in range(hard):
        if not working[i] and _row(G, h, i, x) > -DEGENERATE_ROW * (1.0 + abs(h[i])):
            return True
    return False


@njit(cache=True)
def _refused(G, h, g_rows, level_hard, working, x) -> int:
    """1 if the last level's answer x (its working set ``working``) is degenerate
    (:func:`_degenerate`): the guard would refuse the next tick's deferral with the rows."""
    n_levels = g_rows.shape[0] - 1
    hard = g_rows[n_levels] if level_hard[n_levels - 1] else g_rows[n_levels - 1]
    return 1 if _degenerate(G, h, hard, working[n_levels - 1], x) else 0


@njit(cache=True)
def _keep(states, working, g, saved) -> None:
    """``states`` and ``working``'s first g columns into saved[1:] (:func:`keep_size`)."""
    o = 1
    for k in range(states.shape[0]):
        for j in range(states.shape[1]):
            saved[o] = states[k, j]
            o += 1
    for k in range(working.shape[0]):
        for i in range(g):
            saved[o] = working[k, i]
            o += 1


@njit(cache=True)
def _keep_level(states, saved, k, n_levels) -> None:
    """Level k's bounds' set and the last level's without its rows (row ``n_levels``, if
    ``states`` has it) into their places in saved (:func:`_keep`)."""
    nv = states.shape[1]
    for j in range(nv):
        saved[1 + k * nv + j] = states[k, j]
        if states.shape[0] > n_levels:
            saved[1 + n_levels * nv + j] = states[n_levels, j]


@njit(cache=True)
def _restore(states, working, g, saved) -> None:
    """:func:`_keep` undone."""
    o = 1
    for k in range(states.shape[0]):
        for j in range(states.shape[1]):
            states[k, j] = saved[o]
            o += 1
    for k in range(working.shape[0]):
        for i in range(g):
            working[k, i] = saved[o] != 0
            o += 1


@njit(cache=True)
def _cascade(
    J, b, level_rows, level_hard, G, h, g_rows, params, lower, upper, states, working, h_eff,
    achieved, dq, defer_soft, fw, iw, saved,
) -> int:  # fmt: skip
    """The levels of :func:`cascade_solve` in order, with the bounds set. ``defer_soft``: an
    intermediate soft level (at the top, every level above it deferred too) is deferred as a
    hard one, on the guess that it can be met exactly; returns :data:`DEFERRAL_FAILED` if
    the guess is wrong (the next level's solve fails, or misses its rows; with the rows
    joining it, also where its answer is degenerate: :func:`_degenerate`). fw, iw: the work
    space (:func:`~wbc.compiled.space.cascade_space_size` of the tick, at least); ``saved``:
    the sets the fallback starts from (:func:`_keep`), written where the cascade without the
    rows joining would have failed."""
    mu = params[1]
    hard_tol = params[2]
    tol = params[3]
    n_levels = level_rows.shape[0] - 1
    nv = dq.shape[0]
    for i in range(nv):
        dq[i] = 0.0
    for i in range(g_rows[n_levels]):
        h_eff[i] = h[i]
    widest = 0
    for k in range(n_levels):
        widest = max(widest, level_rows[k + 1] - level_rows[k])
    m_space = level_rows[max(n_levels - 1, 0)] + SPACE_ROWS
    space = level_space_at(fw, iw, m_space, nv, widest + SPACE_ROWS)
    f0, i0 = level_space_size(m_space, nv, widest + SPACE_ROWS)
    entry, free_x = fw[f0 : f0 + nv], fw[f0 + nv : f0 + 2 * nv]
    previous = fw[f0 + 2 * nv : f0 + 3 * nv]
    kept, free_state = iw[i0 : i0 + nv], iw[i0 + nv : i0 + 2 * nv]
    fw, iw = fw[f0 + LEVEL_FLOATS * nv :], iw[i0 + LEVEL_INTS * nv :]  # (the rows' work)
    deferred = 0  # the levels before this row: met exactly by the next level's solve
    soft = False  # a soft level among them
    # with inequality rows, the levels above the last deferred too (params[0] > 0) while no
    # row is active: the last level's solve without its rows must meet every row, else the
    # deferral fails before any row joins (and the levels are solved on their own)
    rows_free = g_rows[n_levels] == 0 or (defer_soft and params[0] > 0.0)
    # PDAS's budget: the stack's (its solver's ``pdas_ties``: lsq.PDAS_TIES or 0)
    ties = np.int64(params[4]) if params.shape[0] > 4 else np.int64(0)
    weak = params[5] if params.shape[0] > 5 else 0.0  # (``lsq_release``: 0 off)
    # (params[0] = 2: the rows join the last level's solve with the levels above deferred;
    # they are checked after it)
    joining = params[0] > 1.0
    for k in range(n_levels):
        r0 = level_rows[k]
        r1 = level_rows[k + 1]
        g0 = g_rows[k]
        g1 = g_rows[k + 1]
        last = k == n_levels - 1
        if (level_hard[k] or defer_soft) and not last and rows_free and deferred == r0:
            # a hard level (of a tick without inequality rows; the levels above it deferred
            # too): its optimal set, when it is met, is {J_k Δq = b_k} within the bounds, so
            # the next level takes it as equalities instead of a solve of its own (the same
            # answer; checked after that solve, which fails if the level cannot be met). A
            # soft level likewise, if it can be met exactly (its least-squares optimum is then
            # that set): if not, the next level's solve fails or misses its rows
            for i in range(r0, r1):
                achieved[i] = b[i]
            deferred = r1
            soft = soft or not level_hard[k]
            continue
        A, a, B, r = J[:r0], achieved[:r0], J[r0:r1], b[r0:r1]
        # with the last tick's working set (a warm start) straight to the inequality rows;
        # else the level without them first (a level of constraints only: Δq so far is one of
        # its optima, if it meets them), and if it misses one, the rows from the hard rows
        # the level above kept at their bounds. A warm start that fails: once more, cold
        # The damped last level (one minimiser) takes its rows most violated first, from its
        # solution without them (``direct``); if that fails, once more as the levels above:
        # from the feasible Δq so far, the rows the level above held joining at once. Its
        # solve without the rows starts from that solve's bounds at the last tick when
        # ``states`` has a row for them (``states[L]``: the last tick's end, with its rows,
        # took that solve 7-10 subproblems on walk_strict's slowest ticks). It goes the
        # second way at once when the level above holds DIRECT_HELD_ROWS rows or more at
        # their bounds: held with positive multipliers, they are active on the whole of this
        # level's feasible set, and the rows joining most violated first then took a
        # dependent set (a face's coplanar corners) and ended INCONSISTENT or cycling after
        # several solves (walk_strict, walk10: 21 ticks, 60-90 µs each)
        above = 0 if k == 0 else (g0 if level_hard[k - 1] else g_rows[k - 1])
        held = 0 if k == 0 else _count(working[k - 1], above)
        entry[:] = dq
        direct = last and mu > 0.0 and held < DIRECT_HELD_ROWS
        kept[:] = states[k]
        free = states.shape[0] > n_levels  # (a row for the last level's set without its rows)
        # the damped level's solution without its rows and its bounds' set, kept for a second
        # attempt (the same strictly convex problem, which the second attempt solved again
        # from another start to the same set and the same Δq: 10-35 µs a time)
        solved = False  # (then free_x, free_state: that solution and its set)
        status = OK
        # the last level from rows carried from the last tick (``working``: CarriedRows): if
        # that fails, the cold start as without them (then the other way, as there)
        carried = direct and free and _any(working[k], g1)
        for _ in range(3):
            warm = _any(working[k], g1)
            status = OK
            near = False
            cont = False  # (the space's last call: this level without its rows)
            if (r1 > r0 or last) and not warm and solved:
                dq[:] = free_x
                states[k, :] = free_state
            elif (r1 > r0 or last) and not warm:
                if direct and free:  # (its set without the rows at the last tick)
                    states[k, :] = states[n_levels]
                    if weak > 0.0:
                        release_marked(states[k])
                status = _level(
                    A, a, B, r, mu, not last, lower, upper, states[k], dq, space, np.bool_(False),
                    ties, previous,
                )  # fmt: skip
                cont = status == OK
                if direct and free:
                    states[n_levels, :] = states[k]
                    if weak > 0.0 and status == OK:
                        mark_weak(states[n_levels], space[0][3], lower, upper, weak)
                if direct and status == OK:
                    free_x[:] = dq
                    free_state[:] = states[k]
                    solved = True
            violated = warm or (status == OK and _violated(G, h_eff, g1, dq, tol))
            if deferred > 0 and g1 > 0 and violated:
                if not joining:
                    return DEFERRAL_FAILED
                if saved[0] == 0:  # (without the rows joining, the deferral failed here:
                    saved[0] = 1  # the fallback starts from the sets it then had)
                    _keep_level(states, saved, k, n_levels)
            if status == OK and violated:
                soft_from = g1 if level_hard[k] else g0
                if not warm and k > 0 and not direct:
                    for i in range(above):
                        working[k, i] = working[k - 1, i]
                # (Δq so far meets the levels above and their rows: a feasible start)
                status, near = solve_with_inequalities(
                    A, a, B, r, mu, not last, lower, upper, states[k], dq, G[:g1], h_eff[:g1],
                    soft_from, tol, working[k, :g1], entry, np.bool_(not direct), space,
                    np.bool_(cont), ties, fw, iw,
                )  # fmt: skip
            if status == OK or not (warm or direct) or (deferred > 0 and not violated):
                break  # (a deferred solve failed without rows: a retry is the same problem)
            working[k, :] = False
            if direct:
                states[k, :] = kept
            else:
                states[k, :] = 0
            dq[:] = entry
            direct = direct and warm
        if carried and status == OK and not solved:  # (its set without the rows: not solved,
            states[n_levels, :] = states[k]  # the set with them, nearer than an older one's)
        if status != OK:
            return DEFERRAL_FAILED if soft or (deferred > 0 and g1 > 0) else status
        for i in range(deferred):  # the deferred levels, met by this solve's equalities
            s = 0.0
            for j in range(nv):
                s += J[i, j] * dq[j]
            achieved[i] = s
            if soft and abs(s - b[i]) > DEFERRED_TOL * (1.0 + abs(b[i])):
                return DEFERRAL_FAILED
            if abs(s - b[i]) > hard_tol:
                return DEFERRAL_FAILED if g1 > 0 else HARD_MISSED
        if joining and deferred > 0 and g1 > 0 and _any(working[k], g1):
            if near:  # (:func:`_degenerate` at dq, from solve_with_inequalities' last scan)
                return DEFERRAL_FAILED
        deferred = 0
        soft = False
        for i in range(r0, r1):
            s = 0.0
            for j in range(nv):
                s += J[i, j] * dq[j]
            achieved[i] = s
            if level_hard[k] and abs(s - b[i]) > hard_tol:
                return HARD_MISSED
        if not level_hard[k]:
            for i in range(g0, g1):  # the slacks the level kept
                s = -h[i]
                for j in range(nv):
                    s += G[i, j] * dq[j]
                if s > 0.0:
                    h_eff[i] = h[i] + s
    return OK


@njit(cache=True)
def cascade_solve(
    J, b, level_rows, level_hard, G, h, g_rows, q, q_min, q_max, params, lower, upper, states,
    working, h_eff, achieved, dq, q_next, fspace, ispace,
) -> int:  # fmt: skip
    """With every level's rows (weighted) and the bounds filled: the levels in order.

    ``level_rows``: row boundaries of the levels in J (L + 1 entries); ``g_rows``: those of
    the levels' inequality rows in G, h; ``states[k]``: the active set of level k's bounds
    and ``working[k]`` of its inequality rows (the last tick's: a warm start; updated), and
    ``states[L]`` if given (L + 1 rows) the last level's without its inequality rows (the
    warm start of that solve), and ``states[L + 1, 0]`` if given (L + 2 rows) 1 if the last
    tick ended with an inequality row active, else 0, and ``states[L + 1, 1]`` 1 if its
    answer was degenerate (:func:`_refused`), else 0 (both written for the next tick);
    ``achieved``: J Δq of each solved level; ``h_eff``: h plus the slack each soft level's
    rows kept (work space); ``params``: [1 to defer the levels above with inequality
    rows too, 2 with the rows joining that solve, 3 and that solve not tried after a
    tick whose answer was degenerate (else 0), μ, tolerance of hard levels,
    tolerance of the inequality rows, and if given PDAS's budget of ties
    (:data:`~wbc.compiled.lsq.PDAS_TIES` or 0: the stack's ``pdas_ties``; else 0), and if
    given the ratio of :mod:`~wbc.compiled.lsq_release` (0: off)]; q ⊕ Δq
    into ``q_next``; ``fspace``, ``ispace``: the work space (float64, int64:
    :mod:`wbc.compiled.space`, allocated here if smaller than the tick needs).

    Level k: min ‖J_k Δq − b_k‖² (+ Σ max(G_k Δq − h_k, 0)², its own inequality rows as
    slacks, unless the level is hard: then as rows to meet) subject to the bounds, every level
    above at its achieved values (``J_i Δq = J_i Δq_i``, the exact optimal set of a
    least-squares level) and the rows above at their bounds plus the slacks they kept
    (``G_i Δq <= h_i + s_i``); the last level damped by μ‖Δq‖² as the weighted QP. The
    inequality rows cost nothing on a level whose solution without them meets them (and which
    had no working set at the last tick); else :func:`solve_with_inequalities`: from the
    feasible Δq of the levels above, the rows the level above held joining at once; on the
    damped last level (one minimiser, whatever the path) from its solution without the rows,
    the most violated joining first (on ``walk_strict``'s slowest ticks the arms' box corners
    against the torso then join once each instead of joining and leaving in turn: the last
    level's subproblems p99 35 -> 22 along walk10; the first way again if this one fails, from
    the same solution without the rows), but the first way at once where the level above holds
    :data:`DIRECT_HELD_ROWS` rows or more at their bounds. In a tick
    without inequality rows, the hard levels at the top are not solved on their own: met, a
    hard level's optimal set is {J_k Δq = b_k} within the bounds, which the next level takes
    as its equalities (the same answer, one level solve fewer); they are checked after it.
    So are the soft levels at the top, on the guess that they can be met exactly (their
    optimal set is then the same; on ``walk10`` the CoM and swing level always can): if the
    next level's solve fails or misses their rows (:data:`DEFERRED_TOL`), the levels are
    solved again with every soft level on its own. With inequality rows too when
    ``params[0]`` > 0 (``HierarchicalQP.defer_with_rows``): the levels above the last are its
    equalities while its solution without the rows meets every row (and the last tick
    ended with no row active, where ``states`` says), the same optimum up to rounding (its
    minimiser over a larger set lies in the hierarchy's; walk_strict: Δq within 2e-15 of the
    levels solved one by one, the median cascade 13.7 -> 7.9 µs); else the levels are solved
    one by one before any row joins (one wasted solve of the last level, 11-38 µs on
    walk_strict's row ticks: so not tried after a tick that ended with a row active; its
    first double-support ticks' cascade 48 -> 43 µs, the p99 -7 to -10 %, replayed).
    """
    # whether the last tick ended with an inequality row active (``states``' last row, when
    # it has one: L + 2 rows): then, in a tick with rows, the deferral is not tried (it would
    # fail on a violated row: one solve of the last level wasted, 11-38 µs on walk_strict's
    # row ticks; ``_cascade`` without ``defer_soft`` is the path it then fell back to)
    n_levels = level_rows.shape[0] - 1
    memo = states.shape[0] > n_levels + 1
    rows_before = memo and states[states.shape[0] - 1, 0] != 0 and g_rows[n_levels] > 0
    joining = params[0] > 1.0 and g_rows[n_levels] > 0  # (2: the rows join the deferred solve)
    # (3: and not tried after a tick whose answer the guard would refuse, ``states``' last
    # row's column 1: :func:`_refused`; the levels one by one at once, the guard's fallback)
    skipping = memo and params[0] > 2.0
    skip = joining and skipping and rows_before and states[states.shape[0] - 1, 1] != 0
    f, i_ = cascade_space_size(level_rows, dq.shape[0], g_rows[n_levels])
    if fspace.shape[0] < f or ispace.shape[0] < i_:
        fspace, ispace = np.empty(f), np.empty(i_, np.int64)
    # (the sets the levels one by one start from if the deferral with the rows fails: those
    # the cascade without the rows joining would have started them from, at the space's end)
    saved = ispace[i_ - keep_size(n_levels, dq.shape[0], g_rows[n_levels]) : i_]
    if joining and not skip:
        _keep(states, working, g_rows[n_levels], saved)
        saved[0] = 2 if rows_before else 0  # (2: it would not have tried the deferral)
    defer = (joining and not skip) or not (rows_before and params[0] > 0.0)
    status = _cascade(
        J, b, level_rows, level_hard, G, h, g_rows, params, lower, upper, states, working,
        h_eff, achieved, dq, np.bool_(defer), fspace, ispace, saved,
    )  # fmt: skip
    failed = status == DEFERRAL_FAILED
    if failed:  # a soft level above cannot be met exactly: solve it
        if joining and saved[0] != 0:
            _restore(states, working, g_rows[n_levels], saved)
        status = _cascade(
            J, b, level_rows, level_hard, G, h, g_rows, params, lower, upper, states, working,
            h_eff, achieved, dq, np.bool_(False), fspace, ispace, saved,
        )  # fmt: skip
    if memo:
        active = False
        for k in range(n_levels):
            active = active or _any(working[k], g_rows[n_levels])
        states[states.shape[0] - 1, 0] = 1 if active else 0
        refused = skipping and active and (skip or failed) and status == OK
        states[states.shape[0] - 1, 1] = (
            _refused(G, h_eff, g_rows, level_hard, working, dq) if refused else 0
        )
    if status != OK:
        return status
    if not _finite(dq):
        return NOT_FINITE
    integrate(q, dq, lower, upper, q_min, q_max, q_next)
    return OK


# numba caches these on ticks.py alone: flush them when the kernels they call change
refresh(
    [
        _violated,
        _any,
        _count,
        _finite,
        _row,
        weighted_solve,
        _level,
        _hard_multipliers,
        solve_with_inequalities,
        _degenerate,
        _refused,
        _keep,
        _keep_level,
        _restore,
        _cascade,
        cascade_solve,
    ],
    [
        Path(__file__).with_name(f)
        for f in (
            "lsq.py lsq_subproblem.py lsq_update.py lsq_linalg.py lsq_multipliers.py proximal.py "
            "lsq_release.py "
            "space.py integrate.py"
        ).split()
    ],
)
