"""Projection onto the hard levels: their errors at a configuration, Gauss–Newton steps onto
them (one cascade of DAQP levels each) and the line search that accepts a step. The solvers'
recovery (:mod:`wbc.solvers.recovery`) and pose iteration (:mod:`wbc.solvers.pose`) project
their iterates with it; :meth:`wbc.solvers.StackSolver.project_hard` is its public face."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..exceptions import WbcError
from ..model import Kinematics, Robot
from .backends import make_backend
from .budget import Work
from .cascade import LevelProblem, solve_cascade
from .rows import loosened, split_rows
from .stack import TaskStack

#: at most this many Gauss–Newton steps per projection onto the hard levels (it converges
#: quadratically: two or three steps from a tick's second-order residual)
HARD_PROJECTION_STEPS = 20
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
#: an iterate's projection onto a hard level (the shorter steps of
#: :func:`wbc.solvers.pose.solve_pose`) stops after PROJECTION_STALLS Gauss–Newton steps in a row
#: that each leave more than PROJECTION_STALL of the level's error: converging is quadratic, and
#: such steps creep along a nearly singular chain (stress trial 3972, double support, 6–7 joints at
#: a limit and pairs at their margin: minimum-norm steps of 2 rad for a 4 mm contact error,
#: accepted at t = 1/32 for 1–3 % each, 20 steps per projection, 84 s of a 93 s pose; none of its
#: projections that ended on their level had three such steps). The final projection of a pose does
#: not stop early: there a creeping projection can still converge once an active row changes
#: (stress trial 1226: seven such steps, then 5e-5 → 1.4e-7 m)
PROJECTION_STALL = 0.9
PROJECTION_STALLS = 3


class HardLevels:
    """The hard levels of a solver's stack, to measure and to project onto: ``kin`` the
    solver's kinematics (left where each method says), the joints kept in [min(``q_min``,
    q_j), max(``q_max``, q_j)], each Gauss–Newton step counted by ``work`` (against a running
    pose's budget)."""

    def __init__(
        self,
        stack: TaskStack,
        robot: Robot,
        kin: Kinematics,
        q_min: np.ndarray,
        q_max: np.ndarray,
        work: Work,
    ) -> None:
        self.stack = stack
        self.robot = robot
        self.kin = kin
        self.q_min = q_min
        self.q_max = q_max
        self.work = work

    def errors_of_last_solve(self) -> list[float]:
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

    def errors(self, kin: Kinematics) -> list[float]:
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

    def problems(self, kin: Kinematics) -> tuple[list[LevelProblem], LevelProblem]:
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

    def project(
        self,
        q: np.ndarray,
        tol: float,
        max_steps: int = HARD_PROJECTION_STEPS,
        stop_stalled: bool = False,
        slack: float = 0.0,
    ) -> tuple[np.ndarray, list[float]]:
        """q moved onto the hard levels, one level after the other, and the hard levels'
        errors there (``kin`` left there): for level k, Gauss–Newton steps δ = argmin ‖δ‖
        subject to the hard levels 0..k in priority order (J_j δ = e_j in least squares over
        the null space of the levels above, their inequalities), the joint limits and a trust
        region (:data:`HARD_PROJECTION_TRUST`), each step halved until it reduces level k's
        error without raising a level above it beyond ``tol``. A level that cannot be met
        (relaxed) keeps the best it reaches and ends the projection; it never costs a level
        above it. ``stop_stalled``: a level's steps stop where they stall
        (:data:`PROJECTION_STALL`); the hard levels' inequality rows loosened by ``slack``
        (:func:`~wbc.solvers.pose.solve_pose`'s last resort). Each Gauss–Newton step counts
        against the running pose's budget (``work``)."""
        kin = self.kin
        kin.update(q)
        errors = self.errors(kin)
        trust = np.full(self.robot.nv, HARD_PROJECTION_TRUST)
        for k in range(len(errors)):
            stalls = 0
            for _ in range(max_steps):
                if errors[k] <= tol:
                    break
                self.work.spend(1)
                kin.update(q)
                problems, held = self.problems(kin)
                if slack:
                    problems = [loosened(p, slack) for p in problems]
                delta = self.step(q, [*problems[: k + 1], held], -trust, trust)
                step = self.halved_step(
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

    def halved_step(
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
            q_t = self.move_joints(q, t * delta)
            kin.update(q_t)
            e_t = self.errors(kin)
            if accept(e_t):
                return q_t, e_t, t
            t *= 0.5
        return None

    def step(
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

    def move_joints(self, q: np.ndarray, delta: np.ndarray) -> np.ndarray:
        """q ⊕ δ with the joints kept in [min(q_min, q_j), max(q_max, q_j)]."""
        q_next = self.robot.integrate(q, delta)
        j, j_prev = q_next[7:], q[7:]
        np.clip(j, np.minimum(self.q_min, j_prev), np.maximum(self.q_max, j_prev), out=j)
        return q_next
