"""The closed loop on a user's own bus and IMU: the documented example runs (short)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from wbc.balance.stepping_params import SteppingParams

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "closed_loop_own_robot.py"


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("closed_loop_own_robot", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_example_walks_closed_loop(example):
    """0.6 s of walk10 (after the IMU's rest) on the example's toy simulator, through the
    deployment, closed loop: it completes, the loop's time is a share of the tick, the
    estimator sees the toy body's lean, and no goal ever left a joint limit. (The off
    switch: test_balance_stabilizer.)"""
    from wbc.balance.live import CALIBRATE_S

    closed = example.main(duration=CALIBRATE_S + 0.6, closed=True)  # (the rest, then 0.6 s)
    assert closed["completed"] and closed["ticks"] >= 55
    assert 0 < closed["feedback_share"] < 1
    assert closed["goal_limit_excess_rad"] <= 0
    assert closed["estimated_tilt_max_deg"] > 0  # the toy body leans; the estimator sees it


def test_an_imu_mounted_otherwise_than_the_robot_says_is_reported(robot):
    """The simulated IMU turned 12° about x on the torso while robot.toml says it is not:
    the start-up calibration at rest stops the run with one line naming the angle (a wrong
    mount is reported, not levelled away); 3° is levelled."""
    pytest.importorskip("mujoco")
    import pinocchio as pin

    from wbc.bench import closed_loop, variation
    from wbc.bench.solvers import registry
    from wbc.bench.trajectories import build
    from wbc.sim.model import ModelParams

    ref = build("walk10_wb", robot)
    # (a 0.3 s rest: the mount check needs no more; the default's 1 s is for the bias)
    spec = closed_loop.ClosedLoopSpec(registry()["wqp-daqp"].make, ref, calibrate_s=0.3)
    for deg, stops in ((12.0, True), (3.0, False)):
        turned = ModelParams(imu_rotation=pin.rpy.rpyToMatrix(np.radians(deg), 0.0, 0.0))
        v = variation.Variation(turned, None, 0, 0.0, {})
        result, loop = closed_loop.play_closed_loop(spec, robot, v, settle=0.0, duration=0.4)
        if stops:
            assert not result.deploy.completed
            trip = str(result.deploy.trip)
            angle = float(trip.split("gravity measured ")[1].split("°")[0])
            assert angle == pytest.approx(12.0, abs=0.5) and "tolerance 5°" in trip
        else:
            assert result.deploy.completed
            assert np.degrees(loop.stabilizer.calibration.tilt_error) == pytest.approx(3, abs=0.3)


def _kokone_on_sim(trajectory: str = "keyposes"):
    """Kokone's simulator behind the SSC-32 bus it reads nothing from: (robot, ref, sim,
    rate, make) for :func:`wbc.balance.live.closed_loop`."""
    from wbc.bench.solvers import registry
    from wbc.bench.trajectories import build
    from wbc.model import load_robot
    from wbc.sim.simulator import Simulation
    from wbc.walking.loop import start_configuration

    kokone = load_robot("kokone")
    ref = build(trajectory, kokone)
    sim = Simulation(kokone)
    sim.reset(start_configuration(kokone, ref))
    return kokone, ref, sim, min(100.0, 1.0 / ref.dt), registry()["hqp-daqp"].make


def test_a_bus_that_reads_no_positions_closes_through_the_imu_and_the_commands():
    """Issue 29 item 5: Kokone's hobby servos behind the simulated SSC-32 report no position;
    the closed loop runs on the IMU and the commanded joints, says so in one line, reads
    nothing back, and estimates every tick. Without an IMU it is refused, naming the bus."""
    pytest.importorskip("mujoco")
    from wbc.balance.live import closed_loop
    from wbc.balance.stabilizer import Gains
    from wbc.bench.trajectories import build
    from wbc.exceptions import ConfigurationError
    from wbc.sim.bus import SimImu, sim_bus

    kokone, ref, sim, rate, make = _kokone_on_sim()
    lines: list[str] = []
    loop = closed_loop(sim_bus(sim, rate), kokone, make(kokone), ref, SimImu(sim),
                       out=lines.append, duration=0.5, calibrate_s=0.3)  # fmt: skip
    assert not loop.deployment.config.read
    said = [x for x in lines if "reports no positions" in x]
    assert len(said) == 1 and "IMU and the commanded joint positions" in said[0]
    sized = [x for x in lines if "torso gains and hip strategy x" in x]  # (wbc.balance.margin)
    assert len(sized) == 1 and "gain margin" in sized[0]
    g = loop.stabilizer.gains  # the hip strategy sized with the torso term (one factor)
    assert g.k_p / Gains().k_p < 0.5
    assert g.k_hip / Gains().k_hip == pytest.approx(g.k_p / Gains().k_p)
    result = loop.deployment.run()
    assert result.completed and loop.deployment.last_present is None
    # the commanded joints hold none of the servos' sag: no pull toward their tilt
    assert Gains().kin_tilt > 0 and loop.stabilizer.estimator.kin_gain == 0.0
    est = loop.stabilizer.last  # (from the IMU and the commanded joints: nothing was read)
    assert est is not None and np.all(np.isfinite(est.values))
    with pytest.raises(ConfigurationError, match="sim bus cannot read and no IMU"):
        closed_loop(sim_bus(sim, rate), kokone, make(kokone), ref, None, out=lines.append)
    # no step adjustment from a DCM the commanded joints make (the servos' sag unseen), unless
    # asked for (benchmarks/kokone_sim.md section 0000)
    walk, said = build("walk10", kokone), []
    loop = closed_loop(sim_bus(sim, rate), kokone, make(kokone), walk, SimImu(sim), out=said.append)
    assert loop.stepping is None and sum("no step adjustment (its DCM" in x for x in said) == 1
    # ... and not on a robot with no dead bands of its own (Kokone states none): the
    # Bioloid's re-plan other robots' unpushed walks (benchmarks/robots.md, second round)
    said.clear()
    loop = closed_loop(sim_bus(sim, rate), kokone, make(kokone), walk, SimImu(sim),
                       out=said.append, step_on_commands=True)  # fmt: skip
    assert loop.stepping is None and sum("states no dead bands" in x for x in said) == 1
    bands = SteppingParams(band_x=0.03, band_y=0.02)  # (the user's: the adjuster runs)
    loop = closed_loop(sim_bus(sim, rate), kokone, make(kokone), walk, SimImu(sim),
                       out=said.append, step_on_commands=True, stepping=bands)  # fmt: skip
    assert loop.stepping is not None and loop.stepping.bands == (0.03, 0.02)


def test_step_adjustment_needs_the_robots_own_dead_bands():
    """The step adjuster's dead bands are what a robot's unpushed walks show: the Bioloid and
    the OP3 state theirs; a robot that states none (Kokone, a robot made from a URDF) walks
    without step adjustment unless the caller gives bands (benchmarks/robots.md)."""
    from wbc.model import load_robot
    from wbc.paths import robots_dir

    assert SteppingParams().measured(load_robot("bioloid"))
    assert SteppingParams().measured(load_robot(robots_dir() / "op3"))
    kokone = load_robot("kokone")
    assert not SteppingParams().measured(kokone)
    assert not SteppingParams(band_x=0.03).measured(kokone)
    assert SteppingParams(band_x=0.03, band_y=0.02).measured(kokone)


def test_the_default_rest_is_long_enough_not_to_take_the_settling_for_gyro_bias(robot):
    """The nominal simulated robot's gyro has no bias, but the compliant body still settles
    (pitches) after the soft start, below the encoders' 0.29° steps (the kinematics cannot
    take it out). 0.3 s at rest took ~0.010 rad/s of that for bias, a false 2.9° tilt through
    the filter's 0.2 /s pull, and the torso feedback tipped the robot by it (turn_wb 3.35°
    nominal); the default rest (CALIBRATE_S) keeps the false bias below 0.005 rad/s (the
    default loop: feed-forward x0.5)."""
    pytest.importorskip("mujoco")
    from wbc.balance.live import CALIBRATE_S
    from wbc.bench import closed_loop
    from wbc.bench.solvers import registry
    from wbc.bench.trajectories import build

    ref = build("turn_wb", robot)
    biases = {}
    for rest in (0.3, CALIBRATE_S):
        spec = closed_loop.ClosedLoopSpec(registry()["wqp-daqp"].make, ref, calibrate_s=rest)
        _, loop = closed_loop.play_closed_loop(
            spec, robot, settle=0.0, duration=rest + 0.05, compensate=0.5
        )
        biases[rest] = float(np.linalg.norm(loop.stabilizer.calibration.gyro_bias))
    assert biases[0.3] > 0.008, biases  # (what the short rest took)
    assert biases[CALIBRATE_S] < 0.005, biases


def test_the_loop_share_counts_the_walking_ticks_only(example):
    """The loop's share of a tick (:func:`wbc.balance.live.loop_share`, what the physics
    benchmark and benchmarks/closed_loop_cost.py report) is taken over the walk's ticks: the
    start-up calibration's ticks at rest are not counted; per tick, the loop's time leaves out
    the drivers' reads, which are kept beside it."""
    from wbc import load_robot
    from wbc.balance.live import CALIBRATE_S, closed_loop, loop_share
    from wbc.balance.stabilizer import Gains
    from wbc.bench.trajectories import build
    from wbc.stacks import load_stack
    from wbc.walking.loop import StackController, start_configuration

    robot = load_robot("bioloid")
    ref = build("walk10", robot)
    sim = example.ToySimulator(robot, start_configuration(robot, ref))
    loop = closed_loop(example.ToyBus(sim), robot, StackController(load_stack("walk", robot)),
                       ref, imu=example.ToyImu(sim), gains=Gains(), out=lambda _l: None,
                       duration=CALIBRATE_S + 0.2)  # fmt: skip
    result = loop.deployment.run()
    rest = loop.stabilizer.calibration_ticks
    source = loop.source
    assert rest > 0 and len(source.solve_time) == result.timing.ticks - rest
    assert len(source.feedback_time) == len(source.read_time) == len(source.solve_time)
    assert min(source.read_time) > 0 and min(source.feedback_time) > 0
    fb, sv = np.array(source.feedback_time), np.array(source.solve_time)
    assert source.cost_share() == loop_share(fb, sv) == pytest.approx(np.median(fb / (fb + sv)))


def test_the_limit_excess_is_the_largest_excursion_of_any_tick():
    """SessionSource.limit_excess (the physics record's goal_limit_excess): the largest
    ``max(q_min − j, j − q_max)`` of any tick's targets, exactly the per-tick formula's number
    (kept as running extremes, read when asked); 0 before any target and within the limits."""
    from wbc import load_robot
    from wbc.balance.live import SessionSource
    from wbc.bench.trajectories import build
    from wbc.stacks import load_stack
    from wbc.walking.loop import Session, StackController

    robot = load_robot("bioloid")
    session = Session(StackController(load_stack("walk", robot)), robot, build("walk10", robot))
    source = SessionSource(session)
    assert source.limit_excess == 0.0
    rng, span, worst = np.random.default_rng(0), robot.q_max - robot.q_min, 0.0
    for tick in range(40):
        scale = 1.0 if tick < 10 else 1.08  # (within the limits first)
        j = robot.q_min + span * (0.5 + scale * rng.uniform(-0.5, 0.5, robot.n_joints))
        q = session.q.copy()
        q[7:] = j
        session.at_time = lambda _t, q=q: q  # (the tick's solve: these targets)
        assert np.array_equal(source(tick, 0.01 * tick), j)
        worst = max(worst, float(np.max(np.maximum(robot.q_min - j, j - robot.q_max))))
        assert source.limit_excess == worst
    assert worst > 0


def test_the_source_counts_the_walking_ticks_whose_solve_failed():
    """SessionSource.failed_ticks (the closed loop's ``failed_solves``): every walking tick
    whose solve raised (the session held its last configuration), not whether the last one
    did; a tick of the stack relaxed by its solver counts in ``relaxed_ticks``."""
    from wbc import load_robot
    from wbc.balance.live import SessionSource
    from wbc.bench.trajectories import build
    from wbc.exceptions import InfeasibleError
    from wbc.stacks import load_stack
    from wbc.walking.loop import Session, StackController

    robot = load_robot("bioloid")
    controller = StackController(load_stack("walk", robot))
    session = Session(controller, robot, build("walk10", robot))
    source = SessionSource(session)
    track, failing = controller.track, {5, 6, 7, 12}

    def flaky(q, targets, dt, changed):
        if targets.i in failing:
            raise InfeasibleError("hard level 0 is infeasible (the test's)")
        out = track(q, targets, dt, changed)
        controller.solver.relaxed = targets.i == 20  # (as a relaxing solver marks its tick)
        return out

    controller.track = flaky
    for tick in range(25):
        source(tick, session.ref.dt * tick)
    assert source.failed_ticks == 4 and not session.failed  # (the last tick solved)
    assert source.relaxed_ticks == 1
    # what `wbc sim` (its JSON) and `wbc deploy --live` report
    assert source.solve_counts() == {"walking_ticks": 25, "failed_solves": 4, "relaxed_solves": 1}
    assert source.solve_line() == ("live solves: 4 of 25 walking ticks failed (the last pose "
                                   "held), 1 relaxed")  # fmt: skip


def test_loop_share_is_the_median_share_and_scale_free():
    """loop_share: the median over the ticks of loop / (loop + solve); the same for times
    scaled together (a slower machine)."""
    from wbc.balance.live import loop_share

    loop, solve = [1.0, 2.0, 3.0], [1.0, 2.0, 1.0]
    assert loop_share(loop, solve) == pytest.approx(0.5)
    assert loop_share(np.multiply(loop, 7.0), np.multiply(solve, 7.0)) == pytest.approx(0.5)
    assert loop_share([0.0], [1.0]) == 0.0


def test_the_default_gains_follow_the_feed_forward_and_given_gains_win(example):
    """Issue 30, best by default: a closed loop given no gains runs the measured best for its
    feed-forward (:func:`wbc.balance.stabilizer.default_gains`): without it (``compensate``
    0) the estimator's ``joint_lag``, the torso's ``k_d`` 0.03 and the DCM integral along the
    walk, ``k_dcm_i`` 0.25 (150 of 150 plants against 147 without it and 143 with
    :class:`Gains`, benchmarks/physics.md), and on plants identified soft the CoM 8 mm lower
    and the DCM integral leaked at the walk's end (``lift``, ``end_leak``, ``end_lead``), the
    hip strategy rolled about the estimated torso's own axis (``hip_axis`` 2); with
    it :class:`Gains` as they are; gains given are used unchanged whatever the feed-forward."""
    from wbc import load_robot
    from wbc.balance.live import closed_loop
    from wbc.balance.stabilizer import NO_FEED_FORWARD_GAINS, Gains, default_gains
    from wbc.bench.trajectories import build
    from wbc.stacks import load_stack
    from wbc.walking.loop import StackController, start_configuration

    no_ff = Gains(k_d=0.03, joint_lag=1.0, k_dcm_i=0.25, lift=-0.008, end_leak=2.0, end_lead=0.4,
                  hip_axis=2)  # fmt: skip
    assert default_gains(0.0) == no_ff == NO_FEED_FORWARD_GAINS
    assert default_gains(0.5) == default_gains(1.0) == Gains()
    robot = load_robot("bioloid")
    ref = build("walk10", robot)
    controller = StackController(load_stack("walk", robot))
    mine = Gains(k_p=2.0, joint_lag=0.0)
    for compensate, gains, expected, lag in (
        (0.0, None, no_ff, True),
        (0.5, None, Gains(), False),
        (0.0, mine, mine, False),
        (0.5, mine, mine, False),
    ):
        sim = example.ToySimulator(robot, start_configuration(robot, ref))
        loop = closed_loop(example.ToyBus(sim), robot, controller, ref, imu=example.ToyImu(sim),
                           gains=gains, compensate=compensate, out=lambda _l: None)  # fmt: skip
        assert loop.stabilizer.gains == expected, (compensate, gains)
        assert loop.stabilizer.estimator.joint_lag is lag


def test_the_users_servo_model_is_taken_whatever_its_law_and_anything_else_is_refused():
    """closed_loop(servo=...) takes a hobby servo's or an X-series servo's model as the
    user's, as it takes an AX-12A's (it silently fell back to servos.toml for any law but
    the AX-12A's), and refuses anything else in one line naming the three laws."""
    pytest.importorskip("mujoco")
    from dataclasses import replace

    from wbc.balance.live import closed_loop
    from wbc.exceptions import ConfigurationError
    from wbc.sim.actuator import nominal_servo
    from wbc.sim.bus import SimImu, sim_bus

    kokone, ref, sim, rate, make = _kokone_on_sim()
    mine = replace(nominal_servo(kokone), stall_torque=nominal_servo(kokone).stall_torque * 0.8)
    lines: list[str] = []
    loop = closed_loop(sim_bus(sim, rate), kokone, make(kokone), ref, SimImu(sim),
                       out=lines.append, calibrate_s=0.0, servo=mine)  # fmt: skip
    assert loop.servo_model == "the user's servo model"
    assert loop.deployment.source.compensator.params is mine  # type: ignore[attr-defined]
    with pytest.raises(ConfigurationError, match="HobbyServoParams, XServoParams"):
        closed_loop(sim_bus(sim, rate), kokone, make(kokone), ref, SimImu(sim),
                    out=lines.append, servo=object())  # type: ignore[arg-type]  # fmt: skip
