"""What every stack solver shares: kinematics, bounds, stepping and iterating to convergence."""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from ..exceptions import ConfigurationError, InfeasibleError, SolverError, TaskError, WbcError
from ..limits import Constraint, box_bounds
from ..model import Kinematics
from ..types import Solution
from .assembly import TaskBlock
from .backends import QPBackend, make_backend
from .cascade import LevelProblem, solve_cascade, solve_cascade_or_daqp
from .diagnostics import infeasible_message
from .stack import TaskStack

#: hard-task error (m, rad) beyond which :meth:`StackSolver.solve_pose` projects an iterate
#: back onto the hard levels (smaller residuals the next QP step corrects to second order;
#: 1e-3 let double-support iterates drift 1e-4 off where the joint limits and the collision
#: rows no longer let the QP or the final projection close the chain: stress trials 384, 584)
HARD_ITERATE_TOL = 1e-4
#: largest hard-task error at the end of :meth:`StackSolver.solve_pose`
HARD_POSE_TOL = 1e-6
#: what the final projection of :meth:`StackSolver.solve_pose` aims at (m, rad): below its
#: tolerance, as far as its steps still reduce the error (a step short of the quadratic one
#: can stop it just under 1e-6; the guard checks the tolerance)
HARD_POSE_AIM = 1e-9
#: at most this many Gauss–Newton steps per projection onto the hard levels (it converges
#: quadratically: two or three steps from a tick's second-order residual)
HARD_PROJECTION_STEPS = 20
#: the restoration of an infeasible tick (:meth:`StackSolver._restore_hard`) stops after
#: RESTORE_STALLS steps in a row that each leave more than RESTORE_STALL of the hard error
#: (Gauss–Newton converging is quadratic; stress trial 1271 got there after two such steps,
#: an active row changing; a stalled one costs a projection per step in a tick that raises)
RESTORE_STALL = 0.5
RESTORE_STALLS = 3
#: the most (m) by which that restoration, where it cannot hold the inequality rows at their
#: bound, may loosen them (and never by more than the hard error it undoes): a tick's
#: second order past a self-collision margin, as the damper's own tests allow (0.5 mm)
RESTORE_SLACK = 5e-4
#: a step from a start outside the joint limits, not ending on the hard levels, is tried at
#: t = 1, ½, … (this many), then 0 (:meth:`StackSolver._on_hard_levels`)
WAY_BACK_HALVINGS = 7
#: at most this many Gauss–Newton steps bring each of those back onto the hard levels
#: (quadratic from a tick's second-order drift: two or three; a step that needs more is
#: one too long, the next halving is cheaper)
WAY_BACK_STEPS = 5
#: at most this many halvings of a projection step that would not reduce its level's error
HARD_PROJECTION_HALVINGS = 12
#: the trust region of a projection's Gauss–Newton step: |δ_i| <= this (rad, m), the step the
#: best one within it (the level in least squares where it cannot be met there). Where joint
#: limits and self-collision rows leave a double-support chain nearly singular, the
#: minimum-norm step was 2 rad for a 4 mm contact error, far outside its linearisation: the
#: line search took it at t = 1/32 for 1–3 % of the error per step, and a pose spent 20
#: steps per projection, 84 s of 93 (stress trial 3972). With the region, 2876 → 183 steps,
#: and poses that ended off their contacts converge (974, 4169, 4875); 0.02 and 0.05 held
#: the six trials tried, 0.1 and 0.2 lost one each (benchmarks/stress_backends.md)
HARD_PROJECTION_TRUST = 0.05
#: an iterate's projection onto a hard level (:meth:`StackSolver._shorter_step`) stops after
#: PROJECTION_STALLS Gauss–Newton steps in a row that each leave more than PROJECTION_STALL
#: of the level's error: converging is quadratic, and such steps creep along a nearly
#: singular chain (stress trial 3972, double support, 6–7 joints at a limit and pairs at
#: their margin: minimum-norm steps of 2 rad for a 4 mm contact error, accepted at t = 1/32
#: for 1–3 % each, 20 steps per projection, 84 s of a 93 s pose; none of its projections that
#: ended on their level had three such steps). The final projection of a pose does not stop
#: early: there a creeping projection can still converge once an active row changes (stress
#: trial 1226: seven such steps, then 5e-5 → 1.4e-7 m)
PROJECTION_STALL = 0.9
PROJECTION_STALLS = 3
#: the most Gauss–Newton steps onto the hard levels that one solve outside
#: :meth:`StackSolver.solve_pose` (a control tick) spends bringing an infeasible start back
#: (:meth:`StackSolver._restore_steps`: the restoration and the way back onto the hard levels
#: from outside the joint limits), each one cascade of DAQP levels and at most
#: :data:`HARD_PROJECTION_HALVINGS` evaluations of the hard levels. With it a tick's worst
#: case is stated: the solve, at most three recovery re-solves (one or two cascades each),
#: TICK_RECOVERY_STEPS such steps, 2 × (:data:`WAY_BACK_HALVINGS` + 1) more evaluations and,
#: where it still fails, the diagnosis (one cascade). Spent, the restoration stops where it
#: is: the tick raises InfeasibleError as any tick whose restoration fails, or keeps the
#: recovery's step (the way back). The most a tick of ``benchmarks/tick_tail.py`` spent:
#: benchmarks/stress.md
TICK_RECOVERY_STEPS = 40
#: the default work budget of :meth:`StackSolver.solve_pose`: this many Gauss–Newton steps of
#: its projections onto the hard levels per iteration and hard level
POSE_PROJECTION_STEPS = 100
#: how much looser than their best achievable way back (m) the rows of constraints violated at
#: the start (self-collision pairs inside their margin, sole corners below the ground) are held
#: by a tick that cannot meet them at their damper's rate
SEPARATION_SLACK = 1e-7
_INSIDE = "constraints violated at the start (their best way back)"
#: weight of "no closer than now" against "separate at the damper's rate" in the best
#: separation of the self-collision pairs inside their margin (one least-squares level)
HOLD_WEIGHT = 100.0
#: the allowed regularization μ (in μ‖Δq‖²): > 0 keeps every QP strictly convex, and beside
#: task weights of 1e-6 … 1e6 (:data:`wbc.tasks.task.WEIGHT_RANGE`) more than 1e-2 would
#: rival the tasks it only regularizes (1e30 held a walk's every joint still: issue 28)
REGULARIZATION_RANGE = (1e-12, 1e-2)
#: the allowed ``hard_tol`` (m, rad): a hard level's largest residual
HARD_TOL_RANGE = (1e-12, 1e-2)
_EMPTY = np.zeros(0)
_NO_JOINTS = np.zeros(0, dtype=int)


class Undiagnosed(InfeasibleError):
    """An infeasible solve whose diagnosis (a cascade of QPs naming the rows in conflict, as
    long as the solve itself) runs only if the recovery re-solve cannot answer the tick
    (:meth:`StackSolver._solve_recovering`): the error the caller then sees is the
    diagnosed one. Most such ticks recover (starts outside the limits or inside a collision
    margin), and the diagnosis was half of their time (issue 28)."""

    def __init__(self, diagnose: Callable[[], str]) -> None:
        super().__init__("infeasible (the diagnosis runs if the recovery fails)")
        self._diagnose = diagnose

    def diagnosed(self) -> InfeasibleError:
        """The InfeasibleError naming the rows (runs the diagnosis)."""
        error = InfeasibleError(self._diagnose())
        error.__cause__ = self.__cause__
        return error


def _diagnosed(exc: WbcError) -> WbcError:
    """``exc`` with its diagnosis, where it was deferred (:class:`Undiagnosed`)."""
    return exc.diagnosed() if isinstance(exc, Undiagnosed) else exc


class SplitRows(NamedTuple):
    """Constraint rows G Δq <= h split into the rows to hold (with each constraint's slice,
    for diagnostics) and the requests of the constraints violated at the start (h < 0: the
    way back; :meth:`~wbc.limits.Constraint.split`: self-collision pairs inside their margin,
    sole corners below the ground)."""

    G: np.ndarray
    h: np.ndarray
    slices: list[tuple[str, slice]]
    G_inside: np.ndarray
    h_inside: np.ndarray


def split_rows(
    constraints: list[Constraint], kin: Kinematics, nv: int, recovering: bool = False
) -> SplitRows:
    """The constraints' rows at ``kin``, the requests of those violated at ``kin`` apart (see
    :class:`SplitRows`; ``recovering``: :meth:`~wbc.limits.Constraint.split`)."""
    G, h, sl, Gi, hi = [], [], [], [], []
    r = 0
    for c in constraints:
        (Gc, hc), (G_ask, h_ask) = c.split(kin, recovering)
        if h_ask.size:
            Gi.append(G_ask)
            hi.append(h_ask)
        G.append(Gc)
        h.append(hc)
        sl.append((c.name, slice(r, r + hc.size)))
        r += hc.size

    def stacked(Gs: list, hs: list) -> tuple[np.ndarray, np.ndarray]:
        return (np.vstack(Gs), np.concatenate(hs)) if Gs else _no_rows(nv)

    return SplitRows(*stacked(G, h), sl, *stacked(Gi, hi))


def _no_rows(nv: int) -> tuple[np.ndarray, np.ndarray]:
    """No inequality rows (G, h) over nv variables."""
    return np.zeros((0, nv)), np.zeros(0)


def _worse(errors: list[float] | None, before: list[float] | None) -> bool:
    """True if a hard level's error grew beyond max(its error before, HARD_ITERATE_TOL)."""
    if errors is None or before is None:
        return False
    return any(e > max(b, HARD_ITERATE_TOL) for e, b in zip(errors, before, strict=True))


@dataclass
class PoseResult:
    """Outcome of :meth:`StackSolver.solve_pose`."""

    q: np.ndarray
    iterations: int
    converged: bool
    errors: dict[str, np.ndarray] = field(default_factory=dict)
    time: float = 0.0
    #: Gauss–Newton steps spent projecting onto the hard levels (``max_projection_steps``)
    projection_steps: int = 0
    #: True if no projection of the last iterate held the hard levels and the pose ended at
    #: the last iterate that did (``converged`` is then False)
    fell_back: bool = False

    def max_error(self) -> float:
        return max((float(np.max(np.abs(e))) for e in self.errors.values()), default=0.0)


@dataclass
class _PoseBudget:
    """What a :meth:`StackSolver.solve_pose` may spend: Gauss–Newton steps onto the hard
    levels and wall time (s; None: no limit), and what it has spent so far."""

    max_steps: int
    seconds: float | None
    start: float = field(default_factory=time.perf_counter)
    steps: int = 0
    iteration: int = 0


class StackSolver(ABC):
    """Solve a :class:`TaskStack` for a configuration increment Δq (size nv).

    * :meth:`solve` — one QP at q (``dt``: time step for velocity limits, None = none);
    * :meth:`step` — one control tick: q ⊕ Δq, joints kept inside their limits;
    * :meth:`solve_pose` — iterate on one pose until the task errors converge.
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
        #: the work budget of the running :meth:`solve_pose` (None outside one)
        self._budget: _PoseBudget | None = None
        #: Gauss–Newton steps the last solve spent bringing an infeasible start back onto
        #: the hard levels (at most :data:`TICK_RECOVERY_STEPS` outside a ``solve_pose``)
        self.recovery_steps = 0
        self._hard: list[Constraint] = []  # (:meth:`_hard_constraints`, for a revision)
        self._hard_key: int | None = None

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
        first order: :meth:`_on_hard_levels`)."""
        return self._timed_solve(q, dt).dq.copy()  # may be a plan's buffer: copy

    def _timed_solve(self, q: np.ndarray, dt: float | None) -> Solution:
        start = time.perf_counter()
        if dt is not None:
            check_dt(dt)
        self.last = None
        self.recovery_steps = 0
        self.kin.update(q)
        try:
            solution = self._solve(self.kin, dt)
        except (InfeasibleError, SolverError) as exc:  # infeasible, or the backend undecided
            self._check_task_errors()  # a non-finite target is the cause: say so
            solution = self._solve_recovering(self.kin, dt, exc)
        except WbcError:
            self._check_task_errors()
            raise
        # nothing non-finite leaves (a compiled tick's solution, integrated: checked by it)
        if solution.q_next is None and not math.isfinite(solution.dq.dot(solution.dq)):
            self._check_task_errors()
            raise SolverError(f"{self.name}: the solve returned a non-finite Δq")
        if not self.relaxed and self._outside_limits(self.kin.q):
            solution = self._on_hard_levels(self.kin, solution)
        if dt is not None:  # a control tick (not an iterate of a pose: its guard checks it)
            for c in self._hard_constraints():
                c.solved()  # (a constraint held violated by the hard tasks raises)
        self.last = solution
        self.solve_time = time.perf_counter() - start
        return solution

    def _solve_recovering(self, kin: Kinematics, dt: float | None, exc: WbcError) -> Solution:
        """Re-solve an infeasible tick, e.g. one that starts outside the joint limits or
        violating a constraint (link pairs inside their self-collision margin, a sole corner
        below the ground: :meth:`~wbc.limits.Constraint.split`), asking of that start only
        what the hard tasks leave possible. One cascade
        (:func:`~wbc.solvers.cascade.solve_cascade`), each level optimal without changing the
        optimum of the levels above:

        1. the hard levels: their tasks and their inequality rows except the requests of the
           violated ones (the weighted QP: every constraint's rows), the rows held at their
           bare bound (``recovering``: the pairs outside the margin may approach down to it,
           e.g. where a hard contact's second-order drift needs it), within the joint
           bounds widened to Δq = 0 for the joints outside their range (never further out);
        2. the way back of those joints (the step their bounds asked: servo speed, or all
           the way without a time step), in least squares;
        3. the requests (e.g. the rows of the pairs inside the margin), in least squares of
           their violation: no worse than now (weighted :data:`HOLD_WEIGHT`: no pair closer,
           no corner lower), then the damper's rate — the best way back the levels above
           leave, which may be an approach where the hard tasks or the joints' way back need
           it; then held there (+ :data:`SEPARATION_SLACK`);
        4. the soft levels as the solver ranks them (levels, or one weighted objective).

        Why the way back before the pairs: a joint outside its range is outside the servo's
        travel, while a pair already inside the margin has lost its guarantee anyway (the
        boxes are a conservative hull); holding such a pair can stop the way back for good.
        Pairs outside the margin keep their rows (1.), so the way back never takes them in.
        Also tried where the solver's backend failed without a verdict (a SolverError: DAQP
        cycling, exit flag −2, in the hierarchy's cascade: stress trials 455, 705); its answer
        counts only if it meets the hard levels. Raises ``exc`` (the solver's diagnosis or
        failure) when the hard levels are infeasible on their own.

        **The hard tasks as given win.** Where they cannot be met with every joint inside its
        range (double support: the contacts, made at a start outside the limits, fix the
        soles' relative pose), the joints come back as far as the hard tasks allow and stay
        there (never further out); the contacts are not re-anchored (that would slide a
        loaded sole). Such a tick's step ends on the hard levels exactly
        (:meth:`_on_hard_levels`), so that the way back does not drift them where no tick
        can bring them back (stress trials 1567, 8832)."""
        nv = self.robot.nv
        lower, upper = np.empty(nv), np.empty(nv)
        self.compute_bounds(kin, dt, lower, upper)
        lo, hi = lower[6:], upper[6:]
        out = np.flatnonzero((lo > 0.0) | (hi < 0.0))
        back = np.where(lo[out] > 0.0, lo[out], hi[out])
        np.minimum(lo, 0.0, out=lo)
        np.maximum(hi, 0.0, out=hi)
        relax = self.on_infeasible == "relax"
        first = None
        for recovering in (False, True):
            try:
                dq, unmet = self._recover(kin, lower, upper, out, back, recovering)
            except (InfeasibleError, SolverError) as e:  # the re-solve failed
                failure = e
                continue
            if not unmet:
                break
            first = first or (dq, unmet)
        else:
            if first is None or not relax:
                restored = self._restore_hard(kin, lower, upper)
                if restored is None:  # infeasible on their own: the solver's diagnosis
                    raise _diagnosed(exc) from (None if first else failure)
                self.diagnosis, self.relaxed = "", False
                return Solution(restored, lower, upper)
            dq, unmet = first
        self.diagnosis = "; ".join(unmet)
        self.relaxed = bool(unmet)
        return Solution(dq, lower, upper)

    def _hard_constraints(self) -> list[Constraint]:
        """The active constraints whose rows the solver holds hard: those of the hard levels
        (every one in the weighted QP); cached per revision of the stack."""
        if self._hard_key != self.stack.revision:
            self._hard_key = self.stack.revision
            self._hard = [
                c
                for lv in self.stack.levels
                if lv.hard or not self.lexicographic
                for c in lv.active_constraints()
            ]
        return self._hard

    def _outside_limits(self, q: np.ndarray) -> bool:
        """True if a joint of q (a configuration checked by :meth:`Kinematics.update`) is
        outside its range (:func:`wbc.compiled.checks.outside`: every tick asks)."""
        outside = self._outside
        if outside is None:  # (numba is imported by the first solve, not by ``import wbc``)
            from ..compiled.checks import entry, outside

            outside = self._outside = entry(outside)
        return outside(q, self._q_min, self._q_max)

    def _on_hard_levels(self, kin: Kinematics, solution: Solution) -> Solution:
        """The step of a solve that starts with joints outside their range, ending on the hard
        levels (within :attr:`hard_tol`) at q ⊕ Δq, not only to first order: the longest
        q ⊕ t·Δq (:meth:`_longest_exact`) that :meth:`_restore_steps` brings back onto them
        within the solve's box (widened to Δq = 0 for the joints outside: never further out);
        where only t = 0 does (the fold below), the solve again with those joints held this
        once, the others free (the soft levels keep going). ``solution`` unchanged if none
        gets there.

        Why: the joints' way back yields to the hard tasks (:meth:`_solve_recovering`), and
        where the hard tasks as given cannot be met with those joints inside their range
        (double support: the contacts fix the soles' relative pose, which a start outside
        the limits made), the way back ends where the contacts stop it — a fold of the
        contact manifold, where the linearisation fails. There a tick's first-order step
        drifted the contacts 1–3 mm per tick, and the drift could not be undone without taking
        the joints back out (never allowed): "hard level 0 is infeasible" at tick 17 / 8
        (stress trials 1567, 8832: both ankle rolls 0.044 / 0.026 rad outside; the contacts
        allow them back to 0.020 rad). Held exactly, the way back stops at the fold and every
        tick stays feasible (Δq = 0 meets the hard levels)."""
        q0 = kin.q.copy()
        lower, upper = solution.lower.copy(), solution.upper.copy()
        np.minimum(lower[6:], 0.0, out=lower[6:])
        np.maximum(upper[6:], 0.0, out=upper[6:])
        hard_tasks = [t for lv in self.stack.levels if lv.hard for t in lv.active_tasks()]
        kept = [t.last_error for t in hard_tasks]  # the solve's errors (the pose reads them)
        dq = np.clip(solution.dq, lower, upper)
        found = self._longest_exact(kin, dq, lower, upper, stop=False)
        if found is None or found[1] == 0.0:
            # at the fold every step that brings a joint outside back drifts off: the
            # joints outside held this once, the others free (the soft levels keep going)
            j = q0[7:]
            held = 6 + np.flatnonzero((j < self._q_min) | (j > self._q_max))
            low, up = lower.copy(), upper.copy()
            low[held] = up[held] = 0.0
            try:
                dq_held, unmet = self._recover(kin, low, up, _NO_JOINTS, _EMPTY, True)
            except WbcError:
                unmet = ["failed"]
            if not unmet:
                moved = self._longest_exact(kin, np.clip(dq_held, low, up), low, up, stop=True)
                if moved is not None:
                    found = moved
        kin.update(q0)
        for task, e in zip(hard_tasks, kept, strict=True):
            task.last_error = e
        if found is None:
            return solution
        return Solution(self.robot.difference(q0, found[0]), lower, upper)

    def _longest_exact(
        self, kin: Kinematics, dq: np.ndarray, lower: np.ndarray, upper: np.ndarray, stop: bool
    ) -> tuple[np.ndarray, float] | None:
        """(q, t): q ⊕ t·dq for the first t of 1, ½, … (:data:`WAY_BACK_HALVINGS`), then 0,
        that :meth:`_restore_steps` brings onto the hard levels within [lower, upper] (from
        ``kin``'s q; its trust region :data:`HARD_PROJECTION_TRUST`), that point; None if none
        does. ``stop``: not t = 0. ``kin`` left at q."""
        q0 = kin.q.copy()
        for t in (*(0.5**k for k in range(WAY_BACK_HALVINGS)), *(() if stop else (0.0,))):
            self._spend()  # (inside a solve_pose: its time budget checked at every try)
            q_t = self._move_joints(q0, t * dq)
            kin.update(q_t)
            errors = self._hard_errors(kin)
            kin.update(q0)
            if max(errors, default=0.0) > self.hard_tol:
                q_t, errors = self._restore_steps(
                    kin, lower, upper, errors, 0.0, q_t, HARD_PROJECTION_TRUST, WAY_BACK_STEPS
                )
            if max(errors, default=0.0) <= self.hard_tol:
                return q_t, t
        return None

    def _restore_hard(
        self, kin: Kinematics, lower: np.ndarray, upper: np.ndarray
    ) -> np.ndarray | None:
        """Δq within [lower, upper] (this tick's box) that brings the hard levels back within
        :attr:`hard_tol` *at q ⊕ Δq*, by Gauss–Newton steps re-linearised at each iterate
        (:meth:`_restore_steps`); None if the steps do not get there.

        The last resort of an infeasible tick whose hard levels the re-solves cannot meet in
        one linearisation: a hard contact's second-order drift after a tick at servo speed
        (1–5 mm) whose full correction, linearised, takes a self-collision pair that sits at
        its margin inside it, while the configuration one tick back met both (stress trials
        771, 1271: the feet side by side in double support). The tick then spends itself on
        the hard levels (the soft ones wait a tick), as a joint outside its range moves back
        first; nothing hard is given up.

        If the steps cannot get there with the inequality rows held (at their bare bound),
        they are tried again with the rows loosened by the hard error at q, ε, at most
        :data:`RESTORE_SLACK`: undoing a drift of ε may take a pair that sits at its margin up
        to ε (to first order) inside it, never more. Stress trials 4888, 5101: the feet 4.99
        mm apart, a distance the two hard contacts fix, drifted to 5.01 / 5.15 mm, outside
        the margin, and held there the contacts' way back stalled 4e-6 m short; 436: a foot
        and the other ankle 5.001 mm apart, the contacts 6e-5 m off, and the way back with
        the pair held was a 0.075 rad detour the box did not allow. A pair so taken inside
        moves back out at the damper's rate from the next tick on."""
        q0 = kin.q.copy()
        start_errors = self._hard_errors(kin)  # (_restore_steps leaves kin at q0)
        q, errors = self._restore_steps(kin, lower, upper, start_errors, 0.0)
        if max(errors, default=0.0) > self.hard_tol:
            # undoing the drift may cost the rows at most the drift's own size
            slack = min(max(start_errors, default=0.0), RESTORE_SLACK)
            q_s, errors_s = self._restore_steps(kin, lower, upper, start_errors, slack)
            if max(errors_s, default=0.0) < max(errors, default=0.0):
                q, errors = q_s, errors_s
        kin.update(q0)
        if max(errors, default=0.0) <= self.hard_tol:
            return self.robot.difference(q0, q)
        return None

    def _restore_steps(
        self,
        kin: Kinematics,
        lower: np.ndarray,
        upper: np.ndarray,
        errors: list[float],
        slack: float,
        q_start: np.ndarray | None = None,
        trust: float = 0.0,
        max_steps: int = HARD_PROJECTION_STEPS,
    ) -> tuple[np.ndarray, list[float]]:
        """The Gauss–Newton steps of :meth:`_restore_hard` from ``q_start`` (default: ``kin``'s
        configuration q0; the hard levels' ``errors`` there), the hard rows loosened by
        ``slack``, the joints' total motion from q0 within [``lower``, ``upper``]: (q,
        errors); ``kin`` left at q0."""
        q0 = kin.q.copy()
        q = q0 if q_start is None else q_start
        total = np.zeros(self.robot.nv)
        total[6:] = q[7:] - q0[7:]
        stalls = 0
        for _ in range(max_steps):
            if max(errors, default=0.0) <= self.hard_tol:
                break
            if self._budget is None and self.recovery_steps >= TICK_RECOVERY_STEPS:
                break  # a tick's work is bounded (a pose has its own budget)
            self.recovery_steps += 1
            self._spend()  # (inside a solve_pose: its time budget, at every step)
            kin.update(q)
            problems, held = self._hard_problems(kin)
            problems += self._weighted_rows(kin)
            if slack:
                problems = [_loosened(p, slack) for p in problems]
            box_lower, box_upper = lower - total, upper - total
            if trust:  # a trust region too (:data:`HARD_PROJECTION_TRUST`)
                np.maximum(box_lower, -trust, out=box_lower)
                np.minimum(box_upper, trust, out=box_upper)
            delta = self._hard_step(q, [*problems, held], box_lower, box_upper)
            worst = max(errors)
            step = self._halved_step(kin, q, delta, lambda e, w=worst: max(e) < w)
            if step is None:
                break
            q, errors, _ = step
            stalls = stalls + 1 if max(errors) > RESTORE_STALL * worst else 0
            total[6:] = q[7:] - q0[7:]
            if stalls == RESTORE_STALLS:  # converging is quadratic
                break
        kin.update(q0)
        return q, errors

    def _weighted_rows(self, kin: Kinematics) -> list[LevelProblem]:
        """The weighted QP's other hard rows for :meth:`_restore_hard`: it holds the
        constraints of every level (e.g. the swing sole's ground clearance), the hierarchy
        only those of its hard levels. One hard level after those, the rows at their bare
        bound and those violated at ``kin`` no worse (a corner below the ground no lower)."""
        if self.lexicographic:
            return []
        constraints = [
            c for lv in self.stack.levels if not lv.hard for c in lv.active_constraints()
        ]
        if not constraints:
            return []
        nv = self.robot.nv
        rows = split_rows(constraints, kin, nv, recovering=True)
        G = np.vstack([rows.G, rows.G_inside])
        h = np.concatenate([rows.h, np.zeros(rows.h_inside.size)])
        return [LevelProblem(1 << 28, _no_jacobian(nv), _EMPTY, G, h, hard=True)]

    def _recover(
        self,
        kin: Kinematics,
        lower: np.ndarray,
        upper: np.ndarray,
        out: np.ndarray,
        back: np.ndarray,
        recovering: bool,
    ) -> tuple[np.ndarray, list[str]]:
        """One re-solve of :meth:`_solve_recovering` (``recovering``: the hard rows at their
        bare bound, :meth:`~wbc.limits.Constraint.split`): Δq and the messages of the hard
        levels it leaves unmet."""
        nv = self.robot.nv
        levels = self.stack.levels
        hard, soft, asks = [], [], []
        if self.lexicographic:
            for lv in levels:
                block = TaskBlock(lv.active_tasks(), nv)
                rows = split_rows(lv.active_constraints(), kin, nv, recovering and lv.hard)
                if lv.hard:
                    block.fill_into(kin, block.J, block.b)
                    asks.append(rows)
                    hard.append(_level(lv.priority, block, rows, hard=True))
                else:  # a soft level's rows are soft anyway: all of them, as in the solver
                    block.fill_weighted(kin)
                    G = np.vstack([rows.G, rows.G_inside])
                    h = np.concatenate([rows.h, rows.h_inside])
                    soft.append(LevelProblem(lv.priority, block.J, block.b, G, h))
        else:
            block = TaskBlock([t for lv in levels if lv.hard for t in lv.active_tasks()], nv)
            block.fill_into(kin, block.J, block.b)
            constraints = [c for lv in levels for c in lv.active_constraints()]
            rows = split_rows(constraints, kin, nv, recovering)
            asks.append(rows)
            hard.append(_level(0, block, rows, hard=True))
            block = TaskBlock([t for lv in levels if not lv.hard for t in lv.active_tasks()], nv)
            block.fill_weighted(kin)
            soft.append(LevelProblem(1 << 30, block.J, block.b, *_no_rows(nv)))
        inside = sum(r.h_inside.size for r in asks)
        recovery = []
        if out.size:
            J = np.zeros((out.size, nv))
            J[np.arange(out.size), 6 + out] = 1.0
            recovery.append(LevelProblem(-1, J, back, *_no_rows(nv)))
        relax = self.on_infeasible == "relax"
        if inside:  # their best separation below the hard levels and the way back
            G_in = np.vstack([r.G_inside for r in asks])
            h_in = np.concatenate([r.h_inside for r in asks])
            # no pair closer than now first (HOLD_WEIGHT), then the damper's rate: one
            # pair may not approach so that another separates faster
            G_in = np.vstack([HOLD_WEIGHT * G_in, G_in])
            h_in = np.concatenate([HOLD_WEIGHT * np.maximum(h_in, 0.0), h_in])
            first = [*hard, *recovery, LevelProblem(-1, _no_jacobian(nv), _EMPTY, G_in, h_in)]
            best, _ = solve_cascade_or_daqp(
                first, lower, upper, self._backends_for(first), final_regularization=1e-12,
                relax=relax,
            )  # fmt: skip
            # then held there, a hair looser (SEPARATION_SLACK): rows held exactly at their
            # best are often pinned against a joint bound, which makes the lower levels'
            # active sets degenerate
            hard = [_with_requests(p, r, best) for p, r in zip(hard, asks, strict=True)]
        problems = [
            *hard,
            *recovery,
            *(soft or [LevelProblem(1 << 30, _no_jacobian(nv), _EMPTY, *_no_rows(nv))]),
        ]
        dq, sols = solve_cascade_or_daqp(
            problems, lower, upper, self._backends_for(problems),
            final_regularization=self.regularization, relax=relax,
        )  # fmt: skip
        unmet = [
            infeasible_message(p, sol, self.hard_tol)
            for p, sol in zip(hard, sols, strict=False)
            if max(abs(sol.residual).max(initial=0.0), sol.slack.max(initial=0.0)) > self.hard_tol
        ]
        return dq, unmet

    @staticmethod
    def _backends_for(problems: list) -> list[QPBackend]:
        """One DAQP backend per level, whatever the solver's backend, for the rare re-solves
        of infeasible ticks (the recovery, the diagnosis and ``on_infeasible="relax"``): an
        exact active set (a first-order backend's iteration caps on these degenerate
        levels cost seconds per tick, to fall back to DAQP in the end)."""
        return [make_backend("daqp") for _ in problems]

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
        Solves once at q with the current targets; counts no tick."""
        ticks = self.compiled_ticks, self.handed_back_ticks, self.interim_ticks
        try:
            self.solve(q, dt)
        except WbcError:
            pass  # targets not set yet may be infeasible: the layout is built all the same
        self.compiled_ticks, self.handed_back_ticks, self.interim_ticks = ticks

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
        check_dt(dt, "step")
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
        max_projection_steps: int | None = None,
        time_budget: float | None = None,
    ) -> PoseResult:
        """Iterate Δq until every task error is below ``tol``, or the steps stall (max |Δq| <
        ``stall_tol``: a weighted compromise or an unreachable target has its fixed point).

        The hard levels hold at the end, not only to first order: a step is one QP on the
        linearised tasks, so a long step (an unreachable or upside-down target pulls hard on
        the soft levels) leaves the hard tasks a second-order residual. An iterate whose hard
        residual grew beyond :data:`HARD_ITERATE_TOL` (or whose hard levels the QP can no
        longer meet within the joint limits) is projected back onto the hard levels
        (:meth:`project_hard`), the step halved while that is not enough; the final pose is
        projected to min(``tol``, :data:`HARD_POSE_TOL`).

        A final guard: every hard level ends within that tolerance (task errors, and
        the violation of its inequality rows other than those of self-collision pairs inside
        their margin): where no projection of the last iterate gets there, the pose ends at
        the last iterate that held them (the start, if none since; ``converged`` False), and
        InfeasibleError is raised only if none did — a pose is never returned off a hard
        contact. With ``on_infeasible="relax"`` the levels from the first one that was not
        met at the start (a relaxed, unreachable level) down are exempt.

        **Bounded time.** Every QP solve has a bounded time (the backends' iteration caps),
        and a pose does a bounded amount of work: at most ``max_iterations`` iterations, each
        one QP solve and, where its step must be shortened, at most
        :data:`HARD_PROJECTION_HALVINGS` more; and at most ``max_projection_steps``
        Gauss–Newton steps in all its projections onto the hard levels (default
        :data:`POSE_PROJECTION_STEPS` × (``max_iterations`` + 1) × the number of hard
        levels), each one cascade of QPs and at most :data:`HARD_PROJECTION_HALVINGS`
        evaluations of the hard levels (an iterate's projection that stalls stops early:
        :data:`PROJECTION_STALL`). ``time_budget`` (s): a wall-time limit too, checked before
        every QP solve and Gauss–Newton step (None: none; the result then depends only on the
        input). A spent budget raises SolverError naming it.

        This is the per-pose iterative mode used to compare with the thesis's solutions.
        """
        start = time.perf_counter()
        if max_projection_steps is not None and not (
            isinstance(max_projection_steps, (int, np.integer)) and max_projection_steps > 0
        ):
            raise ConfigurationError(
                f"max_projection_steps must be a positive integer or None, "
                f"got {max_projection_steps!r}"
            )
        if time_budget is not None and not (
            isinstance(time_budget, (int, float, np.number))
            and math.isfinite(time_budget)
            and time_budget > 0
        ):
            raise ConfigurationError(
                f"time_budget must be a positive number of seconds or None, got {time_budget!r}"
            )
        hard_levels = sum(lv.hard for lv in self.stack.levels)
        if max_projection_steps is None:
            max_projection_steps = POSE_PROJECTION_STEPS * (max_iterations + 1) * hard_levels
        budget = _PoseBudget(max_projection_steps, time_budget)
        q = self.robot.check_configuration(q).copy()
        self._budget = budget
        try:
            return self._iterate_pose(q, tol, max_iterations, dt, stall_tol, start)
        finally:
            self._budget = None

    def _iterate_pose(
        self,
        q: np.ndarray,
        tol: float,
        max_iterations: int,
        dt: float | None,
        stall_tol: float,
        start: float,
    ) -> PoseResult:
        """The iterations of :meth:`solve_pose` (its budget in :attr:`_budget`)."""
        pose_tol = min(tol, HARD_POSE_TOL)
        self.kin.update(q)
        start_errors = self._hard_errors(self.kin)
        converged = False
        it = 0
        q_prev = dq_prev = errors_prev = None
        # the last iterate whose hard tasks were within pose_tol (the start first): where the
        # end cannot be brought back onto the hard levels, the pose ends there, not converged
        held = q.copy() if max(start_errors, default=0.0) <= pose_tol else None
        for it in range(1, max_iterations + 1):
            self._spend(iteration=it)
            try:
                dq = self.solve(q, dt)
                errors = self._hard_errors_of_last_solve()
                back = q_prev is not None and _worse(errors, errors_prev)
            except InfeasibleError:
                if q_prev is None:
                    raise
                back = True
            if back:
                q, dq, errors = self._shorter_step(q_prev, dq_prev, errors_prev, tol, dt)
            if max(errors, default=0.0) <= pose_tol:
                held = q
            if self._converged(tol):
                converged = True
                it -= 1
                break
            q_prev, dq_prev, errors_prev = q, dq, errors
            q = self.integrate(q, dq)
            if abs(dq).max() < stall_tol:
                break
        aim = min(pose_tol, HARD_POSE_AIM)
        q_end, errors = self._project(q, aim)
        if q_prev is not None and any(e > pose_tol for e in errors):
            # the last step (never checked by a solve) left what the projection cannot undo
            # within the joint limits: the longest fraction of it that can be (none of it:
            # the iterate before)
            for t in [*(0.5**k for k in range(1, HARD_PROJECTION_HALVINGS + 1)), 0.0]:
                q_end, errors = self._project(self._move_joints(q_prev, t * dq_prev), aim)
                if all(e <= pose_tol for e in errors):
                    break
        if pose_tol < max(errors, default=0.0) <= RESTORE_SLACK:
            # last resort, as a tick's restoration (:meth:`_restore_hard`): the rows loosened
            # by the drift the projection undoes (stress trial 4169: a pair at its margin
            # stopped every projection 1.7e-6 m off the contacts)
            self.kin.update(q)
            drift = min(max(self._hard_errors(self.kin), default=0.0), RESTORE_SLACK)
            loose = self._project(q, pose_tol, slack=drift)
            if max(loose[1], default=0.0) < max(errors):
                q_end, errors = loose
        fell_back = False
        if held is not None and self._off_hard_levels(errors, start_errors, pose_tol):
            # no projection of the end holds the hard levels (the guard raised on feasible
            # poses: 3 of 2,000 in issue 28's run): the last iterate that held them, which a
            # caller may take as it is (not converged) or start from again
            self.kin.update(held)
            held_errors = self._hard_errors(self.kin)
            if not self._off_hard_levels(held_errors, start_errors, pose_tol):
                q_end, errors, fell_back, converged = held, held_errors, True, False
        self._guard_hard_levels(errors, start_errors, pose_tol)
        q = q_end
        self.kin.update(q)
        errors = self.stack.evaluate(self.kin)
        if not converged and not fell_back:
            converged = all(
                float(np.max(np.abs(errors[t.name]))) <= tol
                for t in self.stack.tasks()
                if t.active and t.blocks_convergence
            )
        steps = self._budget.steps if self._budget is not None else 0
        return PoseResult(q, it, converged, errors, time.perf_counter() - start, steps, fell_back)

    def _spend(self, steps: int = 0, iteration: int | None = None) -> None:
        """Count ``steps`` Gauss–Newton steps against the budget of the running
        :meth:`solve_pose` (none outside one) and raise SolverError if it is spent, or if
        its time budget is; ``iteration``: the iteration it has reached (for the message)."""
        b = self._budget
        if b is None:
            return
        if iteration is not None:
            b.iteration = iteration
        b.steps += steps
        spent = ""
        if b.steps > b.max_steps:
            spent = (
                f"its {b.max_steps} Gauss–Newton steps onto the hard levels (max_projection_steps)"
            )
        elif b.seconds is not None and time.perf_counter() - b.start > b.seconds:
            spent = f"its time budget of {b.seconds:g} s (time_budget)"
        if spent:
            raise SolverError(
                f"{self.name}: solve_pose spent {spent} at iteration {b.iteration} "
                f"({b.steps} Gauss–Newton steps, {time.perf_counter() - b.start:.3g} s)"
            )

    def _off_hard_levels(
        self, errors: list[float], start: list[float], tol: float
    ) -> list[tuple[int, float]]:
        """(index, error) of each hard level a converged pose must hold that ``errors`` leave
        beyond ``tol`` (see :meth:`solve_pose`); ``start``: the levels' errors at the start."""
        held = len(errors)
        if self.on_infeasible == "relax":
            held = next((k for k, e in enumerate(start) if e > tol), held)
        return [(k, e) for k, e in enumerate(errors[:held]) if e > tol]

    def _guard_hard_levels(self, errors: list[float], start: list[float], tol: float) -> None:
        """Raise InfeasibleError if a hard level a converged pose must hold ends beyond
        ``tol`` (see :meth:`solve_pose`); ``start``: the levels' errors at the start."""
        off = self._off_hard_levels(errors, start, tol)
        if off:
            priorities = [lv.priority for lv in self.stack.levels if lv.hard]
            raise InfeasibleError(
                f"{self.name}: the converged pose ends off its hard levels "
                + ", ".join(f"{priorities[k]} (error {e:.3g})" for k, e in off)
                + f", more than {tol:g}, and no shorter last step holds them"
            )

    def _shorter_step(self, q_prev, dq_prev, before, tol: float, dt) -> tuple:
        """(q, Δq, hard errors) from q_prev ⊕ t·Δq_prev projected onto the hard levels, for
        the largest t in 1, ½, ¼, ... at which the QP meets the hard levels and leaves them no
        worse than at q_prev: near the joint limits a long step's second-order residual may
        be beyond what the limits let the projection or the QP undo, a shorter step's is not.
        Raises the QP's InfeasibleError if even the shortest step fails."""
        failure = None
        for k in range(HARD_PROJECTION_HALVINGS):
            q_k = self._move_joints(q_prev, 0.5**k * dq_prev)
            q, projected = self._project(q_k, tol, stop_stalled=True)
            if k < HARD_PROJECTION_HALVINGS - 1 and _worse(projected, before):
                failure = None  # worse already: the QP's check would reject it
                continue
            self._spend()
            try:
                dq = self.solve(q, dt)
            except InfeasibleError as exc:
                failure = exc
                continue
            errors = self._hard_errors_of_last_solve()
            if not _worse(errors, before):
                return q, dq, errors
            failure = None
        if failure is not None:
            raise failure
        return q, dq, errors

    def _hard_errors_of_last_solve(self) -> list[float]:
        """Each hard level's largest task error at the last solve (the tasks' last errors;
        the violation of its inequality rows is not kept by a solve: the final guard checks
        it. Skipping the levels with rows, as before, left the walk stack's iterates
        unchecked: contacts drifting off until the end's projection could not bring them
        back)."""
        return [
            max((float(abs(t.last_error).max()) for t in lv.active_tasks()), default=0.0)
            for lv in self.stack.levels
            if lv.hard
        ]

    def _hard_errors(self, kin: Kinematics) -> list[float]:
        """Each hard level's largest task error and inequality violation at ``kin`` (the
        rows of self-collision pairs inside their margin ask for a motion, which is the
        steps' business, not the pose's: :func:`split_rows`). The constraints whose held
        rows Δq = 0 always meets (:attr:`~wbc.limits.Constraint.held_rows_met`) are not
        computed: this runs at every trial point of the projections' line search, and the
        self-collision rows were 85 % of a slow pose's time (stress trial 3972)."""
        out = []
        for lv in self.stack.levels:
            if not lv.hard:
                continue
            worst = 0.0
            for t in lv.active_tasks():
                worst = max(worst, float(abs(t.compute_error(kin)[t.mask]).max()))
            rows = [c for c in lv.active_constraints() if not c.held_rows_met]
            h = split_rows(rows, kin, self.robot.nv).h
            if h.size:
                worst = max(worst, float(-h.min()))
            out.append(worst)
        return out

    def _hard_problems(self, kin: Kinematics) -> tuple[list[LevelProblem], LevelProblem]:
        """The hard levels' rows at ``kin``, unweighted and at gain 1 (the whole error), and
        a last level with the rows of the self-collision pairs inside their margin held
        (G δ <= 0 in least squares: no closer, as far as the hard levels allow)."""
        nv = self.robot.nv
        problems, inside = [], []
        for lv in self.stack.levels:
            if not lv.hard:
                continue
            tasks = lv.active_tasks()
            rows = [t.compute(kin) for t in tasks]
            J = np.vstack([r[0] for r in rows]) if rows else np.zeros((0, nv))
            e = np.concatenate([r[1] for r in rows]) if rows else np.zeros(0)
            split = split_rows(lv.active_constraints(), kin, nv, recovering=True)
            inside.append(split.G_inside)
            problems.append(LevelProblem(lv.priority, J, e, split.G, split.h, hard=True))
        G_in = np.vstack(inside) if inside else np.zeros((0, nv))
        held = LevelProblem(1 << 29, np.zeros((0, nv)), np.zeros(0), G_in, np.zeros(len(G_in)))
        return problems, held

    def project_hard(
        self, q: np.ndarray, tol: float = 1e-9, max_steps: int = HARD_PROJECTION_STEPS
    ) -> np.ndarray:
        """q moved onto the hard levels, one level after the other: for level k, Gauss–Newton
        steps δ = argmin ‖δ‖ subject to the hard levels 0..k in priority order (J_j δ = e_j in
        least squares over the null space of the levels above, their inequalities), the
        joint limits and a trust region (:data:`HARD_PROJECTION_TRUST`), each step halved
        until it reduces level k's error without raising a level above it beyond ``tol``. A
        level that cannot be met (relaxed) keeps the best it reaches and ends the projection;
        it never costs a level above it."""
        return self._project(q, tol, max_steps)[0]

    def _project(
        self,
        q: np.ndarray,
        tol: float,
        max_steps: int = HARD_PROJECTION_STEPS,
        stop_stalled: bool = False,
        slack: float = 0.0,
    ) -> tuple[np.ndarray, list[float]]:
        """:meth:`project_hard` and the hard levels' errors at the result (kin left there;
        each step within :data:`HARD_PROJECTION_TRUST`); ``stop_stalled``: a level's steps
        stop where they stall (:data:`PROJECTION_STALL`); the hard levels' inequality rows
        loosened by ``slack`` (:meth:`solve_pose`'s last resort). Each Gauss–Newton step
        counts against the running :meth:`solve_pose`'s budget."""
        kin = self.kin
        kin.update(q)
        errors = self._hard_errors(kin)
        trust = np.full(self.robot.nv, HARD_PROJECTION_TRUST)
        for k in range(len(errors)):
            stalls = 0
            for _ in range(max_steps):
                if errors[k] <= tol:
                    break
                self._spend(1)
                kin.update(q)
                problems, held = self._hard_problems(kin)
                if slack:
                    problems = [_loosened(p, slack) for p in problems]
                delta = self._hard_step(q, [*problems[: k + 1], held], -trust, trust)
                step = self._halved_step(
                    kin,
                    q,
                    delta,
                    lambda e, k=k, before=errors: (
                        e[k] < before[k] and all(e[j] <= max(before[j], tol) for j in range(k))
                    ),
                )
                if step is None:
                    break
                was = errors[k]
                q, errors, t = step
                if t * abs(delta).max() < 1e-13:
                    break
                stalls = stalls + 1 if errors[k] > PROJECTION_STALL * was else 0
                if stop_stalled and stalls == PROJECTION_STALLS:
                    break
            if errors[k] > tol:
                break  # an unmet (relaxed) level: the levels below have no exact target left
        if kin.q is not q:  # the last evaluation was of a rejected trial
            kin.update(q)
        return q, errors

    def _halved_step(
        self,
        kin: Kinematics,
        q: np.ndarray,
        delta: np.ndarray,
        accept: Callable[[list[float]], bool],
    ) -> tuple[np.ndarray, list[float], float] | None:
        """The line search of the projections onto the hard levels: the first of q ⊕ t·δ,
        t = 1, ½, ¼, … (:data:`HARD_PROJECTION_HALVINGS` tries) whose hard levels' errors
        ``accept`` takes, as (q_t, its errors, t), ``kin`` left at q_t; None if none is
        (``kin`` left at the last trial)."""
        t = 1.0
        for _ in range(HARD_PROJECTION_HALVINGS):
            q_t = self._move_joints(q, t * delta)
            kin.update(q_t)
            e_t = self._hard_errors(kin)
            if accept(e_t):
                return q_t, e_t, t
            t *= 0.5
        return None

    def _hard_step(
        self,
        q: np.ndarray,
        problems: list[LevelProblem],
        box_lower: np.ndarray | None = None,
        box_upper: np.ndarray | None = None,
    ) -> np.ndarray:
        """One Gauss–Newton step onto the given levels (minimum-norm, joint limits; within
        [``box_lower``, ``box_upper``] too where given, e.g. what is left of a tick's box)."""
        nv = self.robot.nv
        lower, upper = np.full(nv, -np.inf), np.full(nv, np.inf)
        self.stack.position_limit.joint_bounds_into(q[7:], lower[6:], upper[6:])
        np.minimum(lower[6:], 0.0, out=lower[6:])  # a joint outside its range may stay
        np.maximum(upper[6:], 0.0, out=upper[6:])
        if box_lower is not None and box_upper is not None:
            np.maximum(lower, np.minimum(box_lower, 0.0), out=lower)
            np.minimum(upper, np.maximum(box_upper, 0.0), out=upper)
        none = np.zeros((0, nv))
        levels = [*problems, LevelProblem(1 << 30, none, np.zeros(0), none, np.zeros(0))]
        # DAQP whatever the solver's backend: an exact active set (a first-order backend's
        # 1e-6 accuracy would stop the projection short of its 1e-10)
        hard = [p for p in problems if p.hard]
        delta = np.zeros(nv)  # no step: the projection stops where it is
        # DAQP can cycle (exit flag −2) on the least squares of the rows held after the hard
        # levels (the pairs inside their margin no closer: 340 degenerate rows in stress
        # trial 4875's last projection, which then stopped 1.3e-6 m off its contact): the
        # hard levels alone then (such a pair may approach by the step's first order)
        for attempt in (levels, [*hard, levels[-1]]) if len(hard) < len(problems) else (levels,):
            backends = [make_backend("daqp") for _ in attempt]
            try:
                delta, _ = solve_cascade(attempt, lower, upper, backends, relax=True)
                break
            except WbcError:
                continue
        return delta if np.isfinite(delta).all() else np.zeros(nv)

    def _move_joints(self, q: np.ndarray, delta: np.ndarray) -> np.ndarray:
        """q ⊕ δ with the joints kept in [min(q_min, q_j), max(q_max, q_j)]."""
        q_next = self.robot.integrate(q, delta)
        j, j_prev = q_next[7:], q[7:]
        np.clip(j, np.minimum(self._q_min, j_prev), np.maximum(self._q_max, j_prev), out=j)
        return q_next

    def _converged(self, tol: float) -> bool:
        return all(
            abs(t.last_error).max() <= tol
            for t in self.stack.tasks()
            if t.active and t.blocks_convergence
        )

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

    def _switch_layout(self, build: Callable[[], Any]) -> Any:
        """The layout of the stack as it is now (its :attr:`TaskStack.revision` moved): the one
        kept for its :meth:`_layout_key`, else ``build()`` (kept). A kept layout entered again
        starts its active sets afresh (:meth:`wbc.solvers.plan._Plan.forget_warm_start`):
        those of its last visit (a support phase ago, at another configuration) are a worse
        start than none (the hierarchy's first tick of a phase took twice as long from them;
        benchmarks/qp_tick.md)."""
        key = self._layout_key()
        layout = self._layouts.get(key)
        if layout is None:
            if len(self._layouts) >= 16:  # a stack edited in many ways: start afresh
                self._layouts.clear()
            layout = self._layouts[key] = build()
        else:
            plan = layout.fast
            if plan is not None and plan is not self.fast:
                plan.forget_warm_start(self.fast)
        self._key = self.stack.revision
        return layout

    # ------------------------------------------------------------------ compiled path
    @property
    def plan_scratch(self):
        """The work arrays that the compiled plans of this solver's layouts share."""
        if self._plan_scratch is None:
            from .plan import Scratch

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


def _no_jacobian(nv: int) -> np.ndarray:
    """No task rows over nv variables."""
    return np.zeros((0, nv))


def _with_requests(problem: LevelProblem, rows: SplitRows, dq: np.ndarray) -> LevelProblem:
    """A hard level with the requests of its self-collision pairs inside the margin added as
    rows held where ``dq`` (their best achievable separation) leaves them, plus
    :data:`SEPARATION_SLACK`."""
    if not rows.h_inside.size:
        return problem
    G_in = rows.G_inside
    h_in = np.maximum(rows.h_inside, G_in @ dq) + SEPARATION_SLACK
    m = problem.h.size
    named = (_INSIDE, slice(m, m + h_in.size))
    return LevelProblem(
        problem.priority, problem.J, problem.b, np.vstack([problem.G, G_in]),
        np.concatenate([problem.h, h_in]), problem.hard, problem.task_rows,
        [*problem.constraint_rows, named],
    )  # fmt: skip


def _loosened(problem: LevelProblem, slack: float) -> LevelProblem:
    """``problem`` with its inequality rows loosened by ``slack``."""
    if not problem.h.size:
        return problem
    return LevelProblem(
        problem.priority, problem.J, problem.b, problem.G, problem.h + slack, problem.hard,
        problem.task_rows, problem.constraint_rows,
    )  # fmt: skip


def _level(priority: int, block: TaskBlock, rows: SplitRows, hard: bool) -> LevelProblem:
    """A level of the block's rows (as filled) and the held rows of ``rows``."""
    return LevelProblem(priority, block.J, block.b, rows.G, rows.h, hard, block.slices, rows.slices)
