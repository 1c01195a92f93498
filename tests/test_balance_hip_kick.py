"""The push's hip kick (:mod:`wbc.balance.hip_kick`): the swing leg and its arm spun toward
the fall beside the stance hip (``counter_leg``, ``counter_arm``) and the brake before the
torso tips past ``kick_tilt``."""

import numpy as np
import pinocchio as pin
import pytest

from wbc import load_robot
from wbc.balance.estimator import StateEstimate
from wbc.balance.feedback import GyroFeedback
from wbc.balance.stabilizer import Gains, Stabilizer
from wbc.walking.loop import TickTargets

DT = 0.01


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def _setup(robot, gains):
    """(a stabilizer, its tick(offset, R, ω) → joint offsets, the joints, u, the roll's axis
    v = z × u): single support on the left sole, the estimated DCM ``offset`` outward of its
    centre along ``u``, the torso's estimated rotation ``R`` and gyro rate ``ω``."""
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    left = robot.frame_placement(q, "l_sole")
    right = robot.frame_placement(q, "r_sole")
    R0 = robot.frame_placement(q, "torso").rotation
    t = TickTargets(0, 0.0, "single", "l_sole", "r_sole", robot.com(q), left, right, 0.0, R0,
                    right.translation.copy(), right.rotation.copy())  # fmt: skip
    p = left.translation[:2]
    u = left.rotation[:2, 1] / np.linalg.norm(left.rotation[:2, 1])  # (away from the right)
    stab = Stabilizer(robot, 0.2, lambda: None, None, gains)
    joints = q[7:].copy()

    def tick(offset, R=None, omega=None):
        values = np.zeros((8, 3))
        values[:3] = np.eye(3) if R is None else R
        values[6, :2] = p + offset * u
        values[7] = 0.0 if omega is None else omega
        est = stab.last = StateEstimate(values)
        stab._stance, stab._dt = "l_sole", DT
        stab._hip_strategy(t, est, DT)
        return stab.joint_offsets(joints)

    return stab, tick, joints, u, np.array([-u[1], u[0], 0.0])


def _pushed(tick):
    for offset in (-0.03, -0.03, -0.03):
        assert tick(offset) is None  # no push: the goals untouched
    return tick(0.005)  # the jump: the trigger fires, the whole max_hip asked


@pytest.mark.parametrize("counter", [0.0, 1.0])
def test_a_push_spins_the_swing_leg_and_its_arm_toward_the_fall(robot, counter):
    """``counter_leg`` / ``counter_arm``: from the trigger, the other leg's hip roll and that
    side's shoulder roll move so their limbs turn about the roll's axis toward the fall
    (``+a·v``: the swing sole moves away from the stance sole), each by at most its joint's
    speed limit a tick, up to the gain; 0: the stance hip alone is kicked."""
    g = Gains(max_hip=0.5, hip_kick=0.3, kick_tilt=0.0, counter_leg=0.4 * counter,
              counter_arm=1.0 * counter)  # fmt: skip
    _, tick, joints, u, v = _setup(robot, g)
    roles = robot.roles
    pairs = (("left", "hip_roll"), ("right", "hip_roll"), ("right", "shoulder_roll"))
    hip, leg, arm = (robot.joint_index(roles.joint(s, r)) for s, r in pairs)
    axes = GyroFeedback(robot, None, 0.0).axes(joints) @ v
    d = _pushed(tick)
    moved = sorted(int(k) for k in np.flatnonzero(d))
    assert moved == (sorted([hip, leg, arm]) if counter else [hip])
    assert d[hip] * axes[hip] < 0  # the stance hip: the torso turns by −a dθ
    if not counter:
        return
    for k in (leg, arm):
        assert d[k] * axes[k] > 0  # a free limb turns by +a dθ: toward the fall
        assert abs(d[k]) == pytest.approx(robot.v_max[k] * DT)
    out = [tick(0.005) for _ in range(30)]
    steps = np.abs(np.diff([d] + out, axis=0))
    assert np.all(steps <= robot.v_max * DT + 1e-12)  # never above a servo's speed
    assert abs(out[-1][leg]) == pytest.approx(0.4) and abs(out[-1][arm]) == pytest.approx(1.0)
    # the swing sole goes away from the stance sole (the leg abducted: its mass out, spun)
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    kicked = q.copy()
    kicked[7 + leg] += out[-1][leg]
    before = robot.frame_placement(q, "r_sole").translation[:2] @ u
    after = robot.frame_placement(kicked, "r_sole").translation[:2] @ u
    assert after < before - 0.02


@pytest.mark.parametrize("tilt", [0.0, 0.7])
def test_the_kick_is_braked_before_the_torso_tips_past_kick_tilt(robot, tilt):
    """``kick_tilt``: with the estimated torso tilted θ toward the fall and turning at θ̇, the
    kick loses ``kick_brake (θ + kick_lead θ̇ − kick_tilt)⁺`` (beyond the kick: the goal
    pulled back behind the solved one); 0: no brake, the whole kick at any tilt."""
    g = Gains(max_hip=0.5, hip_kick=0.3, kick_tilt=tilt, kick_lead=0.05, kick_brake=2.0,
              counter_leg=0.0, counter_arm=0.0)  # fmt: skip
    stab, tick, _, u, v = _setup(robot, g)
    hip = robot.joint_index(robot.roles.joint("left", "hip_roll"))
    d = _pushed(tick)
    sign = np.sign(d[hip])
    for _ in range(10):
        d = tick(0.005)
    assert d[hip] == pytest.approx(sign * 0.3)  # upright, still: the whole kick
    for theta, rate, brake in ((0.75, 0.0, 0.1), (0.5, 6.0, 0.2), (0.6, 10.0, 0.8)):
        R = pin.exp3(theta * v)  # the torso's top tilted θ toward u
        assert R[:, 2] @ np.r_[u, 0.0] == pytest.approx(np.sin(theta))
        omega = R.T @ (rate * v)  # (the gyro's, in the torso frame)
        for _ in range(30):
            d = tick(0.005, R, omega)
        want = 0.3 - (brake if tilt else 0.0)
        assert d[hip] == pytest.approx(sign * want)
        assert stab._kick.brake == pytest.approx(brake if tilt else 0.0)


@pytest.mark.parametrize("held", [False, True])
def test_the_limbs_are_held_while_the_pushed_sole_stays_on_its_edge(robot, held):
    """``kick_hold``: after a push, the pushed stance sole counts as rolled onto its edge
    once its normal (the estimate's rotation, the present joints) tilts along the roll by
    more than ``kick_hold``; while it is (``held``), the limbs' goals do not move back as the
    roll shrinks, the stance hip's does; not held, all come back with the roll."""
    g = Gains(max_hip=0.5, hip_kick=0.3, kick_tilt=0.0, counter_leg=0.4, counter_arm=1.0,
              kick_hold=0.035)  # fmt: skip
    stab, tick, joints, u, v = _setup(robot, g)
    roles = robot.roles
    pairs = (("left", "hip_roll"), ("right", "hip_roll"), ("right", "shoulder_roll"))
    hip, leg, arm = (robot.joint_index(roles.joint(s, r)) for s, r in pairs)
    _pushed(tick)
    kick = stab._kick
    assert kick.stance == "l_sole" and np.allclose(kick.u, u)
    for theta, rolled in ((0.0, False), (0.02, False), (0.1, True), (-0.1, False)):
        values = np.zeros((8, 3))
        values[:3] = pin.exp3(theta * v)  # the whole robot tilted θ toward u on that sole
        stab.estimator.last = StateEstimate(values)
        assert kick.rolled(stab.estimator, joints, joints, g.kick_hold) is rolled
    for _ in range(40):
        out = tick(0.005)  # the limbs spun out to their gains
    stab.hip[:] *= 0.5  # the roll half back: the kick's share with it
    stab._stance = ""  # (the double support after the pushed single support: held only there)
    kick.held = held
    for _ in range(40):
        back = stab.joint_offsets(joints)
    assert abs(back[hip]) == pytest.approx(0.5 * abs(out[hip]))  # the stance hip: always
    for k in (leg, arm):
        assert abs(back[k]) == pytest.approx(abs(out[k]) if held else 0.5 * abs(out[k]))


@pytest.mark.parametrize("case", ["lifted", "over"])
def test_a_held_kick_lets_go_when_its_sole_lifts_and_ramps_out_after_its_roll(robot, case):
    """``kick_hold`` holds the limbs only while the kicked sole still stands (a sole in its
    own swing is not on its edge: ``lifted``, the limbs come back at their speed); once the
    roll is back to 0 after a hold (``over``), the held limbs' goals ramp back at their
    joints' speed limits, not in one tick. Held only in the double support after the pushed
    single support (in it, the limbs follow the roll)."""
    from wbc.balance.stabilizer import _B_JUMP

    g = Gains(max_hip=0.5, hip_kick=0.3, kick_tilt=0.0, counter_leg=0.4, counter_arm=1.0,
              kick_hold=0.035)  # fmt: skip
    stab, tick, joints, _, _ = _setup(robot, g)
    roles = robot.roles
    leg, arm = (robot.joint_index(roles.joint("right", r)) for r in ("hip_roll", "shoulder_roll"))
    _pushed(tick)
    for _ in range(40):
        out = tick(0.005)  # the limbs spun out to their gains
    kick = stab._kick
    kick.held = True
    stab.hip[:] *= 0.5
    single = stab.joint_offsets(joints).copy()  # its single support: following the roll back
    for k in (leg, arm):
        assert abs(single[k]) < abs(out[k])
    stab._stance = ""  # the double support after it, the pushed sole still rolled
    for _ in range(5):
        held = stab.joint_offsets(joints)  # held: the limbs go no further back
    for k in (leg, arm):
        assert held[k] == pytest.approx(single[k])
    if case == "lifted":
        stab._fb[_B_JUMP + 2] = 0.0  # (the trigger re-armed by the double support between)
        stab._stance = "r_sole"  # the kicked (left) sole lifts: its leg swings
    else:
        stab.hip[:] = 0.0
        stab._fb[_B_JUMP + 4] = 0.0  # the roll is over
    first = stab.joint_offsets(joints)
    for k in (leg, arm):
        step = float(robot.v_max[k]) * DT
        assert abs(first[k]) == pytest.approx(abs(held[k]) - step)  # one tick's speed back
    for _ in range(300):
        last = stab.joint_offsets(joints)
    assert last is None or not np.any(last[[leg, arm]])  # all the way back, then over


def test_under_angle_swings_the_leg_com_across_the_hips_spacing():
    """:func:`under_angle`: the OP3's swing hip roll turned by it carries that leg's CoM
    (its hip roll's subtree) across the hips' spacing to within a few mm (its leg is longer
    than the spacing); the Bioloid's leg CoM sits closer to its hip than the spacing: π/2."""
    from wbc.balance.hip_kick import under_angle

    assert under_angle(load_robot("bioloid")) == pytest.approx(np.pi / 2)
    op3 = load_robot("op3")
    theta = under_angle(op3)
    assert 0.3 < theta < 1.2
    model = op3.model
    data = model.createData()
    q = op3.configuration(op3.stand_pose)
    names = [op3.roles.joint(s, "hip_roll") for s in ("left", "right")]
    ids = [model.getJointId(n) for n in names]
    sub = [i for i in range(1, model.njoints) if ids[0] in model.supports[i]]

    def leg_com(q):
        pin.forwardKinematics(model, data, q)
        m = sum(model.inertias[i].mass for i in sub)
        return sum(model.inertias[i].mass * data.oMi[i].act(model.inertias[i].lever)
                   for i in sub) / m  # fmt: skip

    before = leg_com(q)  # (and the stand's kinematics: the hips below)
    spacing = data.oMi[ids[1]].translation - data.oMi[ids[0]].translation
    w = float(np.linalg.norm(spacing))
    moved = [(leg_com(_turned(op3, q, names[0], s * theta)) - before) @ spacing / w
             for s in (-1, 1)]  # fmt: skip
    best = min(abs(m - w) for m in moved)
    assert best < 0.01  # the CoM moved across the spacing toward the other hip


def _turned(robot, q, name, angle):
    q = q.copy()
    q[robot.q_index(name)] += angle
    return q


@pytest.mark.parametrize("under", [0.0, 0.2])
def test_counter_under_caps_the_swing_leg_at_its_share_of_the_under_angle(robot, under):
    """``counter_under``: the leg's goal settles at ``min(counter_leg, counter_under ×
    under_angle)`` (the Bioloid's π/2 × 0.2 = 0.31 rad below 0.4); 0: ``counter_leg``."""
    g = Gains(max_hip=0.5, hip_kick=0.3, kick_tilt=0.0, counter_leg=0.4, counter_arm=1.0,
              counter_under=under)  # fmt: skip
    _, tick, _, _, _ = _setup(robot, g)
    leg = robot.joint_index(robot.roles.joint("right", "hip_roll"))
    _pushed(tick)
    for _ in range(40):
        out = tick(0.005)
    assert abs(out[leg]) == pytest.approx(min(0.4, under * np.pi / 2) if under else 0.4)


def test_kick_hold_for_ignores_a_one_tick_tilt_reading(robot):
    """``kick_hold_for``: the sole's tilt must read rolled without a break for that long
    before the limbs are held; a single tick's reading (a support switch) does not hold,
    a break restarts the count."""
    g = Gains(max_hip=0.5, hip_kick=0.3, kick_tilt=0.0, counter_leg=0.4, kick_hold=0.035,
              kick_hold_for=0.05)  # fmt: skip
    stab, tick, _, _, _ = _setup(robot, g)
    _pushed(tick)
    kick = stab._kick
    reads = [True, False] + [True] * 5
    held = [kick.debounced(r, DT, g.kick_hold_for) for r in reads]
    assert held == [False, False, False, False, False, False, True]
    assert kick.debounced(True, DT, 0.0)  # 0: at once


@pytest.mark.parametrize("yaw", [0.0, 0.5])
def test_kick_hold_edge_reads_the_dcm_beyond_the_soles_outer_edge(robot, yaw):
    """``kick_hold_edge``: the measured DCM beyond the kicked sole's outer edge along the
    push (the sole rectangle's half extent along ``u``, × the share), not before; no kick:
    never."""
    from wbc.balance.hip_kick import HipKick

    kick = HipKick(robot)
    length, width = robot.foot_size
    sole = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.array([0.1, 0.05, 0.0]))
    u = np.array([-np.sin(yaw), np.cos(yaw)])  # (the sole's lateral axis: its edge at w/2)
    c = sole.translation[:2]
    assert not kick.beyond(np.r_[c + u, 0.0], sole, 1.0)  # (no kick under way)
    kick.joints, kick.stance, kick.u = [[0, 1.0, "hip_kick", None]], "l_sole", u
    for share in (1.0, 0.5):
        edge = share * width / 2
        assert not kick.beyond(np.r_[c + (edge - 1e-3) * u, 0.0], sole, share)
        assert kick.beyond(np.r_[c + (edge + 1e-3) * u, 0.0], sole, share)
    # along the sole's length the edge is its half length
    along = np.array([np.cos(yaw), np.sin(yaw)])
    kick.u = along
    assert not kick.beyond(np.r_[c + (length / 2 - 1e-3) * along, 0.0], sole, 1.0)
    assert kick.beyond(np.r_[c + (length / 2 + 1e-3) * along, 0.0], sole, 1.0)


def test_sole_dcm_reads_the_com_and_its_velocity_from_the_kicked_sole(robot):
    """``kick_hold_edge``'s DCM: from the IMU's rotation and the encoders alone (not the
    estimate's anchored base, set here 50 mm off): the CoM, its velocity relative to the
    kicked sole differenced over ticks (low-passed) over ω₀; the sole where the joints put it."""
    from wbc.balance.estimator import StateEstimator
    from wbc.balance.hip_kick import HipKick

    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    est = StateEstimator(robot, 0.2)
    values = np.zeros((8, 3))
    kick = HipKick(robot)
    torso = robot.frame_placement(q, "torso").rotation
    values[:3] = torso
    values[3] = q[:3] + np.array([0.05, 0.0, 0.0])  # (an anchor gone wrong)
    est.last = StateEstimate(values)
    assert kick.sole_dcm(est, q[7:], q[7:], DT) is None  # (no kick)
    kick.joints, kick.stance = [[0, 1.0, "hip_kick", None]], "l_sole"
    dcm, sole = kick.sole_dcm(est, q[7:], q[7:], DT)
    shift = np.array([0.05, 0.0, 0.0])
    assert np.allclose(dcm, robot.com(q) + shift, atol=1e-9)  # (first tick: no velocity)
    assert np.allclose(sole.translation, robot.frame_placement(q, "l_sole").translation + shift)
    # the left ankle roll turned: the CoM moves relative to the sole
    q2 = q.copy()
    k = robot.joint_index(robot.roles.joint("left", "ankle_roll"))
    q2[7 + k] += 0.01
    dcm2, sole2 = kick.sole_dcm(est, q2[7:], q2[7:], DT)
    rel = lambda d, s: d[:2] - s.translation[:2]  # noqa: E731
    moved = (robot.com(q2) - robot.frame_placement(q2, "l_sole").translation)[:2] - (
        robot.com(q) - robot.frame_placement(q, "l_sole").translation
    )[:2]
    a = DT / (DT + 0.02)
    want = (robot.com(q2) - robot.frame_placement(q2, "l_sole").translation)[:2]
    want = want + a * moved / DT / est.omega0
    assert np.linalg.norm(moved) > 1e-4
    assert np.allclose(rel(dcm2, sole2), want, atol=1e-6)


def test_estimator_com_and_placement_is_the_estimates_kinematics(robot):
    """``StateEstimator.com_and_placement`` (what ``sole_dcm`` reads): the CoM and a frame's
    placement where the last estimate (its base, the torso's rotation) and the joints (NaN:
    the fallback's) put the model; the placement is a copy a later call leaves alone."""
    from wbc.balance.estimator import StateEstimator

    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    est = StateEstimator(robot, 0.2)
    values = np.zeros((8, 3))
    values[:3] = robot.frame_placement(q, "torso").rotation
    shift = np.array([0.03, -0.01, 0.0])
    values[3] = q[:3] + shift
    est.last = StateEstimate(values)
    com, sole = est.com_and_placement("l_sole", q[7:], None)
    assert np.allclose(com, robot.com(q) + shift, atol=1e-9)
    want = robot.frame_placement(q, "l_sole")
    assert np.allclose(sole.translation, want.translation + shift, atol=1e-9)
    assert np.allclose(sole.rotation, want.rotation, atol=1e-9)
    q2 = q.copy()
    k = robot.joint_index(robot.roles.joint("left", "ankle_roll"))
    q2[7 + k] += 0.05
    com2, sole2 = est.com_and_placement("l_sole", q2[7:], None)
    assert not np.allclose(com2, com, atol=1e-5)
    assert not np.allclose(sole2.rotation, want.rotation, atol=1e-3)  # the sole rolled
    assert np.allclose(sole.translation, want.translation + shift, atol=1e-9)  # (a copy)
    gap = q2[7:].copy()
    gap[k] = np.nan  # an encoder that did not answer: the fallback's joint
    com3, _ = est.com_and_placement("l_sole", gap, q[7:])
    assert np.allclose(com3, com, atol=1e-12)
