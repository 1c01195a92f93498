"""The heading corrected by the footsteps (``Gains.step_yaw``, issue 30): the stance sole's
measured heading error at the lift-off turns the swing sole's target (ramped, clipped,
beyond a dead band, never crossing the stance sole); the landed sole keeps the yaw the
controller landed it at; off (the default), the targets pass as the plan has them."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbc.balance.stabilizer import Gains, Stabilizer
from wbc.balance.step_yaw import RATE, StepYaw, ramp, stance_heading_error
from wbc.geometry import yaw_of
from wbc.imu import GRAVITY, Imu, ImuReading
from wbc.model import load_robot
from wbc.walking.loop import TickTargets


@pytest.fixture(scope="module")
def robot():
    return load_robot()


class StillImu(Imu):
    def __init__(self, R) -> None:
        self.R = np.asarray(R, float)

    def read(self) -> ImuReading:
        q = pin.Quaternion(self.R).coeffs()
        return ImuReading(0.0, q, np.zeros(3), self.R.T @ np.array([0, 0, GRAVITY]))


def _rz(a: float) -> np.ndarray:
    return pin.exp3(np.array([0.0, 0.0, a]))


def _standing(robot):
    return robot.place_on_ground(robot.configuration("stand"), "l_sole")


def _targets(robot, q, phase, swing_shift=0.0):
    """Standing on ``q``'s soles; the swing (right) sole's target ``swing_shift`` m ahead of
    its own, or (None) beside the left sole 2 mm from it."""
    left, right = robot.frame_placement(q, "l_sole"), robot.frame_placement(q, "r_sole")
    R = robot.frame_placement(q, "torso").rotation
    pos = right.translation.copy()
    if swing_shift is None:
        pos[:2] = left.translation[:2] - left.rotation[:2, 1] * (robot.foot_size[1] + 0.002)
    else:
        pos[0] += swing_shift
    return TickTargets(0, 0.0, phase, "l_sole", "r_sole", robot.com(q), left, right, 0.0, R,
                       pos, right.rotation.copy())  # fmt: skip


@pytest.mark.parametrize("delta", [0.12, -0.2])
def test_the_stance_soles_heading_error_is_measured_from_the_imu_and_encoders(robot, delta):
    q = _standing(robot)
    R_torso = robot.frame_placement(q, "torso").rotation
    planned = robot.frame_placement(q, "l_sole").rotation
    err = stance_heading_error(robot, q[7:], _rz(delta) @ R_torso, "l_sole", planned)
    assert err == pytest.approx(delta, abs=1e-9)
    assert stance_heading_error(robot, q[7:], R_torso, "l_sole", planned) == pytest.approx(
        0.0, abs=1e-9
    )


def test_ramp_moves_at_the_rate_toward_the_clipped_share():
    dt = 0.01
    assert ramp(0.0, 0.3, 1.0, 0.35, dt) == pytest.approx(RATE * dt)
    a = 0.0
    for _ in range(100):
        a = ramp(a, 0.5, 1.0, 0.35, dt)
    assert a == pytest.approx(0.35)  # clipped
    for _ in range(100):
        a = ramp(a, 0.1, 0.5, 0.35, dt)
    assert a == pytest.approx(0.05)  # the share


def _run(robot, gains, delta, ticks=30, swing_shift=0.3):
    """A stabilizer standing on the left sole, the robot measured turned by ``delta`` about
    the vertical against the controller's configuration: ``ticks`` of double support, then
    of single support (the right sole swinging, its target ``swing_shift`` m ahead, clear
    of the stance sole); returns (the stabilizer, the single support's last targets, the
    plan's)."""
    q = _standing(robot)
    double = _targets(robot, q, "double")
    R_imu = _rz(delta) @ double.torso_rotation
    stab = Stabilizer(robot, 0.2, lambda: q[7:].copy(), StillImu(R_imu), gains)
    stab.estimator.reset(R_imu)
    for _ in range(ticks):
        stab.adjust(double, np.zeros(3), q, 0.01)
    single = _targets(robot, q, "single", swing_shift)
    for _ in range(ticks):
        out = stab.adjust(single, np.zeros(3), q, 0.01)
    return stab, out, single, q


@pytest.mark.parametrize("share, band", [(1.0, 0.0), (0.5, 0.0), (1.0, 0.05)])
def test_the_swing_target_turns_against_the_measured_heading(robot, share, band):
    """Measured turned by −0.1 rad: with ``step_yaw`` the swing sole's target rotation turns
    by +share × (0.1 − band) within a few ticks (RATE), its position the plan's; the default
    (off) leaves the targets as they are."""
    delta = -0.1
    stab, out, plan, _ = _run(robot, Gains(), delta)
    assert out.swing_rotation is plan.swing_rotation and not out.contacts_move
    stab, out, plan, _ = _run(robot, Gains(step_yaw=share, step_yaw_band=band), delta)
    turned = yaw_of(out.swing_rotation) - yaw_of(plan.swing_rotation)
    assert turned == pytest.approx(share * (0.1 - band), abs=2e-3)
    np.testing.assert_array_equal(out.swing_position, plan.swing_position)
    assert stab.steps_yaw.want == pytest.approx(delta + band, abs=2e-3)


def test_a_turn_that_would_cross_the_stance_sole_is_cut(robot):
    """The swing target 2 mm beside the stance sole: any turn brings the soles' rectangles
    nearer than that gap (below CLEARANCE), so it is cut to 0; 0.3 m ahead, the whole turn."""
    g = Gains(step_yaw=1.0, max_step_yaw=0.35)
    near, out, plan, _ = _run(robot, g, -0.35, 60, None)
    assert near.steps_yaw.want == pytest.approx(-0.35, abs=1e-3)
    assert near.steps_yaw.angle == 0.0
    assert out.swing_rotation is plan.swing_rotation
    far, _, _, _ = _run(robot, g, -0.35, 60, 0.3)
    assert far.steps_yaw.angle == pytest.approx(-0.35, abs=1e-9)


def test_the_landed_sole_keeps_its_yaw_and_the_torso_turns_with_it(robot):
    """At the touch-down the landed sole keeps the yaw the controller landed it at (its
    configuration's sole less the plan's): its contact target turned so while it is down
    (``contacts_move``) and the torso target with it when it is the stance sole; the
    freed sole starts from the plan at its lift-off."""
    g = Gains(step_yaw=1.0, k_p=0.0, k_i=0.0, k_d=0.0)  # (the torso term's own turn: none)
    stab, out, plan, q = _run(robot, g, -0.1)
    a = stab.steps_yaw.angle
    assert a == pytest.approx(-0.1, abs=2e-3)
    q_landed = q.copy()  # the controller's configuration with the right sole turned by −a
    ry = robot.joint_index(robot.roles.joint("right", "hip_yaw"))
    for sign in (1.0, -1.0):  # (the hip yaw's sign: the one that turns the sole the way)
        q_landed[7 + ry] = q[7 + ry] + sign * 0.1
        yaw_r = yaw_of(robot.frame_placement(q_landed, "r_sole").rotation)
        if yaw_r - yaw_of(plan.r_sole.rotation) > 0:
            break
    turned = yaw_of(robot.frame_placement(q_landed, "r_sole").rotation) - yaw_of(
        plan.r_sole.rotation
    )
    double = _targets(robot, q, "double")
    out = stab.adjust(double, np.zeros(3), q_landed, 0.01)
    assert stab.steps_yaw.off["r_sole"] == pytest.approx(-turned, abs=1e-9)
    assert out.contacts_move
    assert yaw_of(out.r_sole.rotation) - yaw_of(double.r_sole.rotation) == pytest.approx(turned)
    np.testing.assert_array_equal(out.r_sole.translation, double.r_sole.translation)
    assert out.l_sole is double.l_sole
    # the right sole the stance: the torso target turned with it
    d = double
    lp, lr = d.l_sole.translation.copy(), d.l_sole.rotation.copy()
    single = TickTargets(0, 0.0, "single", "r_sole", "l_sole", d.com, d.l_sole, d.r_sole, 0.0,
                         d.torso_rotation, lp, lr)  # fmt: skip
    plain = stab.steps_yaw.off["r_sole"]
    out = stab.adjust(single, np.zeros(3), q_landed, 0.01)
    assert stab.steps_yaw.off["l_sole"] == 0.0  # (the freed sole: the plan)
    assert stab.steps_yaw.off["r_sole"] == plain
    twist = pin.log3(out.torso_rotation @ single.torso_rotation.T)[2]
    assert twist == pytest.approx(turned, abs=1e-9)


def test_step_yaw_state_starts_from_the_plan(robot):
    s = StepYaw(robot)
    assert s.angle == 0.0 and s.off == {"l_sole": 0.0, "r_sole": 0.0}


@pytest.mark.parametrize("turned, on", [(0.0, False), (0.2, True)])
def test_step_yaw_turn_acts_only_on_a_turning_walks_steps(robot, turned, on):
    """``step_yaw_turn`` 0.1 rad/s: at the second lift-off, a reference heading that did not
    turn since the first (a straight walk's) asks nothing; one that turned 0.2 rad in 1 s
    (a turning walk's step) asks the correction."""
    q = _standing(robot)
    g = Gains(step_yaw=1.0, step_yaw_turn=0.1)
    double = _targets(robot, q, "double")
    R_imu = _rz(-0.1) @ double.torso_rotation
    stab = Stabilizer(robot, 0.2, lambda: q[7:].copy(), StillImu(R_imu), g)
    stab.estimator.reset(R_imu)
    single = _targets(robot, q, "single", 0.3)
    for k, (phase, t) in enumerate([(double, 0.0), (single, 0.5), (double, 1.0), (single, 1.5)]):
        yaw = turned if k == 3 else 0.0  # (the reference's heading at the second lift-off)
        stab.adjust(phase.replace(t=t, torso_yaw=yaw), np.zeros(3), q, 0.01)
        if k == 1:
            assert stab.steps_yaw.want == 0.0  # (the first: no turn since the start)
    assert (stab.steps_yaw.want != 0.0) is on


def _cap_run(robot, turn: float, kept: float, delta: float = -0.3, ticks: int = 60):
    """``step_yaw_cap`` 1: the stance (left) sole kept ``kept`` rad off its plan, the
    robot measured turned by ``delta``, a step planned to turn ``turn`` rad: the swing's
    angle after ``ticks`` of single support."""
    q = _standing(robot)
    g = Gains(step_yaw=1.0, step_yaw_cap=1.0)
    double = _targets(robot, q, "double")
    R_imu = _rz(delta) @ double.torso_rotation
    stab = Stabilizer(robot, 0.2, lambda: q[7:].copy(), StillImu(R_imu), g)
    stab.estimator.reset(R_imu)
    stab.steps_yaw.turns = np.full(5, turn)  # (every tick's step: the targets' i is 0)
    stab.adjust(double, np.zeros(3), q, 0.01)
    stab.steps_yaw.off["l_sole"] = kept
    single = _targets(robot, q, "single", 0.3)
    for _ in range(ticks):
        stab.adjust(single, np.zeros(3), q, 0.01)
    return stab.steps_yaw


@pytest.mark.parametrize("turn, kept, angle", [(0.2, 0.0, -0.2), (0.0, 0.0, 0.0),
                                               (0.0, 0.05, 0.05), (0.1, 0.05, -0.05)])  # fmt: skip
def test_step_yaw_cap_keeps_the_swing_within_the_steps_planned_turn(robot, turn, kept, angle):
    """The correction asked is ≤ −0.25 rad (the measured −0.3 less the kept yaw): with
    ``step_yaw_cap`` 1 the swing's angle stays within ``kept`` ± the step's planned turn —
    a closing (0-turn) step lands parallel to the stance sole as the controller holds it
    (``kept``), a straight walk's step with nothing kept not at all."""
    s = _cap_run(robot, turn, kept)
    assert s.want <= -0.25 + 1e-9
    assert s.angle == pytest.approx(angle, abs=1e-9)
    assert s.window == pytest.approx((kept - turn, kept + turn))


def test_step_yaw_plan_reads_each_steps_turn_from_the_reference(robot):
    """:meth:`StepYaw.plan` on the turning walk: each single support's planned turn is its
    swing sole's landing yaw less its stance sole's (0.2 rad a step on ``turn_wb``, 0 on its
    closing step and in double support); on the straight walk, 0 everywhere."""
    from wbc.bench import trajectories as traj

    s = StepYaw(robot)
    ref = traj.build("turn_wb", robot)
    s.plan(ref)
    singles = [(a, b) for a, b, code in ref.phases() if ref.swing_side(a) is not None]
    steps = [float(s.turns[a]) for a, _ in singles]
    assert steps[1:-1] == pytest.approx([0.2] * (len(steps) - 2), abs=1e-6)
    assert steps[-1] == pytest.approx(0.0, abs=1e-9)
    assert all(s.turns[a - 1] == 0.0 for a, _ in singles)  # (double support before each)
    s.plan(traj.build("walk10_wb", robot))
    assert np.max(np.abs(s.turns)) < 0.01
