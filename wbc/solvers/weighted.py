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
from ..tasks.task import STRUCTURE_EPOCH
from .assembly import TaskBlock, stack_constraints
from .base import StackSolver
from .cascade import LevelProblem, solve_cascade_or_daqp
from .diagnostics import conflicts, infeasible_message

#: weight of the recovery of joints outside their range (relative to the largest curvature of
#: the soft tasks) when it has to yield to the hard tasks
RECOVERY_WEIGHT = 1e4


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
        self.hard_tol = hard_tol
        self._key = None
        self.ws = None
        self.diagnosis = ""

    def _plan(self, m_in: int) -> None:
        """(Re)build the layout when the stack's structure changed; resize the workspace to
        ``m_in`` inequality rows."""
        if self._key != (self.stack.version, STRUCTURE_EPOCH[0]):
            key = self._layout_key()
            layout = self._cached_layout(key)
            if layout is None:
                layout = self._build_layout()
                self._keep_layout(key, layout)
            self.soft, self.hard, self.constraints, self.fast, self.ws = layout
            self._key = (self.stack.version, STRUCTURE_EPOCH[0])
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
            from ..compiled.plan import WeightedPlan

            fast = WeightedPlan(self, self.kin, soft.tasks, hard.tasks)
        return _Layout(soft, hard, constraints, fast, self.backend.workspace(nv, hard.m, 0))

    def _solve(self, kin: Kinematics, dt: float | None) -> np.ndarray:
        if self._key != (self.stack.version, STRUCTURE_EPOCH[0]):
            self._plan(self.ws.shape[2] if self.ws is not None else 0)
        fast = self.fast
        if fast is not None and not self._yield_recovery:
            if fast.solve(kin, dt) == 0 and (
                not self.constraints or self._constraints_hold(kin, self.constraints, fast.dq)
            ):
                self.compiled_ticks += 1
                self._box = fast.box
                self.relaxed = False
                self._stepped = fast.q_next
                return fast.dq
            self.handed_back_ticks += 1
        G, h = None, None
        if self.constraints:
            G, h, _ = stack_constraints(self.constraints, kin, self.robot.nv)
            if G.shape[0] != self.ws.shape[2]:
                self._plan(G.shape[0])
        ws, soft = self.ws, self.soft
        soft.fill_weighted(kin)
        self.hard.fill_into(kin, ws.A, ws.b)
        np.dot(soft.J.T, soft.J, out=ws.H)
        ws.H.flat[:: ws.H.shape[0] + 1] += self.regularization
        np.dot(soft.J.T, soft.b, out=ws.c)
        np.negative(ws.c, out=ws.c)
        if G is not None:
            ws.G[:] = G
            ws.h[:] = h
        self.compute_bounds(kin, dt, ws.lower, ws.upper)
        if self.recovery is not None:  # joints outside their range: a dominant soft objective
            idx, step = self.recovery
            w = RECOVERY_WEIGHT * max(1.0, float(ws.H.diagonal().max()))
            ws.H[idx, idx] += w
            ws.c[idx] -= w * step
        self.relaxed = False
        try:
            return self.backend.solve_workspace(ws)
        except InfeasibleError:
            return self._relax(kin)
        except SolverError:  # e.g. OSQP out of iterations: not known to be infeasible
            return self._relax(kin, failed=True)

    def _relax(self, kin: Kinematics, failed: bool = False) -> np.ndarray:
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
        problems.append(
            LevelProblem(1 << 30, self.soft.J, self.soft.b, G, h, constraint_rows=cslices)
        )
        backends = [type(self.backend)(self.backend.eps) for _ in problems]
        dq, sols = solve_cascade_or_daqp(
            problems,
            ws.lower.copy(),
            ws.upper.copy(),
            backends,
            final_regularization=self.regularization,
        )
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
