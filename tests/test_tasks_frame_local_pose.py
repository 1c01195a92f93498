"""The local frame pose task (wbc.tasks.frame_local_pose): Pinocchio's log6 and LOCAL Jacobian
on every path (numpy, compiled)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc import Kinematics, TaskError
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP
from wbc.tasks import ContactTask, LocalFramePoseTask
from wbc.tasks.frame_local_pose import TAYLOR_ANGLE
from wbc.tasks.task import STACK_TYPES

seeds = st.integers(0, 2**31 - 1)


def random_q(robot, rng):
    q = robot.random_configuration(rng, margin=0.05)
    q[:3] = rng.uniform(-0.1, 0.1, 3)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.5, 0.5, 3))).coeffs()
    return q


@settings(deadline=None, max_examples=30)
@given(seeds, st.sampled_from([0.0, 0.3 * TAYLOR_ANGLE, 3 * TAYLOR_ANGLE, 0.5, 2.5]))
def test_rows_are_pinocchios_log6_and_local_jacobian(robot, seed, angle):
    """e = log6(M⁻¹ M*) and J = the LOCAL frame Jacobian (Pinocchio's, the oracle) at relative
    rotations of every size, both branches of the logarithm's linear part included."""
    rng = np.random.default_rng(seed)
    kin = Kinematics(robot, random_q(robot, rng))
    fid = robot.frame_id("r_sole")
    axis = rng.standard_normal(3)
    relative = pin.SE3(pin.exp3(angle * axis / np.linalg.norm(axis)), rng.uniform(-0.1, 0.1, 3))
    target = kin.placement(fid) * relative
    task = LocalFramePoseTask(robot, "r_sole", target)
    J, e = task.compute(kin)
    oracle = pin.log6(kin.placement(fid).inverse() * target).vector
    assert np.abs(e - oracle).max() < 1e-12
    J_local = pin.getFrameJacobian(robot.model, kin.data, fid, pin.LOCAL)
    assert np.abs(J - J_local).max() < 1e-12
    # the last three rows alone: an orientation, log3(Rᵀ R*)
    torso = LocalFramePoseTask(robot, "torso", target, mask=[False] * 3 + [True] * 3)
    _, e_rot = torso.compute(kin)
    R = kin.rotation(robot.frame_id("torso"))
    assert np.abs(e_rot - pin.log3(R.T @ target.rotation)).max() < 1e-12


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rows_are_the_first_order_model_at_the_target(robot, seed):
    """A frame held where it is: after a step d the error is ``−J d`` to second order in |d|
    (the rows of the balance window and the feasibility IK)."""
    rng = np.random.default_rng(seed)
    q = robot.configuration("stand")
    kin = Kinematics(robot, q)
    task = LocalFramePoseTask(robot, "l_sole")
    task.set_target_from(kin)
    J, e = task.compute(kin)
    assert np.abs(e).max() < 1e-12
    d = rng.standard_normal(robot.nv)

    def miss(step: float) -> float:
        e1 = task.compute(Kinematics(robot, pin.integrate(robot.model, q, step * d)))[1]
        return float(np.abs(e1 + J @ (step * d)).max())

    big, small = miss(1e-3), miss(1e-4)
    assert 0 < small < 1e-6 and big / small > 50  # second order: 10x smaller step, ~100x less
    assert np.abs(J @ d).max() > 0.1  # (not trivially zero)


@pytest.mark.parametrize("solver", [WeightedQP, HierarchicalQP])
def test_places_a_sole_on_every_path(robot, solver):
    """Compiled by default, the same steps as the numpy path, and the sole gets there."""
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    fid = robot.frame_id("r_sole")
    step = pin.SE3(pin.exp3(np.array([0.0, 0.0, 0.1])), np.array([0.01, 0.0, 0.01]))
    goal = kin.placement(fid) * step
    paths = {}
    for compiled in (None, False):
        stack = TaskStack(robot)
        stack.add(ContactTask(robot, "l_sole"), level=0, hard=True).make_contact(kin)
        stack.add(LocalFramePoseTask(robot, "r_sole", goal), level=1, weight=10.0)
        s = solver(stack, compiled=compiled)
        qs = q.copy()
        for _ in range(5):
            qs = s.step(qs, dt=0.01)
        paths[compiled] = qs
        assert (s.fast is not None) == (compiled is None)
        result = s.solve_pose(qs, tol=1e-8, max_iterations=100)
        reached = Kinematics(robot, result.q).placement(fid)
        assert np.abs(pin.log6(reached.inverse() * goal).vector).max() < 1e-6
    assert np.abs(paths[None] - paths[False]).max() < 1e-9


def test_bad_input_and_registration(robot):
    assert STACK_TYPES["local_frame_pose"] is LocalFramePoseTask
    with pytest.raises(TaskError, match=r"pinocchio\.SE3"):
        LocalFramePoseTask(robot, "r_sole", np.eye(4))  # type: ignore[arg-type]
    task = LocalFramePoseTask(robot, "r_sole")
    with pytest.raises(TaskError, match="not a rotation"):
        task.set_rotation_target(2 * np.eye(3))
    with pytest.raises(TaskError, match="non-finite"):
        task.set_position_target([0.0, np.nan, 0.0])
