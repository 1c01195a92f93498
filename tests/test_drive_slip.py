"""The stance sole's slip by the IMU against the kinematics (wbc.drive.slip)."""

from __future__ import annotations

import numpy as np
import pytest

from wbc import load_robot
from wbc.drive.slip import LastReading, SlipEstimate
from wbc.drive.walker import Walker
from wbc.exceptions import ConfigurationError
from wbc.geometry import heading_free, rot_z, yaw_of
from wbc.imu import Imu, ImuReading
from wbc.stacks import load_stack
from wbc.walking import GaitTiming, SwingParams
from wbc.walking.engine import EngineParams, VelocityLimits
from wbc.walking.loop import StackController

DT = 0.01


@pytest.fixture(scope="module")
def robot():
    return load_robot("bioloid")


def _force(robot, q, a_world: np.ndarray, sole_heading: float) -> tuple[np.ndarray, float]:
    """The specific force (torso frame) of a torso accelerating by ``a_world`` and the
    torso's heading, the left sole at ``sole_heading`` (flat)."""
    (torso,) = robot.placements_in(q, "l_sole", ["torso"])
    heading = sole_heading + yaw_of(torso.rotation)
    R = rot_z(heading) @ heading_free(torso.rotation)
    return R.T @ (a_world + np.array([0.0, 0.0, 9.81])), heading


def _interval(robot, slip: SlipEstimate, a_world: np.ndarray, n: int, sole: float = 0.3):
    q = robot.configuration("stand")
    slip.landed("left")  # the left sole's interval starts
    still, heading = _force(robot, q, np.zeros(3), sole)
    for _ in range(slip.window + 1):  # (the kinematics' velocity: still)
        slip.tick(q, still, sole, heading, DT)
    for _ in range(n):
        acc, heading = _force(robot, q, a_world, sole)
        slip.tick(q, acc, sole, heading, DT)
    slip.tick(q, still, sole, heading, DT)  # (the last force integrated)
    return slip.landed("right")


def test_a_still_torso_over_a_still_sole_reads_no_slip(robot):
    slip = SlipEstimate(robot, gain=1.0)
    assert np.allclose(_interval(robot, slip, np.zeros(3), 40), 0.0, atol=1e-9)


def test_the_imu_moving_where_the_legs_do_not_reads_the_sole_slid(robot):
    a = np.array([0.02, -0.01, 0.0])  # m/s², 0.4 s: the torso moved 1.6, -0.8 mm
    slip = SlipEstimate(robot, gain=1.0, most=1.0)
    moved = _interval(robot, slip, a, 40)
    assert np.allclose(moved, 0.5 * a[:2] * (40 * DT) ** 2, rtol=1e-6)
    half = SlipEstimate(robot, gain=0.5, most=1.0)
    assert np.allclose(_interval(robot, half, a, 40), 0.5 * moved)
    capped = SlipEstimate(robot, gain=1.0, most=0.001)
    assert np.linalg.norm(_interval(robot, capped, a, 40)) == pytest.approx(0.001)


def test_a_landing_of_the_same_sole_or_the_first_reads_nothing(robot):
    slip = SlipEstimate(robot, gain=1.0)
    assert not slip.landed("left").any()  # (no interval yet)
    assert not slip.landed("left").any()  # (not the other sole's)


@pytest.mark.parametrize("gain", [-0.1, 1.5, float("nan")])
def test_a_gain_outside_0_1_is_refused(robot, gain):
    with pytest.raises(ConfigurationError):
        SlipEstimate(robot, gain)


class Counting(Imu):
    name = "counting"

    def __init__(self) -> None:
        self.n = 0

    def read(self) -> ImuReading:
        self.n += 1
        return ImuReading(float(self.n), np.array([0, 0, 0, 1.0]), np.zeros(3),
                          np.array([0.0, 0.0, 9.81]))  # fmt: skip


def test_the_walker_reads_the_slip_only_when_asked(robot):
    """``Walker(slip_gain=0)`` (the default): no estimate, the IMU as given; above 0 the
    stabiliser reads the IMU through :class:`LastReading`; outside [0, 1] refused."""
    params = EngineParams(timing=GaitTiming(), swing=SwingParams(apex=0.015),
                          zmp_offset=(0.0, 0.0285), transfer=1.0)  # fmt: skip
    kw = dict(params=params, limits=VelocityLimits(0.08, 0.06, 0.03, 0.5), window=None)
    controller = StackController(load_stack("walk", robot, solver="weighted"))
    imu = Counting()
    off = Walker(robot, controller, imu, **kw)
    assert off.slip is None and off.stabilizer.imu is imu
    on = Walker(robot, controller, imu, slip_gain=0.1, **kw)
    assert isinstance(on.slip, SlipEstimate) and on.slip.gain == 0.1
    assert isinstance(on.stabilizer.imu, LastReading) and on.stabilizer.imu.imu is imu
    with pytest.raises(ConfigurationError, match="slip"):
        Walker(robot, controller, imu, slip_gain=1.5, **kw)


def test_the_last_reading_is_the_one_read():
    imu = LastReading(Counting())
    assert imu.last is None
    r = imu.read()
    assert imu.last is r and r.t == 1.0
