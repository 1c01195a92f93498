"""State estimator: complementary filter (gyro + accelerometer) and stance-leg kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc.balance.estimator import StateEstimator, cross
from wbc.exceptions import WbcError
from wbc.imu import GRAVITY, ImuReading
from wbc.model import load_robot


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def reading(R: np.ndarray, omega=(0.0, 0.0, 0.0)) -> ImuReading:
    """What a still IMU with rotation R (torso in world) measures."""
    quat = pin.Quaternion(R).coeffs()
    return ImuReading(0.0, quat, np.asarray(omega, float), R.T @ np.array([0, 0, GRAVITY]))


def standing(robot):
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    return q, robot.frame_placement(q, "l_sole"), robot.frame_placement(q, "r_sole")


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-3, 3), min_size=6, max_size=6))
def test_cross_is_the_cross_product(v):
    a, b = np.array(v[:3]), np.array(v[3:])
    assert np.allclose(cross(a, b), np.cross(a, b))


def test_kinematics_give_the_true_com(robot):
    """Encoders only, standing on both planned soles: base and CoM are forward kinematics'."""
    q, left, right = standing(robot)
    est = StateEstimator(robot, 0.2, use_imu=False)
    e = est.update(0.01, q[7:], None, [("l_sole", left), ("r_sole", right)])
    assert np.allclose(e.com, robot.com(q), atol=1e-9)
    assert np.allclose(e.base, q[:3], atol=1e-9)
    assert np.allclose(e.rotation, robot.frame_placement(q, "torso").rotation, atol=1e-9)
    assert np.allclose(e.com_vel, 0.0)


def test_imu_tilt_moves_the_com(robot):
    """Standing on the left sole with the whole robot tilted 5° about the sole (the IMU sees
    it, the encoders do not): the CoM estimate follows the tilted body. (The heading, ZYX
    yaw, is the encoders': the tilt keeps the torso's yaw.)"""
    q, left, _ = standing(robot)
    roll, pitch, yaw = pin.rpy.matrixToRpy(robot.frame_placement(q, "torso").rotation)
    R0 = pin.rpy.rpyToMatrix(roll, pitch, yaw)
    tilt = pin.rpy.rpyToMatrix(roll + 0.0872665, pitch, yaw) @ R0.T  # +5° roll
    tilted = pin.SE3(tilt, left.translation - tilt @ left.translation) * pin.XYZQUATToSE3(q[:7])
    q_true = q.copy()
    q_true[:7] = pin.SE3ToXYZQUAT(tilted)
    R_torso = robot.frame_placement(q_true, "torso").rotation
    est = StateEstimator(robot, 0.2)
    est.reset(R_torso)
    e = est.update(0.01, q[7:], reading(R_torso), [("l_sole", left)])
    assert np.allclose(e.com, robot.com(q_true), atol=1e-6)
    enc = StateEstimator(robot, 0.2, use_imu=False).update(0.01, q[7:], None, [("l_sole", left)])
    assert np.linalg.norm(enc.com - robot.com(q_true)) > 0.01  # the encoders alone miss it


def test_filter_converges_to_the_accelerometer_tilt(robot):
    """Started upright while the IMU is still and tilted 6° in pitch, the filter converges
    to the tilt at its gain (time constant 1/k) and keeps the kinematic heading."""
    q, left, _ = standing(robot)
    R_true = pin.rpy.rpyToMatrix(0.0, 0.1047, 0.0)
    est = StateEstimator(robot, 0.2, tilt_gain=2.0)
    est.reset(np.eye(3))
    for _ in range(300):  # 3 s = 6 time constants
        e = est.update(0.01, q[7:], reading(R_true), [("l_sole", left)])
    angle = np.arccos(np.clip(e.rotation[:, 2] @ R_true[:, 2], -1, 1))
    assert angle < np.radians(0.1)
    half = StateEstimator(robot, 0.2, tilt_gain=2.0)
    half.reset(np.eye(3))
    for _ in range(35):  # 0.35 s: 1 − e^(−0.7) ≈ 50 % of the way
        e = half.update(0.01, q[7:], reading(R_true), [("l_sole", left)])
    got = np.arccos(np.clip(e.rotation[2, 2], -1, 1))
    assert 0.4 * 0.1047 < got < 0.6 * 0.1047


def test_gyro_is_integrated(robot):
    """A constant roll rate with the accelerometer ignored (the tilt gain tiny): the
    filter's roll is the integral."""
    q, left, _ = standing(robot)
    est = StateEstimator(robot, 0.2, tilt_gain=1e-9)
    est.reset(np.eye(3))
    for _ in range(50):
        e = est.update(0.01, q[7:], reading(np.eye(3), omega=(0.2, 0.0, 0.0)), [("l_sole", left)])
    assert pin.rpy.matrixToRpy(e.rotation)[0] == pytest.approx(0.1, abs=1e-6)


def test_com_velocity_and_dcm(robot):
    """Joints moving the CoM relative to the stance sole: the filtered velocity converges to
    the CoM's rate; DCM = c + ċ/ω₀; a support switch (same body) makes no velocity jump."""
    q, left, right = standing(robot)
    est = StateEstimator(robot, 0.2, use_imu=False, velocity_cutoff=20.0)
    j = robot.joint_index("l_ankle_roll"), robot.joint_index("r_ankle_roll")
    dt, rate = 0.01, 0.2  # rad/s on both ankle rolls: the body sways sideways
    coms = []
    for k in range(40):
        joints = q[7:].copy()
        joints[list(j)] += rate * dt * k
        e = est.update(dt, joints, None, [("l_sole", left), ("r_sole", right)])
        coms.append(e.com)
    true_vel = (coms[-1] - coms[-2]) / dt
    assert np.allclose(e.com_vel, true_vel, atol=2e-3)
    assert np.linalg.norm(true_vel) > 0.01
    assert np.allclose(e.dcm[:2], e.com[:2] + e.com_vel[:2] / est.omega0)
    assert est.omega0 == pytest.approx(np.sqrt(GRAVITY / 0.2))
    with pytest.raises(WbcError, match="com_height"):
        StateEstimator(robot, 0.0)
    with pytest.raises(WbcError, match="no stance"):
        est.update(dt, q[7:], None, [])
