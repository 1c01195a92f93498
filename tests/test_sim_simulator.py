"""The simulated robot: standing, speed cap, torque limit, faults (short simulations)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco")

from wbc.servo_map import RAD_PER_TICK
from wbc.servos.protocol1 import speed_register, speed_ticks_per_s
from wbc.sim.simulator import Simulation


def _tilt_change(R0, R) -> float:
    return math.degrees(math.acos(np.clip((np.trace(R0.T @ R) - 1) / 2, -1, 1)))


def test_standing_at_walk_ready_holds_10_s_with_little_drift(robot):
    sim = Simulation(robot)
    sim.set_torque(True)
    sim.advance(0.5)  # settle: the joints sag into the compliance ramp under gravity
    R0, p0 = sim.base_rotation(), sim.q()[:3]
    sim.advance(10.0)
    assert _tilt_change(R0, sim.base_rotation()) < 1.0
    assert np.linalg.norm(sim.q()[:3] - p0) < 0.002
    # and relative to the commanded pose: under 1 degree of base orientation change overall
    q_start = robot.configuration("walk_ready")
    sim2 = Simulation(robot)
    sim2.reset(q_start, torque=True)
    R_start = sim2.base_rotation()
    sim2.advance(3.0)
    assert _tilt_change(R_start, sim2.base_rotation()) < 1.0
    assert sim2.q()[2] > 0.9 * q_start[2]


def test_without_torque_the_robot_collapses(robot):
    sim = Simulation(robot)
    sim.set_torque(False)
    z0 = sim.q()[2]
    sim.advance(1.5)
    assert sim.q()[2] < 0.8 * z0  # the servos, not the model, hold the robot up


def test_a_joint_step_moves_at_the_speed_cap(robot):
    sim = Simulation(robot)
    sim.set_torque(True)
    sim.advance(0.3)
    j = robot.joint_index("l_elbow")
    cap = speed_ticks_per_s(speed_register(1.5))  # 1.5 rad/s in moving-speed units
    sim.set_speed_ticks(cap)
    goal = np.rint(sim.servos.goal.copy())
    toward_middle = 1 if sim.q()[7 + j] < 0.5 * (robot.q_min[j] + robot.q_max[j]) else -1
    goal[j] += 120 * toward_middle * robot.servo_map.signs[j]  # 35 degrees, inside the limits
    sim.write_goals(goal)
    q0 = sim.q()[7 + j]
    times, angles = [], []
    for _ in range(100):
        sim.advance(0.01)
        times.append(sim.time)
        angles.append(sim.q()[7 + j])
    v = np.abs(np.gradient(angles, times))
    cap_rad = cap * RAD_PER_TICK
    assert cap_rad == pytest.approx(1.5, rel=0.02)
    mid = v[(np.arange(v.size) > 15) & (np.abs(np.array(angles) - q0) < 0.8 * 120 * RAD_PER_TICK)]
    assert mid.size > 5
    np.testing.assert_allclose(np.median(mid), cap_rad, rtol=0.1)
    assert v.max() < 1.25 * cap_rad
    # reaches the goal (within the compliance ramp) after about 120 ticks / cap
    present = sim.present_ticks()[j]
    assert abs(present - goal[j]) <= 4
    assert times[int(np.argmax(np.abs(np.array(angles) - q0) > 0.95 * 120 * RAD_PER_TICK))] < (
        0.3 + 1.3 * 120 / cap
    )


@pytest.mark.parametrize(("torque", "sags"), [(0.5, False), (2.0, True)])
def test_a_load_above_the_stall_torque_makes_the_joint_sag(robot, torque, sags):
    sim = Simulation(robot)
    sim.set_torque(True)
    sim.advance(0.3)
    j = robot.joint_index("r_elbow")
    q0 = sim.q()[7 + j]
    sim.data.qfrc_applied[sim.vadr[j]] = torque  # an external load on the elbow, N·m
    sim.advance(0.5)
    moved = abs(sim.q()[7 + j] - q0)
    k = sim.servo_params.stiffness[j]
    if sags:  # beyond the ramp: the servo gives way (toward the joint limit)
        assert moved > 0.3
        assert abs(sim.joint_torques()[j]) == pytest.approx(1.5, rel=1e-6)
    else:  # held inside the compliance ramp: deflection about torque / stiffness
        assert moved < 2 * torque / k
        assert moved > 0.3 * torque / k


def test_sustained_stall_raises_overload_and_cuts_torque(robot):
    sim = Simulation(robot)
    sim.set_torque(True)
    sim.advance(0.2)
    j = robot.joint_index("r_elbow")
    sim.data.qfrc_applied[sim.vadr[j]] = 2.0
    sim.advance(0.5)
    assert sim.servos.error[j] == 0  # not yet: under the overload time
    sim.advance(0.7)
    assert sim.servos.error[j] & 0x20
    assert sim.servos.shutdown[j] and sim.joint_torques()[j] == 0.0
    assert not np.any(np.delete(sim.servos.error, j))


def test_push_moves_the_robot_and_is_an_impulse(robot):
    sim = Simulation(robot)
    sim.set_torque(True)
    sim.advance(0.2)
    vy0 = sim.data.qvel[1]
    sim.push([0.0, 20.0, 0.0], 0.01)  # 0.2 N·s
    sim.advance(0.01)
    dv = sim.data.qvel[1] - vy0
    assert 0.2 / robot.total_mass * 0.3 < dv < 0.2 / robot.total_mass * 3  # order of J/m
    assert not np.any(sim.data.xfrc_applied)  # the push ended


def test_faults_are_validated(robot):
    from wbc.exceptions import ConfigurationError

    sim = Simulation(robot)
    with pytest.raises(ConfigurationError, match="unknown fault"):
        sim.inject("smoke", 0)
    with pytest.raises(ConfigurationError, match="outside"):
        sim.inject("silent", 18)


# ---------------------------------------------------------------------- Kokone: hobby servos
@pytest.fixture(scope="module")
def kokone():
    from wbc import load_robot

    return load_robot("kokone")


def _kokone_sim(kokone, gravity: bool = True) -> Simulation:
    sim = Simulation(kokone)
    if not gravity:
        sim.model.opt.gravity[:] = 0.0
    sim.write_goals(np.rint(sim.servos.pulses(sim.q()[7:])))  # the SSC-32 starts the pulses
    return sim


def test_kokone_stands_in_its_crouch_and_collapses_without_pulses(kokone):
    sim = _kokone_sim(kokone)
    R0, z0 = sim.base_rotation(), sim.q()[2]
    sim.advance(2.0)
    assert sim.servos.enabled.all()
    assert _tilt_change(R0, sim.base_rotation()) < 10.0  # sags into the proportional band
    assert sim.q()[2] > 0.95 * z0
    _, fz, _ = sim.contacts()
    assert fz.sum() == pytest.approx(kokone.total_mass * 9.81, rel=0.05)  # at rest on its feet
    limp = Simulation(kokone)  # no move command: the board sends no pulses
    limp.advance(1.5)
    assert not limp.servos.enabled.any()
    assert limp.q()[2] < 0.8 * z0


def test_kokone_servo_tops_out_at_the_no_load_speed(kokone):
    """Full drive against the back-EMF: the unloaded joint settles at (τ_s − friction) / b,
    just under the datasheet's 0.16 s/60°; it never exceeds it."""
    sim = _kokone_sim(kokone, gravity=False)
    p = sim.servo_params
    j = kokone.joint_index("head_yaw")
    goal = np.rint(sim.servos.pulses(sim.q()[7:]))
    goal[j] = np.rint(sim.servos.pulses(sim.q()[7:])[j] + sim.servos.scale[j] * math.radians(70))
    sim.write_goals(goal)
    v = []
    for _ in range(150):
        sim.step()
        v.append(sim.joint_velocities()[j])
    v = np.abs(v)
    steady = (p.stall_torque - p.friction_loss) / p.damping
    assert v.max() <= p.no_load_speed
    assert v.max() == pytest.approx(steady, rel=0.02)
    assert abs(sim.q()[7 + j] - math.radians(70)) < math.radians(2.0)  # arrived (dead band)


@pytest.mark.parametrize(("load", "sags"), [(0.2, False), (0.6, True)])
def test_kokone_load_above_the_stall_torque_makes_the_joint_give_way(kokone, load, sags):
    sim = _kokone_sim(kokone)
    sim.advance(0.3)
    j = kokone.joint_index("r_elbow_yaw")  # vertical axis: no gravity load on it
    q0 = sim.q()[7 + j]
    sim.data.qfrc_applied[sim.vadr[j]] = load
    sim.advance(0.5)
    moved = abs(sim.q()[7 + j] - q0)
    p, us_per_rad = sim.servo_params, abs(sim.servos.scale[j])
    held = (p.dead_band_us + load / p.stall_torque * p.proportional_band_us) / us_per_rad
    if sags:
        assert moved > 0.3
        assert abs(sim.joint_torques()[j]) == pytest.approx(p.stall_torque, rel=1e-9)
    else:  # the servo holds where its drive balances the load
        assert moved == pytest.approx(held, abs=1.5 / us_per_rad)  # within 1.5 µs of pulse
