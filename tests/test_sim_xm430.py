"""The XM430-W350 law of the simulator (wbc.sim.xm430) and the OP3 standing on it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc import load_robot
from wbc.exceptions import ConfigurationError, ModelError
from wbc.robot_data import RobotData
from wbc.sim.actuator import nominal_servo, servo_kind
from wbc.sim.xm430 import PWM_MAX, STALL_TORQUE, XServoArray, XServoParams
from wbc.xseries import HW_OVERLOAD, X_RAD_PER_TICK, XSettings


def one_servo(p=800, i=0, d=0, current=1193, shutdown=0x34):
    s = XSettings(*(np.array([v]) for v in (p, i, d, current, 0)), shutdown=shutdown)
    params = XServoParams.from_settings(s)

    class Map:  # one joint, sign +1, zero at 2048
        signs = np.array([1.0])
        zero_ticks = np.array([2048.0])

        def __len__(self):
            return 1

    servo = XServoArray(Map(), params)
    servo.reset(np.zeros(1))
    servo.enabled[:] = True
    return servo


def test_the_op3_simulates_xm430_servos_with_its_gains(op3):
    assert servo_kind(op3) == "xm430"
    p = nominal_servo(op3)
    knee = op3.joint_names.index("l_knee")
    assert p.kp[knee] == 2000 / 128 and p.ki[knee] == 500 / 65536 and p.kd[knee] == 150 / 16
    # the factory P = 800: 4.1 N·m x 6.25 / 885 per tick = 18.9 N·m/rad
    head = op3.joint_names.index("head_pan")
    assert p.stiffness[head] == pytest.approx(18.87, abs=0.01)
    assert p.damping == pytest.approx(4.1 / (46 * 2 * math.pi / 60))


def test_p_term_saturation_and_quantisation():
    servo = one_servo()
    k = STALL_TORQUE * (800 / 128) / PWM_MAX  # N·m per tick
    servo.goal[:] = servo.tracked[:] = 2048 + 10
    assert servo.law(np.zeros(1), 0.002)[0] == pytest.approx(10 * k)
    # within half a tick of the goal the servo senses no error
    servo.goal[:] = servo.tracked[:] = 2048
    assert servo.law(np.array([0.4 * X_RAD_PER_TICK]), 0.002)[0] == 0.0
    # far away: the stall torque, not more
    servo.goal[:] = servo.tracked[:] = 2048 + 1000
    assert servo.law(np.zeros(1), 0.002)[0] == pytest.approx(STALL_TORQUE)


def test_current_limit_caps_the_torque():
    servo = one_servo(current=428)  # 428 x 2.69 mA = 1.15 A: half the 2.3 A stall current
    servo.goal[:] = servo.tracked[:] = 2048 + 1000
    assert servo.law(np.zeros(1), 0.002)[0] == pytest.approx(STALL_TORQUE * 428 * 2.69e-3 / 2.3)


def test_integral_removes_a_steady_error():
    servo = one_servo(i=1000)
    servo.goal[:] = servo.tracked[:] = 2048 + 4
    first = servo.law(np.zeros(1), 0.002)[0]
    for _ in range(500):
        last = servo.law(np.zeros(1), 0.002)[0]
    assert last > first * 1.5  # the held error integrates up


def test_profile_velocity_caps_the_tracked_goal():
    servo = one_servo()
    servo.speed[:] = 100.0  # ticks/s
    servo.goal[:] = 2048 + 500
    for _ in range(50):
        servo.law(np.zeros(1), 0.002)
    assert servo.tracked[0] == pytest.approx(2048 + 100 * 0.1)


def test_overload_sets_the_bit_and_shutdown_cuts_torque():
    servo = one_servo()
    servo.goal[:] = servo.tracked[:] = 2048 + 1000
    for _ in range(510):  # 1.02 s at the limit
        tau = servo.law(np.zeros(1), 0.002)[0]
    assert servo.error[0] & HW_OVERLOAD and servo.shutdown[0] and tau == 0.0
    servo = one_servo(shutdown=0)  # overload not in Shutdown: the bit, torque stays
    servo.goal[:] = servo.tracked[:] = 2048 + 1000
    for _ in range(510):
        tau = servo.law(np.zeros(1), 0.002)[0]
    assert servo.error[0] & HW_OVERLOAD and tau == pytest.approx(STALL_TORQUE)


def test_a_profile_acceleration_is_refused():
    s = XSettings(*(np.array([v]) for v in (800, 0, 0, 1193, 10)))
    with pytest.raises(ConfigurationError, match="profile_acceleration"):
        XServoParams.from_settings(s)


def test_a_law_that_contradicts_the_protocol_is_refused(op3):
    data = RobotData(servo={"law": "ax12a"}, source="op3")
    robot = load_robot("op3")
    robot.robot_data = data
    with pytest.raises(ModelError, match=r"does not match its servos\.toml protocol 2\.0"):
        servo_kind(robot)


def test_the_op3_stands_on_its_servos(op3):
    from wbc.sim.simulator import Simulation

    sim = Simulation(op3)
    sim.set_torque(True)
    z0 = sim.site_pose("torso").translation[2]
    sim.advance(1.0)
    R = sim.site_pose("torso").rotation
    assert math.degrees(math.acos(min(1.0, R[2, 2]))) < 3.0
    assert sim.site_pose("torso").translation[2] > z0 - 0.01
    sag = np.abs(sim.q()[7:] - op3.configuration("stand")[7:])
    assert sag.max() < math.radians(3.0)


def test_the_simulated_bus_speaks_for_x_series_servos(op3):
    from wbc.servos.protocol2 import XM430_NO_LOAD_SPEED
    from wbc.sim.bus import SimServoBus
    from wbc.sim.simulator import Simulation

    bus = SimServoBus(Simulation(op3))
    assert bus.servo_speed == XM430_NO_LOAD_SPEED and bus.codec.cmd_max == 4095
    assert "SYNC_READ" in bus.budget(True).items[1].what
    bus.open()
    bus.set_speed(1.0)  # Profile Velocity 42 x 0.229 rev/min = 1.007 rad/s
    assert bus.sim.servos.speed[0] * X_RAD_PER_TICK == pytest.approx(42 * 0.229 * 2 * math.pi / 60)
    bus.inject("overload", 3)
    assert bus.poll(3).faults == ("overload",)


@given(
    e=st.integers(-3000, 3000),
    p=st.integers(0, 16383),
    current=st.integers(0, 1193),
)
def test_p_law_is_the_clipped_pwm(e, p, current):
    """P only, goal reached by the profile: τ = clip(τ_s · clip(K_P e / 885, ±1), ±cap)."""
    servo = one_servo(p=p, current=current)
    servo.goal[:] = servo.tracked[:] = 2048 + e
    tau = servo.law(np.zeros(1), 0.002)[0]
    cap = STALL_TORQUE * min(1.0, current * 2.69e-3 / 2.3)
    expected = np.clip(STALL_TORQUE * np.clip(p / 128 * e / PWM_MAX, -1, 1), -cap, cap)
    assert tau == pytest.approx(expected, abs=1e-12)


@given(st.floats(0.05, 4.0), st.sampled_from([400, 800, 1000]))
def test_deflection_inverts_the_p_term(tau, p_gain):
    """The servo held ``deflection(τ)`` off its goal drives τ (to a tick's torque: the encoder
    is quantised), capped at the stall torque."""
    servo = one_servo(p=p_gain)
    delta = servo.params.deflection(np.array([tau]))[0]
    torque = servo.law(np.array([-delta]), 1e-3)[0]
    per_tick = STALL_TORQUE * (p_gain / 128) / PWM_MAX
    assert torque == pytest.approx(min(tau, STALL_TORQUE), abs=per_tick / 2 + 1e-9)
    assert servo.params.deflection(np.array([-tau]))[0] == -delta


def test_integral_time_is_the_pi_law_s():
    """T_i = K_P / K_I cycles: the integral alone gives the P term's output after T_i at a
    constant error; no I gain: inf."""
    servo = one_servo(p=1000, i=500)
    ti = servo.params.integral_time[0]
    assert ti == pytest.approx(1000 / 128 / (500 / 65536) * 1e-3)  # 1.02 s
    assert one_servo(p=800, i=0).params.integral_time[0] == math.inf
    q = np.array([-20 * X_RAD_PER_TICK])  # held 20 ticks off the goal
    steps = round(ti / 1e-3)
    for _ in range(steps):
        servo.law(q, 1e-3)
    p_term = STALL_TORQUE * (1000 / 128) * 20 / PWM_MAX
    assert servo.law(q, 1e-3)[0] == pytest.approx(2 * p_term, rel=0.01)
