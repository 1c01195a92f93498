"""Lexicographic (hierarchical) QP: the thesis's hierarchical control (CJ) as a QP.

Levels are solved in priority order; each level is optimal without changing the optimum of
the levels above. Equalities (tasks) and inequalities (constraints) may sit at any level;
box limits are hard at every level. Two methods:

* ``"cascade"`` — one QP per level over the null space of the levels above, inequality
  slacks frozen for the levels below (Kanoun et al. 2011), any backend;
* ``"daqp"`` — DAQP's native hierarchical mode (one call, ``break_points``).

A *hard* level must be met exactly: if its residual exceeds ``hard_tol`` the solve raises
:class:`InfeasibleError` naming the level and the tasks/constraints involved, or, with
``on_infeasible="relax"``, keeps its least-squares best and goes on with the lower levels.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from ..exceptions import InfeasibleError, SolverError
from ..model import Kinematics
from ..tasks.task import STRUCTURE_EPOCH
from .assembly import TaskBlock, stack_constraints
from .backends import INF, QPBackend, make_backend
from .base import StackSolver
from .cascade import LevelProblem, LevelSolution, solve_cascade, solve_cascade_or_daqp
from .diagnostics import infeasible_message

METHODS = ("cascade", "daqp")


def _unweighted(residual: np.ndarray, sqrt_w: np.ndarray) -> np.ndarray:
    """A level's residual √w (J Δq − α e) back in task units (zero-weight rows: zero)."""
    out = np.zeros_like(residual)
    np.divide(residual, sqrt_w, out=out, where=sqrt_w > 0)
    return out


class _Layout(NamedTuple):
    """One layout of the stack (see :meth:`StackSolver._layout_key`)."""

    levels: list
    blocks: list[TaskBlock]
    constraints: list[list]
    all_constraints: list
    fast: object  # the compiled plan, or None


class HierarchicalQP(StackSolver):
    """Lexicographic QP over the stack's levels (see the module docstring)."""

    def __init__(
        self,
        stack,
        backend: str | QPBackend = "daqp",
        method: str = "cascade",
        regularization: float = 1e-6,
        on_infeasible: str = "raise",
        hard_tol: float = 1e-6,
        compiled: bool | None = None,
    ) -> None:
        if method not in METHODS:
            raise SolverError(f"unknown hierarchical method {method!r}; choose from {METHODS}")
        if method == "daqp" and (backend if isinstance(backend, str) else backend.name) != "daqp":
            raise SolverError("method='daqp' uses DAQP's native hierarchy: backend must be daqp")
        super().__init__(stack, backend, regularization, on_infeasible, compiled)
        self.method = method
        self.hard_tol = hard_tol
        self._backends: list[QPBackend] = []
        self._key = None
        self._problems: list[LevelProblem] = []
        self._solutions: list[LevelSolution] = []
        self._lazy_dq: np.ndarray | None = None  # set when the compiled path solved last
        nv = self.robot.nv
        self._lower, self._upper = np.full(nv, -np.inf), np.full(nv, np.inf)
        self.diagnosis = ""

    @property
    def name(self) -> str:
        return f"HierarchicalQP[{self.method}:{self.backend.name}]"

    def compiled_reason(self) -> str:
        if self.method != "cascade":
            return "DAQP's native hierarchy has no compiled form"
        return super().compiled_reason()

    def _plan(self) -> None:
        key = self._layout_key()
        layout = self._cached_layout(key)
        if layout is None:
            layout = self._build_layout()
            self._keep_layout(key, layout)
        self._levels, self._blocks, self._constraints, self._all_constraints, self.fast = layout
        self._key = (self.stack.version, STRUCTURE_EPOCH[0])

    def _build_layout(self) -> _Layout:
        nv = self.robot.nv
        levels = self.stack.levels
        constraints = [lv.active_constraints() for lv in levels]
        fast = None
        if levels and self._use_compiled():
            from ..compiled.plan import CascadePlan

            fast = CascadePlan(
                self, self.kin, [lv.active_tasks() for lv in levels], [lv.hard for lv in levels]
            )
        return _Layout(
            levels,
            [TaskBlock(lv.active_tasks(), nv) for lv in levels],
            constraints,
            [c for cons in constraints for c in cons],
            fast,
        )

    # ------------------------------------------------------------------ per-level results
    @property
    def problems(self) -> list[LevelProblem]:
        """Each level's rows at the last solve."""
        if self._lazy_dq is not None:
            self._materialize()
        return self._problems

    @property
    def solutions(self) -> list[LevelSolution]:
        """Each level's residual, slacks and constraint margins at the last solve."""
        if self._lazy_dq is not None:
            self._materialize()
        return self._solutions

    def _materialize(self) -> None:
        """Build problems/solutions of a compiled solve (only when someone asks for them)."""
        dq, self._lazy_dq = self._lazy_dq, None
        fast, nv = self.fast, self.robot.nv
        self._problems, self._solutions = [], []
        for k, (lv, cons) in enumerate(zip(self._levels, self._constraints, strict=True)):
            r0, r1 = fast.level_rows[k], fast.level_rows[k + 1]
            G, h, cslices = stack_constraints(cons, self.kin, nv)
            slices = [
                (name, slice(sl.start - r0, sl.stop - r0))
                for name, sl in fast.rows.slices
                if r0 <= sl.start < r1
            ]
            J, b = fast.rows.J[r0:r1].copy(), fast.rows.b[r0:r1].copy()
            self._problems.append(LevelProblem(lv.priority, J, b, G, h, lv.hard, slices, cslices))
            margin = G @ dq - h if h.size else np.zeros(0)
            self._solutions.append(
                LevelSolution(lv.priority, J @ dq - b, np.zeros(h.size), margin=margin)
            )

    def _level_problems(self, kin: Kinematics) -> list[LevelProblem]:
        nv = self.robot.nv
        problems = []
        for lv, block, cons in zip(self._levels, self._blocks, self._constraints, strict=True):
            block.fill_weighted(kin)
            G, h, cslices = stack_constraints(cons, kin, nv)
            problems.append(
                LevelProblem(lv.priority, block.J, block.b, G, h, lv.hard, block.slices, cslices)
            )
        return problems

    def _solve(self, kin: Kinematics, dt: float | None) -> np.ndarray:
        if self._key != (self.stack.version, STRUCTURE_EPOCH[0]):
            self._plan()
        fast = self.fast
        if fast is not None and not self._yield_recovery:
            if fast.solve(kin, dt) == 0 and (
                not self._all_constraints
                or self._constraints_hold(kin, self._all_constraints, fast.dq)
            ):
                self.compiled_ticks += 1
                self._box = fast.box
                self.relaxed = False
                self.diagnosis = ""
                self._stepped = fast.q_next
                self._lazy_dq = fast.dq  # valid until the next solve, which resets it
                return fast.dq
            self.handed_back_ticks += 1
        self._lazy_dq = None
        self._problems = self._level_problems(kin)
        lower, upper = self._lower, self._upper
        self.compute_bounds(kin, dt, lower, upper)
        relax = self.on_infeasible == "relax"
        if self.method == "daqp":
            dq = self._solve_daqp(self.problems, lower, upper)
        else:
            problems, at = self._with_recovery(self.problems)
            while len(self._backends) < len(problems) + 1:
                self._backends.append(make_backend(self.backend.name, self.backend.eps))
            try:
                dq, self._solutions = solve_cascade_or_daqp(
                    problems,
                    lower,
                    upper,
                    self._backends,
                    final_regularization=self.regularization,
                    relax=relax,
                )
            except InfeasibleError as exc:
                raise InfeasibleError(self._hard_inequality_message(kin, lower, upper)) from exc
            if at is not None:
                del self._solutions[at]
        self.relaxed = any(s.relaxed for s in self.solutions)
        self._check_hard_levels(relax)
        return dq

    def _with_recovery(self, problems: list[LevelProblem]) -> tuple[list, int | None]:
        """The levels with the recovery of joints outside their range (when it yields to the
        hard levels, :meth:`StackSolver._solve_yielding_recovery`) right below the leading
        hard levels; and where it was inserted (None: not)."""
        if self.recovery is None:
            return problems, None
        idx, step = self.recovery
        nv = self.robot.nv
        J = np.zeros((idx.size, nv))
        J[np.arange(idx.size), idx] = 1.0
        at = 0
        while at < len(problems) and problems[at].hard:
            at += 1
        recovery = LevelProblem(-1, J, step, np.zeros((0, nv)), np.zeros(0))
        return [*problems[:at], recovery, *problems[at:]], at

    # ------------------------------------------------------------------ hard levels
    def _check_hard_levels(self, relax: bool) -> None:
        # residuals in the tasks' own units (J Δq − α e, as the weighted QP reports them): the
        # levels' rows are scaled by √w, which would put a weight-1000 task's residual 31x up
        solutions = [
            replace(s, residual=_unweighted(s.residual, block.sqrt_w[:, 0]))
            for s, block in zip(self.solutions, self._blocks, strict=True)
        ]
        messages = [
            infeasible_message(p, s, self.hard_tol)
            for p, s in zip(self.problems, solutions, strict=True)
            if p.hard
            and (
                (s.residual.size and abs(s.residual).max() > self.hard_tol)
                or (s.slack.size and s.slack.max() > self.hard_tol)
            )
        ]
        self.diagnosis = "; ".join(messages)
        if messages:
            if not relax:
                raise InfeasibleError(self.diagnosis)
            self.relaxed = True

    def _hard_inequality_message(self, kin, lower, upper) -> str:
        """A hard level's inequalities clash with the bounds: re-solve with slacks to name them."""
        backends = [make_backend(self.backend.name, self.backend.eps) for _ in self.problems]
        backends.append(make_backend(self.backend.name, self.backend.eps))
        try:
            _, sols = solve_cascade(self.problems, lower, upper, backends, relax=True)
        except InfeasibleError as exc:  # a lower level's QP failed even so: name the levels
            names = [
                name
                for p in self.problems
                if p.hard
                for name, _ in [*p.task_rows, *p.constraint_rows]
            ]
            return f"the hard levels ({', '.join(names)}) and the joint limits: {exc}"
        msgs = [
            infeasible_message(p, s, self.hard_tol)
            for p, s in zip(self.problems, sols, strict=True)
            if p.hard and s.relaxed
        ]
        return "; ".join(msgs) or "the bounds are infeasible"

    # ------------------------------------------------------------------ DAQP native
    def _solve_daqp(self, problems, lower, upper) -> np.ndarray:
        import daqp

        n = lower.size
        rows = [np.vstack([p.J, p.G]) for p in problems]
        A = np.vstack(rows) if rows else np.zeros((0, n))
        bu = [np.clip(upper, -INF, INF)]
        bl = [np.clip(lower, -INF, INF)]
        sense = [np.zeros(n, dtype=np.intc)]
        breaks = [0]
        for p in problems:
            m, k = p.J.shape[0], p.G.shape[0]
            bu += [p.b, p.h]
            bl += [p.b, np.full(k, -INF)]
            sense.append(np.zeros(m + k, dtype=np.intc))
            breaks.append(breaks[-1] + m + k)
        H = self.regularization * np.eye(n)
        x, _, exitflag, _ = daqp.solve(
            H,
            np.zeros(n),
            A,
            np.concatenate(bu),
            np.concatenate(bl),
            np.concatenate(sense),
            break_points=np.array(breaks, dtype=np.intc),
            primal_tol=self.backend.eps,
        )
        if exitflag not in (1, 2):
            if exitflag == -1:
                raise InfeasibleError("daqp hierarchical: the bounds are infeasible")
            raise SolverError(f"daqp hierarchical failed with exit flag {exitflag}")
        x = np.asarray(x, dtype=float)
        self._solutions = [
            LevelSolution(
                p.priority, p.J @ x - p.b, np.maximum(p.G @ x - p.h, 0.0), margin=p.G @ x - p.h
            )
            for p in problems
        ]
        return x
