"""Safety layer: safe command range, clamping, rate limiting, soft start, watchdog, checks."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc.exceptions import ServoError, TrajectoryError
from wbc.servo_map import RAD_PER_TICK
from wbc.servos.bus import COMM_CORRUPT, COMM_OK, COMM_TIMEOUT, Codec, DryRunBus, ServoStatus
from wbc.servos.dynamixel import ax_codec
from wbc.servos.safety import (
    GoalLimiter,
    Watchdog,
    check_trajectory,
    max_step,
    soft_start_targets,
)


@pytest.fixture(scope="module")
def codec(robot):
    return ax_codec(robot.servo_map)


@pytest.fixture()
def limiter(robot, codec):
    step = max_step(codec, robot.v_max, 0.02)
    lim = GoalLimiter(codec, robot.q_min, robot.q_max, step, robot.joint_names)
    lim.reset(codec.encode_float(robot.configuration("walk_ready")[7:]))
    return lim


def test_safe_range_commands_decode_inside_the_urdf_limits(robot, codec):
    lo, hi = codec.safe_range(robot.q_min, robot.q_max, robot.joint_names)
    assert np.all(lo >= 0) and np.all(hi <= 1023) and np.all(lo < hi)
    for cmd in (lo, hi):
        q = codec.decode(cmd)
        assert np.all(q >= robot.q_min - 1e-9) and np.all(q <= robot.q_max + 1e-9)
    # one tick further would leave the limits (or the servo range): the range is the largest
    for cmd, out in ((lo - 1, True), (hi + 1, True)):
        q = codec.decode(cmd)
        beyond = (q < robot.q_min - 1e-9) | (q > robot.q_max + 1e-9) | (cmd < 0) | (cmd > 1023)
        assert np.all(beyond == out)
    # shoulder pitch limits reach 0.5 / 1023.5 ticks: the hardware range wins
    j = robot.joint_index("l_shoulder_pitch")
    assert (lo[j], hi[j]) == (1, 1023)


def test_safe_range_refuses_limits_outside_the_servo(robot):
    codec = Codec(np.full(2, 512.0), np.full(2, 1 / RAD_PER_TICK), 0, 1023)
    with pytest.raises(ServoError, match=r"b: limits \[3.0000, 4.0000\]"):
        codec.safe_range(np.array([0.0, 3.0]), np.array([1.0, 4.0]), ["a", "b"])


def test_max_step_from_the_servo_speed(robot, codec):
    step = max_step(codec, robot.v_max, 0.02)
    assert np.all(step == int(6.178466 * 0.02 / RAD_PER_TICK))  # 24 ticks at 50 Hz
    assert np.all(max_step(codec, 1e-6, 0.01) == 1)


def test_clamp_counts_and_reports(robot, limiter):
    q = robot.configuration("walk_ready")[7:].copy()
    j = robot.joint_index("l_knee")
    q[j] = robot.q_max[j] + 0.2
    for _ in range(30):  # long enough for the rate limit to let the knee reach its limit
        cmd = limiter(q)
    assert cmd[j] == limiter.hi[j] or cmd[j] == limiter.lo[j]
    assert limiter.report.clamped[j] == 30
    assert limiter.report.worst_excess[j] == pytest.approx(0.2)
    assert limiter.report.clamped.sum() == 30
    assert any("l_knee" in line for line in limiter.report.lines())


def test_nan_target_is_refused(robot, limiter):
    q = robot.configuration("walk_ready")[7:].copy()
    q[3] = np.nan
    with pytest.raises(ServoError, match="l_knee"):
        limiter(q)


@given(st.lists(st.lists(st.floats(-5, 5), min_size=18, max_size=18), min_size=1, max_size=15))
def test_every_command_is_in_range_and_rate(robot, codec, targets):
    step = max_step(codec, robot.v_max, 0.01)
    lim = GoalLimiter(codec, robot.q_min, robot.q_max, step, robot.joint_names)
    prev = lim.reset(codec.encode_float(robot.configuration("walk_ready")[7:]))
    for q in targets:
        cmd = lim(np.array(q))
        assert np.all(cmd >= lim.lo) and np.all(cmd <= lim.hi)
        assert np.all(np.abs(cmd - prev) <= step)
        q_sent = codec.decode(cmd)
        assert np.all(q_sent >= robot.q_min - 1e-9) and np.all(q_sent <= robot.q_max + 1e-9)
        prev = cmd


def test_rate_limit_counts(robot, limiter):
    q = robot.configuration("walk_ready")[7:].copy()
    j = robot.joint_index("r_elbow")
    q[j] -= 0.5  # 97.7 ticks at once: 4 rate-limited steps of 24 ticks, then 2 ticks
    cmds = [limiter(q) for _ in range(6)]
    steps = np.abs(
        np.diff(
            [limiter.codec.encode_float(robot.configuration("walk_ready")[7:])[j]]
            + [c[j] for c in cmds]
        )
    )
    assert np.all(steps <= limiter.step[j] + 0.5)
    assert limiter.report.rate_limited[j] == 4
    assert limiter.report.rate_limited.sum() == 4 and limiter.report.clamped.sum() == 0


def test_soft_start_is_a_synchronised_straight_line():
    start = np.array([100.0, 500.0, 800.0])
    goal = np.array([160.0, 500.0, 770.0])
    path = soft_start_targets(start, goal, np.array([6, 6, 6]))
    assert len(path) == 10
    assert np.allclose(path[-1], goal)
    steps = np.abs(np.diff(np.vstack([start, *path]), axis=0))
    assert np.all(steps <= 6 + 1e-9)
    assert np.allclose(steps[:, 0], 6) and np.allclose(steps[:, 2], 3)
    assert soft_start_targets(goal, goal, np.array([6, 6, 6])) == []


def test_watchdog_needs_consecutive_failures():
    wd = Watchdog(["a", "b"], max_failures=3)
    assert wd.observe(ServoStatus(1, COMM_TIMEOUT)) is None
    assert wd.observe(ServoStatus(1, COMM_TIMEOUT)) is None
    assert wd.failing() == 1
    assert wd.observe(ServoStatus(1, COMM_OK)) is None  # a good reply resets the streak
    assert wd.failing() is None
    for _ in range(2):
        assert wd.observe(ServoStatus(1, COMM_CORRUPT)) is None
    trip = wd.observe(ServoStatus(1, COMM_TIMEOUT))
    assert trip is not None and trip.index == 1 and trip.servo == "b"
    assert "3 consecutive" in trip.reason


@pytest.mark.parametrize(
    ("error", "name"),
    [(0x20, "overload"), (0x04, "overheating"), (0x01, "input_voltage"), (0x02, "angle_limit")],
)
def test_watchdog_trips_on_error_bits(error, name):
    from wbc.servos.dynamixel import fault_names

    wd = Watchdog(["a"])
    status = ServoStatus(0, COMM_OK, fault_names(error), error, 512.0, 11.1, 71.0)
    trip = wd.observe(status)
    assert trip is not None and trip.servo == "a" and name in trip.reason


def test_watchdog_ignores_non_trip_bits_and_tracks_the_board():
    wd = Watchdog(["a"], max_failures=2, bus_label="board")
    assert wd.observe(ServoStatus(0, COMM_OK, ("checksum",), 0x10)) is None
    assert wd.observe(ServoStatus(None, COMM_TIMEOUT)) is None
    trip = wd.observe(ServoStatus(None, COMM_TIMEOUT))
    assert trip is not None and trip.index is None and trip.servo == "board"


def test_check_trajectory_names_joint_and_tick(robot):
    n = 5
    traj = np.tile(robot.configuration("walk_ready")[7:], (n, 1))
    t = np.arange(n) * 0.02
    check_trajectory(traj, robot.q_min, robot.q_max, robot.joint_names, t=t)
    bad = traj.copy()
    bad[3, robot.joint_index("r_knee")] = np.nan
    with pytest.raises(TrajectoryError, match=r"tick 3 \(t = 0.060 s\): joint r_knee is nan"):
        check_trajectory(bad, robot.q_min, robot.q_max, robot.joint_names, t=t)
    bad = traj.copy()
    j = robot.joint_index("l_hip_roll")
    bad[2, j] = robot.q_max[j] + 0.01
    with pytest.raises(TrajectoryError, match=r"tick 2.*l_hip_roll.*above its upper limit"):
        check_trajectory(bad, robot.q_min, robot.q_max, robot.joint_names)
    bad[2, j] = robot.q_max[j] + 0.0005  # within the tolerance: accepted (and clamped later)
    check_trajectory(bad, robot.q_min, robot.q_max, robot.joint_names, tol=1e-3)


def test_dry_run_bus_refuses_goals_outside_the_limits(robot, codec):
    start = np.rint(codec.encode_float(robot.configuration("walk_ready")[7:]))
    bus = DryRunBus(codec, robot.joint_names, start)
    with pytest.raises(ServoError, match="before the command limits"):
        bus.write_goals(start.astype(int))
    lo, hi = codec.safe_range(robot.q_min, robot.q_max, robot.joint_names)
    bus.set_command_limits(lo, hi)
    bad = start.astype(int)
    bad[0] = hi[0] + 1
    with pytest.raises(ServoError, match="l_hip_yaw"):
        bus.write_goals(bad)
    with pytest.raises(ServoError, match="integer"):
        bus.write_goals(start)


@given(st.lists(st.floats(-2.0, 2.0), min_size=18, max_size=18))
def test_ax_codec_is_the_servo_map(robot, codec, q):
    """Angles <-> ticks of the AX backend are exactly the servo map's conversion."""
    sm = robot.servo_map
    q = np.array(q)
    assert np.allclose(codec.encode_float(q), sm.angles_to_ticks_float(q), atol=1e-9)
    ticks = np.clip(np.rint(codec.encode_float(q)), 0, 1023).astype(int)
    assert np.allclose(codec.decode(ticks), sm.ticks_to_angles(ticks), atol=1e-12)
