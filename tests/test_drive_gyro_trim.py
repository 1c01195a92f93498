"""The gyro's bias trimmed in walking double supports against the encoders
(wbc.drive.gyro_trim, ``Walker(gyro_trim=T0)``)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pinocchio as pin
import pytest

from wbc import load_robot
from wbc.drive.gyro_trim import TRIM_BOUND, RestPeriods, StanceTrim, stance_trim
from wbc.drive.odometry import PoseOdometry
from wbc.drive.walker import Walker
from wbc.exceptions import ConfigurationError
from wbc.imu import GRAVITY, Imu, ImuReading
from wbc.stacks import load_stack
from wbc.walking import GaitTiming, SwingParams
from wbc.walking.engine import EngineParams, VelocityLimits
from wbc.walking.loop import StackController

DT = 0.01
BIAS = np.array([0.01, -0.02, 0.005])  # rad/s, torso frame


@pytest.fixture(scope="module")
def robot():
    return load_robot("bioloid")


def turning(robot, ticks: int, rate: float = 0.2) -> list[np.ndarray]:
    """Standing, both hips' yaw turned together at ``rate`` (rad/s): the torso turns over
    both soles, which stay flat on each other."""
    q = robot.configuration("stand")
    out = []
    for k in range(ticks):
        qk = q.copy()
        for name in ("l_hip_yaw", "r_hip_yaw"):
            qk[7 + robot.joint_names.index(name)] += rate * DT * k
        out.append(qk)
    return out


def torso_rates(robot, qs: list[np.ndarray]) -> list[np.ndarray]:
    """The torso's rate over the left sole per tick (torso frame), by its placement."""
    R = [robot.frame_placement(q, "l_sole").actInv(robot.frame_placement(q, "torso")).rotation
         for q in qs]  # fmt: skip
    return [np.zeros(3)] + [pin.log3(a.T @ b) / DT for a, b in itertools.pairwise(R)]


def test_the_trim_is_the_bias_the_torso_turning_over_its_soles_taken_out(robot):
    """The gyro reads the torso's turn plus a bias: the trim is the bias (prior 0), its
    share T / (T0 + T) with a prior of T0 s; the turn alone (no bias) leaves no trim."""
    qs = turning(robot, 101)
    rates = torso_rates(robot, qs)
    assert np.linalg.norm(rates[-1]) == pytest.approx(0.2, rel=1e-3)  # (it does turn)
    for prior, share in ((0.0, 1.0), (1.0, 1.0 / 2.0)):
        trim = StanceTrim(robot, prior)
        for q, w in zip(qs, rates, strict=True):
            got = trim.sample(q, True, w + BIAS, DT)
        assert trim.time == pytest.approx(1.0)
        np.testing.assert_allclose(got, share * BIAS, atol=2e-4)
    still = StanceTrim(robot, 0.0)
    for q, w in zip(qs, rates, strict=True):
        got = still.sample(q, True, w, DT)
    np.testing.assert_allclose(got, 0.0, atol=2e-4)


def test_only_flat_walking_double_supports_are_taken_and_the_trim_is_bounded(robot):
    stand = robot.configuration("stand")
    tilted = stand.copy()
    tilted[7 + robot.joint_names.index("l_ankle_pitch")] += math.radians(8.0)
    trim = StanceTrim(robot, 0.0)
    for q, double in ((stand, False), (stand, False), (tilted, True), (tilted, True),
                      (None, True), (stand, True)):  # fmt: skip
        assert not trim.sample(q, double, BIAS, DT).any()
    assert trim.time == 0.0  # (a first flat tick has no last to compare with)
    big = np.array([0.0, 0.0, 1.0])
    for _ in range(5):
        got = trim.sample(stand, True, big, DT)
    assert got[2] == pytest.approx(TRIM_BOUND)
    assert trim.time == pytest.approx(5 * DT)


def test_the_odometry_s_unbiased_rate_takes_out_its_own_biases(robot):
    odo = PoseOdometry(robot)
    odo.yaw_bias, odo.rate_bias = 0.1, np.array([0.01, 0.0, 0.0])
    c, s = math.cos(0.3), math.sin(0.3)
    R = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # leaning 0.3 rad
    got = odo.unbiased(R, np.array([0.1, 0.2, 0.3]))
    np.testing.assert_allclose(got, [0.1 - 0.01 + 0.1 * s, 0.2, 0.3 - 0.1 * c])


def test_bad_priors_are_refused_and_zero_is_off(robot):
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ConfigurationError, match="gyro_trim"):
            stance_trim(robot, bad, True)
    assert stance_trim(robot, 0.0, True) is None
    assert stance_trim(robot, 5.0, False) is None
    assert isinstance(stance_trim(robot, 5.0, True), StanceTrim)


def test_the_rest_s_bias_over_whole_periods_takes_a_twist_in_step_with_the_rocking_out():
    """A torso rocking in pitch at 0.7 Hz twists with it about the vertical (a cosine of
    1°/s): over 1.5 s (about one period and a twentieth) the whole rest's mean takes the
    twist's incomplete period for bias, the whole periods' does not; without two upward
    crossings the given mean stands."""
    bias, w, dt = 0.004, 2 * math.pi * 0.7, DT
    t = np.arange(150) * dt
    pitch = 0.2 * np.sin(w * t)  # rad/s
    steps = (bias + math.radians(1.0) * np.cos(w * t + 0.3)) * dt
    periods = RestPeriods()
    for k in range(len(t)):
        got = periods.add(
            np.array([0.0, pitch[k], 0.01]), steps[k], dt, steps[: k + 1].sum() / ((k + 1) * dt)
        )
    plain = steps.sum() / (len(t) * dt)
    assert abs(plain - bias) > math.radians(0.01)  # (the plain mean is off)
    assert got == pytest.approx(bias, abs=math.radians(0.003))
    short = RestPeriods()
    assert short.add(np.zeros(3), 0.0, dt, 0.5) == 0.5
    assert short.add(np.array([0.0, 1.0, 0.0]), 0.0, dt, 0.7) == 0.7


def test_the_odometry_s_rest_over_whole_periods_is_the_rest_periods_mean(robot):
    """PoseOdometry(rest_periods=True) learns the whole periods' bias, the default the
    whole rest's mean."""
    w, dt = 2 * math.pi * 0.7, DT
    learnt = {}
    for on in (False, True):
        odo = PoseOdometry(robot, rest_periods=on)
        for k in range(150):
            t = k * dt
            twist = 0.004 + math.radians(1.0) * math.cos(w * t + 0.3)
            odo.rest(np.eye(3), np.array([0.0, 0.2 * math.sin(w * t), twist]), dt)
        learnt[on] = odo.yaw_bias
    assert learnt[True] == pytest.approx(0.004, abs=math.radians(0.003))
    assert abs(learnt[False] - 0.004) > math.radians(0.01)


def _walked(robot, **options) -> Walker:
    """A walker with a still IMU (zero rates, gravity at the stand's lean) on a plant that
    reads its goals, 450 ticks of a forward command (its 1.8 s rests first)."""
    (torso,) = robot.placements_in(robot.configuration("stand"), "l_sole", ["torso"])
    up = GRAVITY * torso.rotation[2]  # (the world's up in the torso frame, the sole flat)

    class Still(Imu):
        def read(self) -> ImuReading:
            return ImuReading(0.0, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), up)

    params = EngineParams(timing=GaitTiming(), swing=SwingParams(apex=0.015),
                          zmp_offset=(0.0, 0.0285), transfer=1.0)  # fmt: skip
    walker = Walker(robot, StackController(load_stack("walk", robot, solver="weighted")),
                    Still(), params=params, limits=VelocityLimits(0.08, 0.06, 0.03, 0.5),
                    window=None, **options)  # fmt: skip
    walker.present = lambda: walker.q[7:]
    walker.command(0.05, 0.0, 0.2)
    walker.start()
    for _ in range(450):
        walker.tick()
    return walker


def test_the_walker_trims_its_heading_in_double_supports_only_when_asked(robot):
    """Off by default (no trim, the rest's plain mean); ``gyro_trim``: the trim samples the
    walking double supports and reaches the odometry's heading; ``rest_periods`` reaches
    the odometry."""
    off = _walked(robot)
    assert off.trim is None and off.odometry is not None and off.odometry.periods is None
    on = _walked(robot, gyro_trim=0.5)
    assert isinstance(on.trim, StanceTrim) and on.trim.prior == 0.5
    assert 0.05 < on.trim.time < 4.5 * 0.6  # (double supports only)
    assert np.abs(on.trim.bias).max() > 1e-4
    assert abs(on.odometry.heading - off.odometry.heading) > 1e-5  # (bit for bit without)
    assert Walker(robot, StackController(load_stack("walk", robot, solver="weighted")),
                  on.imu, rest_periods=True).odometry.periods is not None  # fmt: skip
