"""What every stack solver shares: the solve and the control tick, the layouts kept per
stack structure, the compiled path's choice and the box bounds. Its collaborators, each in
its own module: the projection onto the hard levels (:mod:`wbc.solvers.projection`), the
recovery of infeasible ticks (:mod:`wbc.solvers.recovery`) and the pose iteration beside it
(:func:`wbc.solvers.pose.solve_pose`)."""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import numpy as np

from ..exceptions import ConfigurationError, InfeasibleError, SolverError, TaskError, WbcError
from ..limits import Constraint, box_bounds
from ..model import Kinematics
from ..types import Solution
from .backends import QPBackend, make_backend
from .budget import Work
from .pose import PoseResult, solve_pose
from .projection import HARD_PROJECTION_STEPS, HardLevels
from .recovery import Recovery
from .stack import TaskStack

#: the allowed regularization μ (in μ‖Δq‖²): > 0 keeps every QP strictly convex, and beside
#: task weights of 1e-6 … 1e6 (:data:`wbc.tasks.task.WEIGHT_RANGE`) more than 1e-2 would
#: rival the tasks it only regularizes (1e30 held a walk's every joint still: issue 28)
REGULARIZATION_RANGE = (1e-12, 1e-2)
#: the allowed ``hard_tol`` (m, rad): a hard level's largest residual
HARD_TOL_RANGE = (1e-12, 1e-2)
#: :attr:`StackSolver.rehearse_switch`'s default: a support phase's first tick rehearsed in
#: the idle part (:mod:`wbc.solvers.rehearsal`; benchmarks/self_collision.md, twentieth session)
REHEARSE_SWITCH = True
#: :attr:`StackSolver.warm_ahead`'s default: the current layout's tick rehearsed at the end of
#: a paced loop's idle part, just before the next tick (:meth:`StackSolver.warm`): a 50 Hz
#: tick 0.37–0.51× its time without on the three robots (~300 µs of idle CPU a tick;
#: benchmarks/self_collision.md, twenty-first session)
WARM_AHEAD = True


class StackSolver(ABC):
    """Solve a :class:`TaskStack` for a configuration increment Δq (size nv).

    * :meth:`solve` — one QP at q (``dt``: time step for velocity limits, None = none);
    * :meth:`step` — one control tick: q ⊕ Δq, joints kept inside their limits;
    * :meth:`solve_pose` — iterate on one pose until the task errors converge
      (:func:`wbc.solvers.pose.solve_pose`).

    Its collaborators: :attr:`hard_levels` (the projection onto the hard levels),
    :attr:`recovery` (infeasible ticks) and :attr:`work` (what a pose or a recovery spent).
    """

    #: True: the soft levels are priorities (the hierarchical QP); False: one weighted
    #: objective, every constraint row hard (the weighted QP)
    lexicographic = True
    #: largest residual of a hard level (m, rad; the subclasses take it as an option)
    hard_tol = 1e-6

    def __init__(
        self,
        stack: TaskStack,
        backend: str | QPBackend = "daqp",
        regularization: float = 1e-6,
        on_infeasible: str = "raise",
        compiled: bool | None = None,
    ) -> None:
        if on_infeasible not in ("raise", "relax"):
            raise ConfigurationError(
                f"on_infeasible must be 'raise' or 'relax', got {on_infeasible!r}"
            )
        if compiled not in (None, True, False):
            raise ConfigurationError(f"compiled must be None, True or False, got {compiled!r}")
        regularization = check_number("regularization", regularization, REGULARIZATION_RANGE)
        self.stack = stack
        self.robot = stack.robot
        self.backend = make_backend(backend) if isinstance(backend, str) else backend
        self.regularization = regularization
        self.on_infeasible = on_infeasible
        #: None: the compiled hot path when the backend is DAQP (the default) and the stack
        #: allows it (see :meth:`compiled_reason`), with DAQP for the ticks it hands back;
        #: True: required, whatever the backend (ConfigurationError if the stack does not
        #: allow it); False: numpy assembly and the backend on every tick
        self.compiled = compiled
        #: the compiled plan of the current layout (None: the numpy path)
        self.fast = None
        #: (plan, array) that :meth:`prepare_output` bound, not returned yet
        self._fresh: tuple[Any, np.ndarray] | None = None
        #: :meth:`prepare_output` binds the tick's output ahead (False: it does nothing, the
        #: step copies): ~6 µs less in a 50 Hz loop's cold tick, ~3.5 µs more back to back
        #: (benchmarks/self_collision.md, fourteenth session): off by default
        self.output_ahead = False
        #: :meth:`rehearse` runs the first tick of a layout switched to ahead once in the idle
        #: part and forgets it (the same answers; that tick then finds its memory and code in
        #: the caches: :mod:`wbc.solvers.rehearsal`)
        self.rehearse_switch = REHEARSE_SWITCH
        #: :meth:`warm` rehearses the current layout's tick just before a paced loop's next
        #: tick (the caches the idle part's sleep left cold warmed; the same answers)
        self.warm_ahead = WARM_AHEAD
        #: solves done by the compiled kernels / handed back by them to the numpy path (an
        #: active inequality row, an active set that did not settle, an infeasible level)
        self.compiled_ticks = 0
        self.handed_back_ticks = 0
        #: solves done on the numpy path while the compiled tick was being compiled in the
        #: background (``compiled=None`` only: True waits for it; see
        #: :meth:`wbc.compiled.dispatch.Ticks.ready`), and the hierarchy's numpy-path solves
        #: by the backend cascade while its level kernel compiles, on any backend
        #: (:meth:`wbc.compiled.dispatch.Ticks.kernel_ready`)
        self.interim_ticks = 0
        self._layouts: dict = {}
        #: the work arrays that the compiled plans of the layouts share
        #: (:class:`wbc.solvers.plan.Scratch`; None until a plan is built)
        self._plan_scratch = None
        self.kin = Kinematics(self.robot)
        self._q_min = self.robot.q_min
        self._q_max = self.robot.q_max
        self._outside: Callable | None = None  # (the compiled check of _outside_limits)
        #: the last solve's result (None before the first)
        self.last: Solution | None = None
        #: seconds spent in the last :meth:`solve` (kinematics, assembly and QP)
        self.solve_time = 0.0
        #: True if the last solve had to relax an infeasible hard level
        self.relaxed = False
        #: what a relaxed or failed solve could not meet ("" otherwise)
        self.diagnosis = ""
        self._hard: list[Constraint] = []  # (:meth:`_hard_constraints`, for a revision)
        self._hard_key: int | None = None
        #: each kept layout's hard constraints (by its :meth:`_layout_key`: a support switch
        #: takes them with the layout instead of listing them again)
        self._layout_hard: dict = {}
        #: (:meth:`note_phase`) the phase the stack is in at a revision, and each noted
        #: phase's layout key
        self._phase_note: tuple | None = None
        self._phase_keys: dict = {}
        #: what the solver's work spent: a running :meth:`solve_pose`'s budget, the last
        #: solve's recovery steps (:class:`~wbc.solvers.budget.Work`)
        self.work = Work()
        #: the hard levels of the stack, to measure and project onto
        #: (:class:`~wbc.solvers.projection.HardLevels`)
        self.hard_levels = HardLevels(
            stack, self.robot, self.kin, self._q_min, self._q_max, self.work
        )
        #: the recovery of this solver's infeasible ticks
        #: (:class:`~wbc.solvers.recovery.Recovery`)
        self.recovery = Recovery(self, self.hard_levels, self.work)

    @property
    def recovery_steps(self) -> int:
        """Gauss–Newton steps the last solve spent bringing an infeasible start back onto the
        hard levels (at most :data:`~wbc.solvers.recovery.TICK_RECOVERY_STEPS` outside a
        :meth:`solve_pose`)."""
        return self.work.recovery_steps

    @property
    def name(self) -> str:
        return f"{type(self).__name__}[{self.backend.name}]"

    # ------------------------------------------------------------------ interface
    @abstractmethod
    def _solve(self, kin: Kinematics, dt: float | None) -> Solution:
        """The solution at the configuration of ``kin`` (kinematics already updated)."""

    def solve(self, q: np.ndarray, dt: float | None = None) -> np.ndarray:
        """Δq (nv) for one QP at configuration q; ``dt`` enables the velocity limits. From a
        q with joints outside their range, Δq ends on the hard levels at q ⊕ Δq (not only to
        first order: :meth:`Recovery.on_hard_levels
        <wbc.solvers.recovery.Recovery.on_hard_levels>`)."""
        return self._timed_solve(q, dt).dq.copy()  # may be a plan's buffer: copy

    def _timed_solve(self, q: np.ndarray, dt: float | None, dt_checked: bool = False) -> Solution:
        start = time.perf_counter()
        if dt is not None and not dt_checked:
            check_dt(dt)
        self.last = None
        self.work.recovery_steps = 0
        self.kin.update(q)
        try:
            solution = self._solve(self.kin, dt)
        except (InfeasibleError, SolverError) as exc:  # infeasible, or the backend undecided
            self._check_task_errors()  # a non-finite target is the cause: say so
            solution, unmet = self.recovery.solve(self.kin, dt, exc)
            self.diagnosis = "; ".join(unmet)
            self.relaxed = bool(unmet)
        except WbcError:
            self._check_task_errors()
            raise
        # nothing non-finite leaves (a compiled tick's solution, integrated: checked by it)
        if solution.q_next is None and not math.isfinite(solution.dq.dot(solution.dq)):
            self._check_task_errors()
            raise SolverError(f"{self.name}: the solve returned a non-finite Δq")
        if not self.relaxed and self._outside_kin():
            solution = self.recovery.on_hard_levels(self.kin, solution)
        if dt is not None:  # a control tick (not an iterate of a pose: its guard checks it)
            hard = self._hard if self._hard_key == self.stack.revision else self._hard_constraints()
            for c in hard:  # (the cached list read here: a cold tick's call less)
                c.solved()  # (a constraint held violated by the hard tasks raises)
        self.last = solution
        self.solve_time = time.perf_counter() - start
        return solution

    def _hard_constraints(self) -> list[Constraint]:
        """The active constraints whose rows the solver holds hard: those of the hard levels
        (every one in the weighted QP); cached per revision of the stack."""
        if self._hard_key != self.stack.revision:
            self._hard_key = self.stack.revision
            self._hard = self._list_hard()
        return self._hard

    def _list_hard(self) -> list[Constraint]:
        return [
            c
            for lv in self.stack.levels
            if lv.hard or not self.lexicographic
            for c in lv.active_constraints()
        ]

    def _outside_kin(self) -> bool:
        """:meth:`_outside_limits` of :attr:`kin`'s q: what its update found
        (:attr:`wbc.model.Kinematics.outside`, one compiled call with the configuration's check)
        where the robot checks the limits this solver holds, else asked again."""
        kin = self.kin
        q_min, q_max = self.robot.checked_limits
        if q_min is self._q_min and q_max is self._q_max:
            return kin.outside
        return self._outside_limits(kin.q)

    def _outside_limits(self, q: np.ndarray) -> bool:
        """True if a joint of q (a configuration checked by :meth:`Kinematics.update`) is
        outside its range (:func:`wbc.compiled.checks.outside`: every tick asks)."""
        outside = self._outside
        if outside is None:  # (numba is imported by the first solve, not by ``import wbc``)
            from ..compiled.checks import entry, outside

            outside = self._outside = entry(outside)
        return outside(q, self._q_min, self._q_max)

    def _check_task_errors(self) -> None:
        """Raise TaskError naming an active task whose error at the last solve is not finite
        (a target array written in place with NaN or inf bypasses ``set_target``'s check)."""
        for t in self.stack.tasks():
            e = t.last_error
            if t.active and e.size == t.rows and not np.isfinite(e).all():
                raise TaskError(
                    f"task {t.name!r}: non-finite error {e} at the last solve (a target holds "
                    "NaN or inf: set targets with set_target, which checks them)"
                )

    def prepare(self, q: np.ndarray, dt: float | None = None) -> None:
        """Pay the one-off costs of a first solve now (building the layout, loading the
        compiled kernels from numba's cache: milliseconds), e.g. before a control loop starts.
        Solves once at q with the current targets, and leaves room in the compiled plan for
        twice the inequality rows it had (:meth:`wbc.solvers.plan._Plan.reserve_rows`); counts
        no tick."""
        ticks = self.compiled_ticks, self.handed_back_ticks, self.interim_ticks
        try:
            self.solve(q, dt)
        except WbcError:
            pass  # targets not set yet may be infeasible: the layout is built all the same
        self.compiled_ticks, self.handed_back_ticks, self.interim_ticks = ticks
        if self.fast is not None:  # room for more inequality rows than at q (no growth later)
            self.fast.reserve_rows()

    def forget_warm_starts(self) -> None:
        """Start the compiled level solvers' active sets afresh (as after building a layout)."""
        for layout in self._layouts.values():
            plan = getattr(layout, "fast", None)
            if plan is not None:
                plan.forget_warm_start()

    def step(self, q: np.ndarray, dt: float) -> np.ndarray:
        """One control tick of ``dt`` seconds (a number > 0: the servos' speed limits need it;
        :meth:`solve` and :meth:`solve_pose` take None for no time step): q ⊕ Δq with the
        joints inside their limits.

        The QP keeps Δq inside its box bounds up to the solver's tolerance (~1e-9); before
        integrating, the joint increments are projected onto that box exactly, and the joints
        onto their limits, so that no returned configuration ever exceeds a limit (a joint that
        started outside is moved back towards its range, never further out).
        """
        if type(dt) is not float or not 0.0 < dt < math.inf:  # (a float step: no call)
            check_dt(dt, "step")
        solution = self._timed_solve(q, dt, True)
        q_next = solution.q_next
        if q_next is not None:  # integrated by the compiled tick, the same way
            fresh = self._fresh
            if fresh is not None and q_next is fresh[1]:  # (an array no one holds: no copy)
                self._fresh = None
                fresh[0].lent = True  # (its plan writes there no more)
                return q_next
            return q_next.copy()
        return self.integrate(self.kin.q, solution.dq)

    def prepare_output(self) -> None:
        """The idle part of a loop, before a :meth:`step`: the compiled plan's tick made to
        write q ⊕ Δq into a new array, which the step then returns as it is (no copy in the
        tick: :mod:`wbc.solvers.buffers`). The same numbers as without; nothing unless
        :attr:`output_ahead`, if no compiled plan has ticked yet, or if a new array is bound
        and not returned yet."""
        plan = self.fast
        if not self.output_ahead or plan is None or plan._entry is None:
            return  # (off by default: every tick's idle part returns here)
        from .buffers import bind

        fresh = self._fresh
        if fresh is not None and fresh[0] is plan and plan.q_next is fresh[1] and not plan.lent:
            return
        out = np.empty(plan.q_next.shape)
        bind(plan, out)
        self._fresh = (plan, out)

    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """q ⊕ dq with dq's joint part clipped to the last solve's box bounds and the joints
        to [min(q_min, q_j), max(q_max, q_j)] (exact limits despite solver tolerances);
        :func:`wbc.compiled.integrate.integrate`, as the compiled tick does."""
        from ..compiled.integrate import integrate

        if self.last is not None:
            lower, upper = self.last.lower, self.last.upper
        else:
            lower, upper = np.full(dq.shape, -np.inf), np.full(dq.shape, np.inf)
        q = np.ascontiguousarray(q, dtype=float)
        dq = np.ascontiguousarray(dq, dtype=float)
        q_next = np.empty_like(q)
        integrate(q, dq, lower, upper, self._q_min, self._q_max, q_next)
        return q_next

    def solve_pose(
        self,
        q: np.ndarray,
        tol: float = 1e-6,
        max_iterations: int = 200,
        dt: float | None = None,
        stall_tol: float = 1e-9,
        max_projection_steps: int | None = None,
        time_budget: float | None = None,
    ) -> PoseResult:
        """Iterate Δq on one pose until every task error is below ``tol`` (or the steps
        stall), the hard levels held at the end, within a bounded work budget:
        :func:`wbc.solvers.pose.solve_pose` (the loop beside the solver) with this solver."""
        return solve_pose(
            self, q, tol, max_iterations, dt, stall_tol, max_projection_steps, time_budget
        )

    def project_hard(
        self, q: np.ndarray, tol: float = 1e-9, max_steps: int = HARD_PROJECTION_STEPS
    ) -> np.ndarray:
        """q moved onto the hard levels, one level after the other: for level k, Gauss–Newton
        steps δ = argmin ‖δ‖ subject to the hard levels 0..k in priority order (J_j δ = e_j in
        least squares over the null space of the levels above, their inequalities), the
        joint limits and a trust region, each step halved until it reduces level k's error
        without raising a level above it beyond ``tol``. A level that cannot be met (relaxed)
        keeps the best it reaches and ends the projection; it never costs a level above it
        (:meth:`wbc.solvers.projection.HardLevels.project`)."""
        return self.hard_levels.project(q, tol, max_steps)[0]

    # ------------------------------------------------------------------ layouts
    def _layout_key(self) -> tuple:
        """What a solver's preallocated layout depends on: the stack's structure
        (:attr:`TaskStack.version`: its levels, tasks and constraints) and each task's activity,
        gain/mask/weight (``params_version``) and frames, each constraint's activity. Switching
        between support phases alternates between a few layouts, which are kept
        (:meth:`_switch_layout`); a switch computes this key (flat lists: a few µs)."""
        stack = self.stack
        tasks, constraints = stack.members()
        return (
            stack.version,
            *[(t.params_version, t.frame_ids()) if t.active else -1 for t in tasks],
            *[c.active for c in constraints],
        )

    def rehearse(self, dt: float) -> bool:
        """In a loop's idle part, after :meth:`switch_layout`: the compiled tick of the layout
        switched to run once at the last tick's kinematics and forgotten
        (:func:`wbc.solvers.rehearsal.rehearse`; nothing unless :attr:`rehearse_switch`, a
        compiled plan ready, and one that leaves no trace). True if it ran."""
        return self.rehearse_switch and self._rehearse(dt)

    def warm(self, dt: float) -> bool:
        """At the end of a paced loop's idle part, just before its next tick: the kinematics
        at the last tick's q computed again (the same numbers) and the current layout's
        compiled tick run once there and forgotten (:func:`wbc.solvers.rehearsal.rehearse`,
        the switch's rehearsal): after the idle part's sleep every tick starts with its code
        and arrays evicted; this brings them back. Nothing unless :attr:`warm_ahead`, a
        compiled plan ready and one that leaves no trace. True if it ran."""
        if not self.warm_ahead:
            return False
        self.kin.update(self.kin.q)
        return self._rehearse(dt)

    def _rehearse(self, dt: float) -> bool:
        """:func:`wbc.solvers.rehearsal.rehearse` of the current plan at :attr:`kin`."""
        plan = self.fast
        if plan is None or not plan.is_ready:
            return False
        from .rehearsal import rehearse

        return rehearse(plan, self.kin, dt)

    def switch_layout(self) -> None:  # noqa: B027
        """Take the layout of the stack as it is now if the stack changed since the last solve
        (what a solve does first): a support switch made in a loop's idle part
        (:meth:`wbc.walking.controller.StackController.prepare_phase`) then leaves its tick nothing
        to switch. Nothing else changes: the next solve is the same."""

    def note_phase(self, phase: tuple, revision: int) -> None:
        """The stack at ``revision`` is in the state that ``phase`` names (hashable; its first
        item an epoch token, compared by identity: within one epoch, the same phase is the
        same state of every task and constraint that a layout reads): a switch at that
        revision takes the layout key kept for ``phase`` instead of reading the stack
        (:meth:`wbc.stacks.ControlStack.set_phase` notes its support phases so)."""
        self._phase_note = (phase, revision)

    def _switch_layout(self, build: Callable[[], Any]) -> Any:
        """The layout of the stack as it is now (its :attr:`TaskStack.revision` moved): the one
        kept for its :meth:`_layout_key`, else ``build()`` (kept), with its hard constraints
        (:meth:`_hard_constraints`). Nothing else happens at a switch: every compiled tick
        starts its active sets afresh (:meth:`wbc.solvers.plan._Plan.solve`)."""
        note = self._phase_note
        if note is not None and note[1] == self.stack.revision:  # a noted phase: its key
            phase = note[0]
            key = self._phase_keys.get(phase)
            if key is None:
                if self._phase_keys and next(iter(self._phase_keys))[0] is not phase[0]:
                    self._phase_keys.clear()  # (another epoch)
                key = self._phase_keys[phase] = self._layout_key()
        else:
            key = self._layout_key()
        layout = self._layouts.get(key)
        if layout is None:
            if len(self._layouts) >= 16:  # a stack edited in many ways: start afresh
                self._layouts.clear()
                self._layout_hard.clear()
            layout = self._layouts[key] = build()
            self._layout_hard[key] = self._list_hard()
        self._hard = self._layout_hard[key]
        self._key = self._hard_key = self.stack.revision
        return layout

    # ------------------------------------------------------------------ compiled path
    @property
    def plan_scratch(self):
        """The work arrays that the compiled plans of this solver's layouts share."""
        if self._plan_scratch is None:
            from .buffers import Scratch

            self._plan_scratch = Scratch()
        return self._plan_scratch

    def compiled_reason(self) -> str:
        """Why the compiled hot path cannot serve this stack ("" if it can)."""
        from .plan import box_limits, compiled, numba_available

        if not numba_available():
            return "numba is not installed (pip install numba)"
        active = [t for lv in self.stack.levels for t in lv.active_tasks()]
        others = sorted({type(t).__name__ for t in active if not compiled(t)})
        if others:
            return f"no row kernel (compiled form) for the task types {others}"
        limits = sorted({type(b).__name__ for b in box_limits(self.stack) if not compiled(b)})
        if limits:
            return f"no bound kernel (compiled form) for the box limit types {limits}"
        return ""

    def _use_compiled(self) -> bool:
        """Decide at (re)planning time whether the compiled path serves the new layout."""
        if self.compiled is False or (self.compiled is None and self.backend.name != "daqp"):
            return False  # by default the kernel stands in for DAQP only (its fallback)
        reason = self.compiled_reason()
        if reason and self.compiled:
            raise ConfigurationError(f"{self.name}: compiled=True but {reason}")
        return not reason

    # ------------------------------------------------------------------ helpers
    def compute_bounds(
        self, kin: Kinematics, dt: float | None, lower: np.ndarray, upper: np.ndarray
    ) -> None:
        """Box bounds on Δq, written into ``lower``/``upper`` (nv each; the floating base's rows
        are unbounded): the stack's box limits' kernels, folded by :func:`wbc.limits.box_bounds`
        as the compiled tick does.

        Joint position: q_min − q <= Δq <= q_max − q. With a time step and velocity limits both
        are clipped into [−v_max·dt, v_max·dt]; a joint outside its range then moves back at
        the servo's speed (the bounds never cross). Other box limits are intersected after.
        """
        from .plan import box_limits

        box_bounds(box_limits(self.stack), kin, dt, lower, upper)


def check_number(name: str, value: object, allowed: tuple[float, float]) -> float:
    """``value`` as a float if it is a real number within ``allowed`` (inclusive), else one
    ConfigurationError line naming ``name`` and the range."""
    lo, hi = allowed
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not lo <= value <= hi  # (NaN fails this too)
    ):
        raise ConfigurationError(f"{name} must be a number in [{lo:g}, {hi:g}], got {value!r}")
    return float(value)


def check_dt(dt: object, caller: str = "solve") -> float:
    """``dt`` as a float if it is a time step in seconds (a real number, finite, > 0; not a
    bool), else one ConfigurationError line naming ``caller``'s argument."""
    if (
        isinstance(dt, bool)
        or not isinstance(dt, (int, float, np.integer, np.floating))
        or not (math.isfinite(dt) and dt > 0)
    ):
        raise ConfigurationError(
            f"{caller}: dt must be a time step in seconds (a finite number > 0), got {dt!r}"
        )
    return float(dt)
