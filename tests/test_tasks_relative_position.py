"""The relative frame position task (wbc.tasks.relative_position), and a task type defined
outside the package running on the compiled path."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from wbc import Kinematics, TaskError
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP
from wbc.tasks import ContactTask, PostureTask, Task
from wbc.tasks.relative_position import RelativeFramePositionTask

seeds = st.integers(0, 2**31 - 1)


def relative(kin, frame, reference):
    """R_aᵀ (p_b − p_a) from Pinocchio's placements (the oracle)."""
    a = kin.placement(kin.robot.frame_id(reference))
    b = kin.placement(kin.robot.frame_id(frame))
    return a.actInv(b).translation


@settings(deadline=None, max_examples=20)
@given(seeds)
def test_error_and_jacobian(robot, seed):
    """e = x* − x (x from Pinocchio's relative placement) and J = −de/dΔq (finite
    differences on the configuration manifold)."""
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng, margin=0.05)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.5, 0.5, 3))).coeffs()
    kin = Kinematics(robot, q)
    target = rng.uniform(-0.1, 0.1, 3)
    task = RelativeFramePositionTask(robot, "r_sole", "l_sole", target)
    J, e = task.compute(kin)
    assert np.abs(e - (target - relative(kin, "r_sole", "l_sole"))).max() < 1e-12
    eps = 1e-6
    J_fd = np.zeros_like(J)
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = eps
        kp = Kinematics(robot, pin.integrate(robot.model, q, dq))
        km = Kinematics(robot, pin.integrate(robot.model, q, -dq))
        J_fd[:, i] = -(task.compute(kp)[1] - task.compute(km)[1]) / (2 * eps)
    assert np.allclose(J, J_fd, atol=1e-6), np.abs(J - J_fd).max()


def stack_with(robot, q, task: Task, posture: bool = True) -> TaskStack:
    kin = Kinematics(robot, q)
    stack = TaskStack(robot)
    stack.add(ContactTask(robot, "l_sole"), level=0, hard=True).make_contact(kin)
    stack.add(task, level=1, weight=10.0)
    if posture:
        stack.add(PostureTask(robot), level=2, weight=1e-3).set_target_from(kin)
    return stack


@pytest.mark.parametrize("solver", [WeightedQP, HierarchicalQP])
def test_places_the_swing_sole_relative_to_the_support_sole(robot, solver):
    """Compiled by default, the same steps as the numpy path, and the sole gets there."""
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    start = relative(kin, "r_sole", "l_sole")
    goal = start + [0.02, 0.01, 0.015]
    paths = {}
    for compiled in (None, False):
        task = RelativeFramePositionTask(robot, "r_sole", "l_sole", goal)
        s = solver(stack_with(robot, q, task, posture=False), compiled=compiled)
        qs = q.copy()
        for _ in range(5):
            qs = s.step(qs, dt=0.01)
        paths[compiled] = qs
        assert (s.fast is not None) == (compiled is None)
        result = s.solve_pose(qs, tol=1e-7, max_iterations=100)
        assert result.converged
        assert np.allclose(
            relative(Kinematics(robot, result.q), "r_sole", "l_sole"), goal, atol=1e-6
        )
    assert np.abs(paths[None] - paths[False]).max() < 1e-9  # (allclose's rtol: 1e-5 of q)


def test_bad_input(robot):
    with pytest.raises(TaskError, match="shape"):
        RelativeFramePositionTask(robot, "r_sole", "l_sole", [0.0, 0.1])
    with pytest.raises(TaskError, match="non-finite"):
        RelativeFramePositionTask(robot, "r_sole", "l_sole", [0.0, np.nan, 0.0])


# ---------------------------------------------------------------------- a user's own task
@njit(cache=True)
def _com_height_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    e[0] = target[0] - com[2]
    for k in range(Jcom.shape[1]):
        J[0, k] = Jcom[2, k]


class ComHeightTask(Task):
    """A task type written outside the package: the CoM height (1 row)."""

    dim = 1
    row_kernel = staticmethod(_com_height_rows)
    target_fields = ("target",)

    def __init__(self, height: float) -> None:
        super().__init__("com_height")
        self.target = np.array([height])


def test_a_task_defined_outside_the_package_runs_compiled(robot):
    q = robot.configuration("walk_ready")
    height = robot.com(q)[2] - 0.01
    steps = {}
    for compiled in (None, False):
        task = ComHeightTask(height)
        handle = task.target  # taken before the first solve: must be honoured on every path
        s = WeightedQP(stack_with(robot, q, task), compiled=compiled)
        s.step(q, dt=0.01)
        handle[0] = height - 0.005
        steps[compiled] = s.step(q, dt=0.01)
        assert (s.compiled_ticks == 2) == (compiled is None)
    assert np.abs(steps[None] - steps[False]).max() < 1e-9
    moved = robot.com(steps[None])[2] - robot.com(q)[2]
    assert moved < -1e-3  # it followed the updated handle downwards
