"""Pose iteration beside the solver: :func:`solve_pose` iterates a solver's QP on one pose
until the task errors converge, projecting its iterates onto the hard levels
(:class:`~wbc.solvers.projection.HardLevels`) where a long step leaves them a second-order
residual, within a bounded work budget. The loop lives outside the solver, as pink's and
mink's do; :meth:`wbc.solvers.StackSolver.solve_pose` calls it."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..exceptions import ConfigurationError, InfeasibleError
from ..model import Kinematics, Robot
from .budget import PoseBudget, Work
from .projection import HARD_PROJECTION_HALVINGS, HardLevels
from .recovery import RESTORE_SLACK
from .stack import TaskStack

#: hard-task error (m, rad) beyond which :func:`solve_pose` projects an iterate
#: back onto the hard levels (smaller residuals the next QP step corrects to second order;
#: 1e-3 let double-support iterates drift 1e-4 off where the joint limits and the collision
#: rows no longer let the QP or the final projection close the chain: stress trials 384, 584)
HARD_ITERATE_TOL = 1e-4
#: largest hard-task error at the end of :func:`solve_pose`
HARD_POSE_TOL = 1e-6
#: what the final projection of :func:`solve_pose` aims at (m, rad): below its
#: tolerance, as far as its steps still reduce the error (a step short of the quadratic one
#: can stop it just under 1e-6; the guard checks the tolerance)
HARD_POSE_AIM = 1e-9
#: the default work budget of :func:`solve_pose`: this many Gauss–Newton steps of
#: its projections onto the hard levels per iteration and hard level
POSE_PROJECTION_STEPS = 100


def _worse(errors: list[float] | None, before: list[float] | None) -> bool:
    """True if a hard level's error grew beyond max(its error before, HARD_ITERATE_TOL)."""
    if errors is None or before is None:
        return False
    return any(e > max(b, HARD_ITERATE_TOL) for e, b in zip(errors, before, strict=True))


@dataclass
class PoseResult:
    """Outcome of :func:`solve_pose`."""

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


class PoseSolver(Protocol):
    """What :func:`solve_pose` uses of a solver (:class:`~wbc.solvers.base.StackSolver`)."""

    robot: Robot
    stack: TaskStack
    kin: Kinematics
    on_infeasible: str
    hard_levels: HardLevels
    work: Work

    @property
    def name(self) -> str: ...

    def solve(self, q: np.ndarray, dt: float | None = None) -> np.ndarray: ...

    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray: ...


def solve_pose(
    solver: PoseSolver,
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
    (:meth:`~wbc.solvers.StackSolver.project_hard`), the step halved while that is not
    enough; the final pose is projected to min(``tol``, :data:`HARD_POSE_TOL`).

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
    :data:`~wbc.solvers.projection.PROJECTION_STALL`). ``time_budget`` (s): a wall-time
    limit too, checked before every QP solve and Gauss–Newton step (None: none; the result
    then depends only on the input). A spent budget raises SolverError naming it.

    This is the per-pose iterative mode used to compare with the thesis's solutions.
    """
    start = time.perf_counter()
    if max_projection_steps is not None and not (
        isinstance(max_projection_steps, (int, np.integer)) and max_projection_steps > 0
    ):
        raise ConfigurationError(
            f"max_projection_steps must be a positive integer or None, got {max_projection_steps!r}"
        )
    if time_budget is not None and not (
        isinstance(time_budget, (int, float, np.number))
        and math.isfinite(time_budget)
        and time_budget > 0
    ):
        raise ConfigurationError(
            f"time_budget must be a positive number of seconds or None, got {time_budget!r}"
        )
    hard_levels = sum(lv.hard for lv in solver.stack.levels)
    if max_projection_steps is None:
        max_projection_steps = POSE_PROJECTION_STEPS * (max_iterations + 1) * hard_levels
    budget = PoseBudget(solver.name, max_projection_steps, time_budget)
    q = solver.robot.check_configuration(q).copy()
    solver.work.pose = budget
    try:
        return _iterate(solver, q, tol, max_iterations, dt, stall_tol, start)
    finally:
        solver.work.pose = None


def _iterate(
    solver: PoseSolver,
    q: np.ndarray,
    tol: float,
    max_iterations: int,
    dt: float | None,
    stall_tol: float,
    start: float,
) -> PoseResult:
    """The iterations of :func:`solve_pose` (its budget in ``solver.work``)."""
    hard = solver.hard_levels
    pose_tol = min(tol, HARD_POSE_TOL)
    solver.kin.update(q)
    start_errors = hard.errors(solver.kin)
    converged = False
    it = 0
    q_prev = dq_prev = errors_prev = None
    # the last iterate whose hard tasks were within pose_tol (the start first): where the
    # end cannot be brought back onto the hard levels, the pose ends there, not converged
    held = q.copy() if max(start_errors, default=0.0) <= pose_tol else None
    for it in range(1, max_iterations + 1):
        solver.work.spend(iteration=it)
        try:
            dq = solver.solve(q, dt)
            errors = hard.errors_of_last_solve()
            back = q_prev is not None and _worse(errors, errors_prev)
        except InfeasibleError:
            if q_prev is None:
                raise
            back = True
        if back:
            q, dq, errors = _shorter_step(solver, q_prev, dq_prev, errors_prev, tol, dt)
        if max(errors, default=0.0) <= pose_tol:
            held = q
        if _converged(solver.stack, tol):
            converged = True
            it -= 1
            break
        q_prev, dq_prev, errors_prev = q, dq, errors
        q = solver.integrate(q, dq)
        if abs(dq).max() < stall_tol:
            break
    aim = min(pose_tol, HARD_POSE_AIM)
    q_end, errors = hard.project(q, aim)
    if q_prev is not None and any(e > pose_tol for e in errors):
        # the last step (never checked by a solve) left what the projection cannot undo
        # within the joint limits: the longest fraction of it that can be (none of it:
        # the iterate before)
        for t in [*(0.5**k for k in range(1, HARD_PROJECTION_HALVINGS + 1)), 0.0]:
            q_end, errors = hard.project(hard.move_joints(q_prev, t * dq_prev), aim)
            if all(e <= pose_tol for e in errors):
                break
    if pose_tol < max(errors, default=0.0) <= RESTORE_SLACK:
        # last resort, as a tick's restoration (Recovery.restore_hard): the rows loosened
        # by the drift the projection undoes (stress trial 4169: a pair at its margin
        # stopped every projection 1.7e-6 m off the contacts)
        solver.kin.update(q)
        drift = min(max(hard.errors(solver.kin), default=0.0), RESTORE_SLACK)
        loose = hard.project(q, pose_tol, slack=drift)
        if max(loose[1], default=0.0) < max(errors):
            q_end, errors = loose
    fell_back = False
    if held is not None and _off_hard_levels(solver, errors, start_errors, pose_tol):
        # no projection of the end holds the hard levels (the guard raised on feasible
        # poses: 3 of 2,000 in issue 28's run): the last iterate that held them, which a
        # caller may take as it is (not converged) or start from again
        solver.kin.update(held)
        held_errors = hard.errors(solver.kin)
        if not _off_hard_levels(solver, held_errors, start_errors, pose_tol):
            q_end, errors, fell_back, converged = held, held_errors, True, False
    _guard_hard_levels(solver, errors, start_errors, pose_tol)
    q = q_end
    solver.kin.update(q)
    errors = solver.stack.evaluate(solver.kin)
    if not converged and not fell_back:
        converged = all(
            float(np.max(np.abs(errors[t.name]))) <= tol
            for t in solver.stack.tasks()
            if t.active and t.blocks_convergence
        )
    steps = solver.work.pose.steps if solver.work.pose is not None else 0
    return PoseResult(q, it, converged, errors, time.perf_counter() - start, steps, fell_back)


def _off_hard_levels(
    solver: PoseSolver, errors: list[float], start: list[float], tol: float
) -> list[tuple[int, float]]:
    """(index, error) of each hard level a converged pose must hold that ``errors`` leave
    beyond ``tol`` (see :func:`solve_pose`); ``start``: the levels' errors at the start."""
    held = len(errors)
    if solver.on_infeasible == "relax":
        held = next((k for k, e in enumerate(start) if e > tol), held)
    return [(k, e) for k, e in enumerate(errors[:held]) if e > tol]


def _guard_hard_levels(
    solver: PoseSolver, errors: list[float], start: list[float], tol: float
) -> None:
    """Raise InfeasibleError if a hard level a converged pose must hold ends beyond
    ``tol`` (see :func:`solve_pose`); ``start``: the levels' errors at the start."""
    off = _off_hard_levels(solver, errors, start, tol)
    if off:
        priorities = [lv.priority for lv in solver.stack.levels if lv.hard]
        raise InfeasibleError(
            f"{solver.name}: the converged pose ends off its hard levels "
            + ", ".join(f"{priorities[k]} (error {e:.3g})" for k, e in off)
            + f", more than {tol:g}, and no shorter last step holds them"
        )


def _shorter_step(solver: PoseSolver, q_prev, dq_prev, before, tol: float, dt) -> tuple:
    """(q, Δq, hard errors) from q_prev ⊕ t·Δq_prev projected onto the hard levels, for
    the largest t in 1, ½, ¼, ... at which the QP meets the hard levels and leaves them no
    worse than at q_prev: near the joint limits a long step's second-order residual may
    be beyond what the limits let the projection or the QP undo, a shorter step's is not.
    Raises the QP's InfeasibleError if even the shortest step fails."""
    hard = solver.hard_levels
    failure = None
    for k in range(HARD_PROJECTION_HALVINGS):
        q_k = hard.move_joints(q_prev, 0.5**k * dq_prev)
        q, projected = hard.project(q_k, tol, stop_stalled=True)
        if k < HARD_PROJECTION_HALVINGS - 1 and _worse(projected, before):
            failure = None  # worse already: the QP's check would reject it
            continue
        solver.work.spend()
        try:
            dq = solver.solve(q, dt)
        except InfeasibleError as exc:
            failure = exc
            continue
        errors = hard.errors_of_last_solve()
        if not _worse(errors, before):
            return q, dq, errors
        failure = None
    if failure is not None:
        raise failure
    return q, dq, errors


def _converged(stack: TaskStack, tol: float) -> bool:
    return all(
        abs(t.last_error).max() <= tol for t in stack.tasks() if t.active and t.blocks_convergence
    )
