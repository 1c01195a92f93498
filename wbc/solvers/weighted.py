"""Weighted QP: the thesis's augmented task vector (VAT) as a QP.

    min_Δq  Σ_soft w_i ‖J_i Δq − α_i e_i‖² + μ ‖Δq‖²
    s.t.    J_h Δq = α_h e_h          (tasks of hard levels)
            G Δq <= h                  (every constraint, at any level)
            lower <= Δq <= upper       (joint position, and velocity when stepping in time)

Priority levels other than "hard or soft" are ignored: this is a single weighted problem.
The hot path writes every task's rows straight into preallocated arrays (for DAQP, views
into the solver's own packed buffers) and re-plans only when the stack's structure changes.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..exceptions import InfeasibleError, SolverError
from ..model import Kinematics
from ..types import CONSTRAINT_TOL, Solution
from .assembly import TaskBlock, stack_constraints
from .backends import daqp_for
from .base import HARD_TOL_RANGE, StackSolver, check_number
from .cascade import LevelProblem, solve_cascade_or_daqp
from .diagnostics import conflicts, infeasible_message
from .recovery import Undiagnosed

#: weight of the recovery of joints outside their range (relative to the largest curvature of
#: the soft tasks) when it has to yield to the hard tasks


class WeightedValue(NamedTuple):
    """One tick's weighted QP: min ‖J Δq − b‖² + μ‖Δq‖² s.t. A Δq = a, G Δq <= h and
    lower <= Δq <= upper (J, b weighted by √w; rows from the compiled plan or the numpy
    blocks, never both)."""

    J: np.ndarray | None
    b: np.ndarray | None
    A: np.ndarray | None
    a: np.ndarray | None
    G: np.ndarray
    h: np.ndarray
    lower: np.ndarray | None
    upper: np.ndarray | None


class _Layout(NamedTuple):
    """One layout of the stack (see :meth:`StackSolver._layout_key`)."""

    soft: TaskBlock
    hard: TaskBlock
    constraints: list
    fast: object  # the compiled plan, or None
    ws: object  # the backend's workspace


class WeightedQP(StackSolver):
    """One QP per solve over all tasks; see the module docstring for the formulation.

    ``on_infeasible="relax"``: if the hard tasks/constraints admit no solution, return the
    lexicographic best instead (hard rows in least squares first, soft tasks next) and set
    :attr:`relaxed` and :attr:`diagnosis`.
    """

    lexicographic = False

    def __init__(
        self,
        stack,
        backend="daqp",
        regularization=1e-6,
        on_infeasible="raise",
        hard_tol: float = 1e-6,
        compiled: bool | None = None,
    ) -> None:
        super().__init__(stack, backend, regularization, on_infeasible, compiled)
        self.hard_tol = check_number("hard_tol", hard_tol, HARD_TOL_RANGE)
        self._key = None
        self.ws = None
        self.diagnosis = ""
        nv = self.robot.nv
        self._lower, self._upper = np.full(nv, -np.inf), np.full(nv, np.inf)
        self._no_rows = (np.zeros((0, nv)), np.zeros(0), [])

    def switch_layout(self) -> None:
        if self._key != self.stack.revision:
            self._plan(self.ws.shape[2] if self.ws is not None else 0)

    def _plan(self, m_in: int) -> None:
        """(Re)build the layout when the stack's structure changed; resize the workspace to
        ``m_in`` inequality rows."""
        if self._key != self.stack.revision:
            layout = self._switch_layout(self._build_layout)
            self.soft, self.hard, self.constraints, self.fast, self.ws = layout
        if self.ws.shape[2] != m_in:
            self.ws = self.backend.workspace(self.robot.nv, self.hard.m, m_in)

    def _build_layout(self) -> _Layout:
        levels = self.stack.levels
        nv = self.robot.nv
        soft = TaskBlock([t for lv in levels if not lv.hard for t in lv.active_tasks()], nv)
        hard = TaskBlock([t for lv in levels if lv.hard for t in lv.active_tasks()], nv)
        constraints = [c for lv in levels for c in lv.active_constraints()]
        fast = None
        if self._use_compiled():
            from .plan import WeightedPlan

            fast = WeightedPlan(self, self.kin, soft.tasks, hard.tasks, constraints)
        return _Layout(soft, hard, constraints, fast, self.backend.workspace(nv, hard.m, 0))

    def _solve(self, kin: Kinematics, dt: float | None) -> Solution:
        """kinematics → one assembly into a QP value → the compiled least squares (bounds,
        equalities, inequality rows), or the backend fed from the same arrays when the stack
        is not compiled or the compiled solve fails."""
        if self._key != self.stack.revision:
            self._plan(self.ws.shape[2] if self.ws is not None else 0)
        fast = self.fast
        if fast is not None and self.compiled is None and not (fast.is_ready or fast.ready()):
            # compiling in the background: meanwhile the numpy path (the same QP, by the
            # backend); compiled=True waits for the compiled tick
            self.interim_ticks += 1
            return self._solve_value(kin, self._assemble(kin, dt, None), dt, kernel=False)
        if fast is not None:
            # the compiled tick: the plan's rows and bounds, the inequality rows (the
            # constraints' kernels called in the tick; an active set on them in the compiled
            # least squares), the integration
            if fast.solve(kin, dt) == 0:
                self.compiled_ticks += 1
                self.relaxed = False
                return fast.solution
            self.handed_back_ticks += 1  # the backend, on the same arrays (the tick's rows)
            G, h, _ = fast.constraints.level_blocks()[0] if self.constraints else self._no_rows
            value = WeightedValue(
                fast.soft.J, fast.soft.b, fast.hard.J, fast.hard.b, G, h, fast.lower, fast.upper
            )
            # (not the least squares again: the compiled tick tried it cold already)
            return self._solve_value(kin, value, dt, kernel=False)
        return self._solve_value(kin, self._assemble(kin, dt, fast), dt)

    def _assemble(self, kin: Kinematics, dt: float | None, fast) -> WeightedValue:
        """The QP value: the inequality rows, and on the numpy path (``fast`` None) every row
        and the bounds (the compiled tick fills those itself, into its plan)."""
        if self.constraints:
            G, h, _ = stack_constraints(self.constraints, kin, self.robot.nv)
        else:
            G, h, _ = self._no_rows
        if fast is not None:
            return WeightedValue(None, None, None, None, G, h, None, None)
        soft, hard = self.soft, self.hard
        soft.fill_weighted(kin)
        hard.fill_into(kin, hard.J, hard.b)
        self.compute_bounds(kin, dt, self._lower, self._upper)
        return WeightedValue(soft.J, soft.b, hard.J, hard.b, G, h, self._lower, self._upper)

    def _solve_value(
        self, kin: Kinematics, value: WeightedValue, dt: float | None = None, kernel=True
    ) -> Solution:
        """The QP value through the backend (its workspace filled in place); with DAQP and
        ``kernel``, the compiled tick's own least squares first (:meth:`_least_squares`)."""
        if kernel and self.backend.name == "daqp":
            dq = self._least_squares(kin, value, dt)
            if dq is not None:
                return Solution(dq, value.lower, value.upper)
        if value.h.size != self.ws.shape[2]:
            self._plan(value.h.size)
        ws = self.ws
        np.dot(value.J.T, value.J, out=ws.H)
        ws.H.flat[:: ws.H.shape[0] + 1] += self.regularization
        np.dot(value.J.T, value.b, out=ws.c)
        np.negative(ws.c, out=ws.c)
        ws.A[:] = value.A
        ws.b[:] = value.a
        ws.G[:] = value.G
        ws.h[:] = value.h
        ws.lower[:] = value.lower
        ws.upper[:] = value.upper
        self.relaxed = False
        try:
            dq = self.backend.solve_workspace(ws)
        except InfeasibleError as exc:
            if self.on_infeasible == "raise":  # named only if the recovery cannot answer
                raise Undiagnosed(lambda: self._diagnosis(kin, value)) from exc
            dq = self._relax(kin, value)
        except SolverError:  # e.g. OSQP out of iterations: not known to be infeasible
            dq = self._relax(kin, value, failed=True)
        return Solution(dq, ws.lower, ws.upper)

    def _least_squares(
        self, kin: Kinematics, value: WeightedValue, dt: float | None
    ) -> np.ndarray | None:
        """Δq by the compiled tick's least squares (:func:`wbc.compiled.ticks.weighted_solve`,
        cold: no working set carried from another tick) on these rows, so that the numpy
        path and a tick the compiled one hands back give the compiled tick's answer whatever
        ticks came before (DAQP's, through the condition of H = JᵀWJ + μI, was up to 1e-7
        off: issue 28). None if it cannot finish (DAQP then solves, or names why the QP is
        infeasible) or its kernel is being compiled in the background (counted an interim
        tick: :meth:`wbc.compiled.dispatch.Ticks.kernel_ready`)."""
        from ..compiled.lsq import OK
        from ..compiled.ticks import weighted_solve

        if not weighted_solve.overloads:
            from .plan import package_ticks

            if not package_ticks().kernel_ready(weighted_solve, "weighted_tick"):
                self.interim_ticks += 1
                return None
        nv = self.robot.nv
        G = np.ascontiguousarray(value.G, dtype=float)
        h = np.ascontiguousarray(value.h, dtype=float)
        params = np.array([0.0, self.regularization, self.hard_tol, CONSTRAINT_TOL])
        lower, upper = value.lower, value.upper  # (the bounds: filled by compute_bounds)
        dq = np.zeros(nv)
        status = weighted_solve(
            np.ascontiguousarray(value.J, dtype=float), np.ascontiguousarray(value.b, dtype=float),
            np.ascontiguousarray(value.A, dtype=float), np.ascontiguousarray(value.a, dtype=float),
            G, h, np.array([0, h.size], dtype=np.int64), np.ascontiguousarray(kin.q, dtype=float),
            self._q_min, self._q_max, params, lower, upper, np.zeros(nv, dtype=np.int8),
            np.zeros(h.size, dtype=np.bool_), dq,
            np.zeros(self.robot.nq),
        )  # fmt: skip
        if status != OK:
            self.compute_bounds(kin, dt, lower, upper)  # the backend starts afresh
            return None
        self.relaxed = False
        self.diagnosis = ""
        return dq

    def _diagnosis(self, kin: Kinematics, value: WeightedValue) -> str:
        """What an infeasible QP cannot meet (:meth:`_relax`'s message; also
        :attr:`diagnosis`)."""
        try:
            self._relax(kin, value)
        except InfeasibleError as exc:
            return str(exc)
        return self.diagnosis or "infeasible (no task or constraint stands out)"

    def _relax(self, kin: Kinematics, value: WeightedValue, failed: bool = False) -> np.ndarray:
        """The hard levels in priority order, each in least squares, then the soft tasks
        (a cascade); names what the first unmet hard level could not satisfy.

        ``failed``: the backend failed for another reason than infeasibility; if the cascade
        meets every hard row, its answer is the weighted QP's (hard rows met exactly, the soft
        ones in least squares over what they leave free) and is returned as a plain solve."""
        nv = self.robot.nv
        ws = self.ws
        problems = []
        for lv in self.stack.levels:
            if lv.hard:
                block = TaskBlock(lv.active_tasks(), nv)
                block.fill_into(kin, block.J, block.b)
                G, h, cslices = stack_constraints(lv.active_constraints(), kin, nv)
                problems.append(
                    LevelProblem(
                        lv.priority,
                        block.J,
                        block.b,
                        G,
                        h,
                        hard=False,
                        task_rows=block.slices,
                        constraint_rows=cslices,
                    )
                )
        soft_constraints = [
            c for lv in self.stack.levels if not lv.hard for c in lv.active_constraints()
        ]
        G, h, cslices = stack_constraints(soft_constraints, kin, nv)
        problems.append(LevelProblem(1 << 30, value.J, value.b, G, h, constraint_rows=cslices))
        # DAQP, as the recovery's re-solve (daqp_for): a first-order backend's
        # capped iterations on these degenerate levels cost seconds (stress trial 104, OSQP)
        backends = daqp_for(problems)
        try:
            dq, sols = solve_cascade_or_daqp(
                problems,
                ws.lower.copy(),
                ws.upper.copy(),
                backends,
                final_regularization=self.regularization,
            )
        except SolverError as exc:  # the diagnosis failed (DAQP cycling): name the rows
            if failed:
                raise
            names = [n for p in problems for n, _ in [*p.task_rows, *p.constraint_rows]]
            raise InfeasibleError(
                f"infeasible: the hard tasks, the constraints ({', '.join(names)}) and the "
                f"joint limits (their diagnosis failed: {exc})"
            ) from exc
        messages = [
            infeasible_message(p, s, self.hard_tol, f"hard level {p.priority}")
            for p, s in zip(problems[:-1], sols[:-1], strict=True)
            if conflicts(p, s, self.hard_tol)
        ]
        constraint_clash = conflicts(problems[-1], sols[-1], self.hard_tol, tasks=False)
        if constraint_clash:
            messages.append(
                "the constraints are infeasible: cannot satisfy "
                + ", ".join(f"{n} (violation {v:.3g})" for n, v in constraint_clash)
            )
        if failed and not messages:
            self.diagnosis = ""
            return dq
        self.diagnosis = "; ".join(messages) or "infeasible (no task or constraint stands out)"
        if self.on_infeasible == "raise":
            raise InfeasibleError(self.diagnosis)
        self.relaxed = True
        return dq
