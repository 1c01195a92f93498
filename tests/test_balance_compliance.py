"""Servo compliance compensation: the deflection law, the static contact torques, goals
inside the joint limits, and (simulated) smaller tracking error when standing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc.balance.compliance import (
    CompensatedSource,
    ComplianceCompensator,
    EncoderCorrection,
    servo_deflection,
    support_schedule,
)
from wbc.exceptions import ConfigurationError
from wbc.model import load_robot
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT, Recording
from wbc.servo_map import RAD_PER_TICK
from wbc.sim.actuator import ServoParams


@pytest.fixture(scope="module")
def robot():
    return load_robot()


@pytest.fixture(scope="module")
def comp(robot):
    return ComplianceCompensator(robot)


def _params(n: int = 1, margin=1.0, slope=32.0, punch=32.0, limit=1023.0) -> ServoParams:
    return ServoParams(
        margin=np.full(n, margin),
        slope=np.full(n, slope),
        punch=np.full(n, punch / 1023.0),
        torque_cap=np.full(n, 1.5 * limit / 1023.0),
    )


def test_deflection_by_hand():
    # margin 1, slope 32, punch 32/1023, 1.5 N·m stall: 0.5 N·m needs
    # 1 + 32 (0.5/1.5 - 32/1023) = 10.6656 ticks of error
    p = _params()
    ticks = 1.0 + 32.0 * (0.5 / 1.5 - 32.0 / 1023.0)
    assert servo_deflection(np.array([0.5]), p)[0] == pytest.approx(ticks * RAD_PER_TICK)
    assert servo_deflection(np.array([-0.5]), p)[0] == pytest.approx(-ticks * RAD_PER_TICK)
    assert servo_deflection(np.array([0.0]), p)[0] == 0.0
    # without punch: δ = τ/k + margin, k the simulator's stiffness (one definition)
    p0 = _params(punch=0.0)
    k = p0.stiffness[0]
    assert servo_deflection(np.array([0.3]), p0)[0] == pytest.approx(0.3 / k + RAD_PER_TICK)
    # above the torque limit no further offset helps
    pl = _params(limit=511.0)
    assert servo_deflection(np.array([1.4]), pl)[0] == pytest.approx(
        servo_deflection(np.array([1.5 * 511 / 1023]), pl)[0]
    )


@settings(max_examples=40, deadline=None)
@given(st.floats(0.05, 1.45))
def test_deflection_inverts_the_servo_law(tau):
    """The simulator's law, fed the deflection as its error, gives back the torque."""
    p = _params()
    e = servo_deflection(np.array([tau]), p)[0] / RAD_PER_TICK  # ticks
    u = min(1.0, p.punch[0] + (abs(e) - p.margin[0]) / p.slope[0])
    assert p.stall_torque * u == pytest.approx(tau, rel=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.floats(-1.5, 1.5), st.floats(-1.5, 1.5))
def test_deflection_odd_monotone(a, b):
    p = _params()
    da, db = servo_deflection(np.array([a, b]), _params(2))
    assert servo_deflection(np.array([-a]), p)[0] == pytest.approx(-da)
    if a <= b:
        assert da <= db + 1e-15


def _virtual_work(robot, q: np.ndarray, joint: str, sole: str, h: float = 1e-6) -> float:
    """Hand statics: with the stance sole held flat on the floor, the torque holding joint i
    is the derivative of the potential energy ``V = m g z_com`` along q_i (virtual work)."""

    def energy(d: float) -> float:
        qq = q.copy()
        qq[robot.q_index(joint)] += d
        return robot.total_mass * 9.81 * robot.com(robot.place_on_ground(qq, sole))[2]

    return (energy(h) - energy(-h)) / (2 * h)


@pytest.mark.parametrize("support,side", [(SUPPORT_LEFT, "l"), (SUPPORT_RIGHT, "r")])
def test_single_support_torques_by_hand(robot, comp, support, side):
    rng = np.random.default_rng(3)
    q = robot.random_configuration(rng, margin=0.2)
    q = robot.place_on_ground(q, f"{side}_sole")
    tau = comp.torques(robot.joints(q), support)
    assert np.abs(tau).max() > 0.1  # a loaded case
    for joint in robot.joint_names:  # stance leg, swing leg and arms
        expected = _virtual_work(robot, q, joint, f"{side}_sole")
        assert tau[robot.joint_index(joint)] == pytest.approx(expected, abs=1e-6)


def test_double_support_shares_the_weight(robot, comp):
    joints = robot.joints(robot.configuration("walk_ready"))
    tau = comp.torques(joints, SUPPORT_DOUBLE)
    li, ri = robot.joint_index("l_knee"), robot.joint_index("r_knee")
    assert tau[li] == pytest.approx(tau[ri], rel=0.05)  # symmetric pose, CoM in the middle
    single = comp.torques(joints, SUPPORT_LEFT)
    assert abs(tau[li]) < abs(single[li])  # the left knee carries less with two feet down
    with pytest.raises(ConfigurationError, match="support"):
        comp.torques(joints, 7)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31), st.sampled_from([SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT]))
def test_goals_stay_inside_limits(seed, support):
    robot = load_robot()
    comp = ComplianceCompensator(robot, gain=3.0)
    rng = np.random.default_rng(seed)
    joints = rng.uniform(robot.q_min, robot.q_max)
    # push some joints onto their limits: the offset must not take them beyond
    on = rng.random(robot.n_joints) < 0.5
    joints[on] = np.where(rng.random(on.sum()) < 0.5, robot.q_min[on], robot.q_max[on])
    goals = comp.goals(joints, support)
    assert np.all(goals >= robot.q_min) and np.all(goals <= robot.q_max)


class _Const:
    def __init__(self, q, names):
        self.q, self.joint_names = q, names

    def first(self):
        return self.q.copy()

    def __call__(self, tick, t):
        return None if t > 0.5 else self.q.copy()


def _servo_run(corr: EncoderCorrection, s_true, beta, n: int = 600, seed: int = 0, dt=0.01):
    """A servo whose static deflection is ``s_true`` × the model's plus a dynamic lag
    ``beta · v``: loads and velocities of a walk (slow sine loads, fast joint motion)."""
    rng = np.random.default_rng(seed)
    m = corr.scale.size
    phase = rng.uniform(0, 2 * np.pi, (2, m))
    for k in range(n):
        t = k * dt
        delta = 0.02 * np.sin(2 * np.pi * 0.8 * t + phase[0])  # rad, the model's deflection
        v = 1.5 * np.sin(2 * np.pi * 2.0 * t + phase[1])  # rad/s
        noise = 0.0015 * rng.standard_normal(m)  # the encoder's 0.29° steps
        corr.update(delta, v, s_true * delta + beta * v + noise, dt)


@settings(max_examples=20, deadline=None)
@given(st.floats(0.4, 1.8), st.floats(0.0, 0.03), st.integers(0, 2**31))
def test_correction_converges_on_the_true_deflection(s_true, beta, seed):
    """A servo softer or stiffer than its settings (deflection s × the model's), moving
    with a dynamic lag β·v: the scale converges to s, the lag does not bias it."""
    corr = EncoderCorrection(3)
    _servo_run(corr, s_true, beta, seed=seed)
    assert np.allclose(corr.scale, s_true, atol=0.05)
    assert np.allclose(corr.lag, beta, atol=0.01)


def test_correction_keeps_the_model_where_nothing_is_learnt():
    """No load on a joint (δ_m = 0) or nothing read (NaN): the scale stays 1."""
    corr = EncoderCorrection(2)
    for _ in range(300):
        corr.update(np.zeros(2), np.array([0.0, 1.0]), np.array([0.01, np.nan]), 0.01)
    assert np.allclose(corr.scale, 1.0, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31))
def test_correction_is_bounded(seed):
    """Whatever the encoders report (garbage, huge, NaN), the scale stays in
    [s_min, s_max] and moves at most ``rate`` per second."""
    rng = np.random.default_rng(seed)
    corr = EncoderCorrection(4, s_min=0.3, s_max=1.7, rate=2.0)
    for _ in range(200):
        before = corr.scale.copy()
        dt = rng.uniform(0.005, 0.05)
        measured = rng.choice([-1.0, 1.0], 4) * 10.0 ** rng.uniform(-4, 3, 4)
        measured[rng.random(4) < 0.1] = np.nan
        corr.update(rng.normal(0, 0.02, 4), rng.normal(0, 2, 4), measured, dt)
        assert np.all(corr.scale >= 0.3) and np.all(corr.scale <= 1.7)
        assert np.all(np.abs(corr.scale - before) <= 2.0 * dt + 1e-12)
    with pytest.raises(ConfigurationError, match="s_min"):
        EncoderCorrection(2, s_min=1.2)
    with pytest.raises(ConfigurationError, match="window"):
        EncoderCorrection(2, window=0.0)


class _Servos:
    """Static servos answering each goal with ``present = goal − s · δ_m(plan)`` one call
    late (as a deployment reads them right after sending the next goal)."""

    def __init__(self, comp, s_true):
        self.comp, self.s_true, self.sent, self.now = comp, s_true, [], None

    def present(self):
        return self.now

    def answer(self, plan, goal):
        tau = self.comp.torques(plan, SUPPORT_LEFT)
        self.sent.append(goal - self.s_true * servo_deflection(tau, self.comp.params))
        self.now = self.sent[-2] if len(self.sent) > 1 else None


def test_source_off_switch_is_the_feed_forward(robot, comp):
    """Without a correction (or before any position is read), the goals are exactly the
    feed-forward's; a correction without positions is refused."""
    plan = robot.joints(robot.configuration("walk_ready")).copy()
    off = CompensatedSource(_Const(plan, robot.joint_names), comp, lambda t: SUPPORT_DOUBLE)
    unread = CompensatedSource(_Const(plan, robot.joint_names), comp, lambda t: SUPPORT_DOUBLE,
                               lambda: None, EncoderCorrection(robot.n_joints))  # fmt: skip
    base = comp.goals(plan, SUPPORT_DOUBLE)
    for k in range(20):
        assert np.array_equal(off(k, k * 0.01), base)
        assert np.array_equal(unread(k, k * 0.01), base)
    with pytest.raises(ConfigurationError, match="present positions"):
        CompensatedSource(off.source, comp, lambda t: 0, None, EncoderCorrection(3))


def test_source_forwards_its_sources_idle(robot, comp):
    """A deployment's ``idle()`` reaches the wrapped source (a live controller's switch made
    in the idle part); a source without one is left alone."""
    plan = robot.joints(robot.configuration("walk_ready")).copy()
    inner = _Const(plan, robot.joint_names)
    calls: list[int] = []
    inner.idle = lambda: calls.append(1)  # type: ignore[attr-defined]
    CompensatedSource(inner, comp, lambda t: SUPPORT_DOUBLE).idle()
    assert calls == [1]
    CompensatedSource(_Const(plan, robot.joint_names), comp, lambda t: SUPPORT_DOUBLE).idle()


@pytest.mark.parametrize("s_true", [0.6, 1.4])
def test_source_learns_a_servo_the_model_gets_wrong(robot, comp, s_true):
    """Servos s_true × as compliant as their settings say, on the left foot: the feed-forward
    alone leaves (s_true − 1) δ_m; with the encoder correction the present positions converge
    to the plan; every goal stays within the joint limits."""
    plan = robot.joints(robot.configuration("walk_ready")).copy()
    plan[0] = robot.q_max[0]  # on a limit
    servos = _Servos(comp, s_true)
    src = CompensatedSource(_Const(plan, robot.joint_names), comp, lambda t: SUPPORT_LEFT,
                            servos.present, EncoderCorrection(robot.n_joints))  # fmt: skip
    for k in range(50):
        goal = src(k, k * 0.01)
        assert np.all(goal <= robot.q_max) and np.all(goal >= robot.q_min)
        servos.answer(plan, goal)
    ff_error = np.abs(comp.goals(plan, SUPPORT_LEFT) - plan) * abs(s_true - 1)
    error = np.abs(servos.sent[-1] - plan)
    loaded = ff_error > np.radians(0.3)
    assert loaded.sum() >= 4  # the legs carry the weight
    assert np.all(error[loaded] < 0.1 * ff_error[loaded])
    assert src(60, 0.6) is None


def test_support_schedule(robot):
    q = np.tile(robot.configuration("walk_ready"), (4, 1))
    t = np.array([1.0, 1.1, 1.2, 1.3])
    rec = Recording(t, q, robot.joint_names, {"support": np.array([0, 1, 1, 2], np.int8)}, {})
    at = support_schedule(rec)
    assert [at(x) for x in (0.0, 0.05, 0.15, 0.25, 0.35, 9.0)] == [0, 0, 1, 1, 2, 2]
    assert support_schedule(Recording(t, q, robot.joint_names, {}, {}))(0.2) == SUPPORT_DOUBLE


def test_standing_tracks_better_with_compensation(robot):
    """1 s standing in Walk Ready on the simulated AX-12As: the joints sag less."""
    pytest.importorskip("mujoco")
    from wbc.bench.play import play

    q = robot.configuration("walk_ready")
    t = np.arange(0.0, 0.6, 0.01)
    rec = Recording(t, np.tile(q, (len(t), 1)), robot.joint_names, {}, {})
    rms = {}
    for gain in (0.0, 1.0):
        res = play(rec, robot, settle=0.4, limit_tol=math.inf, compensate=gain)
        err = res.log["q"][-1, 7:] - q[7:]
        rms[gain] = float(np.sqrt(np.mean(err**2)))
        assert np.all(res.log["goal"][-1] <= robot.q_max + 1e-9)
        assert np.all(res.log["goal"][-1] >= robot.q_min - 1e-9)
    assert rms[1.0] < 0.5 * rms[0.0]


def test_deploy_compensate(robot, comp, tmp_path, capsys):
    """``wbc deploy --compensate``: the playback goals are the compensated ones (dry run)."""
    from wbc.cli import main as wbc_main

    q = robot.configuration("walk_ready")
    t = np.arange(0.0, 0.3, 0.02)
    path = tmp_path / "stand.npz"
    Recording(t, np.tile(q, (len(t), 1)), robot.joint_names, {}, {}).save(path)
    log = tmp_path / "log.npz"
    argv = ["deploy", str(path), "--dry-run", "--compensate", "--log", str(log)]
    assert wbc_main(argv) == 0
    data = np.load(log)
    goal = data["goal"][data["phase"] == 1][-1]
    assert str(data["unit"]) == "tick"
    expected = robot.servo_map.angles_to_ticks_float(comp.goals(robot.joints(q), SUPPORT_DOUBLE))
    plain = robot.servo_map.angles_to_ticks_float(robot.joints(q))
    assert np.abs(goal - expected).max() <= 0.5 + 1e-9  # rounded to whole ticks
    assert np.abs(goal - plain).max() >= 3  # and not the plain plan
    with pytest.raises(SystemExit) as exit_:  # argparse: wbc.cli.number, one line
        wbc_main(["deploy", str(path), "--dry-run", "--compensate", "-1"])
    assert exit_.value.code == 2
    assert "--compensate: must be a finite number in [0, 10]" in capsys.readouterr().err
    assert wbc_main(["deploy", str(path), "--dry-run", "--compensate-encoders"]) == 2
    assert "give --compensate too" in capsys.readouterr().err
    # the dry-run bus reads back what it was sent: the correction runs, goals stay in range
    argv = ["deploy", str(path), "--dry-run", "--compensate", "--compensate-encoders", "--log",
            str(log)]  # fmt: skip
    assert wbc_main(argv) == 0
    goal = np.load(log)["goal"]
    lo, hi = (
        robot.servo_map.angles_to_ticks_float(robot.q_min),
        robot.servo_map.angles_to_ticks_float(robot.q_max),
    )
    assert np.all(goal >= np.minimum(lo, hi) - 0.5) and np.all(goal <= np.maximum(lo, hi) + 0.5)


def test_physics_runs_pass_the_loop_options_to_randomised_models(robot, monkeypatch):
    """``simulate`` (robustness sweeps, pushes) hands compensate / gyro to every run."""
    from wbc.bench import closed_loop
    from wbc.bench import play as play_module
    from wbc.bench.variation import models

    seen = []

    def fake_play(rec, robot, **kw):
        seen.append(kw)
        raise RuntimeError("stop")

    monkeypatch.setattr(play_module, "play", fake_play)
    q = robot.configuration("walk_ready")
    rec = Recording(np.array([0.0, 0.1]), np.tile(q, (2, 1)), robot.joint_names, {}, {})
    variation = models(robot, 1, 0)[0]
    for v in (None, variation):
        with pytest.raises(RuntimeError):
            closed_loop.simulate(rec, robot, v, compensate=0.7, gyro=0.2, correct=True)
    assert [(k["compensate"], k["gyro"], k["correct"]) for k in seen] == [(0.7, 0.2, True)] * 2
    assert seen[1]["imu_noise"] == variation.imu_noise


def test_encoder_correction_on_softer_servos_in_the_simulator(robot):
    """Standing in Walk Ready on simulated AX-12As 0.7× as stiff as their settings say (the
    feed-forward's model is wrong): with the encoder correction the joints end nearer the
    plan than with the feed-forward alone."""
    pytest.importorskip("mujoco")
    from wbc.bench.play import play

    q = robot.configuration("walk_ready")
    t = np.arange(0.0, 1.5, 0.01)
    rec = Recording(t, np.tile(q, (len(t), 1)), robot.joint_names, {}, {})
    soft = ServoParams.from_settings(robot.servo_map.settings).scaled(stiffness=0.7)
    err = {}
    for correct in (False, True):
        res = play(rec, robot, settle=0.0, limit_tol=math.inf, compensate=1.0,
                   correct=correct, servo_params=soft)  # fmt: skip
        err[correct] = np.abs(res.log["q"][-1, 7:] - q[7:])
        assert np.all(res.log["goal"] <= robot.q_max + 1e-9)
        assert np.all(res.log["goal"] >= robot.q_min - 1e-9)
    assert np.sqrt(np.mean(err[True] ** 2)) < 0.8 * np.sqrt(np.mean(err[False] ** 2))
    assert err[True].max() < 0.8 * err[False].max()


@pytest.mark.parametrize("stiffness", [0.6, 1.0, 1.8])
def test_stiffness_identified_from_the_sag_under_gravity(robot, stiffness):
    """identify_stiffness: encoders that sag as a servo ``stiffness`` times as stiff as
    servos.toml's would (the ramp's part; the dead band's unchanged) give that stiffness."""
    from wbc.balance.compliance import identify_stiffness

    joints = robot.configuration("walk_ready")[7:]
    real = ServoParams.from_settings(robot.servo_map.settings).scaled(stiffness=stiffness)
    sag = servo_deflection(ComplianceCompensator(robot).torques(joints, SUPPORT_DOUBLE), real)
    k, used = identify_stiffness(robot, joints, joints + sag, joints)
    assert k == pytest.approx(stiffness, rel=1e-6) and used >= 2
    with pytest.raises(ConfigurationError, match="sag against their gravity load"):
        identify_stiffness(robot, joints, joints - sag, joints)


# ---------------------------------------------------------------------- hobby PWM servos
@pytest.fixture(scope="module")
def kokone():
    return load_robot("kokone")


@settings(max_examples=40, deadline=None)
@given(st.floats(0.06, 1.0), st.sampled_from([-1.0, 1.0]), st.integers(0, 21))
def test_hobby_deflection_inverts_the_simulators_hobby_law(kokone, load, sign, joint):
    """A hobby servo whose pulse leads its potentiometer by the feed-forward's deflection
    pushes with the torque the deflection was computed for (the simulator's own law: one
    definition; within the SSC-32's 1 µs pulse resolution)."""
    from wbc.balance.compliance import hobby_deflection
    from wbc.sim.actuator import HobbyServoArray, nominal_servo, pwm_map

    params = nominal_servo(kokone)
    codec = pwm_map(kokone).codec()
    tau = np.zeros(kokone.n_joints)
    tau[joint] = sign * load * params.stall_torque
    delta = hobby_deflection(tau, params, codec.scale)
    servos = HobbyServoArray(codec, params, 0.001)
    q = np.zeros(kokone.n_joints)
    servos.reset(q)
    servos.write(servos.pulses(q + delta))
    out = servos.law(q, 0.001)
    one_us = params.stall_torque / params.proportional_band_us
    assert out[joint] == pytest.approx(tau[joint], abs=one_us)
    assert np.all(np.delete(out, joint) == 0.0)


def test_hobby_compensator_uses_the_robots_own_servo(kokone):
    """On Kokone (no servos.toml) the compensator takes the BMS-380MAX of robot.toml and the
    SSC-32 map's µs per rad; the encoder correction is refused (no position read-back)."""
    from wbc.bench.play import play
    from wbc.sim.actuator import HobbyServoParams

    comp = ComplianceCompensator(kokone)
    assert isinstance(comp.params, HobbyServoParams) and comp.us_per_rad is not None
    q = kokone.joints(kokone.configuration("stand"))
    tau = comp.torques(q, SUPPORT_LEFT)
    knee = kokone.joint_index("l_knee")
    # the stance knee holds ~0.7 of the stall torque: ~0.3° dead band + 0.7 × 3° band
    d = comp.deflection(q, SUPPORT_LEFT)
    expect = (4.0 + 40.0 * abs(tau[knee]) / 0.412) / abs(comp.us_per_rad[knee])
    assert abs(d[knee]) == pytest.approx(expect)
    assert 0.6 < abs(tau[knee]) / 0.412 < 0.8
    rec = Recording(
        t=np.array([0.0, 0.02]),
        q=np.tile(kokone.configuration("stand"), (2, 1)),
        joint_names=kokone.joint_names,
    )
    with pytest.raises(ConfigurationError, match="report no position"):
        play(rec, kokone, compensate=1.0, correct=True)


def test_the_default_feed_forward_is_the_measured_best_per_servo_law(kokone, robot):
    """best_compensate: x0.5 on the AX-12A (issue 30's sweep), x1 on hobby PWM servos (all nine
    Kokone walks stand with it and fall without it: benchmarks/kokone_sim.md), x0.5 on the
    XM430 (the OP3's walks: benchmarks/op3.md section 7); a plain `wbc sim --robot kokone`
    uses it open loop."""
    import argparse

    from wbc.balance import best_compensate
    from wbc.cli.options import resolve_compensate

    assert best_compensate(robot) == 0.5
    assert best_compensate(kokone) == 1.0
    assert best_compensate(load_robot("op3")) == 0.5
    args = argparse.Namespace(compensate=None, compensate_encoders=False)
    resolve_compensate(args, kokone, best=True)
    assert args.compensate == 1.0


class _Plan:
    """A target source playing ``f(t)`` (joint positions) for ever."""

    def __init__(self, f, names):
        self.f, self.joint_names = f, names

    def first(self):
        return self.f(0.0)

    def __call__(self, tick, t):
        return self.f(t)


def test_x_series_deflection_is_the_p_terms(op3, comp):
    """An X-series robot's compensator inverts its P term (δ = τ / k, the servo law's own
    stiffness); it had no model before (ServoParams of X-series settings). Its servos hold a
    slow load on their integral (get_up then feeds nothing forward); the AX-12A's do not."""
    from wbc.sim.xm430 import XServoParams

    assert not comp.integral
    comp = ComplianceCompensator(op3)
    assert isinstance(comp.params, XServoParams) and comp.integral
    q = op3.joints(op3.configuration("stand"))
    tau = comp.torques(q, SUPPORT_LEFT)
    delta = comp.servo_deflection(tau)
    knee = op3.joint_names.index("l_knee")
    assert abs(tau[knee]) > 1.0  # the stance knee holds the body
    assert delta[knee] == pytest.approx(tau[knee] / comp.params.stiffness[knee])


def test_x_series_feed_forward_decays_with_the_servos_integral(op3):
    """At rest the integral holds the load (first goal = plan); a load step (double → left
    support) is fed forward, then decays as exp(−t / T_i) per joint, T_i the PI's."""
    comp = ComplianceCompensator(op3)
    q = op3.joints(op3.configuration("stand")).copy()
    switch, dt = 0.2, 0.01
    src = CompensatedSource(_Plan(lambda t: q, op3.joint_names), comp,
                            lambda t: SUPPORT_DOUBLE if t < switch else SUPPORT_LEFT)  # fmt: skip
    assert np.array_equal(src.first(), np.clip(q, op3.q_min, op3.q_max))
    jump = comp.servo_deflection(comp.torques(q, SUPPORT_LEFT) - comp.torques(q, SUPPORT_DOUBLE))
    ti = comp.params.integral_time
    out = {}
    for k in range(200):
        out[round(k * dt, 6)] = src(k, k * dt) - q
    assert np.allclose(out[0.1], 0.0)  # constant load at rest: absorbed
    for t in (0.2, 0.6, 1.5):
        want = jump * np.exp(-(t - switch + dt) / ti)  # (a moves within the switch's tick)
        got = out[t]
        inside = (q + want > op3.q_min) & (q + want < op3.q_max)
        assert np.allclose(got[inside], want[inside], atol=1e-9)


def test_x_series_feed_forward_leads_a_moving_joint_by_its_back_emf(op3):
    """A joint ramping at v (no load change, no integral: the head's P-only servo) gets
    b·v / k ahead of the plan once the goals' smoothing has settled."""
    from wbc.balance.compliance import DRIVE_FILTER_S

    comp = ComplianceCompensator(op3)
    j = op3.joint_names.index("head_pan")
    q0 = op3.joints(op3.configuration("stand")).copy()
    v = 0.5  # rad/s

    def plan(t):
        q = q0.copy()
        q[j] = v * t
        return q

    src = CompensatedSource(_Plan(plan, op3.joint_names), comp, lambda t: SUPPORT_DOUBLE)
    dt = 0.02
    for k in range(round(20 * DRIVE_FILTER_S / dt)):
        goal = src(k, k * dt)
    lead = goal[j] - plan(k * dt)[j]
    p = comp.params
    assert p.integral_time[j] == math.inf
    assert lead == pytest.approx(p.damping * v / p.stiffness[j], rel=1e-3)
