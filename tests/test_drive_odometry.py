"""wbc.drive.odometry: the IMU-aided pose odometry of driven walks."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc import load_robot
from wbc.compiled.rows import log3
from wbc.drive.odometry import PoseOdometry
from wbc.geometry import yaw_of
from wbc.walking import StandingState


@pytest.fixture(scope="module")
def robot():
    return load_robot("bioloid")


@settings(max_examples=20, deadline=None)
@given(
    st.floats(0.0, 0.3),  # lean (pitch, rad)
    st.floats(0.02, 0.15),  # roll amplitude
    st.floats(0.0, 0.08),  # pitch amplitude
    st.floats(-0.6, 0.6),  # turning rate (rad/s)
    st.floats(0.0, 2 * math.pi),  # phase
)
def test_heading_of_a_leaning_rocking_torso(robot, lean, roll, pitch, rate, phase) -> None:
    """The heading integrated from the body rates is the torso's heading (the yaw of its
    rotation), however the torso leans and rocks meanwhile: 10 s of a walk's rocking (1 Hz
    roll, pitch out of phase) at 100 Hz, within 0.3°. (The vertical rate's integral,
    ``Σ (R ω)_z dt``, is not: it drifts by the rocking's enclosed area per cycle, ~20° over
    30 s on the randomised Bioloids.)"""
    dt, w = 0.01, 2 * math.pi
    t = np.arange(1001) * dt

    def R(tk: float) -> np.ndarray:
        return pin.rpy.rpyToMatrix(roll * math.sin(w * tk),
                                   lean + pitch * math.sin(w * tk + phase), rate * tk)  # fmt: skip

    odo = PoseOdometry(robot)
    v = np.empty(3)
    for a, b in itertools.pairwise(t):
        Ra, Rb = R(a), R(b)
        log3(np.ascontiguousarray(Ra.T @ Rb), v)
        odo.turn(Ra, v / dt, dt)
    assert odo.heading == pytest.approx(rate * t[-1], abs=math.radians(0.3))


def test_a_stance_sole_turned_on_the_floor_is_seen(robot) -> None:
    """The robot standing, its stance (right) sole turned by 0.2 rad on the floor — the IMU
    sees the torso's heading turned, the encoders nothing: the landed left sole is placed
    turned about the right one, and the walking frame measured heads 0.2 rad left of the
    plan (the engine's own leg odometry would see no offset at all)."""
    q = robot.configuration("stand")
    start = StandingState.from_robot(robot, q)
    feet = {"left": start.left, "right": start.right}
    torso = yaw_of(robot.frame_placement(q, "torso").rotation)
    odo = PoseOdometry(robot)
    odo.start(feet, torso)
    still = odo.landed("left", q)
    mid = 0.5 * (start.left.xy + start.right.xy)
    assert still[:2] == pytest.approx(mid, abs=1e-5)  # (the stand pose's soles not quite flat)
    assert still[2] == pytest.approx(0.5 * (start.left.yaw + start.right.yaw), abs=1e-3)
    odo.start(feet, torso + 0.2)
    turned = odo.landed("left", q)
    assert turned[2] == pytest.approx(still[2] + 0.2, abs=1e-6)
    c, s = math.cos(0.2), math.sin(0.2)
    left = start.right.xy + np.array([[c, -s], [s, c]]) @ (start.left.xy - start.right.xy)
    assert odo.soles["left"][:2] == pytest.approx(left, abs=1e-5)
    assert odo.soles["right"][:2] == pytest.approx(start.right.xy)  # (a sole does not slide)
