"""The pose iteration beside the solver (:func:`wbc.solvers.pose.solve_pose`): convergence,
its bounded work, the hard levels held at the end."""

from __future__ import annotations

import numpy as np
import pytest
from test_solvers import random_start, walking_stack

from wbc import ConfigurationError, Kinematics, SolverError
from wbc.solvers import HierarchicalQP, WeightedQP, solve_pose


def test_solve_pose_is_a_function_beside_the_solver(robot):
    """The pose loop lives beside the solver, as pink's and mink's do:
    ``wbc.solvers.solve_pose(solver, q, ...)`` is ``solver.solve_pose(q, ...)`` bit for bit,
    every argument passed through (none at its default), and leaves no budget running."""
    q = robot.configuration("walk_ready")
    args = {
        "tol": 1e-5, "max_iterations": 40, "dt": 0.05, "stall_tol": 1e-10,
        "max_projection_steps": 5000, "time_budget": 600.0,
    }  # fmt: skip
    results = []
    for cls in (WeightedQP, HierarchicalQP):
        for call in (
            lambda s: solve_pose(s, q, **args),
            lambda s: s.solve_pose(q, *args.values()),
        ):
            stack = walking_stack(robot, q, com_shift=(0.005, 0.01, -0.005), lift=0.01)
            solver = cls(stack, "daqp", compiled=False)
            results.append(call(solver))
            assert solver.work.pose is None
    for a, b in (results[:2], results[2:]):
        np.testing.assert_array_equal(a.q, b.q)
        assert (a.iterations, a.converged, a.projection_steps, a.fell_back) == (
            b.iterations, b.converged, b.projection_steps, b.fell_back,
        )  # fmt: skip
        assert a.iterations > 1


def test_solve_pose_converges_to_a_reachable_target(robot):
    q = robot.configuration("walk_ready")
    for cls in (WeightedQP, HierarchicalQP):
        stack = walking_stack(robot, q, com_shift=(0.005, 0.01, -0.005), lift=0.01)
        stack.set_active(["posture"], False)  # a posture target would conflict with the rest
        result = cls(stack, "daqp").solve_pose(q, tol=1e-6, max_iterations=100)
        assert result.converged and not result.fell_back, (cls, result.errors)
        assert result.iterations < 100
        q_final = result.q
        kin = Kinematics(robot, q_final)
        # converged to tol: the CoM is there, read from a fresh evaluation (q_final is within
        # the limits by construction: solve_pose clips each pose)
        assert np.abs(kin.com - stack.task("com").target).max() <= 1e-6


def test_solve_pose_raises_a_typed_error_when_its_budget_is_spent(robot):
    """solve_pose's work is bounded (issue 17, item 5): its Gauss–Newton steps onto the hard
    levels (max_projection_steps) and, optionally, its wall time (time_budget). A spent
    budget raises SolverError naming it; bad budgets are ConfigurationErrors."""
    q = robot.configuration("walk_ready")
    stack = walking_stack(robot, q, com_shift=(0.05, 0.05, 0.0))  # out of reach: projections
    solver = WeightedQP(stack, "daqp", compiled=False)
    result = solver.solve_pose(q, max_iterations=20)  # the default budget
    assert 0 < result.projection_steps <= 20 * 21
    with pytest.raises(SolverError, match=r"spent its 1 Gauss–Newton steps .*max_projection_steps"):
        solver.solve_pose(q, max_iterations=20, max_projection_steps=1)
    with pytest.raises(SolverError, match=r"time budget of 1e-09 s \(time_budget\) at iteration 1"):
        solver.solve_pose(q, max_iterations=20, time_budget=1e-9)
    again = solver.solve_pose(q, max_iterations=20, time_budget=60.0)
    np.testing.assert_array_equal(again.q, result.q)  # nothing spent, nothing changed
    for bad in ({"max_projection_steps": 0}, {"max_projection_steps": 2.5}):
        with pytest.raises(ConfigurationError, match="max_projection_steps"):
            solver.solve_pose(q, **bad)
    for bad in (0.0, -1.0, float("nan"), "1"):
        with pytest.raises(ConfigurationError, match="time_budget"):
            solver.solve_pose(q, time_budget=bad)


def test_a_pose_checks_its_time_budget_inside_a_solve_that_steps_back_onto_the_hard_levels(
    robot, monkeypatch
):
    """A solve from a start outside the limits walks its step back onto the hard levels
    (Gauss–Newton steps and halvings, :meth:`Recovery.on_hard_levels`): inside a pose,
    that work checks the time budget too (issue 28: an OSQP hierarchy's pose overran its
    budget inside such solves, where nothing checked it). A clock that jumps once the pose
    is inside that work: the pose stops there, naming its budget."""
    from wbc.solvers import budget, recovery

    q, _ = random_start(robot, 3, outside=0.05)
    solver = HierarchicalQP(walking_stack(robot, q), "daqp", compiled=False)
    real = budget.time.perf_counter
    clock = {"jump": 0.0}
    monkeypatch.setattr(budget.time, "perf_counter", lambda: real() + clock["jump"])
    longest = recovery.Recovery.longest_exact

    def late(self, *args, **kwargs):
        clock["jump"] += 100.0  # (the work inside runs past the budget)
        return longest(self, *args, **kwargs)

    monkeypatch.setattr(recovery.Recovery, "longest_exact", late)
    with pytest.raises(SolverError, match=r"time budget of 10 s \(time_budget\) at iteration 1"):
        solver.solve_pose(q, max_iterations=5, time_budget=10.0)


def test_a_pose_whose_end_cannot_be_projected_ends_at_its_last_iterate_on_the_hard_levels(
    robot, monkeypatch
):
    """Issue 28: feasible converged poses raised "ends off its hard levels" (3 of 2,000) when
    no projection of their end got back onto them. The pose then ends at the last iterate
    that held them (here the start: every projection is made to fail), not converged, on its
    contacts (it raises only when no iterate held them, as before)."""
    from wbc.solvers import projection

    q = robot.configuration("walk_ready")
    stack = walking_stack(robot, q, com_shift=(0.03, 0.02, 0.0))
    solver = HierarchicalQP(stack, "daqp", compiled=False)
    project = projection.HardLevels.project

    def failing(self, q_in, tol, *args, **kwargs):
        q_out, errors = project(self, q_in, tol, *args, **kwargs)
        return q_out, [max(e, 1e-5) for e in errors]  # as if 1e-5 were the closest

    monkeypatch.setattr(projection.HardLevels, "project", failing)
    result = solver.solve_pose(q, max_iterations=10)
    assert not result.converged and result.fell_back
    kin = Kinematics(robot, result.q)
    hard = [t for lv in stack.levels if lv.hard for t in lv.active_tasks()]
    assert hard
    for task in hard:
        assert abs(task.compute(kin)[1]).max() <= 1e-6, task.name
        assert abs(result.errors[task.name]).max() <= 1e-6, task.name
