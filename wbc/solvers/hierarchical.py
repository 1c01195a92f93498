"""Lexicographic (hierarchical) QP: the thesis's hierarchical control (CJ) as a QP.

Levels are solved in priority order; each level is optimal without changing the optimum of
the levels above. Equalities (tasks) and inequalities (constraints) may sit at any level;
box limits are hard at every level. One method, ``"cascade"``: level by level, each a
least-squares problem subject to the optimal set of the levels above, inequality slacks frozen
for the levels below (Kanoun et al. 2011). One algorithm serves every path: the compiled
cascade (:func:`wbc.compiled.ticks.cascade_solve`) on the plan's rows or the numpy blocks; the
cascade of backend QPs (:func:`wbc.solvers.cascade.solve_cascade`) only solves the ticks it
cannot finish (and names infeasible hard levels), and is the tests' oracle. (DAQP's native
hierarchical mode was dropped: it reports feasible hierarchies infeasible.)

A *hard* level must be met exactly: if its residual exceeds ``hard_tol`` the solve raises
:class:`InfeasibleError` naming the level and the tasks/constraints involved, or, with
``on_infeasible="relax"``, keeps its least-squares best and goes on with the lower levels.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from ..exceptions import ConfigurationError, InfeasibleError, SolverError
from ..model import Kinematics
from ..types import CONSTRAINT_TOL, Solution
from .assembly import TaskBlock, stack_constraints
from .backends import QPBackend, daqp_for, make_backend
from .base import HARD_TOL_RANGE, StackSolver, check_number
from .cascade import LevelProblem, LevelSolution, solve_cascade, solve_cascade_or_daqp
from .diagnostics import infeasible_message
from .recovery import Undiagnosed

METHODS = ("cascade",)


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
        defer_with_rows: bool = True,
        carry_rows: bool = False,
        pdas_ties: bool = False,
        carry_at_switch: bool = False,
        defer_rows_join: bool = True,
        skip_degenerate: bool = True,
        release_small: float = 0.0,
    ) -> None:
        if method not in METHODS:
            raise ConfigurationError(
                f"unknown hierarchical method {method!r}; choose from {METHODS}"
            )
        super().__init__(stack, backend, regularization, on_infeasible, compiled)
        self.method = method
        self.hard_tol = check_number("hard_tol", hard_tol, HARD_TOL_RANGE)
        #: the compiled cascade defers the levels above the last into its solve while no
        #: inequality row is active (one level solve instead of three on walk_strict)
        self.defer_with_rows = bool(defer_with_rows)
        #: the compiled cascade's last level starts each tick from the inequality rows its
        #: working set held at the last tick's end, found again by their values (the
        #: numpy path starts them afresh): the same minimiser, up to rounding (off: on
        #: walk_strict its cascade's total -12 %, but turn's p99 +3-6 %: the ticks where
        #: the rows carried leave; benchmarks/self_collision.md, twelfth pass)
        self.carry_rows = bool(carry_rows)
        #: the compiled levels' PDAS goes on through :data:`wbc.compiled.lsq.PDAS_TIES` steps
        #: that do not lower its count before the dual method takes over (on: the stacks with
        #: self-collision rows, ``pdas_ties = true`` in their file; off: the thesis's schemes,
        #: ill-posed, whose runs the other rounding moves; benchmarks/self_collision.md)
        self.pdas_ties = bool(pdas_ties)
        #: the compiled cascade's last level starts the first tick of a support phase (another
        #: layout) from the inequality rows its working set held at the last phase's end,
        #: found again by their values: the same minimiser, up to rounding (off: walk_strict's
        #: touch-down tick -3 to -6 µs on the Bioloid, the OP3's phases' first ticks +3 µs;
        #: ``carry_at_switch = true`` in a stack file; benchmarks/self_collision.md, 2026-12-06
        #: thirteenth session)
        self.carry_at_switch = bool(carry_at_switch)
        #: with ``defer_with_rows``, the deferral holds on ticks with inequality rows active
        #: too: the levels above the last stay its equalities while the rows join its solve
        #: (the hierarchy's optimum where the levels above are met exactly with the rows, up
        #: to rounding; checked after the solve, else the levels are solved one by one),
        #: and it is tried after a tick that ended with a row active; where its answer is
        #: degenerate (a hard row outside its working set at its bound,
        #: :func:`wbc.compiled.ticks._degenerate`) the levels are solved one by one from the
        #: sets the cascade without it would have had. On by default (the stacks'
        #: ``defer_rows_join = false`` turns it off): replayed, Δq within 2.5e-15 of the
        #: levels one by one on every tick of the walks' captures, walk_strict's cascade -9 to
        #: -16 % in total (benchmarks/self_collision.md, 2026-12-07 sixteenth session). Read
        #: when a plan sets its parameters (its first tick)
        self.defer_rows_join = bool(defer_rows_join)
        #: with ``defer_rows_join``, after a tick whose answer was degenerate the next tick
        #: solves the levels one by one at once, without the deferral the guard would most
        #: likely refuse (:func:`wbc.compiled.ticks._refused`): the guard's fallback, so the
        #: same answer. On by default (``skip_degenerate = false`` in a stack file turns it
        #: off; benchmarks/self_collision.md, 2026-12-07 seventeenth session)
        self.skip_degenerate = bool(skip_degenerate)
        #: the compiled cascade's last level without its rows starts each tick with the bounds
        #: the last tick held with a multiplier below this share of its largest released
        #: (:mod:`wbc.compiled.lsq_release`; ``cascade_solve``'s ``params[5]``): the same
        #: minimiser, on another path (Δq up to rounding). 0: off, the default
        #: (benchmarks/self_collision.md, 2026-12-07 twenty-third session)
        self.release_small = check_number("release_small", release_small, (0.0, 1.0))
        self._backends: list[QPBackend] = []
        self._key = None
        self._problems: list[LevelProblem] = []
        self._solutions: list[LevelSolution] = []
        #: True when the last compiled solve's problems/solutions were built (on demand)
        self._built = False
        nv = self.robot.nv
        self._lower, self._upper = np.full(nv, -np.inf), np.full(nv, np.inf)
        self._no_rows = (np.zeros((0, nv)), np.zeros(0), [])
        self.diagnosis = ""

    @property
    def name(self) -> str:
        return f"HierarchicalQP[{self.method}:{self.backend.name}]"

    def switch_layout(self) -> None:
        if self._key != self.stack.revision:
            self._plan()

    def _plan(self) -> None:
        layout = self._switch_layout(self._build_layout)
        self._levels, self._blocks, self._constraints, self._all_constraints, self.fast = layout

    def _build_layout(self) -> _Layout:
        nv = self.robot.nv
        levels = self.stack.levels
        constraints = [lv.active_constraints() for lv in levels]
        fast = None
        if levels and self._use_compiled():
            from .plan import CascadePlan

            fast = CascadePlan(
                self,
                self.kin,
                [lv.active_tasks() for lv in levels],
                [lv.hard for lv in levels],
                constraints,
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
    def pdas_budget(self) -> int:
        """The compiled levels' PDAS tie budget this hierarchy passes (``cascade_solve``'s
        ``params[4]``): :data:`wbc.compiled.lsq.PDAS_TIES` with :attr:`pdas_ties`, else 0."""
        from ..compiled.lsq import PDAS_TIES

        return PDAS_TIES if self.pdas_ties else 0

    @property
    def problems(self) -> list[LevelProblem]:
        """Each level's rows at the last solve."""
        self._build_compiled()
        return self._problems

    @property
    def solutions(self) -> list[LevelSolution]:
        """Each level's residual, slacks and constraint margins at the last solve."""
        self._build_compiled()
        return self._solutions

    def _build_compiled(self) -> None:
        """Each level's rows and residuals of a compiled solve (only when someone asks for
        them), with the rows copied (the plan's arrays are refilled at the next tick)."""
        last = self.last
        if last is None or last.q_next is None or self._built:
            return
        self._built = True
        dq = last.dq
        problems, _, _ = self._assemble(self.kin, None, self._plan_inequalities(), self.fast)
        self._problems = [
            LevelProblem(
                p.priority,
                p.J.copy(),
                p.b.copy(),
                p.G.copy(),
                p.h.copy(),
                p.hard,
                p.task_rows,
                p.constraint_rows,
            )
            for p in problems
        ]
        g = self.fast.inequalities
        self._solutions = [
            LevelSolution(
                p.priority,
                p.J @ dq - p.b,
                g.h_eff[g0:g1] - g.h[g0:g1],  # the slacks the level kept
                margin=p.G @ dq - p.h if p.h.size else np.zeros(0),
            )
            for p, g0, g1 in zip(self._problems, g.g_rows[:-1], g.g_rows[1:], strict=True)
        ]

    def _plan_inequalities(self) -> list | None:
        """Each level's (G, h, row slices) of the last compiled tick: views of the plan's
        buffers, which the tick filled (None: the stack has no constraint)."""
        if not self._all_constraints:
            return None
        return self.fast.constraints.level_blocks()

    def _inequalities_at(self, kin: Kinematics) -> list | None:
        """Each level's (G, h, row slices) at ``kin`` (None: the stack has no constraint)."""
        if not self._all_constraints:
            return None
        nv = self.robot.nv
        return [stack_constraints(cons, kin, nv) for cons in self._constraints]

    def _assemble(self, kin: Kinematics, dt: float | None, inequalities: list | None, fast):
        """The QP value: each level's rows (J, b weighted by √w: the arrays of the plan
        ``fast``, which the compiled tick fills, or with None the numpy blocks) and inequality
        rows, and the box bounds."""
        problems = []
        for k, (lv, block) in enumerate(zip(self._levels, self._blocks, strict=True)):
            G, h, cslices = self._no_rows if inequalities is None else inequalities[k]
            if fast is not None:
                r0, r1 = fast.level_rows[k], fast.level_rows[k + 1]
                J, b = fast.rows.J[r0:r1], fast.rows.b[r0:r1]
            else:
                block.fill_weighted(kin)
                J, b = block.J, block.b
            problems.append(LevelProblem(lv.priority, J, b, G, h, lv.hard, block.slices, cslices))
        if fast is not None:
            return problems, fast.lower, fast.upper
        self.compute_bounds(kin, dt, self._lower, self._upper)
        return problems, self._lower, self._upper

    def _solve(self, kin: Kinematics, dt: float | None) -> Solution:
        """kinematics → one assembly into a QP value → the compiled cascade
        (:func:`wbc.compiled.ticks.cascade_solve`: bounds, equalities and inequality rows) on
        the plan's rows or the numpy blocks; the cascade of backend QPs on the same arrays only
        when that fails (an infeasible hard level, an active set that does not settle)."""
        if self._key != self.stack.revision:
            self._plan()
        fast = self.fast
        interim = fast is not None and self.compiled is None and not (fast.is_ready or fast.ready())
        if interim:  # compiling in the background: meanwhile the numpy path and the backend
            fast = None  # cascade (the compiled level algorithm is being built); compiled=True
            # waits for the compiled tick
            self.interim_ticks += 1
        if fast is not None:
            # fills the plan's rows, bounds and inequality rows (the constraints' kernels)
            if fast.solve(kin, dt) == 0:
                self.compiled_ticks += 1
                self.relaxed = False
                self.diagnosis = ""
                self._built = False
                return fast.solution
            self.handed_back_ticks += 1
            inequalities = self._plan_inequalities()
        else:
            inequalities = self._inequalities_at(kin)
        problems, lower, upper = self._assemble(kin, dt, inequalities, fast)
        self._problems = problems
        if fast is None and not interim:
            if self._level_solver_ready():
                dq = self._level_solver(problems, kin, dt, lower, upper)
                if dq is not None:
                    return Solution(dq, lower, upper)
            else:  # its kernel compiles in the background: the backend cascade meanwhile
                self.interim_ticks += 1
        relax = self.on_infeasible == "relax"
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
        except InfeasibleError as exc:  # named only if the recovery cannot answer the tick
            bounds = lower.copy(), upper.copy()
            raise Undiagnosed(lambda: self._hard_inequality_message(kin, *bounds)) from exc
        self.relaxed = any(s.relaxed for s in self.solutions)
        self._check_hard_levels(relax)
        return Solution(dq, lower, upper)

    @staticmethod
    def _level_solver_ready() -> bool:
        """True if the numpy path's level cascade runs without compiling now (else it is
        being compiled in the background: :meth:`wbc.compiled.dispatch.Ticks.kernel_ready`)."""
        from ..compiled.ticks import cascade_solve

        if cascade_solve.overloads:  # (compiled in this process: every later tick)
            return True
        from .plan import package_ticks

        return package_ticks().kernel_ready(cascade_solve, "cascade_tick")

    def _level_solver(self, problems, kin: Kinematics, dt: float | None, lower, upper):
        """The levels on the numpy path: the compiled tick's own level algorithm
        (:func:`wbc.compiled.ticks.cascade_solve`, inequality rows included) on these rows,
        so that one hierarchy algorithm serves every path. None if it cannot finish (the
        backend cascade then solves the tick, or names why it is infeasible)."""
        from ..compiled.lsq import OK
        from ..compiled.ticks import cascade_solve

        nv = self.robot.nv
        J = np.vstack([p.J for p in problems]) if problems else np.zeros((0, nv))
        b = np.concatenate([p.b for p in problems]) if problems else np.zeros(0)
        G = np.vstack([p.G for p in problems]) if problems else np.zeros((0, nv))
        h = np.concatenate([p.h for p in problems]) if problems else np.zeros(0)
        level_rows = np.cumsum([0] + [p.J.shape[0] for p in problems]).astype(np.int64)
        g_rows = np.cumsum([0] + [p.h.shape[0] for p in problems]).astype(np.int64)
        level_hard = np.array([p.hard for p in problems], dtype=np.bool_)
        params = np.array(
            [
                (1.0 + self.defer_rows_join) if self.defer_with_rows else 0.0,
                self.regularization,
                self.hard_tol,
                CONSTRAINT_TOL,
                self.pdas_budget,
            ]
        )
        states = np.zeros((len(problems), nv), dtype=np.int8)
        working = np.zeros((len(problems), h.size), dtype=np.bool_)
        h_eff = np.zeros(h.size)
        achieved = np.zeros(J.shape[0])
        dq = np.zeros(nv)
        q_next = np.zeros(self.robot.nq)
        q = np.ascontiguousarray(kin.q, dtype=float)
        status = cascade_solve(
            J, b, level_rows, level_hard, np.ascontiguousarray(G, dtype=float),
            np.ascontiguousarray(h, dtype=float), g_rows, q, self._q_min, self._q_max, params,
            lower, upper, states, working, h_eff, achieved, dq, q_next, np.zeros(0),
            np.zeros(0, np.int64),
        )  # fmt: skip
        if status != OK:
            self.compute_bounds(kin, dt, lower, upper)  # the backend cascade starts afresh
            return None
        self._solutions = [
            LevelSolution(
                p.priority,
                p.J @ dq - p.b,
                h_eff[g0:g1] - p.h,
                margin=p.G @ dq - p.h,
            )
            for p, g0, g1 in zip(problems, g_rows[:-1], g_rows[1:], strict=True)
        ]
        self.relaxed = False
        self.diagnosis = ""
        return dq

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
        # DAQP (daqp_for): a diagnosis, where a first-order backend's capped
        # iterations on these degenerate levels cost seconds
        backends = daqp_for([*self.problems, None])
        try:
            _, sols = solve_cascade(self.problems, lower, upper, backends, relax=True)
        except (InfeasibleError, SolverError) as exc:  # a level's QP failed: name the levels
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
