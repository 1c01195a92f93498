"""Lexicographic least squares with inequalities: a cascade of QPs (Kanoun et al. 2011).

Level k minimises ‖J_k Δq − b_k‖² + ‖s_k‖² subject to everything the levels above fixed:

* their equality residuals — kept by searching Δq = x + Z u in the null space of the stacked
  higher-level Jacobians (redundant or conflicting rows never become ill-posed equality
  constraints),
* their inequalities ``G_j Δq <= h_j + s_j*`` with the slacks s_j* they could not avoid,
* the box bounds (always hard).

Each level is solved in the coordinates of a rank-revealing QR of (J_k Z)ᵀ = Q R: u = [y; w]
with y along the level's row space (where its cost is well conditioned, R Rᵀ) and w along its
null space (free for the levels below, kept small by a tiny ridge that cannot bias the level's
optimum). The last level instead uses the damping μ‖Δq‖² of the weighted QP, on the whole Δq,
so the result does not depend on how the levels above split it. A level whose unconstrained
optimum already satisfies every bound and inherited inequality skips its QP.

A *hard* level's inequalities get no slack (infeasible ⇒ :class:`InfeasibleError` unless
``relax``); a hard level's equality residual is checked by the caller.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import lapack

from ..exceptions import InfeasibleError, SolverError
from .backends import DaqpBackend, QPBackend

#: ridge along the null space of an intermediate level, relative to its mean curvature: it
#: keeps the QP strictly convex; the level's optimum only feels it through active constraints
#: that couple its null space to its row space, by ~1e-10 (the tests check 1e-8)
NULL_RIDGE = 1e-10
_EMPTY = np.zeros(0)
#: relative threshold of the rank decision on R's diagonal
RANK_RTOL = 1e-9
#: backends that solve a hard level with its task rows as equalities (:func:`_solve_exact`)
EXACT_BACKENDS = ("daqp", "quadprog")


@dataclass
class LevelProblem:
    """Rows of one level: J Δq ≈ b (already weighted) and G Δq <= h."""

    priority: int
    J: np.ndarray
    b: np.ndarray
    G: np.ndarray
    h: np.ndarray
    hard: bool = False
    task_rows: list[tuple[str, slice]] = field(default_factory=list)
    constraint_rows: list[tuple[str, slice]] = field(default_factory=list)


@dataclass
class LevelSolution:
    priority: int
    residual: np.ndarray  # J Δq − b at the final Δq
    slack: np.ndarray  # s* (>= 0) of this level's inequalities
    relaxed: bool = False
    margin: np.ndarray = field(default_factory=lambda: np.zeros(0))  # G Δq − h at the final Δq


class PivotedQR:
    """Rank-revealing QR of Mᵀ (r x m): Mᵀ[:, perm] = Q R, Q (r x r) orthonormal.

    The first ``rank`` columns of Q span the row space of M, the others its null space.
    """

    def __init__(self, M: np.ndarray) -> None:
        m, r = M.shape
        self.m = m
        if m == 0:
            self.Q, self.rank = np.eye(r), 0
            return
        qr, jpvt, tau, _, _ = lapack.dgeqp3(M.T)
        k = min(m, r)
        d = [abs(v) for v in qr.diagonal()[:k].tolist()]  # |R_ii|, decreasing (pivoting)
        self.rank = sum(v > RANK_RTOL * d[0] for v in d) if d[0] > 1e-12 else 0
        a = np.zeros((r, r), order="F")
        a[:, :k] = qr[:, :k]
        self.Q = lapack.dorgqr(a, tau[:k])[0] if k else np.eye(r)
        self._qr, self._perm = qr, jpvt - 1

    @property
    def null_space(self) -> np.ndarray:
        return self.Q[:, self.rank :]

    def least_squares(self, v: np.ndarray) -> np.ndarray | None:
        """The minimum-norm z with M z = v when M has full row rank (else None)."""
        if self.rank != self.m or self.m == 0:
            return None
        y, info = lapack.dtrtrs(self._qr[: self.m, : self.m], v[self._perm], lower=0, trans=1)
        return self.Q[:, : self.m] @ y if info == 0 else None


class _Feasible:
    """The constraints every level inherits: box bounds and frozen higher-level inequalities."""

    def __init__(self, lower: np.ndarray, upper: np.ndarray) -> None:
        self.lower, self.upper = lower, upper
        self.G: list[np.ndarray] = []
        self.h: list[np.ndarray] = []
        #: False until a level has solved: x = 0 may violate the bounds (a joint outside its
        #: range), which the first level must then enforce rather than take as met
        self.bounds_met = False

    def holds(self, dq: np.ndarray, x: np.ndarray, level: LevelProblem | None = None) -> bool:
        """Δq meets the bounds, the inherited rows and (if given) the level's own rows."""
        if (dq < self.lower).any() or (dq > self.upper).any():  # methods: 2x np.any's speed
            return False
        if level is not None and level.G.shape[0] and (level.G @ dq > level.h).any():
            return False
        return all(
            (G @ dq <= np.maximum(h, G @ x)).all() for G, h in zip(self.G, self.h, strict=True)
        )

    def rows(self, x: np.ndarray, B: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Inherited rows in the coordinates u of Δq = x + B u (B None: u = Δq − x)."""
        Gs, hs = [], []
        for G, h in zip(self.G, self.h, strict=True):  # met above (to tolerance): keep them
            Gs.append(G if B is None else G @ B)
            hs.append(np.maximum(h - G @ x, 0.0))
        if B is not None:  # bounds become rows in u (finite ones only)
            lo_idx = np.flatnonzero(np.isfinite(self.lower))
            hi_idx = np.flatnonzero(np.isfinite(self.upper))
            floor = 0.0 if self.bounds_met else -np.inf
            Gs.append(B[hi_idx])
            hs.append(np.maximum(self.upper[hi_idx] - x[hi_idx], floor))
            Gs.append(-B[lo_idx])
            hs.append(np.maximum(x[lo_idx] - self.lower[lo_idx], floor))
        if not Gs:
            return np.zeros((0, x.size if B is None else B.shape[1])), np.zeros(0)
        G_all = np.vstack(Gs)
        h_all = np.concatenate(hs)
        # rows the remaining freedom cannot move (fixed by the levels above) only make the QP
        # degenerate (quadprog then reports inconsistent constraints): drop them; scale the
        # others to unit norm (an equivalent constraint, better conditioned)
        norms = np.sqrt(np.einsum("ij,ij->i", G_all, G_all))
        keep = norms > 1e-9
        return G_all[keep] / norms[keep, None], h_all[keep] / norms[keep]


def solve_cascade(
    levels: list[LevelProblem],
    lower: np.ndarray,
    upper: np.ndarray,
    backends: list[QPBackend],
    relax: bool = False,
    final_regularization: float = 1e-6,
) -> tuple[np.ndarray, list[LevelSolution]]:
    """Solve the levels in order; returns Δq and each level's residual and slacks.

    ``backends[k]`` solves level k (one object per level keeps warm starts per shape).
    """
    n = lower.size
    x = np.zeros(n)
    Z: np.ndarray | None = None  # None = identity (nothing fixed yet)
    pinned = lower == upper  # e.g. a joint outside its range, moving back at full speed
    if pinned.any():  # fixed variables: eliminate them up front (a pair of opposite active
        x[pinned] = lower[pinned]  # bound rows would make every level's QP degenerate)
        Z = np.eye(n)[:, ~pinned]
    feasible = _Feasible(lower, upper)
    slacks: list[np.ndarray] = []
    relaxed_flags: list[bool] = []
    last = len(levels) - 1
    for k, lvl in enumerate(levels):
        p = lvl.G.shape[0]
        if Z is not None and Z.shape[1] == 0:  # nothing left to move
            slacks.append(np.maximum(lvl.G @ x - lvl.h, 0.0) if p else np.zeros(0))
            relaxed_flags.append(False)
            continue
        M = lvl.J if Z is None else lvl.J @ Z
        v = lvl.b - lvl.J @ x
        B = Z
        qr: PivotedQR | None = None
        H = c = None
        u = None
        if k == last:  # damped least squares on the whole Δq (as the weighted QP)
            mu = final_regularization
            H = M.T @ M
            H.reshape(-1)[:: H.shape[0] + 1] += mu
            c = mu * (x if Z is None else Z.T @ x) - M.T @ v
            u = _unconstrained(H, c)
        else:
            qr = PivotedQR(M)
            u = qr.least_squares(v)  # exact in the level's row space, nothing in its null space
        # the unconstrained optimum solves the level if it meets every inherited constraint and
        # the level's own inequalities (then with zero slack)
        if u is not None and not feasible.holds(x + (u if B is None else B @ u), x, lvl):
            u = None
        was_relaxed = False
        if u is not None:
            s = np.zeros(p)
        else:
            if H is None:  # ridge only along the level's null space N: no bias on its optimum
                N = qr.null_space
                H = M.T @ M
                ridge = NULL_RIDGE * max(1.0, float(np.trace(H)) / max(qr.rank, 1))
                H += ridge * (N @ N.T)
                c = -(M.T @ v)
                if (u := _unconstrained(H, c)) is not None:
                    if not feasible.holds(x + (u if B is None else B @ u), x, lvl):
                        u = None
            if u is None and lvl.hard and qr is not None and qr.rank == qr.m > 0:
                u = _solve_exact(lvl, x, B, M, v, feasible, backends[k])
            if u is not None:
                s = np.zeros(p)
            else:
                args = (lvl, x, B, H, c, feasible, backends[k])
                slack = p > 0 and not lvl.hard
                try:
                    u, s = _solve_qp(*args, slack=slack)
                except (InfeasibleError, SolverError):
                    # an infeasible hard level may also show as a backend failure (OSQP:
                    # "maximum iterations reached"): relaxing it with slacks is always feasible
                    if not (lvl.hard and p and relax):
                        raise
                    slack = was_relaxed = True
                    u, s = _solve_qp(*args, slack=True)
        x = x + (u if B is None else B @ u)
        feasible.bounds_met = True
        if p:
            s = np.maximum(s, 0.0)
            feasible.G.append(lvl.G)
            feasible.h.append(lvl.h + s)
        slacks.append(s)
        relaxed_flags.append(was_relaxed)
        if qr is not None:
            Z = qr.null_space if Z is None else Z @ qr.null_space
    sols = [
        LevelSolution(
            lvl.priority, lvl.J @ x - lvl.b, s, rf, lvl.G @ x - lvl.h if lvl.G.shape[0] else _EMPTY
        )
        for lvl, s, rf in zip(levels, slacks, relaxed_flags, strict=True)
    ]
    return x, sols


def solve_cascade_or_daqp(
    levels: list[LevelProblem],
    lower: np.ndarray,
    upper: np.ndarray,
    backends: list[QPBackend],
    **options,
) -> tuple[np.ndarray, list[LevelSolution]]:
    """:func:`solve_cascade`; if another backend than DAQP fails on a level (a first-order
    one can stall on the degenerate QPs of the lower levels, many rows active at one point,
    or call them primal infeasible), the whole cascade again with DAQP, as a tick the
    compiled kernels cannot finish goes to DAQP; DAQP's verdict stands (where DAQP cannot
    decide, cycling, the other backend's InfeasibleError: a tick's recovery can follow it)."""
    try:
        return solve_cascade(levels, lower, upper, backends, **options)
    except (SolverError, InfeasibleError) as first:
        if all(b.name == "daqp" for b in backends):
            raise
        daqp = [DaqpBackend(backends[0].eps) for _ in backends]
        try:
            return solve_cascade(levels, lower, upper, daqp, **options)
        except SolverError:  # DAQP undecided (cycling): the other backend's verdict stands
            if isinstance(first, InfeasibleError):
                raise first from None
            raise


def _unconstrained(H: np.ndarray, c: np.ndarray) -> np.ndarray | None:
    """argmin ½uᵀHu + cᵀu for positive-definite H (Cholesky); None if H is not."""
    _, u, info = lapack.dposv(H, -c)
    return u if info == 0 else None


def _solve_exact(
    lvl: LevelProblem,
    x: np.ndarray,
    B: np.ndarray | None,
    M: np.ndarray,
    v: np.ndarray,
    feasible: _Feasible,
    backend: QPBackend,
) -> np.ndarray | None:
    """A hard level's rows met exactly: min ½‖u‖² s.t. M u = v, its own and the inherited
    inequalities and the bounds (the least-squares optimum when it has zero residual, M of
    full row rank: u's row-space part is then fixed, the rest as small as the ridge would
    keep it); None if that QP is infeasible or the backend fails (then least squares).

    Why not only least squares with a ridge ρ on the level's null space: where active rows
    couple that null space to the row space, the optimum trades a residual r for ρ‖Nᵀu‖²,
    r ~ ρ / κ² for a coupling κ — 5e-6 m on a contact with ρ = 2e-10 (stress trial 1529, a
    start with many pairs inside the self-collision margin): a hard level reported
    infeasible although a point meeting it exists (with no ridge, DAQP's singular Hessian
    was worse: 3.5e-4).
    The active-set backends only (DAQP, quadprog): a first-order one meets an equality to
    its tolerance, not exactly, and fails on an infeasible one only at its iteration cap."""
    if backend.name not in EXACT_BACKENDS:
        return None
    r = M.shape[1]
    G_all, h_all = feasible.rows(x, B)
    if lvl.G.shape[0]:
        G_all = np.vstack([G_all, lvl.G if B is None else lvl.G @ B])
        h_all = np.concatenate([h_all, lvl.h - lvl.G @ x])
    if B is None:
        lo, hi = feasible.lower - x, feasible.upper - x
    else:
        lo, hi = np.full(r, -np.inf), np.full(r, np.inf)
    try:
        return backend.solve(np.eye(r), np.zeros(r), M, v, G_all, h_all, lo, hi)
    except (InfeasibleError, SolverError):
        return None


def _solve_qp(
    lvl: LevelProblem,
    x: np.ndarray,
    B: np.ndarray | None,
    H: np.ndarray,
    c: np.ndarray,
    feasible: _Feasible,
    backend: QPBackend,
    slack: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """One level's QP over [u; s] (Δq = x + B u), a slack s_i per own inequality row where
    ``slack`` (½‖s‖² in the cost: the rows in least squares of their violation); returns
    (u, s). A level with many such rows is solved over u alone first
    (:func:`_solve_hinge`)."""
    if slack and lvl.G.shape[0] > HINGE_ROWS:
        found = _solve_hinge(lvl, x, B, H, c, feasible, backend)
        if found is not None:
            return found
    r = H.shape[0]
    p = lvl.G.shape[0]
    ns = p if slack else 0
    G_all, h_all = feasible.rows(x, B)
    if p:  # this level's own inequalities, with slacks unless hard
        G_all = np.vstack([G_all, lvl.G if B is None else lvl.G @ B])
        h_all = np.concatenate([h_all, lvl.h - lvl.G @ x])
    if ns:
        H = np.block([[H, np.zeros((r, ns))], [np.zeros((ns, r)), np.eye(ns)]])
        c = np.concatenate([c, np.zeros(ns)])
        slack_cols = np.zeros((G_all.shape[0], ns))
        slack_cols[G_all.shape[0] - p :] = -np.eye(p)
        G_all = np.hstack([G_all, slack_cols])
    lo, hi = _box(feasible, x, B, r, ns)
    y = backend.solve(H, c, np.zeros((0, r + ns)), np.zeros(0), G_all, h_all, lo, hi)
    return y[:r], (y[r:] if ns else np.zeros(p))


#: a level with more own inequality rows than this in least squares of their violation is
#: solved over u alone first (:func:`_solve_hinge`)
HINGE_ROWS = 24
#: at most this many QPs of :func:`_solve_hinge`, then the QP with a slack per row
HINGE_ROUNDS = 20
#: a row this close to its bound (G u − h) counts as on it in :func:`_solve_hinge`
HINGE_TOL = 1e-12


def _box(
    feasible: _Feasible, x: np.ndarray, B: np.ndarray | None, r: int, ns: int
) -> tuple[np.ndarray, np.ndarray]:
    """The bounds on [u; s] of a level's QP (u: the bounds left by x, or none in a null
    space's coordinates B; s: none)."""
    if B is None:
        lo = np.concatenate([feasible.lower - x, np.full(ns, -np.inf)])
        hi = np.concatenate([feasible.upper - x, np.full(ns, np.inf)])
    else:
        lo = np.full(r + ns, -np.inf)
        hi = np.full(r + ns, np.inf)
    return lo, hi


def _solve_hinge(
    lvl: LevelProblem,
    x: np.ndarray,
    B: np.ndarray | None,
    H: np.ndarray,
    c: np.ndarray,
    feasible: _Feasible,
    backend: QPBackend,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The slack QP of :func:`_solve_qp` as its equivalent over u alone: min ½uᵀHu + cᵀu +
    ½Σ max(0, g_i u − d_i)² (the optimal slack of a row is its violation), by a damped
    Newton method on that piecewise quadratic: each step one QP over u with the rows
    violated at the current u as least-squares terms (the inherited rows and the bounds
    held); where the QP's solution violates the same rows, it is the optimum (the cost is
    convex and C¹, and its gradient there is that QP's); otherwise the longest halving of
    the step towards it that lowers the cost. None after :data:`HINGE_ROUNDS` QPs or if
    one fails (then the QP with a slack per row).

    Why: a self-collision level has 16 rows per pair and a slack per row made its QPs
    400-850 variables, 0.5-1 s each, most of a 40-70 s pose (stress trials 4875, 9547);
    over u alone they have 18-24."""
    G = lvl.G if B is None else lvl.G @ B
    d = lvl.h - lvl.G @ x
    G_in, h_in = feasible.rows(x, B)
    r = H.shape[0]
    lo, hi = _box(feasible, x, B, r, 0)
    none = np.zeros((0, r))

    def cost(u: np.ndarray) -> float:
        return float(0.5 * u @ H @ u + c @ u + 0.5 * np.square(np.maximum(G @ u - d, 0.0)).sum())

    u = np.zeros(r)  # feasible: x meets the inherited rows and the bounds
    f = cost(u)
    violated = d < -HINGE_TOL
    for _ in range(HINGE_ROUNDS):
        Gv = G[violated]
        try:
            u_qp = backend.solve(
                H + Gv.T @ Gv, c - Gv.T @ d[violated], none, _EMPTY, G_in, h_in, lo, hi
            )
        except (InfeasibleError, SolverError):
            return None
        gap = G @ u_qp - d
        # the set repeats (a row on its bound adds nothing to the gradient either way)
        if not ((gap > HINGE_TOL) != violated)[np.abs(gap) > HINGE_TOL].any():
            return u_qp, np.maximum(gap, 0.0)
        # u_qp − u descends (the QP's cost and its gradient are the true ones at u): the
        # longest step of 1, ½, ... that lowers the cost (a full step can cycle)
        step = u_qp - u
        t = 1.0
        while (f_t := cost(u + t * step)) >= f and t > HINGE_TOL:
            t *= 0.5
        if f_t >= f:  # rounding: the QP with a slack per row decides
            return None
        u, f = u + t * step, f_t
        violated = G @ u - d > HINGE_TOL
    return None
