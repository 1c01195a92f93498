"""The driven walk on the simulator (wbc.drive.sim): a fall, then the get-up, end to end;
the judge of standing."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("mujoco")

from wbc.bench.solvers import registry
from wbc.drive.commands import Command
from wbc.drive.getup_sim import drop
from wbc.drive.sim import drive_sim, judge, make_sim
from wbc.exceptions import ConfigurationError
from wbc.model import load_robot


def test_a_shove_fells_the_driven_robot_and_it_gets_up_by_itself() -> None:
    """``wbc drive``'s path in Python: the walker standing on its velocity commands (the
    hqp-daqp controller, closed loop, on the simulated bus and IMU), a 4 N·s shove forward
    at 1 s fells it on its front; the deployment ends, and after_fall (get_up on the same
    bus and IMU) stands it up again: the judge finds it standing (torso within 10° of its
    standing attitude, soles flat, CoM over the feet)."""
    robot = load_robot("bioloid")
    controller = registry("physics")["hqp-daqp"].make(robot)
    lines: list[str] = []
    record = drive_sim(robot, controller, [Command(3.0, 0.0, 0.0, 0.0)],
                       walker_options={"compensate": 0.5, "calibrate_s": 0.3},  # (as measured)
                       push=(1.0, (20.0, 0.0, 0.0), 0.2),
                       get_up=True, out=lines.append)  # fmt: skip
    assert record["fell"] and 1.0 < record["fall_time_s"] < 2.0
    assert record["getup_side"] == "prone"
    assert record["got_up"], record["getup_reason"]
    assert record["getup_phases"][-1] == "settle"
    assert "get-up: lying prone" in lines


def test_without_get_up_a_felled_robot_stays_down() -> None:
    robot = load_robot("bioloid")
    controller = registry("physics")["hqp-daqp"].make(robot)
    record = drive_sim(robot, controller, [Command(2.0, 0.0, 0.0, 0.0)],
                       push=(0.5, (20.0, 0.0, 0.0), 0.2))  # fmt: skip
    assert record["fell"] and "got_up" not in record


def test_standing_is_judged_up_whatever_the_heading_and_lying_is_not() -> None:
    """Standing in Walk Ready (its torso 10 deg from the vertical by design) is up, at any
    heading; lying on the front or back is not."""
    robot = load_robot("bioloid")
    sim, _bus, _imu = make_sim(robot)
    for yaw in (0.0, 2.5):
        q = robot.configuration("stand")
        q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(0.0, 0.0, yaw)).coeffs()
        sim.reset(q, torque=True)
        sim.advance(1.0)
        ok, why = judge(sim, robot)
        assert ok, why
    for side in ("prone", "supine"):
        drop(sim, robot, side)
        ok, why = judge(sim, robot)
        assert not ok and "from standing" in why


def test_the_walker_calibrates_its_imu_at_rest_before_it_walks() -> None:
    """With an IMU the walker first stands ``calibrate_s`` (DRIVE_CALIBRATE_S) at rest for the IMU's
    start-up calibration (gyro bias, levelling: ``wbc deploy``'s closed loop does the same);
    a start asked meanwhile waits for its end (on the randomised Bioloids of
    benchmarks/drive.md the heading error of random sequences fell from a median 6.2° to
    2.4° with it); ``yaw_rest_s`` > 0 rests that much longer while the outer loop's odometry
    learns the gyro's bias about the vertical (PoseOdometry.rest)."""
    from wbc.drive.walker import DRIVE_CALIBRATE_S, DRIVE_YAW_REST_S, Walker

    robot = load_robot("bioloid")
    _sim, _bus, imu = make_sim(robot)
    walker = Walker(robot, registry("physics")["hqp-daqp"].make(robot), imu)
    walker.present = lambda: walker.q[7:]
    assert walker.calibrating
    walker.command(0.03, 0.0, 0.0)
    walker.start()
    assert walker.walking and not walker.engine.walking  # asked, waiting
    ticks = 0
    while walker.calibrating:
        walker.tick()
        ticks += 1
    dt = walker.engine.dt
    assert ticks == round(DRIVE_CALIBRATE_S / dt) + round(DRIVE_YAW_REST_S / dt)
    assert walker.odometry.rest_time == pytest.approx(DRIVE_YAW_REST_S)
    walker.tick()
    assert walker.engine.walking
    make = registry("physics")["hqp-daqp"].make
    longer = Walker(robot, make(robot), imu, yaw_rest_s=0.2)
    longer.present = lambda: longer.q[7:]
    ticks = 0
    while longer.calibrating:
        longer.tick()
        ticks += 1
    assert ticks == round(DRIVE_CALIBRATE_S / dt) + 20
    assert longer.odometry.rest_time == pytest.approx(0.2)
    assert longer.stabilizer.calibration is not None
    assert Walker(robot, make(robot), imu, calibrate_s=0.0, yaw_rest_s=0.0).calibrating is False
    for bad in (-1.0, math.nan):
        with pytest.raises(ConfigurationError, match="yaw_rest_s must be"):
            Walker(robot, make(robot), imu, yaw_rest_s=bad)
    for option, bad in (("stride_gain", 0.9), ("stride_gain", math.inf), ("yaw_learn", -0.1),
                        ("yaw_learn", 1.5), ("yaw_learn", math.nan), ("lift_gain", 0.9),
                        ("lift_gain", math.inf)):  # fmt: skip
        with pytest.raises(ConfigurationError, match=f"{option} must be"):
            Walker(robot, make(robot), imu, **{option: bad})


def test_a_settling_calibration_waits_for_a_still_gyro_and_takes_its_quietest_window() -> None:
    """``Walker(settle_s=S)``: the IMU's start-up calibration rests up to S s more until its
    window's gyro is still (wbc.imu.SETTLE_STILL) and takes the quietest window, so a robot
    still rocking at the planned end (here 4 Hz about the pitch axis, ±0.3 rad/s decaying to
    nothing by 0.6 s) leaves its rocking out of the bias; without it (the default) the 0.3 s
    calibration takes part of a swing as bias. Bounded: never still, it stops after S."""
    from wbc.drive.walker import DRIVE_CALIBRATE_S, Walker
    from wbc.imu import SETTLE_STILL, ImuReading

    robot = load_robot("bioloid")
    _sim, _bus, imu = make_sim(robot)
    bias = np.array([0.01, -0.02, 0.005])

    class Rocking:  # the simulated IMU (at rest) plus a bias and a decaying rocking
        mount = imu.mount

        def __init__(self, decay: float) -> None:
            self.k, self.decay = 0, decay

        def read(self) -> ImuReading:
            r, t = imu.read(), 0.01 * self.k
            self.k += 1
            rock = 0.3 * max(0.0, 1.0 - t / self.decay) * math.sin(2 * math.pi * 4 * t + 0.7)
            w = r.angular_velocity + bias + np.array([0.0, rock, 0.0])
            return ImuReading(r.t, r.orientation, w, r.linear_acceleration)

    def rest(settle_s: float, decay: float = 0.6) -> tuple[int, np.ndarray]:
        make = registry("physics")["hqp-daqp"].make
        walker = Walker(robot, make(robot), Rocking(decay), yaw_rest_s=0.0, settle_s=settle_s)
        walker.present = lambda: walker.q[7:]
        ticks = 0
        while walker.calibrating:
            walker.tick()
            ticks += 1
        true = imu.mount.rotation @ bias if imu.mount is not None else bias
        return ticks, walker.stabilizer.calibration.gyro_bias - true

    planned = round(DRIVE_CALIBRATE_S / 0.01)
    ticks, off = rest(0.0)
    assert ticks == planned and np.max(np.abs(off)) > 2 * SETTLE_STILL  # the rocking as bias
    ticks, off = rest(1.0)
    assert planned < ticks < planned + 100 and np.max(np.abs(off)) < SETTLE_STILL  # (its motion)
    ticks, off = rest(0.2, decay=100.0)  # never still: bounded, the quietest window taken
    assert ticks == planned + 20
    with pytest.raises(ConfigurationError, match="settle_s must be"):
        Walker(robot, registry("physics")["hqp-daqp"].make(robot), imu, settle_s=-1.0)


def _compliant_walk(options: dict) -> tuple:
    """benchmarks/drive.md's most compliant randomised Bioloid (model 7) walking 4 s at 5 cm/s
    with ``options`` on top of the feed-forward and a 0.3 s rest: (its Walker, the distance
    travelled forward, m); it must not fall."""
    from wbc.bench.variation import models
    from wbc.drive import sim as drive
    from wbc.drive.walker import Walker, default_compensate

    robot = load_robot("bioloid")
    made: list[Walker] = []

    class Kept(Walker):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            made.append(self)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(drive, "Walker", Kept)
        r = drive.drive_sim(robot, registry("physics")["hqp-daqp"].make(robot),
                            [Command(4.0, 0.05)], models(robot, 8, 0)[7], settle=0.2,
                            walker_options={"compensate": default_compensate(),
                                            "yaw_rest_s": 0.3, **options})  # fmt: skip
    assert not r["fell"]
    return made[0], r["travelled_xy_m"][0]


def test_the_stride_gain_lengthens_a_compliant_robots_short_steps() -> None:
    """The most compliant randomised Bioloid of benchmarks/drive.md (model 7: servo
    stiffness ×0.56) walks 4 s at 5 cm/s: its steps fall short of their plans, the odometry
    measures it, and with the default ``stride_gain`` (1.5) the forward stride is planned
    longer (the gain at its bound here) and the robot walks 2 cm further than with the steps
    as commanded (12.9 cm against 10.2 of the 20 commanded, the swing's lift gain off in both:
    with it, 13.6 against 11.6)."""
    from wbc.drive.walker import DRIVE_STRIDE_GAIN

    # (lift_gain 1, no finish step: the stride's part alone; the lift gain lengthens this
    # model's walk too, and a finish step after the stop moves the base by its own slip)
    options = {"lift_gain": 1.0, "finish_steps": 0}
    runs = [_compliant_walk({"stride_gain": g, **options}) for g in (1.0, DRIVE_STRIDE_GAIN)]
    made, travelled = [w for w, _ in runs], [t for _, t in runs]
    assert made[0].engine.stride_gain == pytest.approx([1.0, 1.0, 1.0])
    assert made[1].engine.stride_gain[0] > 1.3
    assert made[1].engine.stride_gain[2] == 1.0  # (the turn: not from the biased gyro)
    assert travelled[1] > travelled[0] + 0.02


def test_the_lift_gain_raises_a_compliant_robots_dragging_swing() -> None:
    """The most compliant randomised Bioloid of benchmarks/drive.md (model 7: servo
    stiffness ×0.53) walks 4 s at 5 cm/s with the stride as commanded: its swing sole,
    planned 10 mm high, reaches about 2 mm above the stance sole (the servos lag the
    swing's rise) and drags on the floor. The encoders see it: with the default
    ``lift_gain`` (2) the apex is planned higher (the gain above 1.5 in 4 s) and the robot
    walks 11.4 cm of the 20 commanded instead of 10.1 (1: the apex as planned)."""
    from wbc.drive.walker import DRIVE_LIFT_GAIN

    runs = [_compliant_walk({"stride_gain": 1.0, "lift_gain": g}) for g in (1.0, DRIVE_LIFT_GAIN)]
    made, travelled = [w for w, _ in runs], [t for _, t in runs]
    assert made[0].lift is None and made[0].engine.params.swing.apex == 0.01
    assert made[1].lift is not None and made[1].lift.gain > 1.5
    assert made[1].engine.params.swing.apex == pytest.approx(0.01 * made[1].lift.gain)
    assert travelled[1] > travelled[0] + 0.01


def test_a_run_can_start_turned_in_the_simulators_world() -> None:
    """``make_sim(start_yaw=...)``: the standing robot turned about the world's vertical
    (its soles, base and IMU with it), so that a drift fixed in the floor's frame and one
    that turns with the robot can be told apart (benchmarks/drive.md)."""
    import numpy as np

    from wbc.geometry import yaw_of
    from wbc.sim.model import ModelParams

    robot = load_robot("bioloid")
    sim0, _, _ = make_sim(robot)
    sim, _, imu = make_sim(robot, start_yaw=math.radians(90.0),
                           model_params=ModelParams(noslip_iterations=2))  # fmt: skip
    assert sim.model.opt.noslip_iterations == 2 and sim0.model.opt.noslip_iterations == 0
    assert yaw_of(sim.base_rotation()) == pytest.approx(yaw_of(sim0.base_rotation()) + math.pi / 2)
    for s in ("l_sole", "r_sole"):
        p0, p = sim0.site_pose(s).translation, sim.site_pose(s).translation
        np.testing.assert_allclose(p, [-p0[1], p0[0], p0[2]], atol=1e-12)
    q = imu.read().orientation
    assert yaw_of(pin.Quaternion(q[3], q[0], q[1], q[2]).matrix()) == pytest.approx(
        yaw_of(sim.site_pose("imu").rotation)
    )
