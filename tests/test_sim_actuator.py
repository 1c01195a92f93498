"""The AX-12A servo law: parameters from the shared servo settings, compiled == numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc.servo_map import RAD_PER_TICK, ServoSettings
from wbc.sim.actuator import BACK_EMF_DAMPING, STALL_TORQUE, ServoArray, ServoParams


def test_parameters_come_from_the_servo_settings(robot):
    s = robot.servo_map.settings
    p = ServoParams.from_settings(s)
    np.testing.assert_array_equal(p.slope, s.compliance_slope)
    np.testing.assert_array_equal(p.margin, s.compliance_margin)
    np.testing.assert_allclose(p.punch, s.punch / 1023)
    np.testing.assert_allclose(p.torque_cap, 1.5 * s.torque_limit / 1023)
    # stiffness ≈ stall torque / slope angle: 9.2 N·m/rad at slope 32, half at 64
    k = p.stiffness
    i32 = robot.joint_index("l_knee")
    i64 = robot.joint_index("l_ankle_roll")
    assert s.compliance_slope[i32] == 32 and s.compliance_slope[i64] == 64
    assert k[i32] == pytest.approx(1.5 / (32 * RAD_PER_TICK)) == pytest.approx(9.16, abs=0.01)
    assert k[i64] == pytest.approx(k[i32] / 2)
    assert BACK_EMF_DAMPING == pytest.approx(STALL_TORQUE / (59 * 2 * math.pi / 60))
    assert BACK_EMF_DAMPING == pytest.approx(0.24, abs=0.005)


def _array(robot, **settings):
    n = robot.n_joints
    base = ServoSettings.defaults(n)
    values = {k: np.full(n, v, dtype=int) for k, v in settings.items()}
    s = ServoSettings(**{**base.__dict__, **values})
    servos = ServoArray(robot.servo_map, ServoParams.from_settings(s))
    servos.reset(np.zeros(n))
    servos.enabled[:] = True
    return servos


def test_dead_band_punch_ramp_and_cap(robot):
    servos = _array(robot, compliance_margin=2, compliance_slope=32, punch=100, torque_limit=512)
    z, sign = servos.zero[0], servos.signs[0]
    torque = []
    for e in (0, 1, 2, 3, 10, 40, 200):  # goal e ticks above the present position
        servos.reset(np.zeros(robot.n_joints))
        servos.enabled[:] = True
        servos.goal[0] = servos.tracked[0] = np.rint(z) + e
        q = np.zeros(robot.n_joints)
        q[0] = sign * (np.rint(z) - z) * RAD_PER_TICK  # exactly on a tick
        torque.append(servos.law(q, 1e-3)[0] * sign)
    cap = 1.5 * 512 / 1023
    expected = [0, 0, 0, 1.5 * (100 / 1023 + 1 / 32), 1.5 * (100 / 1023 + 8 / 32), cap, cap]
    np.testing.assert_allclose(torque, expected, atol=1e-12)


def test_speed_cap_moves_the_tracked_goal(robot):
    servos = _array(robot)
    servos.speed[:] = 100.0  # ticks/s
    servos.goal[:] = servos.tracked + 50
    servos.law(np.zeros(robot.n_joints), 0.1)
    np.testing.assert_allclose(servos.tracked - np.rint(servos.zero), 10.0, atol=1.0)


@given(
    q=st.lists(st.floats(-1.0, 1.0), min_size=18, max_size=18),
    goal=st.lists(st.integers(0, 1023), min_size=18, max_size=18),
    slope=st.integers(1, 254),
    margin=st.integers(0, 10),
    punch=st.integers(32, 1023),
    limit=st.integers(0, 1023),
    backlash=st.sampled_from([0.0, 0.01]),
)
def test_compiled_law_equals_the_numpy_law(robot, q, goal, slope, margin, punch, limit, backlash):
    a = _array(robot, compliance_slope=slope, compliance_margin=margin, punch=punch,
               torque_limit=limit)  # fmt: skip
    from dataclasses import replace

    a.params = replace(a.params, backlash=backlash, overload_time=0.004)
    b = _array(robot)
    b.params = a.params
    for s in (a, b):
        s.goal[:] = goal
        s.speed[:] = 3000.0
    for _ in range(5):  # several steps: tracked goal, overload timer and shutdown evolve
        ta = a.law(np.array(q), 2e-3).copy()
        tb = b.law_numpy(np.array(q), 2e-3).copy()
        np.testing.assert_allclose(ta, tb, atol=1e-12)
        np.testing.assert_allclose(a.tracked, b.tracked, atol=1e-9)
        np.testing.assert_array_equal(a.error, b.error)
        np.testing.assert_array_equal(a.shutdown, b.shutdown)


def test_backlash_is_a_play_between_link_and_sensed_motor(robot):
    from dataclasses import replace

    servos = _array(robot)
    servos.params = replace(servos.params, backlash=0.02)  # ±0.01 rad of play
    q = np.zeros(robot.n_joints)
    servos.reset(q)
    t0 = servos.sensed(q).copy()
    q[0] = 0.005  # inside the play: the motor side does not move
    np.testing.assert_allclose(servos.sensed(q), t0)
    q[0] = 0.03  # beyond it: the motor side is dragged along, 0.01 rad behind
    expected = servos.ticks(q)[0] - servos.signs[0] * 0.01 / RAD_PER_TICK
    assert servos.sensed(q)[0] == pytest.approx(expected)
    q[0] = 0.025  # back by less than the play: stays
    assert servos.sensed(q)[0] == pytest.approx(expected)


# ---------------------------------------------------------------------- hobby PWM servos
# The hobby law is numpy only (a few operations per 20 ms frame): no compiled twin to compare.
@pytest.fixture(scope="module")
def kokone():
    from wbc import load_robot

    return load_robot("kokone")


def _hobby(kokone, **changes):
    from dataclasses import replace

    from wbc.sim.actuator import HobbyServoArray, nominal_servo, pwm_map

    p = replace(nominal_servo(kokone), **changes)
    return HobbyServoArray(pwm_map(kokone).codec(), p, 0.002)


def test_kokone_servo_is_table_3_1s_bms380max(kokone):
    from wbc.sim.actuator import HobbyServoParams, nominal_servo, servo_kind

    p = nominal_servo(kokone)
    assert servo_kind(kokone) == "hobby_pwm" and isinstance(p, HobbyServoParams)
    assert p.name == "Blue-Bird BMS-380MAX"
    assert p.stall_torque == pytest.approx(4.2 * 9.80665 / 100, abs=1e-3)  # 4.2 kg·cm
    assert p.no_load_speed == pytest.approx(math.radians(60) / 0.16, abs=1e-3)  # 0.16 s/60°
    assert p.damping == pytest.approx(p.stall_torque / p.no_load_speed)
    assert p.frame_period == 0.02 and p.period == 0.02  # analog: one drive update per pulse
    # the URDF's effort and velocity limits are the same servo's
    assert np.allclose(kokone.model.effortLimit[6:], p.stall_torque, atol=1e-3)
    assert np.allclose(kokone.v_max, p.no_load_speed, atol=1e-3)


def test_servo_kind_of_the_bioloid_is_the_ax12a(robot):
    from wbc.sim.actuator import nominal_servo, servo_kind

    assert servo_kind(robot) == "ax12a"
    assert isinstance(nominal_servo(robot), ServoParams)


@pytest.mark.parametrize(
    "table, message",
    [
        ({"law": "hobby_pwm", "no_load_speed": 6.5}, "stall_torque is required"),
        ({"stall_torque": 0.4, "no_load_speed": 6.5, "deadband": 3}, "unknown keys"),
        ({"stall_torque": -0.4, "no_load_speed": 6.5}, "stall_torque = -0.4 must be > 0"),
        ({"stall_torque": 0.4, "no_load_speed": "fast"}, "must be a finite number"),
        ({"stall_torque": 0.4, "no_load_speed": 6.5, "frame_period": 0.5}, "at most 0.1 s"),
        ({"stall_torque": 0.4, "no_load_speed": 6.5, "loop_period": 0.03}, "loop_period"),
    ],
)
def test_bad_servo_tables_are_one_clear_line(table, message):
    from wbc.exceptions import ModelError
    from wbc.sim.actuator import HobbyServoParams

    with pytest.raises(ModelError, match=message):
        HobbyServoParams.from_table(table, "robot.toml [servo]")


@given(
    e_us=st.floats(-400.0, 400.0),
    q=st.floats(-0.5, 0.5),
    dead=st.floats(0.0, 10.0),
    band=st.floats(1.0, 200.0),
    joint=st.integers(0, 21),
)
def test_hobby_law_dead_band_ramp_and_stall_cap(kokone, e_us, q, dead, band, joint):
    """τ = sign · τ_s · sign(e) · min(1, (|e| − dead band)/band) outside the dead band, 0
    inside; never above the stall torque; always toward the commanded pulse."""
    s = _hobby(kokone, dead_band_us=dead, proportional_band_us=band)
    qs = np.zeros(s.n)
    qs[joint] = q
    pulses = np.clip(np.rint(s.pulses(qs)), 500, 2500)
    pulses[joint] = np.clip(np.rint(s.pulses(qs)[joint] + e_us), 500, 2500)
    s.write(pulses)
    tau = s.law(qs, s.dt)[joint]
    e = pulses[joint] - s.pulses(qs)[joint]  # what the servo sees (the pulse is whole µs)
    stall = s.params.stall_torque
    expected = 0.0 if abs(e) <= dead else math.copysign(min(1.0, (abs(e) - dead) / band), e)
    assert tau == pytest.approx(s.signs[joint] * stall * expected, abs=1e-12)
    assert abs(tau) <= stall + 1e-12
    goal_q = s.angles(pulses)[joint]
    assert tau * (goal_q - q) >= 0.0  # toward the goal (joint direction)


def test_hobby_drive_is_held_between_pulses_and_limp_without_them(kokone):
    s = _hobby(kokone)
    q = np.zeros(s.n)
    tau0 = s.law(q, s.dt).copy()  # no pulse yet: limp
    assert np.all(tau0 == 0.0) and not s.enabled.any()
    s.write(np.rint(s.pulses(q + 0.2)))  # 0.2 rad away on every joint
    assert np.all(s.law(q, s.dt) == 0.0)  # the pulses arrive at the next 20 ms frame
    for _ in range(s.frame_steps - 2):
        s.law(q, s.dt)
    tau = s.law(q, s.dt).copy()  # step 10 = t 20 ms: the frame
    assert np.all(np.abs(tau) == pytest.approx(s.params.stall_torque)) and s.enabled.all()
    q_moved = q + 0.2  # at the goal now, but the drive is held until the next update
    for _ in range(s.frame_steps - 1):
        np.testing.assert_array_equal(s.law(q_moved, s.dt), tau)
    assert np.all(s.law(q_moved, s.dt) == 0.0)  # next frame: inside the dead band
    s.off(np.arange(s.n) < 3)  # '#<ch>L' on three channels
    for _ in range(s.frame_steps):
        tau = s.law(q, s.dt)
    assert np.all(tau[:3] == 0.0) and np.all(tau[3:] != 0.0)
    assert not s.enabled[:3].any() and s.enabled[3:].all()


def test_ssc32_group_move_interpolates_at_the_frame_rate(kokone):
    """First command: a jump; then ``T`` ms: linear from where the pulse is, every channel
    arriving together, rounded to 1 µs once per 20 ms frame; a new move starts from there."""
    s = _hobby(kokone)
    q = np.zeros(s.n)
    s.write(np.full(s.n, 1500.0))
    s.law(q, s.dt)
    assert np.all(s.out == 1500.0)
    s.write(np.full(s.n, 1600.0), move_ms=100)  # at t = 2 ms
    outs = []
    for _ in range(60):  # 120 ms
        s.law(q, s.dt)
        if (s.steps - 1) % s.frame_steps == 0:
            outs.append(s.out[0])
    # frames at 20, 40, ... ms: 1500 + 100 · (t − 2 ms) / 100 ms
    t = np.arange(1, 7) * 0.02
    np.testing.assert_array_equal(outs, np.rint(1500 + 100 * np.clip((t - 0.002) / 0.1, 0, 1)))
    s.write(np.full(s.n, 1500.0), move_ms=40)  # back, from 1600, in 40 ms
    for _ in range(30):
        s.law(q, s.dt)
    assert np.all(s.out == 1500.0)
