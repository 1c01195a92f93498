"""SimServoBus and SimImu: ``wbc deploy --sim`` runs the deployment path on the simulator."""

from __future__ import annotations

import argparse
import math
import re
import time

import numpy as np
import pytest

pytest.importorskip("mujoco")

from wbc.cli import deploy as deploy_cmd
from wbc.exceptions import ConfigurationError, ServoError
from wbc.imu import GRAVITY
from wbc.recording import Recording
from wbc.servo_map import RAD_PER_TICK, ServoSettings
from wbc.servos import DeployConfig, Deployment, RecordingSource
from wbc.sim.bus import SimImu, SimServoBus
from wbc.sim.simulator import Simulation

RATE = 50.0


def _sway(robot, duration=1.0, rate=RATE, amplitude=0.15):
    """Walk Ready plus a smooth sway of hips, knees and arms (as tests/test_servos_deploy)."""
    q0 = robot.configuration("walk_ready")
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    s = amplitude * np.sin(np.pi * t / duration) ** 2
    q = np.tile(q0, (t.size, 1))
    for name, sign in (("l_hip_pitch", -1), ("r_hip_pitch", -1), ("l_knee", 1), ("r_knee", 1),
                       ("l_elbow", 1), ("r_shoulder_roll", -1)):  # fmt: skip
        q[:, robot.q_index(name)] += sign * s
    return Recording(t, q, robot.joint_names)


@pytest.fixture(scope="module")
def recording(robot, tmp_path_factory):
    path = tmp_path_factory.mktemp("sim") / "sway.npz"
    _sway(robot).save(path)
    return str(path)


def _deploy(robot, bus, rec, **config):
    source = RecordingSource(rec, robot)
    return Deployment(bus, source, robot, DeployConfig(rate=RATE, **config), out=lambda s: None)


def test_deploy_sim_plays_a_recording_through_every_safety_feature(robot, recording, tmp_path,
                                                                   capsys):  # fmt: skip
    parser = argparse.ArgumentParser()
    deploy_cmd.add_arguments(parser)
    log = tmp_path / "log.npz"
    args = parser.parse_args([recording, "--sim", "--rate", str(RATE), "--read", "--log", str(log)])
    start = time.perf_counter()
    rc = deploy_cmd.run(args)
    wall = time.perf_counter() - start
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert "on sim" in out and "completed" in out and "tracking error" in out
    data = np.load(log)
    goals = data["goal"]
    rec = Recording.load(recording)
    assert goals.shape == (len(rec), 18)  # the robot starts at Walk Ready = the first pose
    sm = robot.servo_map
    q_goal = np.array([sm.ticks_to_angles(g) for g in goals])
    assert np.all(q_goal >= robot.q_min - 1e-9) and np.all(q_goal <= robot.q_max + 1e-9)
    step = np.floor(np.minimum(robot.v_max, 6.18) / RATE / RAD_PER_TICK + 1e-9)
    assert np.all(np.abs(np.diff(goals, axis=0)) <= step)  # the rate limit held
    # present positions (the simulated encoders) follow the goals within the compliance ramp
    present = data["present"]
    assert np.all(np.isfinite(present))
    assert np.max(np.abs(present[-1] - goals[-1])) <= 12
    # lockstep: simulated time ran at the rate, the wall clock did not pace it
    assert wall < 1.0 * len(rec) / RATE + 5.0


def test_lockstep_runs_faster_than_real_time_and_realtime_follows_the_wall(robot):
    rec = _sway(robot, duration=0.6)
    for realtime in (False, True):
        sim = Simulation(robot)
        sim.reset(rec.q[0])
        bus = SimServoBus(sim, realtime=realtime)
        start = time.perf_counter()
        result = _deploy(robot, bus, rec).run()
        wall = time.perf_counter() - start
        assert result.completed
        assert sim.time == pytest.approx(len(rec) / RATE - 1 / RATE, abs=2.5 / RATE)
        if realtime:
            assert wall >= 0.9 * sim.time
        assert bus.clock is None if realtime else bus.clock.now() == sim.time


def _fault_run(robot, rec, kind, index, after, **config):
    sim = Simulation(robot)
    sim.reset(rec.q[0])
    bus = SimServoBus(sim)
    bus.inject(kind, index, after_goals=after)
    result = _deploy(robot, bus, rec, **config).run()
    return result, bus, sim


@pytest.mark.parametrize(
    ("kind", "joint", "on_fault", "expected"),
    [
        ("silent", "r_hip_yaw", "hold", "id 7 (r_hip_yaw): 3 consecutive failed exchanges "
         "(timeout): servo missing or not answering"),
        ("overload", "r_shoulder_roll", "torque-off", "id 3 (r_shoulder_roll): error bits 0x20 "
         "(overload)"),
    ],
)  # fmt: skip
def test_injected_faults_trip_the_watchdog_as_with_the_emulator(robot, kind, joint, on_fault,
                                                                 expected):  # fmt: skip
    rec = _sway(robot)
    i = robot.joint_index(joint)
    result, bus, sim = _fault_run(robot, rec, kind, i, 15, on_fault=on_fault)
    assert not result.completed
    assert result.stop_action == on_fault
    assert str(result.trip) == expected
    # stopped within one polling round (18 ticks) + 3 tries of the fault
    assert 15 <= bus.goals_written <= 15 + 18 + 3
    others = np.delete(sim.servos.enabled, i)
    assert np.all(others) if on_fault == "hold" else not np.any(others)


def test_sustained_stall_trips_the_watchdog_with_the_overload_bit(robot):
    """A real overload: knees limited to 4 % torque cannot hold the robot up."""
    rec = _sway(robot, duration=2.0)
    s = robot.servo_map.settings
    limit = s.torque_limit.copy()
    knees = [robot.joint_index("l_knee"), robot.joint_index("r_knee")]
    limit[knees] = 40
    settings = ServoSettings(**{**s.__dict__, "torque_limit": limit})
    sim = Simulation(robot, settings=settings)
    sim.reset(rec.q[0])
    bus = SimServoBus(sim)
    result = _deploy(robot, bus, rec, read=True).run()
    assert not result.completed
    assert "error bits 0x20 (overload)" in str(result.trip)
    assert result.trip.index in knees
    assert sim.time > sim.servo_params.overload_time  # only after the overload time


def test_silent_servo_is_refused_at_start(robot):
    from wbc.exceptions import ServoError

    rec = _sway(robot)
    sim = Simulation(robot)
    bus = SimServoBus(sim)
    bus.inject("silent", 4)
    with pytest.raises(ServoError, match="no reply to PING"):
        _deploy(robot, bus, rec).run()


def test_latency_delays_goals_by_whole_ticks(robot):
    sim = Simulation(robot)
    bus = SimServoBus(sim, latency_ticks=1)
    lo = np.zeros(18, int)
    bus.set_command_limits(lo, np.full(18, 1023))
    bus.open()
    g0 = sim.servos.goal.copy()
    first = np.rint(g0).astype(int) + 1
    bus.write_goals(first)
    np.testing.assert_array_equal(sim.servos.goal, g0)  # not yet
    bus.write_goals(first + 1)
    np.testing.assert_array_equal(sim.servos.goal, first)


# ---------------------------------------------------------------- IMU
def test_imu_reads_gravity_at_rest(robot):
    sim = Simulation(robot)
    sim.set_torque(True)
    sim.advance(0.5)
    r = SimImu(sim).read()
    R = sim.site_pose("imu").rotation
    np.testing.assert_allclose(r.linear_acceleration, R.T @ [0, 0, GRAVITY], atol=0.05)
    assert np.linalg.norm(r.linear_acceleration) == pytest.approx(GRAVITY, abs=0.05)
    np.testing.assert_allclose(r.angular_velocity, 0.0, atol=0.02)
    np.testing.assert_allclose(r.rotation(), R, atol=1e-9)
    assert r.t == pytest.approx(sim.time)
    # Walk Ready leans the torso forward: the IMU sees that tilt
    assert math.degrees(r.tilt()) == pytest.approx(
        math.degrees(math.acos(sim.base_rotation()[2, 2])), abs=1e-6
    )


def test_imu_reads_the_rate_of_a_known_rotation(robot):
    sim = Simulation(robot)
    sim.model.opt.gravity[:] = 0.0
    q = robot.configuration("walk_ready")
    q[2] += 1.0  # in the air: no contact
    sim.reset(q)
    omega_local = np.array([0.3, -0.7, 1.1])
    sim.data.qvel[3:6] = omega_local  # MuJoCo's free joint: angular velocity in the body frame
    sim.advance(0.002)
    r = SimImu(sim).read()
    R_imu_in_body = sim.base_rotation().T @ sim.site_pose("imu").rotation
    np.testing.assert_allclose(r.angular_velocity, R_imu_in_body.T @ omega_local, atol=1e-3)
    # with the rotation going on, the orientation turns at that rate
    R0 = r.rotation()
    sim.advance(0.1)
    R1 = SimImu(sim).read().rotation()
    angle = math.acos(np.clip((np.trace(R0.T @ R1) - 1) / 2, -1, 1))
    assert angle == pytest.approx(np.linalg.norm(omega_local) * 0.1, rel=0.05)


def test_imu_noise_and_bias_are_seeded(robot):
    sim = Simulation(robot)
    a = [SimImu(sim, gyro_noise=0.01, acc_bias_std=0.1, seed=3).read() for _ in range(2)]
    b = SimImu(sim, gyro_noise=0.01, acc_bias_std=0.1, seed=3).read()
    np.testing.assert_array_equal(a[0].angular_velocity, b.angular_velocity)
    clean = SimImu(sim).read()
    assert not np.allclose(b.linear_acceleration, clean.linear_acceleration)
    with pytest.raises(Exception, match="gyro_noise must be >= 0"):
        SimImu(sim, gyro_noise=-1.0)


def test_soft_start_and_rate_limit_act_on_the_simulated_servos(robot):
    """The robot stands at Walk Ready; the recording starts elsewhere and jumps: the soft
    start brings the servos over at the soft speed, the rate limit caps the jump."""
    rec = _sway(robot, duration=0.6)
    k = robot.q_index("l_elbow")
    q = rec.q.copy()
    q[:, k] += 0.3  # first pose 0.3 rad away from the standing pose
    q[len(q) // 2 :, k] += 0.4  # and a jump of 0.4 rad in one tick mid-way
    rec = Recording(rec.t, q, robot.joint_names)
    sim = Simulation(robot)  # at Walk Ready
    bus = SimServoBus(sim)
    d = _deploy(robot, bus, rec, read=True, soft_speed=0.5)
    result = d.run()
    assert result.completed
    # 0.3 rad at no more than 0.5 rad/s at 50 Hz: at least 30 ticks (at most 59 if the step
    # per tick is rounded down to whole AX ticks: floor(1.95) = 1)
    per_tick = max(1, math.floor(0.5 / RATE / RAD_PER_TICK))
    assert 0.3 / 0.5 * RATE - 1 <= result.soft_start_ticks <= 0.3 / RAD_PER_TICK / per_tick + 2
    j = robot.joint_index("l_elbow")
    assert result.limits.rate_limited[j] >= 1
    assert result.limits.rate_limited.sum() == result.limits.rate_limited[j]
    # the servo got there: present position within the compliance ramp of the last goal
    assert abs(sim.q()[k] - q[-1, k]) < 3 * 32 * RAD_PER_TICK


def test_torque_limit_option_overrides_register_34_at_configure(robot):
    sim = Simulation(robot)
    bus = SimServoBus(sim, torque_limit=100)
    bus.open()
    bus.configure()
    np.testing.assert_allclose(sim.servos.params.torque_cap, 1.5 * 100 / 1023)
    assert not np.any(sim.servos.enabled)  # configure leaves torque off
    from wbc.exceptions import ServoError

    with pytest.raises(ServoError, match=r"torque limit must be 0\.\.1023"):
        SimServoBus(sim, torque_limit=2000)


# ---------------------------------------------------------------------- SSC-32 over the simulator
@pytest.fixture(scope="module")
def kokone():
    from wbc import load_robot

    return load_robot("kokone")


def _kokone_sway(kokone, duration=0.6, rate=RATE):
    q0 = kokone.configuration("stand")
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    q = np.tile(q0, (t.size, 1))
    q[:, kokone.q_index("r_shoulder_pitch")] += 0.4 * np.sin(np.pi * t / duration) ** 2
    return Recording(t, q, kokone.joint_names)


def test_ssc32_bus_drives_the_simulated_board_with_the_real_backends_bytes(kokone):
    """SimSsc32Bus is the SSC-32 backend unchanged: its ASCII lines reach the simulated board,
    one group move per tick with T = the tick, and the servos follow the pulses."""
    from wbc.servos.ssc32 import Ssc32Bus
    from wbc.sim.bus import SimSsc32Bus, sim_bus

    rec = _kokone_sway(kokone)
    sim = Simulation(kokone)
    sim.reset(rec.q[0])
    bus = sim_bus(sim, RATE)
    assert isinstance(bus, SimSsc32Bus) and isinstance(bus, Ssc32Bus) and not bus.can_read
    result = _deploy(kokone, bus, rec).run()
    assert result.completed
    moves = [ln for ln in bus.ser.lines if ln.startswith("#")]
    assert len(moves) == len(rec) + 1  # the start pose, then one move per tick
    assert all(ln.endswith(f"T{round(1000 / RATE)}") for ln in moves)
    assert bus.ser.lines[0] == "VER"
    j = kokone.joint_index("r_shoulder_pitch")
    target = np.rint(sim.servos.pulses(rec.q[-1, 7:]))
    np.testing.assert_array_equal(sim.servos.target, target)  # parsed back from the bytes
    sim.advance(0.3)
    assert abs(sim.q()[7 + j] - rec.q[-1, 7 + j]) < math.radians(4.0)  # the arm followed
    assert sim.time == pytest.approx(len(rec) / RATE + 0.3, abs=2.5 / RATE)  # lockstep


def test_cut_signal_wire_goes_unnoticed_by_the_ssc32_deployment(kokone):
    """What the safety layer says it cannot check: a servo without pulses goes limp and the
    deployment completes (no feedback)."""
    from wbc.sim.bus import sim_bus

    rec = _kokone_sway(kokone)
    sim = Simulation(kokone)
    sim.reset(rec.q[0])
    bus = sim_bus(sim, RATE)
    j = kokone.joint_index("r_shoulder_pitch")
    bus.inject("silent", j)
    with pytest.raises(ServoError, match="only 'silent'"):
        bus.inject("overload", j)
    result = _deploy(kokone, bus, rec).run()
    assert result.completed
    assert not sim.servos.enabled[j] and sim.servos.enabled[np.arange(kokone.n_joints) != j].all()
    assert sim.joint_torques()[j] == 0.0


@pytest.mark.parametrize(
    ("robot_name", "bus", "message"),
    [("kokone", "dynamixel", "no servo map"), ("bioloid", "ssc32", "use --bus dynamixel")],
)
def test_deploy_sim_needs_the_robots_own_bus(robot_name, bus, message, capsys):
    parser = argparse.ArgumentParser()
    deploy_cmd.add_arguments(parser)
    args = parser.parse_args(["--live", "walk", "--sim", "--robot", robot_name, "--bus", bus])
    assert deploy_cmd.run(args) == 2
    assert message in capsys.readouterr().err


def test_deploy_kokone_on_the_simulated_ssc32_from_the_command_line(kokone, tmp_path, capsys):
    path = tmp_path / "sway.npz"
    _kokone_sway(kokone).save(path)
    parser = argparse.ArgumentParser()
    deploy_cmd.add_arguments(parser)
    args = parser.parse_args([str(path), "--robot", "kokone", "--bus", "ssc32", "--sim"])
    rc = deploy_cmd.run(args)
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert "on sim" in out and "completed" in out + err
    assert "cannot check the servos' positions" in out
    assert re.search(r"^sim: stayed up; torso tilt at most \d+\.\d°", out, flags=re.M)


def test_the_ax12a_bus_refuses_hobby_servos(kokone):
    with pytest.raises(ConfigurationError, match="SimSsc32Bus"):
        SimServoBus(Simulation(kokone))


def test_ssc32_bus_in_real_time_follows_the_wall_clock(kokone):
    from wbc.sim.bus import sim_bus

    rec = _kokone_sway(kokone, duration=0.4)
    sim = Simulation(kokone)
    sim.reset(rec.q[0])
    bus = sim_bus(sim, RATE, realtime=True)
    assert bus.clock is None
    start = time.perf_counter()
    assert _deploy(kokone, bus, rec).run().completed
    wall = time.perf_counter() - start
    assert sim.time == pytest.approx(len(rec) / RATE, abs=3.0 / RATE)
    assert wall >= 0.9 * sim.time


class _StiffSource:
    """Walk Ready held, asking the servos for ``factor`` × their stiffness from tick 5 on
    (recording the servo law's slopes it sees each tick)."""

    def __init__(self, robot, sim, factor, ticks=20):
        self.joint_names = robot.joint_names
        self.q = robot.configuration("walk_ready")[7:]
        self.sim, self.factor, self.ticks = sim, factor, ticks
        self.stiffness = None
        self.slopes: list[np.ndarray] = []

    def first(self):
        return self.q.copy()

    def __call__(self, tick, t):
        self.slopes.append(self.sim.servos.params.slope.copy())
        if tick >= self.ticks:
            return None
        self.stiffness = self.factor if tick >= 5 else None
        return self.q


@pytest.mark.parametrize("fault", [None, "overload"])
def test_a_sources_stiffness_reaches_the_servo_law_and_every_end_restores_it(robot, fault):
    """The deployment writes a source's stiffness (set_stiffness: the registers the real bus
    writes) and the servo law follows them, keeping a randomised model's own scale; the end
    of the motion, and a safe stop, leave the configured stiffness."""
    from dataclasses import replace

    sim = Simulation(robot)
    sim.reset(robot.configuration("walk_ready"))
    sim.servos.params = replace(sim.servos.params, slope=sim.servos.params.slope * 1.5)
    base = sim.servos.params.slope.copy()
    bus = SimServoBus(sim)
    if fault:
        bus.inject(fault, robot.joint_index("l_knee"), after_goals=40)
    source = _StiffSource(robot, sim, 4.0, ticks=200 if fault else 20)
    result = Deployment(bus, source, robot, DeployConfig(rate=RATE, read=True),
                        out=lambda _l: None).run()  # fmt: skip
    assert np.allclose(source.slopes[8], base / 4)  # slope 32 -> 8, 128 -> 32 (x1.5 kept)
    assert np.array_equal(sim.servos.params.slope, base)
    assert np.all(bus.stiffness == 1.0)
    if fault:
        assert not result.completed and result.stop_action == "crouch, torque-off"
    else:
        assert result.completed


def test_stiffness_out_of_the_registers_range_is_refused_in_one_line(robot):
    sim = Simulation(robot)
    bus = SimServoBus(sim)
    bus.open()
    one_line = r"compliance slope allowed 1\.\.254\): id 8 \(l_hip_yaw\)"
    with pytest.raises(ServoError, match=one_line):
        bus.set_stiffness(0.1)
    bus.set_stiffness(2.0)
    assert sim.servos.params.slope[robot.joint_index("l_shoulder_pitch")] == 64
    bus.configure()  # the start-up writes the configuration back
    assert sim.servos.params.slope[robot.joint_index("l_shoulder_pitch")] == 128


def test_an_integrating_imu_reads_the_rotation_since_its_last_reading(robot):
    """SimImu(integrate=True): the gyro is the site's rotation since the last reading over
    the time since it (a delta-angle IMU), where MuJoCo's sensor is the rate at the read;
    the first reading, with no last, is the sensor's."""
    import pinocchio as pin

    sim = Simulation(robot)
    sim.set_torque(False)  # (it collapses: the torso's rate changes between reads)
    mean, instant = SimImu(sim, integrate=True), SimImu(sim)
    first = mean.read()
    np.testing.assert_allclose(first.angular_velocity, instant.read().angular_velocity)
    R, t, apart = sim.site_pose("imu").rotation, sim.time, []
    for _ in range(20):
        sim.advance(0.02)
        got, now = mean.read().angular_velocity, sim.site_pose("imu").rotation
        np.testing.assert_allclose(got, pin.log3(R.T @ now) / (sim.time - t), atol=1e-9)
        apart.append(np.linalg.norm(got - instant.read().angular_velocity))
        R, t = now, sim.time
    assert max(apart) > 0.05  # (rad/s: the mean rate is not the rate at the read)
