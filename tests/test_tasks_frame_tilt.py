"""The frame tilt task (wbc.tasks.frame_tilt): rows first-order at upright, on every path."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc import Kinematics, TaskError
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP
from wbc.tasks import ContactTask, FrameTiltTask, TorsoOrientationTask
from wbc.tasks.task import STACK_TYPES

seeds = st.integers(0, 2**31 - 1)


@settings(deadline=None, max_examples=20)
@given(seeds)
def test_error_and_jacobian(robot, seed):
    """e = x* − [u·k, v·k] (k the frame's z axis) and J = −de/dΔq (central differences)."""
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng, margin=0.05)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.5, 0.5, 3))).coeffs()
    kin = Kinematics(robot, q)
    directions = rng.standard_normal((2, 3))
    target = rng.uniform(-0.3, 0.3, 2)
    task = FrameTiltTask(robot, "torso", directions, target)
    J, e = task.compute(kin)
    k = kin.rotation(robot.frame_id("torso"))[:, 2]
    assert np.abs(e - (target - directions @ k)).max() < 1e-14
    eps = 1e-6
    J_fd = np.zeros_like(J)
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = eps
        ep = task.compute(Kinematics(robot, pin.integrate(robot.model, q, dq)))[1]
        em = task.compute(Kinematics(robot, pin.integrate(robot.model, q, -dq)))[1]
        J_fd[:, i] = -(ep - em) / (2 * eps)
    assert np.abs(J - J_fd).max() < 1e-8


def test_the_jacobian_does_not_vanish_at_upright(robot):
    """At upright the tilt rows move with the torso's pitch and roll (the thesis's 1 − a·k,
    quadratic in the angle, does not): a lean limit is a linear row there. And a target
    taken where the frame is gives exactly zero error."""
    q = robot.configuration("stand")
    kin = Kinematics(robot, q)
    tilt = FrameTiltTask(robot, "torso")
    tilt.set_target_from(kin)
    J, e = tilt.compute(kin)
    assert np.array_equal(e, np.zeros(2))
    R = kin.rotation(robot.frame_id("torso"))
    axis = TorsoOrientationTask(robot, axis=R[:, 2])  # aligned: its Jacobian vanishes
    assert np.abs(axis.compute(kin)[0]).max() < 1e-12
    # the base's pitch and roll (dofs 3, 4) tilt the torso one-to-one
    assert np.abs(np.abs(J[:, 3:5]) - np.eye(2)[::-1]).max() < 0.05


@pytest.mark.parametrize("solver", [WeightedQP, HierarchicalQP])
def test_leans_the_torso_on_every_path(robot, solver):
    """Both soles held, the torso asked to lean 5° to the left: compiled by default, the same
    steps as the numpy path, and the torso gets there."""
    q = robot.configuration("stand")
    kin = Kinematics(robot, q)
    lean = np.sin(np.deg2rad(5.0))
    paths = {}
    for compiled in (None, False):
        stack = TaskStack(robot)
        for sole in ("l_sole", "r_sole"):
            stack.add(ContactTask(robot, sole), level=0, hard=True).make_contact(kin)
        tilt = FrameTiltTask(robot, "torso")
        tilt.set_target_from(kin)
        tilt.target[1] += lean  # k·y grows: the top toward +y
        stack.add(tilt, level=1, weight=10.0)
        s = solver(stack, compiled=compiled)
        qs = q.copy()
        for _ in range(5):
            qs = s.step(qs, dt=0.01)
        paths[compiled] = qs
        assert (s.fast is not None) == (compiled is None)
        result = s.solve_pose(qs, tol=1e-8, max_iterations=100)
        assert np.abs(tilt.compute(Kinematics(robot, result.q))[1]).max() < 1e-6
    assert np.abs(paths[None] - paths[False]).max() < 1e-9


def test_bad_input_and_registration(robot):
    assert STACK_TYPES["frame_tilt"] is FrameTiltTask
    with pytest.raises(TaskError, match="two rows of 3"):
        FrameTiltTask(robot, "torso", directions=[1.0, 0.0, 0.0])
    with pytest.raises(TaskError, match="two rows of 3"):
        FrameTiltTask(robot, "torso", directions="xy")  # type: ignore[arg-type]
    with pytest.raises(TaskError, match="non-finite"):
        FrameTiltTask(robot, "torso", directions=[[1.0, 0.0, np.inf], [0.0, 1.0, 0.0]])
    with pytest.raises(TaskError, match="shape"):
        FrameTiltTask(robot, "torso", target=[0.0, 0.0, 0.0])


def test_a_stack_file_names_both_pre_motion_types(robot):
    """``frame_tilt`` (its directions and target keys) and ``local_frame_pose`` in a stack
    file's entries: built, the tilt's given target kept, the pose's taken where it is."""
    import tomllib

    from wbc.stacks import build_stack, stack_file
    from wbc.tasks import LocalFramePoseTask

    spec = tomllib.loads(stack_file("walk").read_text())
    spec["levels"][-1]["tasks"] = [
        *spec["levels"][-1]["tasks"],
        {"type": "frame_tilt", "frame": "torso", "directions": [[0, 1, 0], [1, 0, 0]],
         "target": [0.01, 0.0], "weight": 1.0},
        {"type": "local_frame_pose", "frame": "l_hand", "weight": 1.0},
    ]  # fmt: skip
    q = robot.configuration("walk_ready")
    control = build_stack(spec, robot, q)
    tasks = {t.name: t for t in control.stack.tasks()}
    tilt, hand = tasks["frame_tilt_torso"], tasks["local_frame_pose_l_hand"]
    assert isinstance(tilt, FrameTiltTask) and isinstance(hand, LocalFramePoseTask)
    assert np.array_equal(tilt.directions, [0, 1, 0, 1, 0, 0])
    assert np.array_equal(tilt.target, [0.01, 0.0])
    assert np.abs(hand.compute(Kinematics(robot, q))[1]).max() < 1e-12
