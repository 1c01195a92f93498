"""Tasks: Jacobians equal finite differences of their errors; bad targets are rejected."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc import Kinematics, TaskError
from wbc.tasks import (
    ComTask,
    ContactTask,
    DampingTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    PostureTask,
    SwingFootOrientationTask,
    TorsoOrientationTask,
)


def random_q(robot, seed):
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng, margin=0.05)
    q[:3] = rng.uniform(-0.1, 0.1, 3)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.5, 0.5, 3))).coeffs()
    return q


def make_tasks(robot, rng):
    R = pin.exp3(rng.uniform(-0.3, 0.3, 3))
    target = pin.SE3(R, rng.uniform(-0.1, 0.1, 3))
    return [
        ComTask(robot, rng.uniform(-0.05, 0.05, 3)),
        FramePositionTask(robot, "r_sole", rng.uniform(-0.1, 0.1, 3)),
        FrameOrientationTask(robot, "torso", R),
        FramePoseTask(robot, "l_hand", target),
        SwingFootOrientationTask(robot, "r_sole", R),
        TorsoOrientationTask(robot),
        PostureTask(robot, robot.random_configuration(rng)[7:]),
        FramePoseTask(robot, "r_sole", target, mask=[1, 0, 1, 1, 0, 1], name="masked"),
    ]


@given(seed=st.integers(0, 2**31 - 1))
def test_jacobian_is_minus_derivative_of_error(robot, seed):
    """e = x* − x, so de/dΔq = −J (finite differences on the configuration manifold)."""
    rng = np.random.default_rng(seed)
    q = random_q(robot, seed)
    kin = Kinematics(robot, q)
    eps = 1e-6
    for task in make_tasks(robot, rng):
        J, e0 = task.compute(kin)
        J_fd = np.zeros_like(J)
        for i in range(robot.nv):
            dq = np.zeros(robot.nv)
            dq[i] = eps
            kin_i = Kinematics(robot, robot.integrate(q, dq))
            J_fd[:, i] = -(task.compute(kin_i)[1] - e0) / eps
        assert np.allclose(J, J_fd, atol=1e-4), task.name


def test_orientation_jacobian_exact_at_small_error(robot):
    """At a near-zero SO(3) error the log-error Jacobian is exact."""
    q = random_q(robot, 1)
    kin = Kinematics(robot, q)
    task = FrameOrientationTask(robot, "torso")
    task.set_target_from(kin)
    J, e0 = task.compute(kin)
    assert np.allclose(e0, 0)
    eps = 1e-7
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = eps
        e1 = task.compute(Kinematics(robot, robot.integrate(q, dq)))[1]
        assert np.allclose(-(e1 - e0) / eps, J[:, i], atol=1e-6)


def test_thesis_orientation_errors_vanish_at_alignment(robot):
    q = robot.configuration("zero")
    kin = Kinematics(robot, q)
    foot = SwingFootOrientationTask(robot, "r_sole")
    torso = TorsoOrientationTask(robot)
    assert np.allclose(foot.compute(kin)[1], 0)
    assert np.allclose(torso.compute(kin)[1], 0)
    # 10 deg torso pitch: 1 − cos(10°)
    q2 = robot.configuration("walk_ready")
    e = torso.compute(Kinematics(robot, q2))[1]
    pitch = np.arccos(robot.frame_placement(q2, "torso").rotation[2, 2])
    assert e[0] == pytest.approx(1 - np.cos(pitch))


def test_mask_and_weights(robot):
    kin = Kinematics(robot, robot.configuration("walk_ready"))
    full = FramePoseTask(robot, "r_sole", pin.SE3.Identity())
    masked = FramePoseTask(
        robot,
        "r_sole",
        pin.SE3.Identity(),
        mask=[0, 0, 1, 0, 0, 0],
        weight=[1, 2, 3, 4, 5, 6],
        name="z_only",
    )
    J, e = full.compute(kin)
    Jm, em = masked.compute(kin)
    assert masked.rows == 1
    assert np.allclose(Jm, J[2:3]) and np.allclose(em, e[2:3])
    assert np.allclose(masked.weight, [3.0])
    H, c = masked.objective(kin)
    assert np.allclose(H, 3.0 * Jm.T @ Jm)
    assert np.allclose(c, -3.0 * Jm.T @ em)


def test_contact_holds_where_it_was_made(robot):
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    contact = ContactTask(robot, "l_sole")
    contact.make_contact(kin)
    assert np.allclose(contact.compute(kin)[1], 0)
    kin.update(robot.integrate(q, np.r_[0.01, np.zeros(23)]))
    assert np.linalg.norm(contact.compute(kin)[1]) > 5e-3


def test_damping_and_posture(robot):
    kin = Kinematics(robot, robot.configuration("walk_ready"))
    d = DampingTask(robot, weight=np.r_[np.zeros(6), np.ones(18)])
    J, e = d.compute(kin)
    assert np.array_equal(J, np.eye(24)) and not e.any()
    p = PostureTask(robot, robot.configuration("zero"))
    J, e = p.compute(kin)
    assert np.allclose(e, -kin.q[7:])
    assert np.array_equal(J[:, 6:], np.eye(18)) and not J[:, :6].any()


@pytest.mark.parametrize("bad", [[np.nan, 0, 0], [0, np.inf, 0], [0, 0]])
def test_bad_targets_are_rejected(robot, bad):
    com = ComTask(robot)
    com.set_target([0.1, 0.2, 0.3])
    with pytest.raises(TaskError, match="com"):
        com.set_target(bad)
    assert np.array_equal(com.target, [0.1, 0.2, 0.3])  # checked before it is copied in


def test_a_refused_rotation_leaves_the_target_as_it_was(robot):
    pose = FramePoseTask(robot, "torso")
    R = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)
    pose.set_rotation_target(R)
    for bad in (np.diag([1.0, 1.0, -1.0]), 2 * R, np.full((3, 3), np.nan)):
        with pytest.raises(TaskError, match="rotation"):
            pose.set_rotation_target(bad)
        assert np.array_equal(pose.target_rotation, R)
    pose.set_rotation_target(R.T)  # a strided (transposed) view is copied as it reads
    assert np.array_equal(pose.target_rotation, R.T)


def test_bad_task_parameters(robot):
    with pytest.raises(TaskError, match="gain"):
        ComTask(robot, gain=-1)
    with pytest.raises(TaskError, match="mask"):
        ComTask(robot, mask=[1, 0])
    with pytest.raises(TaskError, match="selects no row"):
        ComTask(robot, mask=[0, 0, 0])
    with pytest.raises(TaskError, match="weight"):
        ComTask(robot, weight=[1, 2])
    with pytest.raises(TaskError, match="not a rotation"):
        FrameOrientationTask(robot, "torso", np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(TaskError, match=r"pinocchio\.SE3"):
        FramePoseTask(robot, "torso", target=np.eye(4))
    from wbc import ModelError

    with pytest.raises(ModelError, match="unknown frame"):
        FramePositionTask(robot, "nose")


def test_a_pose_target_packed_ahead_is_set_as_set_target_sets_it(robot):
    """FramePoseTask.pack_target checks a target as set_target does and packs it
    (position, rotation row-major); set_target(target, packed) then copies it: the same
    target arrays bit for bit. A rotation that fails the check packs to None (set_target
    raises as before); a subclass with its own setter ignores a packed target (its setter
    runs)."""
    rng = np.random.default_rng(3)
    for _ in range(8):
        target = pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3))
        direct, packed_task = FramePoseTask(robot, "l_sole"), FramePoseTask(robot, "l_sole")
        direct.set_target(target)
        packed = packed_task.pack_target(target)
        assert packed is not None and not np.array_equal(packed_task.target_packed, packed)
        packed_task.set_target(target, packed)
        assert np.array_equal(direct.target_packed, packed_task.target_packed)
        assert np.array_equal(packed_task.target_position, target.translation)
        assert np.array_equal(packed_task.target_rotation, target.rotation)
    skewed = pin.SE3(np.diag([1.0, 1.0, 1.1]), np.zeros(3))
    assert FramePoseTask(robot, "l_sole").pack_target(skewed) is None
    with pytest.raises(TaskError):
        FramePoseTask(robot, "l_sole").set_target(skewed)

    class Own(FramePoseTask):
        def set_position_target(self, position) -> None:
            super().set_position_target(np.asarray(position) + 1.0)

    own = Own(robot, "l_sole")
    own.set_target(target, FramePoseTask(robot, "l_sole").pack_target(target))
    assert np.array_equal(own.target_position, target.translation + 1.0)
