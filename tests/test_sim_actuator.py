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
