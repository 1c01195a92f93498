"""Recovery of an infeasible tick: the re-solve that asks of a start outside the joint limits
or inside a constraint's margin only what the hard tasks leave possible, the restoration of
hard levels a tick's second order drifted off, and the way back onto the hard levels of a
step from outside the joint limits. :class:`~wbc.solvers.base.StackSolver` hands its
infeasible ticks to :class:`Recovery`."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from ..exceptions import InfeasibleError, SolverError, WbcError
from ..model import Kinematics
from ..types import Solution
from .assembly import TaskBlock
from .backends import daqp_for
from .budget import Work
from .cascade import LevelProblem, solve_cascade_or_daqp
from .diagnostics import infeasible_message
from .projection import HARD_PROJECTION_STEPS, HARD_PROJECTION_TRUST, HardLevels
from .rows import EMPTY, SplitRows, loosened, no_jacobian, no_rows, split_rows

#: the restoration of an infeasible tick (:meth:`Recovery.restore_hard`) stops after
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
#: t = 1, ½, … (this many), then 0 (:meth:`Recovery.on_hard_levels`)
WAY_BACK_HALVINGS = 7
#: at most this many Gauss–Newton steps bring each of those back onto the hard levels
#: (quadratic from a tick's second-order drift: two or three; a step that needs more is
#: one too long, the next halving is cheaper)
WAY_BACK_STEPS = 5
#: the most Gauss–Newton steps onto the hard levels that one solve outside
#: :meth:`StackSolver.solve_pose` (a control tick) spends bringing an infeasible start back
#: (:meth:`Recovery.restore_steps`: the restoration and the way back onto the hard levels
#: from outside the joint limits), each one cascade of DAQP levels and at most
#: :data:`HARD_PROJECTION_HALVINGS` evaluations of the hard levels. With it a tick's worst
#: case is stated: the solve, at most three recovery re-solves (one or two cascades each),
#: TICK_RECOVERY_STEPS such steps, 2 × (:data:`WAY_BACK_HALVINGS` + 1) more evaluations and,
#: where it still fails, the diagnosis (one cascade). Spent, the restoration stops where it
#: is: the tick raises InfeasibleError as any tick whose restoration fails, or keeps the
#: recovery's step (the way back). The most a tick of ``benchmarks/tick_tail.py`` spent:
#: benchmarks/stress.md
TICK_RECOVERY_STEPS = 40
#: how much looser than their best achievable way back (m) the rows of constraints violated at
#: the start (self-collision pairs inside their margin, sole corners below the ground) are held
#: by a tick that cannot meet them at their damper's rate
SEPARATION_SLACK = 1e-7
_INSIDE = "constraints violated at the start (their best way back)"
#: weight of "no closer than now" against "separate at the damper's rate" in the best
#: separation of the self-collision pairs inside their margin (one least-squares level)
HOLD_WEIGHT = 100.0
_NO_JOINTS = np.zeros(0, dtype=int)


class Undiagnosed(InfeasibleError):
    """An infeasible solve whose diagnosis (a cascade of QPs naming the rows in conflict, as
    long as the solve itself) runs only if the recovery re-solve cannot answer the tick
    (:meth:`Recovery.solve`): the error the caller then sees is the diagnosed one. Most such
    ticks recover (starts outside the limits or inside a collision margin), and the diagnosis
    was half of their time (issue 28)."""

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


class Settings(Protocol):
    """What the recovery reads of its solver (:class:`~wbc.solvers.base.StackSolver`), at
    each call: the settings a tick's re-solves share with its solve."""

    hard_tol: float
    on_infeasible: str
    regularization: float
    lexicographic: bool

    def compute_bounds(
        self, kin: Kinematics, dt: float | None, lower: np.ndarray, upper: np.ndarray
    ) -> None: ...


class Recovery:
    """The recovery of a solver's infeasible ticks (its ``settings``), its Gauss–Newton steps
    by ``hard`` (the solver's :class:`~wbc.solvers.projection.HardLevels`) and counted by
    ``work``."""

    def __init__(self, settings: Settings, hard: HardLevels, work: Work) -> None:
        self.settings = settings
        self.hard = hard
        self.work = work
        self.stack = hard.stack
        self.robot = hard.robot

    def solve(self, kin: Kinematics, dt: float | None, exc: WbcError) -> tuple[Solution, list[str]]:
        """Re-solve an infeasible tick: its solution and the messages of the hard levels it
        leaves unmet (the solver's diagnosis; relaxed if any). E.g. a tick that starts
        outside the joint limits or violating a constraint (link pairs inside their
        self-collision margin, a sole corner below the ground:
        :meth:`~wbc.limits.Constraint.split`), asking of that start only what the hard tasks
        leave possible. One cascade
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
        (:meth:`on_hard_levels`), so that the way back does not drift them where no tick
        can bring them back (stress trials 1567, 8832)."""
        nv = self.robot.nv
        lower, upper = np.empty(nv), np.empty(nv)
        self.settings.compute_bounds(kin, dt, lower, upper)
        lo, hi = lower[6:], upper[6:]
        out = np.flatnonzero((lo > 0.0) | (hi < 0.0))
        back = np.where(lo[out] > 0.0, lo[out], hi[out])
        np.minimum(lo, 0.0, out=lo)
        np.maximum(hi, 0.0, out=hi)
        relax = self.settings.on_infeasible == "relax"
        first = None
        for recovering in (False, True):
            try:
                dq, unmet = self.re_solve(kin, lower, upper, out, back, recovering)
            except (InfeasibleError, SolverError) as e:  # the re-solve failed
                failure = e
                continue
            if not unmet:
                break
            first = first or (dq, unmet)
        else:
            if first is None or not relax:
                restored = self.restore_hard(kin, lower, upper)
                if restored is None:  # infeasible on their own: the solver's diagnosis
                    raise _diagnosed(exc) from (None if first else failure)
                return Solution(restored, lower, upper), []
            dq, unmet = first
        return Solution(dq, lower, upper), unmet

    def on_hard_levels(self, kin: Kinematics, solution: Solution) -> Solution:
        """The step of a solve that starts with joints outside their range, ending on the hard
        levels (within the solver's ``hard_tol``) at q ⊕ Δq, not only to first order: the longest
        q ⊕ t·Δq (:meth:`longest_exact`) that :meth:`restore_steps` brings back onto them
        within the solve's box (widened to Δq = 0 for the joints outside: never further out);
        where only t = 0 does (the fold below), the solve again with those joints held this
        once, the others free (the soft levels keep going). ``solution`` unchanged if none
        gets there.

        Why: the joints' way back yields to the hard tasks (:meth:`solve`), and
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
        found = self.longest_exact(kin, dq, lower, upper, stop=False)
        if found is None or found[1] == 0.0:
            # at the fold every step that brings a joint outside back drifts off: the
            # joints outside held this once, the others free (the soft levels keep going)
            j = q0[7:]
            held = 6 + np.flatnonzero((j < self.hard.q_min) | (j > self.hard.q_max))
            low, up = lower.copy(), upper.copy()
            low[held] = up[held] = 0.0
            try:
                dq_held, unmet = self.re_solve(kin, low, up, _NO_JOINTS, EMPTY, True)
            except WbcError:
                unmet = ["failed"]
            if not unmet:
                moved = self.longest_exact(kin, np.clip(dq_held, low, up), low, up, stop=True)
                if moved is not None:
                    found = moved
        kin.update(q0)
        for task, e in zip(hard_tasks, kept, strict=True):
            task.last_error = e
        if found is None:
            return solution
        return Solution(self.robot.difference(q0, found[0]), lower, upper)

    def longest_exact(
        self, kin: Kinematics, dq: np.ndarray, lower: np.ndarray, upper: np.ndarray, stop: bool
    ) -> tuple[np.ndarray, float] | None:
        """(q, t): q ⊕ t·dq for the first t of 1, ½, … (:data:`WAY_BACK_HALVINGS`), then 0,
        that :meth:`restore_steps` brings onto the hard levels within [lower, upper] (from
        ``kin``'s q; its trust region :data:`HARD_PROJECTION_TRUST`), that point; None if none
        does. ``stop``: not t = 0. ``kin`` left at q."""
        q0 = kin.q.copy()
        for t in (*(0.5**k for k in range(WAY_BACK_HALVINGS)), *(() if stop else (0.0,))):
            self.work.spend()  # (inside a solve_pose: its time budget checked at every try)
            q_t = self.hard.move_joints(q0, t * dq)
            kin.update(q_t)
            errors = self.hard.errors(kin)
            kin.update(q0)
            if max(errors, default=0.0) > self.settings.hard_tol:
                q_t, errors = self.restore_steps(
                    kin, lower, upper, errors, 0.0, q_t, HARD_PROJECTION_TRUST, WAY_BACK_STEPS
                )
            if max(errors, default=0.0) <= self.settings.hard_tol:
                return q_t, t
        return None

    def restore_hard(
        self, kin: Kinematics, lower: np.ndarray, upper: np.ndarray
    ) -> np.ndarray | None:
        """Δq within [lower, upper] (this tick's box) that brings the hard levels back within
        the solver's ``hard_tol`` *at q ⊕ Δq*, by Gauss–Newton steps re-linearised at each iterate
        (:meth:`restore_steps`); None if the steps do not get there.

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
        start_errors = self.hard.errors(kin)  # (restore_steps leaves kin at q0)
        q, errors = self.restore_steps(kin, lower, upper, start_errors, 0.0)
        if max(errors, default=0.0) > self.settings.hard_tol:
            # undoing the drift may cost the rows at most the drift's own size
            slack = min(max(start_errors, default=0.0), RESTORE_SLACK)
            q_s, errors_s = self.restore_steps(kin, lower, upper, start_errors, slack)
            if max(errors_s, default=0.0) < max(errors, default=0.0):
                q, errors = q_s, errors_s
        kin.update(q0)
        if max(errors, default=0.0) <= self.settings.hard_tol:
            return self.robot.difference(q0, q)
        return None

    def restore_steps(
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
        """The Gauss–Newton steps of :meth:`restore_hard` from ``q_start`` (default: ``kin``'s
        configuration q0; the hard levels' ``errors`` there), the hard rows loosened by
        ``slack``, the joints' total motion from q0 within [``lower``, ``upper``]: (q,
        errors); ``kin`` left at q0."""
        q0 = kin.q.copy()
        q = q0 if q_start is None else q_start
        total = np.zeros(self.robot.nv)
        total[6:] = q[7:] - q0[7:]
        stalls = 0
        for _ in range(max_steps):
            if max(errors, default=0.0) <= self.settings.hard_tol:
                break
            if self.work.pose is None and self.work.recovery_steps >= TICK_RECOVERY_STEPS:
                break  # a tick's work is bounded (a pose has its own budget)
            self.work.recovery_steps += 1
            self.work.spend()  # (inside a solve_pose: its time budget, at every step)
            kin.update(q)
            problems, held = self.hard.problems(kin)
            problems += self.weighted_rows(kin)
            if slack:
                problems = [loosened(p, slack) for p in problems]
            box_lower, box_upper = lower - total, upper - total
            if trust:  # a trust region too (:data:`HARD_PROJECTION_TRUST`)
                np.maximum(box_lower, -trust, out=box_lower)
                np.minimum(box_upper, trust, out=box_upper)
            delta = self.hard.step(q, [*problems, held], box_lower, box_upper)
            worst = max(errors)
            step = self.hard.halved_step(kin, q, delta, lambda e, w=worst: max(e) < w)
            if step is None:
                break
            q, errors, _ = step
            stalls = stalls + 1 if max(errors) > RESTORE_STALL * worst else 0
            total[6:] = q[7:] - q0[7:]
            if stalls == RESTORE_STALLS:  # converging is quadratic
                break
        kin.update(q0)
        return q, errors

    def weighted_rows(self, kin: Kinematics) -> list[LevelProblem]:
        """The weighted QP's other hard rows for :meth:`restore_hard`: it holds the
        constraints of every level (e.g. the swing sole's ground clearance), the hierarchy
        only those of its hard levels. One hard level after those, the rows at their bare
        bound and those violated at ``kin`` no worse (a corner below the ground no lower)."""
        if self.settings.lexicographic:
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
        return [LevelProblem(1 << 28, no_jacobian(nv), EMPTY, G, h, hard=True)]

    def re_solve(
        self,
        kin: Kinematics,
        lower: np.ndarray,
        upper: np.ndarray,
        out: np.ndarray,
        back: np.ndarray,
        recovering: bool,
    ) -> tuple[np.ndarray, list[str]]:
        """One re-solve of :meth:`solve` (``recovering``: the hard rows at their
        bare bound, :meth:`~wbc.limits.Constraint.split`): Δq and the messages of the hard
        levels it leaves unmet."""
        nv = self.robot.nv
        levels = self.stack.levels
        hard, soft, asks = [], [], []
        if self.settings.lexicographic:
            for lv in levels:
                block = TaskBlock(lv.active_tasks(), nv)
                rows = split_rows(lv.active_constraints(), kin, nv, recovering and lv.hard)
                if lv.hard:
                    block.fill_into(kin, block.J, block.b)
                    asks.append(rows)
                    hard.append(_level_problem(lv.priority, block, rows, hard=True))
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
            hard.append(_level_problem(0, block, rows, hard=True))
            block = TaskBlock([t for lv in levels if not lv.hard for t in lv.active_tasks()], nv)
            block.fill_weighted(kin)
            soft.append(LevelProblem(1 << 30, block.J, block.b, *no_rows(nv)))
        inside = sum(r.h_inside.size for r in asks)
        recovery = []
        if out.size:
            J = np.zeros((out.size, nv))
            J[np.arange(out.size), 6 + out] = 1.0
            recovery.append(LevelProblem(-1, J, back, *no_rows(nv)))
        relax = self.settings.on_infeasible == "relax"
        if inside:  # their best separation below the hard levels and the way back
            G_in = np.vstack([r.G_inside for r in asks])
            h_in = np.concatenate([r.h_inside for r in asks])
            # no pair closer than now first (HOLD_WEIGHT), then the damper's rate: one
            # pair may not approach so that another separates faster
            G_in = np.vstack([HOLD_WEIGHT * G_in, G_in])
            h_in = np.concatenate([HOLD_WEIGHT * np.maximum(h_in, 0.0), h_in])
            first = [*hard, *recovery, LevelProblem(-1, no_jacobian(nv), EMPTY, G_in, h_in)]
            best, _ = solve_cascade_or_daqp(
                first, lower, upper, daqp_for(first), final_regularization=1e-12,
                relax=relax,
            )  # fmt: skip
            # then held there, a hair looser (SEPARATION_SLACK): rows held exactly at their
            # best are often pinned against a joint bound, which makes the lower levels'
            # active sets degenerate
            hard = [_with_requests(p, r, best) for p, r in zip(hard, asks, strict=True)]
        problems = [
            *hard,
            *recovery,
            *(soft or [LevelProblem(1 << 30, no_jacobian(nv), EMPTY, *no_rows(nv))]),
        ]
        dq, sols = solve_cascade_or_daqp(
            problems, lower, upper, daqp_for(problems),
            final_regularization=self.settings.regularization, relax=relax,
        )  # fmt: skip
        tol = self.settings.hard_tol
        unmet = [
            infeasible_message(p, sol, tol)
            for p, sol in zip(hard, sols, strict=False)
            if max(abs(sol.residual).max(initial=0.0), sol.slack.max(initial=0.0)) > tol
        ]
        return dq, unmet


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


def _level_problem(priority: int, block: TaskBlock, rows: SplitRows, hard: bool) -> LevelProblem:
    """A level of the block's rows (as filled) and the held rows of ``rows``."""
    return LevelProblem(priority, block.J, block.b, rows.G, rows.h, hard, block.slices, rows.slices)
