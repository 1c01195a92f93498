"""The physics benchmark: falls, deviations, robustness sweeps and pushes (short runs)."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("mujoco")

from wbc.bench import closed_loop, physics, pushes, sim_record, variation
from wbc.bench.play import play
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT, Recording


@pytest.fixture(scope="module")
def standing(robot):
    """Walk Ready held for 1 s, with a fake left single support in the middle (for pushes)."""
    t = np.arange(0.0, 1.0 + 1e-9, 0.02)
    q = np.tile(robot.configuration("walk_ready"), (t.size, 1))
    support = np.full(t.size, SUPPORT_DOUBLE, dtype=np.int8)
    support[15:35] = SUPPORT_LEFT
    com = np.tile(robot.com(q[0]), (t.size, 1))
    return Recording(t, q, robot.joint_names, {"support": support, "com": com})


def test_standing_stays_up_with_small_deviations(robot, standing):
    r = sim_record.physics_record(standing, play(standing, robot, settle=0.5), robot)
    assert r["fell"] is False and r["fall_time_s"] is None
    assert r["orientation_dev_max_deg"] < 1.0
    assert r["foot_slip_max_mm"] < 1.0
    assert r["distance_ratio"] is None  # nothing planned to travel
    assert r["tracking_err_max_deg"] < 3.0
    assert 0.0 < r["torque_peak_ratio"] < 0.5
    assert r["cop_margin_min_mm"] > 5.0  # two flat feet: the CoP well inside
    assert r["deploy_completed"]


def test_a_hard_push_makes_it_fall_and_the_record_says_when(robot, standing):
    t_push = sim_record.mid_single_support(standing)
    assert t_push == pytest.approx(0.5 * (standing.t[15] + standing.t[34]))
    force = np.array([0.0, 1.5, 0.0]) / pushes.PUSH_DURATION  # 1.5 N·s sideways
    r = closed_loop.simulate(standing, robot, push=(t_push, force, pushes.PUSH_DURATION))
    assert r["fell"] is True
    assert t_push < r["fall_time_s"] < t_push + 1.5
    assert r["fall_phase"] in ("double", "left", "right") and "stall" in r["fall_joint"]


def test_largest_push_brackets_the_fall(robot, standing):
    survived = pushes.largest_push(standing, robot, (0, 1, 0), max_impulse=1.2, steps=2,
                                    settle=0.5)  # fmt: skip
    assert survived is not None and 0.0 < survived < 1.2
    force = np.array([0.0, survived, 0.0]) / pushes.PUSH_DURATION
    t_push = sim_record.mid_single_support(standing)
    assert not closed_loop.simulate(standing, robot, push=(t_push, force, 0.01), settle=0.5)["fell"]


def test_largest_push_at_a_later_push_time(robot, standing, monkeypatch):
    """``offset``: every bisection run pushes that long after mid single support (one
    bisection per push time: benchmarks/pushes.py ``--offsets``)."""
    times = []

    def fake(rec, robot, push=None, **kw):
        times.append(None if push is None else push[0])
        return {"fell": push is not None and push[1][1] * pushes.PUSH_DURATION > 0.5}

    monkeypatch.setattr(pushes, "simulate", fake)
    survived = pushes.largest_push(standing, robot, (0, 1, 0), steps=3, offset=0.03)
    assert survived == pytest.approx(0.375)
    t_push = sim_record.mid_single_support(standing)
    assert times and set(times) == {t_push + 0.03}


def test_random_models_and_the_sweep_are_reproducible_from_the_seed(robot, standing):
    a = [v.summary for v in variation.models(robot, 3, seed=7)]
    b = [v.summary for v in variation.models(robot, 3, seed=7)]
    c = [v.summary for v in variation.models(robot, 3, seed=8)]
    assert a == b and a != c
    assert (
        variation.models(robot, 3, seed=7)[2].summary
        == variation.models(robot, 5, seed=7)[2].summary
    )
    v = variation.models(robot, 1, seed=7)[0]
    assert 0.85 <= v.model_params.mass_scale.min() <= v.model_params.mass_scale.max() <= 1.15
    assert v.latency_ticks == 0 and 0.0 <= v.latency_s <= 0.02
    s1 = closed_loop.robustness(standing, robot, 2, seed=7, settle=0.2)
    s2 = closed_loop.robustness(standing, robot, 2, seed=7, settle=0.2)
    assert s1 == s2 and s1["models"] == 2 and s1["up_fraction"] == 1.0


def test_a_run_the_deployment_stopped_is_not_up(robot, standing, monkeypatch):
    """A plant whose run was safe-stopped before the end (say its start-up IMU check refused
    a rocking body) did not fall, but did not walk either: robustness counts it not up and
    names why; a completed standing run carries no stop reason."""
    done = closed_loop.simulate(standing, robot, settle=0.2)
    assert done["stopped"] is None and not done["fell"]
    outcomes = iter([dict(done), {**done, "stopped": "imu: gravity 7.2 deg off"}])
    monkeypatch.setattr(closed_loop, "simulate", lambda *a, **k: next(outcomes))
    r = closed_loop.robustness(standing, robot, 2, seed=7)
    assert r["up"] == [True, False] and r["up_fraction"] == 0.5 and r["falls"] == []
    assert [s["model"] for s in r["stopped"]] == [1]
    assert r["stopped"][0]["reason"] == "imu: gravity 7.2 deg off"


def test_bench_physics_command(robot, tmp_path, capsys):
    from wbc.cli import main

    out = tmp_path / "physics.json"
    rc = main(["bench", "--physics", "--solvers", "hqp-daqp", "--trajectories", "thesis_step",
               "--json", str(out)])  # fmt: skip
    assert rc == 0
    text = capsys.readouterr().out
    assert "physics: thesis_step" in text and "hqp-daqp" in text
    record = json.loads(out.read_text())["records"][0]
    for key in sim_record.PHYSICS_KEYS:
        assert key in record
    assert record["solver"] == "hqp-daqp" and record["trajectory"] == "thesis_step"
    assert record["realtime_factor"] > 0 and record["sim_steps"] > 0
    # the thesis step tips sideways in single support but stays up on the nominal model
    assert record["fell"] is False
    assert 5.0 < record["orientation_dev_max_deg"] < 45.0
    lines = physics.physics_summary_lines([record])
    assert all(len(line) <= 100 for line in lines)


def test_fall_summary_counts_phases_and_joints():
    falls = [
        {"phase": "left", "joint": "l_hip_roll (1.00 stall)", "latency": 1},
        {"phase": "left", "joint": "l_hip_roll (0.90 stall)", "latency": 0},
        {"phase": "double", "joint": "r_knee (0.50 stall)", "latency": 1},
    ]
    line = physics.fall_summary(falls)
    assert line.startswith("3 falls: phase left 2, double 1; most loaded l_hip_roll 2, r_knee 1")
    assert line.endswith("67% with one-tick latency")


def test_lateral_push_goes_away_from_the_swing_foot(standing):
    np.testing.assert_array_equal(pushes.push_direction(standing, "lateral"), [0, 1, 0])
    right = Recording(standing.t, standing.q, standing.joint_names,
                      {"support": np.where(standing["support"] == SUPPORT_LEFT, 2, 0)})  # fmt: skip
    np.testing.assert_array_equal(pushes.push_direction(right, "lateral"), [0, -1, 0])
    np.testing.assert_array_equal(pushes.push_direction(right, "forward"), [1, 0, 0])
    np.testing.assert_array_equal(pushes.push_direction(right, "backward"), [-1, 0, 0])
    np.testing.assert_array_equal(pushes.push_direction(right, "away"), [0, -1, 0])
    np.testing.assert_array_equal(pushes.push_direction(right, "toward"), [0, 1, 0])
    np.testing.assert_array_equal(pushes.push_direction(standing, "toward"), [0, -1, 0])
    with pytest.raises(Exception, match="forward, backward, toward, away"):
        pushes.push_direction(right, "up")


def test_bench_physics_refuses_bad_options(capsys):
    from wbc.cli import main

    with pytest.raises(SystemExit) as exit_:  # argparse: wbc.cli.number, one line
        main(["bench", "--physics", "--robustness", "-1"])
    assert exit_.value.code == 2
    assert "--robustness: must be an integer in [0, 10000]" in capsys.readouterr().err
    assert main(["bench", "--physics", "--mode", "converge"]) == 2
    assert "use --mode tick" in capsys.readouterr().err
    # hobby servos report no position: no encoders-only closed loop (IMU + commanded joints)
    args = ["bench", "--physics", "--robot", "kokone", "--encoders-only"]
    assert main([*args, "--trajectories", "keyposes", "--solvers", "hqp-daqp"]) == 2
    assert "--encoders-only: kokone's hobby servos report no positions" in capsys.readouterr().err


def test_closed_loop_spec_reaches_every_run(robot, standing, monkeypatch):
    """Robustness sweeps and push bisections hand the closed loop (controller, reference,
    gains, randomised model, push) to every live run, and measure it against the plan."""
    seen = []

    def fake(spec, robot_, variation=None, push=None, settle=1.0, compensate=0.0, correct=False):
        seen.append((spec, variation, push, compensate, correct))
        raise RuntimeError("stop")

    monkeypatch.setattr(closed_loop, "play_closed_loop", fake)
    spec = closed_loop.ClosedLoopSpec(make=lambda r: None, ref="REF", gains="G")
    with pytest.raises(RuntimeError):
        closed_loop.robustness(standing, robot, 2, 0, compensate=0.5, closed=spec, correct=True)
    assert seen[0][0] is spec and seen[0][1] is not None and seen[0][3:] == (0.5, True)
    with pytest.raises(RuntimeError):
        closed_loop.simulate(standing, robot, push=(0.1, [1.0, 0, 0], 0.01), closed=spec)
    assert seen[1][0] is spec and seen[1][2][0] == 0.1


def test_kokone_randomised_models_spread_around_its_hobby_servo():
    """--robustness on Kokone: the plant's draws as factors of the BMS-380MAX's values."""
    from wbc import load_robot
    from wbc.sim.actuator import HobbyServoParams, nominal_servo

    kokone = load_robot("kokone")
    nominal = nominal_servo(kokone)
    variations = variation.models(kokone, 8, seed=3)
    for v in variations:
        sp, mp, s = v.servo_params, v.model_params, v.summary
        assert isinstance(sp, HobbyServoParams)
        us = abs(float(np.mean(sp.stiffness(1.0) / nominal.stiffness(1.0))))
        assert us == pytest.approx(s["stiffness"])  # the small-error stiffness, exactly
        assert 0.8 * nominal.stall_torque <= sp.stall_torque <= nominal.stall_torque
        assert 0.5 * nominal.damping <= mp.damping <= 1.5 * nominal.damping
        assert 0.4 * nominal.armature <= mp.armature == sp.armature <= 2.4 * nominal.armature
        assert 0.0 <= sp.friction_loss <= 2 * nominal.friction_loss
    again = variation.models(kokone, 8, seed=3)
    assert [v.summary for v in again] == [v.summary for v in variations]


def test_the_sweep_randomises_the_plant_not_the_controller(robot):
    """Issue 30: stiffness ×0.5–2 exactly (small-error stiffness), backlash ≤ 1°, latency
    0–20 ms, IMU bias and noise, masses ±15 %; the feed-forward keeps servos.toml."""
    from wbc.balance.compliance import ComplianceCompensator
    from wbc.sim.actuator import nominal_servo

    nominal = nominal_servo(robot)
    variations = variation.models(robot, 12, seed=1)
    ratios = [float(np.mean(v.servo_params.stiffness / nominal.stiffness)) for v in variations]
    assert ratios == pytest.approx([v.summary["stiffness"] for v in variations])
    assert 0.5 <= min(ratios) and max(ratios) <= 2.0 and max(ratios) / min(ratios) > 2.0
    assert all(0 <= v.servo_params.backlash <= np.radians(1.0) for v in variations)
    assert max(v.latency_s for v in variations) > 0.01
    assert all(v.imu["gyro_bias_std"] >= 0 and v.imu["acc_noise"] >= 0 for v in variations)
    scale = np.concatenate([v.model_params.mass_scale for v in variations])
    assert scale.min() >= 0.85 and scale.max() <= 1.15 and scale.max() - scale.min() > 0.2
    # the controller's feed-forward: the nominal settings, whatever the plant
    ff = ComplianceCompensator(robot)
    assert np.array_equal(ff.params.slope, nominal.slope)


def test_goal_latency_delays_the_servos_by_that_time(robot):
    """Simulation.goal_delay: a goal written now reaches the servos that many s later."""
    pytest.importorskip("mujoco")
    from wbc.sim.simulator import Simulation

    sim = Simulation(robot)
    sim.goal_delay = 0.013
    before = sim.servos.goal.copy()
    sim.write_goals(before + 5)
    sim.advance(0.012)
    assert np.array_equal(sim.servos.goal, before)
    sim.advance(0.004)  # (the step that starts at 0.014 s acts on it)
    assert np.array_equal(sim.servos.goal, before + 5)


def test_on_the_physics_stack_the_hierarchy_is_the_weighted_qp_and_on_walk_strict_not(robot):
    """The physics benchmark's ``walk`` stack is one hard level (contacts, self-collision)
    and ONE soft level: a lexicographic QP then minimises that level's weighted tasks subject
    to the hard rows and every constraint, the weighted QP's problem exactly, so hqp-daqp
    and wqp-daqp plan the same joints (to rounding; benchmarks/physics.md). On
    ``walk_strict`` (the torso and posture a level below) they genuinely differ."""
    from wbc.bench import solvers
    from wbc.bench import trajectories as traj
    from wbc.walking.loop import Session

    ref = traj.build("walk10_wb", robot)
    ticks = range(40, 70)  # into the first single support (the swing foot tracked)
    gaps = {}
    for stack in ("walk", "walk_strict"):
        reg = solvers.registry("physics", stack)
        suffix = "" if stack == solvers.BENCH_STACKS["physics"] else f"@{stack}"
        qs = []
        for name in ("wqp-daqp", "hqp-daqp"):
            session = Session(reg[name + suffix].make(robot), robot, ref)
            qs.append(np.array([session.tick(i) for i in range(max(ticks) + 1)])[list(ticks)])
        gaps[stack] = float(np.abs(qs[0] - qs[1]).max())
    assert gaps["walk"] < 1e-8, gaps
    assert gaps["walk_strict"] > 1e-4, gaps
