"""The yaw-momentum task (wbc.tasks.momentum): the locked body's turn about the vertical
through its CoM, against Pinocchio's centroidal quantities, on every solver path."""

from __future__ import annotations

import tomllib

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc import Kinematics, TaskError
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP
from wbc.tasks import ContactTask, FramePositionTask, PostureTask, YawMomentumTask
from wbc.tasks.task import STACK_TYPES

seeds = st.integers(0, 2**31 - 1)


@settings(deadline=None, max_examples=20)
@given(seeds)
def test_rows_are_the_vertical_momentum_over_the_yaw_inertia(robot, seed):
    """J v = L_z / I_zz for any velocity v (Pinocchio's centroidal momentum and composite
    inertia, computed here independently), e = the target, and a pure turn of the whole
    body about the vertical at unit rate gives J v = 1 at any base orientation."""
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng, margin=0.05)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.6, 0.6, 3))).coeffs()
    kin = Kinematics(robot, q)
    task = YawMomentumTask(robot, target=0.02)
    J, e = task.compute(kin)
    assert e.tolist() == [0.02]
    model, data = robot.model, robot.model.createData()
    v = rng.standard_normal(robot.nv)
    pin.ccrba(model, data, q, v)
    izz = data.Ig.inertia[2, 2]
    hg = pin.computeCentroidalMomentum(model, data, q, v)
    assert abs(float(J[0] @ v) - hg.angular[2] / izz) < 1e-9 * max(1.0, abs(hg.angular[2] / izz))
    turn = np.zeros(robot.nv)  # the base turning about the world's vertical, joints still
    R = pin.Quaternion(q[3:7]).toRotationMatrix()
    turn[3:6] = R.T @ [0.0, 0.0, 1.0]
    assert abs(float(J[0] @ turn) - 1.0) < 1e-9


@pytest.mark.parametrize("solver", [WeightedQP, HierarchicalQP])
def test_the_arms_give_back_what_the_swing_leg_makes(robot, solver):
    """One sole held, the other swung forward: without the task the step carries the swing's
    vertical angular momentum; with it the rest of the body gives it back (the step's turn
    below a tenth of it) while the swing sole still gets where it is asked. Compiled by
    default, the same step as the numpy path."""
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    steps, turns = {}, {}
    for weight in (None, 10.0):
        for compiled in (None, False):
            stack = TaskStack(robot)
            stack.add(ContactTask(robot, "l_sole"), level=0, hard=True).make_contact(kin)
            swing = FramePositionTask(robot, "r_sole")
            swing.set_target(kin.translation(robot.frame_id("r_sole")) + [0.004, 0.0, 0.002])
            stack.add(swing, level=1, weight=100.0)
            posture = PostureTask(robot)
            posture.set_target(q)
            stack.add(posture, level=1, weight=0.01)
            yaw = YawMomentumTask(robot)
            if weight is not None:
                stack.add(yaw, level=1, weight=weight)
            s = solver(stack, compiled=compiled)
            q1 = s.step(q, dt=0.01)
            dq = pin.difference(robot.model, q, q1)
            steps[weight, compiled] = dq
            turns[weight] = float(yaw.compute(kin)[0][0] @ dq)
            reached = Kinematics(robot, q1).translation(robot.frame_id("r_sole"))
            assert np.abs(reached - swing.target).max() < 5e-4
        assert np.abs(steps[weight, None] - steps[weight, False]).max() < 1e-9
    assert abs(turns[None]) > 1e-3  # the swing alone turns the body
    assert abs(turns[10.0]) < 0.1 * abs(turns[None])


def test_bad_input_and_a_stack_file_entry(robot):
    assert STACK_TYPES["yaw_momentum"] is YawMomentumTask
    with pytest.raises(TaskError, match="non-finite"):
        YawMomentumTask(robot, target=float("nan"))
    with pytest.raises(TaskError, match="1 numbers"):
        YawMomentumTask(robot, target="left")  # type: ignore[arg-type]
    with pytest.raises(TaskError, match="follow must be true or false"):
        YawMomentumTask(robot, follow="yes")  # type: ignore[arg-type]
    from wbc.stacks import build_stack, stack_file

    spec = tomllib.loads(stack_file("walk").read_text())
    spec["levels"][-1]["tasks"] = [
        *spec["levels"][-1]["tasks"],
        {"type": "yaw_momentum", "weight": 2.0, "target": 0.001},
    ]
    control = build_stack(spec, robot, robot.configuration("walk_ready"))
    (task,) = [t for t in control.stack.tasks() if isinstance(t, YawMomentumTask)]
    assert task.name == "yaw_momentum" and task.target.tolist() == [0.001]
    assert task.weight.tolist() == [2.0]


@pytest.mark.parametrize("follow", [True, False])
def test_a_walking_controller_sets_the_followed_target_to_the_yaw_step(robot, follow):
    """Along the ``turn`` walk, a ``follow`` task's target is the reference torso's yaw step of
    each tick (0 on the first); without ``follow`` it stays the file's."""
    from wbc.bench.trajectories import build
    from wbc.stacks import build_stack, stack_file
    from wbc.walking.loop import Session, StackController

    spec = tomllib.loads(stack_file("walk").read_text())
    spec["levels"][-1]["tasks"] = [
        *spec["levels"][-1]["tasks"],
        {"type": "yaw_momentum", "weight": 0.3, "follow": follow, "target": 0.002},
    ]
    controller = StackController(build_stack(spec, robot))
    (task,) = [t for t in controller.control.stack.tasks() if isinstance(t, YawMomentumTask)]
    yaws, seen = [], []
    track = controller.track

    def spy(q, targets, dt, phase_changed):
        yaws.append(targets.torso_yaw)
        out = track(q, targets, dt, phase_changed)
        seen.append(float(task.target[0]))
        return out

    controller.track = spy  # type: ignore[method-assign]
    session = Session(controller, robot, build("turn", robot))
    for i in range(120):
        session.tick(i)
    steps = np.r_[0.0, np.diff(yaws)] if follow else np.full(len(yaws), 0.002)
    assert np.abs(np.array(seen) - steps).max() < 1e-12
    assert not follow or np.abs(steps).max() > 1e-4  # (the walk turns in these ticks)


def test_a_new_walk_on_the_same_controller_starts_without_a_yaw_step(robot):
    """A second walk run by the same controller asks no yaw step at its first tick (the last
    walk's final yaw is forgotten at the start, as after the first tick's rehearsal)."""
    from wbc.bench.trajectories import build
    from wbc.stacks import build_stack, stack_file
    from wbc.walking.loop import Session, StackController

    spec = tomllib.loads(stack_file("walk").read_text())
    spec["levels"][-1]["tasks"] = [
        *spec["levels"][-1]["tasks"],
        {"type": "yaw_momentum", "weight": 0.3, "follow": True},
    ]
    controller = StackController(build_stack(spec, robot))
    (task,) = [t for t in controller.control.stack.tasks() if isinstance(t, YawMomentumTask)]
    ref = build("turn", robot)
    session = Session(controller, robot, ref)
    for i in range(len(ref.t) // 2):
        session.tick(i)
    assert abs(controller._torso_yaw or 0.0) > 0.05  # (the first walk turned)
    Session(controller, robot, ref).tick(0)
    assert task.target[0] == 0.0
