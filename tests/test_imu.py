"""The IMU interface: readings are checked, and a user's own IMU plugs in."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wbc.exceptions import ConfigurationError
from wbc.imu import GRAVITY, Imu, ImuReading


def test_reading_rotation_and_tilt():
    half = math.radians(30) / 2
    r = ImuReading(0.5, [math.sin(half), 0, 0, math.cos(half)], [0, 0, 0], [0, 0, GRAVITY])
    np.testing.assert_allclose(
        r.rotation(), [[1, 0, 0], [0, math.cos(2 * half), -math.sin(2 * half)],
                       [0, math.sin(2 * half), math.cos(2 * half)]], atol=1e-12)  # fmt: skip
    assert math.degrees(r.tilt()) == pytest.approx(30)


@pytest.mark.parametrize(
    ("field", "value"),
    [("orientation", [0, 0, 1]), ("angular_velocity", [0, np.nan, 0]),
     ("linear_acceleration", [0, 0])],
)  # fmt: skip
def test_bad_readings_are_refused(field, value):
    good = {"orientation": [0, 0, 0, 1], "angular_velocity": [0, 0, 0],
            "linear_acceleration": [0, 0, GRAVITY]}  # fmt: skip
    with pytest.raises(ConfigurationError, match=f"ImuReading.{field}"):
        ImuReading(0.0, **{**good, field: value})


def test_a_user_imu_plugs_in():
    class Level(Imu):
        name = "level"

        def read(self) -> ImuReading:
            return ImuReading(1.0, [0, 0, 0, 1], [0, 0, 0], [0, 0, GRAVITY])

    with Level() as imu:
        assert imu.read().tilt() == 0.0
    with pytest.raises(TypeError):
        Imu()  # read() is abstract


def test_a_rotated_imu_reads_the_torso_through_its_mount():
    """ImuMount.to_torso: an IMU turned 90° about z and pitched 10° on the torso gives the
    torso's rotation, rate and specific force (the lever arm's centripetal part removed)."""
    import pinocchio as pin

    from wbc.imu import ImuMount

    mount = ImuMount.from_rpy((0.0, 10.0, 90.0), (0.02, 0.0, 0.05))
    M = mount.rotation
    assert np.allclose(M, pin.rpy.rpyToMatrix(0.0, np.radians(10.0), np.radians(90.0)))
    R_torso = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)
    w_torso = np.array([0.3, -0.5, 1.0])
    a_torso = np.array([0.2, 0.1, 9.7])
    a_imu = M.T @ (a_torso + np.cross(w_torso, np.cross(w_torso, mount.position)))
    quat = pin.Quaternion(R_torso @ M).coeffs()
    raw = ImuReading(0.0, np.asarray(quat), M.T @ w_torso, a_imu)
    r = mount.to_torso(raw)
    assert np.allclose(r.rotation(), R_torso)
    assert np.allclose(r.angular_velocity, w_torso) and np.allclose(r.linear_acceleration, a_torso)
    assert ImuMount().identity and not mount.identity
    with pytest.raises(ConfigurationError, match="rotation"):
        ImuMount(np.ones((3, 3)))


def test_calibration_at_rest_finds_the_bias_levels_and_refuses_a_wrong_mount():
    from wbc.imu import ImuError, calibrate

    rng = np.random.default_rng(0)
    bias = np.array([0.01, -0.02, 0.005])
    up = np.array([np.sin(0.03), 0.0, np.cos(0.03)])  # 1.7° off the kinematics' up
    gyros = bias + rng.normal(0, 0.002, (40, 3))
    accs = 9.81 * up + rng.normal(0, 0.02, (40, 3))
    cal = calibrate(gyros, accs, np.array([0.0, 0.0, 1.0]))
    assert np.allclose(cal.gyro_bias, bias, atol=1e-3)
    assert np.degrees(cal.tilt_error) == pytest.approx(1.72, abs=0.1)
    assert np.allclose(cal.level @ up, [0, 0, 1], atol=1e-3)  # levelled
    moving = calibrate(gyros, accs, [0, 0, 1], motion=np.array([0.01, 0.0, 0.0]))
    assert moving.gyro_bias[0] == pytest.approx(bias[0] - 0.01, abs=1e-3)
    tilted = 9.81 * np.array([np.sin(0.2), 0.0, np.cos(0.2)]) + np.zeros((40, 3))
    with pytest.raises(ImuError, match=r"gravity measured 11\.5° from .* check the mount"):
        calibrate(gyros, tilted, [0, 0, 1], where="the mount")
    with pytest.raises(ImuError, match="not at rest"):
        calibrate(gyros, accs * 2, [0, 0, 1])


def test_the_quietest_window_is_where_the_gyro_moved_least():
    """wbc.imu.quietest_window: among the windows ending at ``first_end`` or later, the one
    whose samples spread least about their mean (window_spread: 0 for a constant rate)."""
    from wbc.imu import quietest_window, window_spread

    t = np.arange(100) * 0.01
    amp = np.where(t < 0.5, 0.3, 0.0) + np.where((t > 0.8) & (t < 0.9), 0.1, 0.0)
    g = np.c_[np.zeros(100), amp * np.sin(2 * np.pi * 4 * t), np.full(100, 0.01)]
    assert window_spread(np.tile([0.01, 0.02, 0.03], (10, 1))) < 1e-12
    start = quietest_window(g, 15, 30)
    assert start >= 15 and window_spread(g[start : start + 15]) < 1e-12  # (in 0.50–0.80 s)
    assert 50 <= start <= 65
    assert quietest_window(g, 15, 100) == 85  # only the last window ends that late
    noisy = np.random.default_rng(0).normal(0.0, 0.02, (30, 3))  # white noise: no motion
    assert window_spread(noisy) < 0.01 < window_spread(g[10:40])
