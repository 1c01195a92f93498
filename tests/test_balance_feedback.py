"""Gyro feedback: offsets that turn the torso against its measured rotation, clipped and
inside the joint limits."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc.balance.feedback import OP3_GAINS, FeedbackSource, GyroFeedback
from wbc.exceptions import ConfigurationError
from wbc.imu import Imu, ImuReading
from wbc.model import load_robot


class FixedImu(Imu):
    def __init__(self, omega) -> None:
        self.omega = np.asarray(omega, dtype=float)

    def read(self) -> ImuReading:
        return ImuReading(0.0, np.array([0.0, 0.0, 0.0, 1.0]), self.omega, np.zeros(3))


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def test_gains_by_joint(robot):
    fb = GyroFeedback(robot, FixedImu([0.0, 0.0, 0.0]), scale=0.5)
    for name, k in zip(robot.joint_names, fb.k, strict=True):
        suffix = name.split("_", 1)[1]
        assert k == pytest.approx(0.5 * OP3_GAINS.get(suffix, 0.0))
    with pytest.raises(ConfigurationError, match="scale"):
        GyroFeedback(robot, FixedImu([0.0, 0.0, 0.0]), scale=-1.0)


@settings(max_examples=20, deadline=None)
@given(st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3), st.sampled_from(["l", "r"]))
def test_offsets_turn_the_torso_against_the_rate(omega, side):
    """With the stance sole held flat, the offsets turn the torso by r with r · ω <= 0."""
    robot = load_robot()
    omega = np.array(omega)
    fb = GyroFeedback(robot, FixedImu(omega), scale=0.01, max_offset=1.0)
    q = robot.configuration("walk_ready")
    joints = robot.joints(q).copy()
    d = fb.offsets(joints)
    for j, name in enumerate(robot.joint_names):  # the stance leg's offsets only
        if not name.startswith(side):
            d[j] = 0.0
    q1 = robot.place_on_ground(robot.with_joints(joints + d), f"{side}_sole")
    q0 = robot.place_on_ground(q, f"{side}_sole")
    R0 = pin.Quaternion(q0[3:7]).toRotationMatrix()
    R1 = pin.Quaternion(q1[3:7]).toRotationMatrix()
    r = pin.log3(R0.T @ R1)  # torso rotation, torso frame
    assert r @ omega <= 1e-12
    if np.linalg.norm(omega[:2]) > 0.1:  # a roll/pitch rate is damped
        assert r @ omega < 0


def test_offsets_are_clipped_and_goals_inside_limits(robot):
    fb = GyroFeedback(robot, FixedImu([50.0, -50.0, 0.0]), max_offset=0.1)
    joints = robot.joints(robot.configuration("walk_ready"))
    d = fb.offsets(joints)
    assert np.abs(d).max() == pytest.approx(0.1)
    assert d[robot.joint_index("l_shoulder_pitch")] == 0.0  # arms untouched

    class Src:
        joint_names = robot.joint_names

        def first(self):
            return robot.q_max.copy()

        def __call__(self, tick, t):
            return None if t > 0.1 else robot.q_max.copy()

    src = FeedbackSource(Src(), GyroFeedback(robot, FixedImu([50.0, -50.0, 0.0])))
    out = src(0, 0.0)
    assert np.all(out <= robot.q_max) and np.all(out >= robot.q_min)
    assert src(20, 0.2) is None
