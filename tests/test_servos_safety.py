"""Safety layer: safe command range, clamping, rate limit in time, soft start, watchdog, health
schedule, checks."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc.exceptions import ServoError, TrajectoryError
from wbc.servo_map import RAD_PER_TICK
from wbc.servos.bus import COMM_CORRUPT, COMM_OK, COMM_TIMEOUT, Codec, DryRunBus, ServoStatus
from wbc.servos.protocol1 import ax_codec
from wbc.servos.safety import (
    GoalLimiter,
    HealthSchedule,
    Watchdog,
    check_trajectory,
    command_speed,
    soft_start_target,
)


@pytest.fixture(scope="module")
def codec(robot):
    return ax_codec(robot.servo_map)


@pytest.fixture()
def limiter(robot, codec):
    lim = GoalLimiter(
        codec, robot.q_min, robot.q_max, command_speed(codec, robot.v_max), robot.joint_names
    )
    lim.reset(codec.encode_float(robot.configuration("walk_ready")[7:]), 0.0)
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


def test_allowed_step_from_the_servo_speed_and_elapsed_time(robot, limiter):
    assert np.all(limiter.allowed(0.02) == int(6.178466 * 0.02 / RAD_PER_TICK))  # 24 at 50 Hz
    assert np.all(limiter.allowed(0.0) == 0)
    assert np.all(limiter.allowed(0.001) == 1)  # 1.2 ticks in 1 ms: one tick, never two
    slow = command_speed(limiter.codec, 0.5)  # 97.7 ticks/s
    assert np.all(limiter.allowed(0.01, slow) == 0)  # 0.98 of a tick: not yet
    assert np.all(limiter.allowed(0.011, slow) == 1)


def test_clamp_counts_and_reports(robot, limiter):
    q = robot.configuration("walk_ready")[7:].copy()
    j = robot.joint_index("l_knee")
    q[j] = robot.q_max[j] + 0.2
    for k in range(30):  # long enough for the rate limit to let the knee reach its limit
        cmd = limiter(q, 0.02 * (k + 1))
    assert cmd[j] == limiter.hi[j] or cmd[j] == limiter.lo[j]
    assert limiter.report.clamped[j] == 30
    assert limiter.report.worst_excess[j] == pytest.approx(0.2)
    assert limiter.report.clamped.sum() == 30
    assert any("l_knee" in line for line in limiter.report.lines())


def test_nan_target_is_refused(robot, limiter):
    q = robot.configuration("walk_ready")[7:].copy()
    q[3] = np.nan
    with pytest.raises(ServoError, match="l_knee"):
        limiter(q, 0.02)


@given(
    st.lists(
        st.tuples(
            st.floats(1e-4, 0.1),  # time since the previous goal: bursts and late ticks
            st.lists(st.floats(-5, 5), min_size=18, max_size=18),
        ),
        min_size=1,
        max_size=15,
    )
)
def test_every_command_is_in_range_and_never_faster_than_the_servo(robot, codec, ticks):
    """Law: between any two goals sent, each joint's goal moved at most speed x elapsed time
    plus one command unit (the quantum), whatever the tick timing (late ticks, ticks 0.1 ms
    apart): never a burst."""
    speed = command_speed(codec, robot.v_max)
    lim = GoalLimiter(codec, robot.q_min, robot.q_max, speed, robot.joint_names)
    sent = [(0.0, lim.reset(codec.encode_float(robot.configuration("walk_ready")[7:]), 0.0))]
    now = 0.0
    for dt, q in ticks:
        now += dt
        cmd = lim(np.array(q), now)
        assert np.all(cmd >= lim.lo) and np.all(cmd <= lim.hi)
        q_sent = codec.decode(cmd)
        assert np.all(q_sent >= robot.q_min - 1e-9) and np.all(q_sent <= robot.q_max + 1e-9)
        sent.append((now, cmd))
    for a in range(len(sent)):
        for b in range(a + 1, len(sent)):
            (ta, ca), (tb, cb) = sent[a], sent[b]
            assert np.all(np.abs(cb - ca) <= speed * (tb - ta) + 1 + 1e-9)


def test_rate_limit_counts(robot, limiter):
    q = robot.configuration("walk_ready")[7:].copy()
    j = robot.joint_index("r_elbow")
    q[j] -= 0.5  # 97.7 ticks at once: 4 rate-limited steps of 24 ticks (50 Hz), then 2 ticks
    cmds = [limiter(q, 0.02 * (k + 1)) for k in range(6)]
    steps = np.abs(
        np.diff(
            [limiter.codec.encode_float(robot.configuration("walk_ready")[7:])[j]]
            + [c[j] for c in cmds]
        )
    )
    assert np.all(steps <= 24 + 0.5)
    assert limiter.report.rate_limited[j] == 4
    assert limiter.report.rate_limited.sum() == 4 and limiter.report.clamped.sum() == 0


def test_soft_start_is_a_synchronised_straight_line():
    start = np.array([100.0, 500.0, 800.0])
    goal = np.array([160.0, 500.0, 770.0])
    speed = np.array([60.0, 60.0, 60.0])  # units/s: the longest move (60) takes 1 s
    path = np.array([soft_start_target(start, goal, speed, t) for t in np.linspace(0, 1.5, 16)])
    assert np.allclose(path[10:], goal)  # arrived at 1 s, every joint together
    assert np.allclose(path[5], (start + goal) / 2)
    steps = np.abs(np.diff(path, axis=0))  # 0.1 s apart
    assert np.all(steps <= 6 + 1e-9)
    assert np.allclose(steps[:10, 0], 6) and np.allclose(steps[:10, 2], 3)
    assert np.allclose(soft_start_target(goal, goal, speed, 0.0), goal)


@pytest.mark.parametrize("rate", [100.0, 50.0])
def test_soft_start_never_exceeds_its_speed(robot, codec, rate):
    """The limiter at the soft speed (0.5 rad/s = 97.7 ticks/s: less than one tick per tick at
    100 Hz) never moves a goal faster than 0.5 rad/s (+ one tick over any window), unlike a
    one-tick minimum step (0.51 rad/s: 150 ticks in 1.5 s instead of 146.6)."""
    soft = command_speed(codec, 0.5)
    lim = GoalLimiter(
        codec, robot.q_min, robot.q_max, command_speed(codec, robot.v_max), robot.joint_names
    )
    start = codec.encode_float(robot.configuration("walk_ready")[7:])
    goal = start + 40.0 * np.sign(codec.scale)
    sent = [(0.0, lim.reset(start, 0.0))]
    for k in range(1, int(rate * 1.5)):
        t = k / rate
        sent.append((t, lim.limit_cmd(soft_start_target(start, goal, soft, t), t, soft)))
    assert np.array_equal(sent[-1][1], np.clip(np.rint(goal), lim.lo, lim.hi))
    for a in range(len(sent)):
        for b in range(a + 1, len(sent)):
            (ta, ca), (tb, cb) = sent[a], sent[b]
            assert np.all(np.abs(cb - ca) <= soft * (tb - ta) + 1 + 1e-9)
    # 40 ticks at 97.7 ticks/s take 0.41 s: arrival no earlier than (40 - 1) / 97.7 s
    arrival = next(t for t, c in sent if np.array_equal(c, sent[-1][1]))
    assert arrival >= 39 / soft[0] - 1e-9


def test_watchdog_needs_consecutive_failures():
    wd = Watchdog(["a", "b"], max_failures=3)
    assert wd.observe(ServoStatus(1, COMM_TIMEOUT)) is None
    assert wd.observe(ServoStatus(1, COMM_TIMEOUT)) is None
    assert wd.failing() == [1]
    assert wd.observe(ServoStatus(1, COMM_OK)) is None  # a good reply resets the streak
    assert wd.failing() == []
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
    from wbc.servos.protocol1 import fault_names

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


@pytest.mark.parametrize(
    ("rate", "rotation", "polls", "bound_ms"),
    [(50.0, 2, 10, 80.0), (100.0, 7, 4, 90.0), (25.0, 1, 18, 120.0)],
)
def test_health_schedule_rotation_and_bound(rate, rotation, polls, bound_ms):
    h = HealthSchedule(18, rate)
    assert (h.rotation, h.polls_per_tick) == (rotation, polls)
    assert h.detection_s * 1e3 == pytest.approx(bound_ms)


@given(
    st.sampled_from([30.0, 50.0, 60.0, 100.0]),
    st.lists(st.tuples(st.integers(0, 17), st.booleans()), max_size=60),
)
def test_health_schedule_checks_every_servo_within_its_rotation(rate, events):
    """Law: whatever fails, each servo is checked at least every R ticks, and a servo with a
    failure streak is checked again in the very next tick."""
    h = HealthSchedule(18, rate)
    wd = Watchdog([str(i) for i in range(18)], max_failures=10**6)
    last = np.full(18, -1)
    for tick, (servo, fails) in enumerate([*events, *[(0, False)] * 2 * h.rotation]):
        streak = set(wd.failing())
        picked = h.pick(wd)
        assert len(picked) == len(set(picked)) == h.polls_per_tick
        assert streak <= set(picked) or len(streak) >= h.polls_per_tick
        last[picked] = tick
        if tick >= h.rotation - 1:
            assert np.all(tick - last < h.rotation) or len(streak) > 1
        for i in picked:
            bad = fails and i == servo
            wd.observe(ServoStatus(i, COMM_TIMEOUT if bad else COMM_OK))


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


@given(
    gaps=st.lists(st.floats(0.001, 0.05), min_size=5, max_size=60),
    rate=st.sampled_from([50.0, 100.0]),
)
def test_no_goal_faster_than_the_servo_rounding_included(robot, codec, gaps, rate):
    """Rule 3: the limiter never asks two consecutive goals for more than the servo's top
    speed (here the AX-12A's 1,207 ticks/s, every joint), whatever the tick timing; without it
    the carried credit lets a step of 25 ticks follow 20 ms (1,250 ticks/s)."""
    from wbc.servos.protocol1 import AX12_MAX_SPEED

    top = command_speed(codec, AX12_MAX_SPEED)
    lim = GoalLimiter(codec, robot.q_min, robot.q_max, top, robot.joint_names, hard_speed=top)
    prev = lim.reset(codec.encode_float(np.clip(0.0, robot.q_min, robot.q_max)), 0.0)
    t = 0.0
    for k, gap in enumerate([*gaps, *([1.0 / rate] * 20)]):
        t += gap
        target = np.where(k % 40 < 20, lim.hi, lim.lo)  # far away: full speed all the time
        cmd = lim.limit_cmd(target.astype(float), t)
        assert np.all(np.abs(cmd - prev) <= top * gap + 1e-9), (k, gap, np.abs(cmd - prev).max())
        prev = cmd
