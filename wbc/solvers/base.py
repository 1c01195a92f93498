"""What every stack solver shares: kinematics, bounds, stepping and iterating to convergence."""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..exceptions import ConfigurationError, WbcError
from ..limits import Bounds, intersect_bounds
from ..model import Kinematics
from .backends import QPBackend, make_backend
from .stack import TaskStack

#: violation up to which a compiled solution counts as meeting the inequality rows (the
#: backends' own primal tolerance is of the same order)
CONSTRAINT_TOL = 1e-9


@dataclass
class PoseResult:
    """Outcome of :meth:`StackSolver.solve_pose`."""

    q: np.ndarray
    iterations: int
    converged: bool
    errors: dict[str, np.ndarray] = field(default_factory=dict)
    time: float = 0.0

    def max_error(self) -> float:
        return max((float(np.max(np.abs(e))) for e in self.errors.values()), default=0.0)


class Solution(NamedTuple):
    """What one solve returns: Δq, the box it was solved in, and q ⊕ Δq when the compiled
    tick integrated it already (None: not yet)."""

    dq: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    q_next: np.ndarray | None = None


class StackSolver(ABC):
    """Solve a :class:`TaskStack` for a configuration increment Δq (size nv).

    * :meth:`solve` — one QP at q (``dt``: time step for velocity limits, None = none);
    * :meth:`step` — one control tick: q ⊕ Δq, joints kept inside their limits;
    * :meth:`solve_pose` — iterate on one pose until the task errors converge.
    """

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
        #: solves done by the compiled kernels / handed back by them to the numpy path (an
        #: active inequality row, an active set that did not settle, an infeasible level)
        self.compiled_ticks = 0
        self.handed_back_ticks = 0
        self._layouts: dict = {}
        self.kin = Kinematics(self.robot)
        self._q_min = self.robot.q_min
        self._q_max = self.robot.q_max
        #: the last solve's result (None before the first)
        self.last: Solution | None = None
        #: seconds spent in the last :meth:`solve` (kinematics, assembly and QP)
        self.solve_time = 0.0
        #: True if the last solve had to relax an infeasible hard level
        self.relaxed = False

    @property
    def name(self) -> str:
        return f"{type(self).__name__}[{self.backend.name}]"

    # ------------------------------------------------------------------ interface
    @abstractmethod
    def _solve(self, kin: Kinematics, dt: float | None) -> Solution:
        """The solution at the configuration of ``kin`` (kinematics already updated)."""

    def solve(self, q: np.ndarray, dt: float | None = None) -> np.ndarray:
        """Δq (nv) for one QP at configuration q; ``dt`` enables the velocity limits."""
        return self._timed_solve(q, dt).dq.copy()  # may be a plan's buffer: copy

    def _timed_solve(self, q: np.ndarray, dt: float | None) -> Solution:
        start = time.perf_counter()
        if dt is not None and not (math.isfinite(dt) and dt > 0):
            raise ConfigurationError(f"dt must be a positive number, got {dt}")
        self.last = None
        self.kin.update(q)
        self.last = solution = self._solve(self.kin, dt)
        self.solve_time = time.perf_counter() - start
        return solution

    def prepare(self, q: np.ndarray, dt: float | None = None) -> None:
        """Pay the one-off costs of a first solve now (building the layout, loading the
        compiled kernels from numba's cache: milliseconds), e.g. before a control loop starts.
        Solves once at q with the current targets; counts no tick."""
        ticks = self.compiled_ticks, self.handed_back_ticks
        try:
            self.solve(q, dt)
        except WbcError:
            pass  # targets not set yet may be infeasible: the layout is built all the same
        self.compiled_ticks, self.handed_back_ticks = ticks

    def forget_warm_starts(self) -> None:
        """Start the compiled level solvers' active sets afresh (as after building a layout)."""
        for layout in self._layouts.values():
            plan = getattr(layout, "fast", None)
            for name in ("state", "states"):
                if plan is not None and hasattr(plan, name):
                    getattr(plan, name)[...] = 0

    def step(self, q: np.ndarray, dt: float | None = None) -> np.ndarray:
        """One control tick: q ⊕ Δq with the joints inside their limits.

        The QP keeps Δq inside its box bounds up to the solver's tolerance (~1e-9); before
        integrating, the joint increments are projected onto that box exactly, and the joints
        onto their limits, so that no returned configuration ever exceeds a limit (a joint that
        started outside is moved back towards its range, never further out).
        """
        solution = self._timed_solve(q, dt)
        if solution.q_next is not None:  # integrated by the compiled tick, the same way
            return solution.q_next.copy()
        return self.integrate(self.kin.q, solution.dq)

    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """q ⊕ dq with dq's joint part clipped to the last solve's box bounds and the joints
        to [min(q_min, q_j), max(q_max, q_j)] (exact limits despite solver tolerances);
        :func:`wbc.compiled.ticks.integrate`, as the compiled tick does."""
        from ..compiled.ticks import integrate

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
    ) -> PoseResult:
        """Iterate Δq until every task error is below ``tol``, or the steps stall (max |Δq| <
        ``stall_tol``: a weighted compromise or an unreachable target has its fixed point).

        This is the per-pose iterative mode used to compare with the thesis's solutions.
        """
        start = time.perf_counter()
        q = self.robot.check_configuration(q).copy()
        converged = False
        it = 0
        for it in range(1, max_iterations + 1):
            dq = self.solve(q, dt)
            if self._converged(tol):
                converged = True
                it -= 1
                break
            q = self.integrate(q, dq)
            if abs(dq).max() < stall_tol:
                break
        self.kin.update(q)
        errors = self.stack.evaluate(self.kin)
        if not converged:
            converged = all(
                float(np.max(np.abs(errors[t.name]))) <= tol
                for t in self.stack.tasks()
                if t.active and t.blocks_convergence
            )
        return PoseResult(q, it, converged, errors, time.perf_counter() - start)

    def _converged(self, tol: float) -> bool:
        return all(
            abs(t.last_error).max() <= tol
            for t in self.stack.tasks()
            if t.active and t.blocks_convergence
        )

    # ------------------------------------------------------------------ layouts
    def _layout_key(self) -> tuple:
        """What a solver's preallocated layout depends on: the active tasks (with their gains,
        masks, weights and frames) and constraints, level by level. Switching between support
        phases alternates between a few layouts, which are kept (:meth:`_cached_layout`)."""
        return (
            self.stack.version,
            tuple(
                (
                    lv.priority,
                    lv.hard,
                    tuple((id(t), t.params_version, t.frame_ids()) for t in lv.active_tasks()),
                    tuple(id(c) for c in lv.active_constraints()),
                )
                for lv in self.stack.levels
            ),
        )

    def _cached_layout(self, key: tuple):
        """The layout kept for ``key`` (None if none)."""
        return self._layouts.get(key)

    def _keep_layout(self, key: tuple, layout) -> None:
        if len(self._layouts) >= 16:  # a stack edited in many ways: start afresh
            self._layouts.clear()
        self._layouts[key] = layout

    # ------------------------------------------------------------------ compiled path
    def compiled_reason(self) -> str:
        """Why the compiled hot path cannot serve this stack ("" if it can)."""
        from ..compiled.plan import compiled, numba_available

        if not numba_available():
            return "numba is not installed (pip install numba)"
        active = [t for lv in self.stack.levels for t in lv.active_tasks()]
        others = sorted({type(t).__name__ for t in active if not compiled(t)})
        if others:
            return f"no row kernel (compiled form) for the task types {others}"
        if self.stack.extra_limits:
            return "extra box limits are not compiled"
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
        are unbounded), by :func:`wbc.compiled.ticks.joint_bounds` as the compiled tick does.

        Joint position: q_min − q <= Δq <= q_max − q. With a time step and velocity limits both
        are clipped into [−v_max·dt, v_max·dt]; a joint outside its range then moves back at
        the servo's speed (the bounds never cross). Other box limits are intersected after.
        """
        from ..compiled.ticks import joint_bounds  # the compiled tick's own, one definition

        limit = self.stack.velocity_limit
        use = dt is not None and limit is not None
        step = limit.step(dt) if use else self._q_min  # (not read without a time step)
        joint_bounds(kin.q[7:], self._q_min, self._q_max, step, use, lower, upper)
        if self.stack.extra_limits:
            position = Bounds(lower.copy(), upper.copy())
            others = [lim.bounds(kin, dt) for lim in self.stack.extra_limits]
            intersect_bounds(position, others, lower, upper)
