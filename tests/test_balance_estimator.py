"""State estimator: complementary filter (gyro + accelerometer) and stance-leg kinematics."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc.balance.estimator import StateEstimator, exp3
from wbc.compiled.rows import log3 as log3_into
from wbc.exceptions import ConfigurationError
from wbc.imu import GRAVITY, ImuReading
from wbc.model import load_robot


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def reading(R: np.ndarray, omega=(0.0, 0.0, 0.0)) -> ImuReading:
    """What a still IMU with rotation R (torso in world) measures."""
    quat = pin.Quaternion(R).coeffs()
    return ImuReading(0.0, quat, np.asarray(omega, float), R.T @ np.array([0, 0, GRAVITY]))


def standing(robot):
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    return q, robot.frame_placement(q, "l_sole"), robot.frame_placement(q, "r_sole")


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3), st.floats(0.0, np.pi - 2e-3))
def test_exp3_log3_are_pinocchios(axis, angle):
    """The compiled SO(3) maps the estimator and stabilizer use give pinocchio's, near 0 and
    near π too."""
    a = np.array(axis)
    if np.linalg.norm(a) < 1e-3:
        a = np.array([0.0, 0.0, 1.0])
    for t in (angle, 1e-7 * angle, np.pi - 1e-4 * (1 + angle)):
        w = a / np.linalg.norm(a) * t
        assert np.allclose(exp3(w), pin.exp3(w), atol=1e-12)
        tol = 1e-9 if t < np.pi - 1e-3 else 1e-7  # (the axis near π: to rounding of R)
        v = np.empty(3)
        log3_into(pin.exp3(w), v)
        assert np.allclose(v, pin.log3(pin.exp3(w)), atol=tol)


class ReferenceEstimator:
    """The estimator's previous implementation (pinocchio calls and numpy, one step at a
    time): the compiled kernel must give its answers."""

    def __init__(self, robot, com_height, use_imu=True, tilt_gain=0.2, cutoff=6.0,
                 gyro_heading=False, kin_heading=False, kin_band=0.0):  # fmt: skip
        self.robot, self.omega0 = robot, np.sqrt(GRAVITY / com_height)
        self.use_imu, self.gyro_heading, self.tilt_gain, self.cutoff = (
            use_imu, gyro_heading, tilt_gain, cutoff)  # fmt: skip
        self.kin_heading, self.kin_band = kin_heading, kin_band
        self.model, self.data = robot.model, robot.model.createData()
        self.q = robot.neutral()
        self.torso_b = robot.model.frames[robot.frame_id("torso")].placement.rotation.copy()
        self.rotation, self.rel, self.com_vel = None, {}, np.zeros(3)

    def update(self, dt, joints, reading, stance):
        m, d, q = self.model, self.data, self.q
        q[7:] = joints
        com_b = pin.centerOfMass(m, d, q, False).copy()
        soles = {n: pin.updateFramePlacement(m, d, self.robot.frame_id(n)) for n, _ in stance}
        yaw = lambda R: np.arctan2(R[1, 0], R[0, 0])  # noqa: E731
        name0, anchor0 = stance[0]
        imu = self.use_imu and reading is not None
        R_kin = None
        if self.rotation is None or not imu or not self.gyro_heading or self.kin_heading:
            R_kin = anchor0.rotation @ soles[name0].rotation.T
        if self.rotation is None:
            self.rotation, self.rel, self.com_vel = R_kin @ self.torso_b, {}, np.zeros(3)
        if imu:
            R, a = self.rotation, reading.linear_acceleration
            w = reading.angular_velocity.copy()
            norm = np.linalg.norm(a)
            if 0.8 * GRAVITY < norm < 1.2 * GRAVITY:
                w += (self.tilt_gain / norm) * np.cross(a, R[2])
            R_t = R @ pin.exp3(w * dt)
            if not self.gyro_heading:
                z = yaw(R_kin @ self.torso_b) - yaw(R_t)
                R_t = pin.rpy.rpyToMatrix(0.0, 0.0, z) @ R_t
            self.rotation, R_base = R_t, R_t @ self.torso_b.T
            if self.gyro_heading and self.kin_heading:  # the soles' heading, the gyro's tilt
                z = yaw(R_kin @ self.torso_b) - yaw(R_t)
                if self.kin_band > 0:  # (wrapped, less the band)
                    z = np.arctan2(np.sin(z), np.cos(z))
                    z = np.sign(z) * max(abs(z) - self.kin_band, 0.0)
                R_base = pin.rpy.rpyToMatrix(0.0, 0.0, z) @ R_base
            omega = reading.angular_velocity
        else:
            R_base = R_kin
            self.rotation, omega = R_base @ self.torso_b, np.zeros(3)
        bases, rel = [], {}
        for name, anchor in stance:
            bases.append(anchor.translation - R_base @ soles[name].translation)
            rel[name] = R_base @ (com_b - soles[name].translation)
        base = np.mean(bases, axis=0)
        com = base + R_base @ com_b
        common = [s for s in rel if s in self.rel]
        if common and dt > 0:
            raw = np.mean([rel[s] - self.rel[s] for s in common], axis=0)
            alpha = np.exp(-2.0 * np.pi * self.cutoff * dt)
            self.com_vel = alpha * self.com_vel + ((1.0 - alpha) / dt) * raw
        self.rel = rel
        dcm = com + self.com_vel / self.omega0
        dcm[2] = com[2]
        return self.rotation, base, com, self.com_vel, dcm, omega


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 2**31), st.booleans(), st.booleans(), st.booleans(), st.sampled_from(
    [0.0, 0.02, 0.1]))  # fmt: skip
def test_estimator_gives_the_reference_answers(
    robot, seed, use_imu, gyro_heading, kin_heading, kin_band
):
    """Random joints (some unread: NaN, the fallback's), IMU samples (some impacts), stance
    switches: every output equals the reference implementation's to 1e-9."""
    rng = np.random.default_rng(seed)
    q, left, right = standing(robot)
    kw = dict(use_imu=use_imu, gyro_heading=gyro_heading, kin_heading=kin_heading)
    kw["kin_band"] = kin_band
    new = StateEstimator(robot, 0.2, velocity_cutoff=7.0, tilt_gain=0.5, **kw)
    ref = ReferenceEstimator(robot, 0.2, cutoff=7.0, tilt_gain=0.5, **kw)
    phases = [[("l_sole", left), ("r_sole", right)], [("l_sole", left)], [("r_sole", right)],
              [("r_sole", right), ("l_sole", left)]]  # fmt: skip
    for k in range(60):
        fallback = q[7:] + 0.1 * rng.standard_normal(robot.n_joints)
        present = fallback + 0.05 * rng.standard_normal(robot.n_joints)
        present[rng.random(robot.n_joints) < 0.1] = np.nan
        used = np.where(np.isfinite(present), present, fallback)
        acc = np.array([0, 0, GRAVITY]) + rng.normal(0, 1 if k % 5 else 6, 3)
        r = ImuReading(0.0, np.array([0, 0, 0, 1.0]), rng.normal(0, 0.5, 3), acc)
        stance = phases[(k // 7) % 4]
        dt = 0.01 * (1 + k % 3)
        got = new.update(dt, present, r, stance, fallback=fallback)
        want = ref.update(dt, used, r, stance)
        for name, w in zip(
            ("rotation", "base", "com", "com_vel", "dcm", "angular_velocity"), want, strict=True
        ):
            assert np.allclose(getattr(got, name), w, rtol=0, atol=1e-9), (k, name)


def test_kinematics_give_the_true_com(robot):
    """Encoders only, standing on both planned soles: base and CoM are forward kinematics'."""
    q, left, right = standing(robot)
    est = StateEstimator(robot, 0.2, use_imu=False)
    e = est.update(0.01, q[7:], None, [("l_sole", left), ("r_sole", right)])
    assert np.allclose(e.com, robot.com(q), atol=1e-9)
    assert np.allclose(e.base, q[:3], atol=1e-9)
    assert np.allclose(e.rotation, robot.frame_placement(q, "torso").rotation, atol=1e-9)
    assert np.allclose(e.com_vel, 0.0)


def test_imu_tilt_moves_the_com(robot):
    """Standing on the left sole with the whole robot tilted 5° about the sole (the IMU sees
    it, the encoders do not): the CoM estimate follows the tilted body. (The heading, ZYX
    yaw, is the encoders': the tilt keeps the torso's yaw.)"""
    q, left, _ = standing(robot)
    roll, pitch, yaw = pin.rpy.matrixToRpy(robot.frame_placement(q, "torso").rotation)
    R0 = pin.rpy.rpyToMatrix(roll, pitch, yaw)
    tilt = pin.rpy.rpyToMatrix(roll + 0.0872665, pitch, yaw) @ R0.T  # +5° roll
    tilted = pin.SE3(tilt, left.translation - tilt @ left.translation) * pin.XYZQUATToSE3(q[:7])
    q_true = q.copy()
    q_true[:7] = pin.SE3ToXYZQUAT(tilted)
    R_torso = robot.frame_placement(q_true, "torso").rotation
    est = StateEstimator(robot, 0.2)
    est.reset(R_torso)
    e = est.update(0.01, q[7:], reading(R_torso), [("l_sole", left)])
    assert np.allclose(e.com, robot.com(q_true), atol=1e-6)
    enc = StateEstimator(robot, 0.2, use_imu=False).update(0.01, q[7:], None, [("l_sole", left)])
    assert np.linalg.norm(enc.com - robot.com(q_true)) > 0.01  # the encoders alone miss it


@pytest.mark.parametrize("kin_heading, kin_band", [(False, 0.0), (True, 0.0), (True, 0.1),
                                                     (True, 0.5)])  # fmt: skip
def test_kin_heading_reads_the_com_about_the_slipped_sole(robot, kin_heading, kin_band):
    """Standing on the left sole, the whole robot (the sole too) turned 20° about the
    vertical through it, the gyro's heading following it: with ``kin_heading`` the CoM and
    base are read about the sole where the plan holds it (the robot balanced about its
    feet: the standing pose's CoM), the torso's rotation keeps the gyro's heading; without,
    the CoM is the turned robot's; with ``kin_band`` the robot turned by the band (0.1 rad)
    or, a band beyond the slip (0.5 rad), as without."""

    def turned(angle):
        turn = pin.rpy.rpyToMatrix(0.0, 0.0, angle)
        moved = pin.SE3(turn, left.translation - turn @ left.translation)
        out = q.copy()
        out[:7] = pin.SE3ToXYZQUAT(moved * pin.XYZQUATToSE3(q[:7]))
        return out

    q, left, _ = standing(robot)
    q_true = turned(0.349)
    R_torso = robot.frame_placement(q_true, "torso").rotation
    est = StateEstimator(robot, 0.2, gyro_heading=True, kin_heading=kin_heading,
                         kin_band=kin_band)  # fmt: skip
    est.reset(R_torso)
    e = est.update(0.01, q[7:], reading(R_torso), [("l_sole", left)])
    assert np.allclose(e.rotation, R_torso, atol=1e-6)  # (the gyro's heading, all)
    read = 0.349 if not kin_heading else min(kin_band, 0.349)  # the turn the CoM is read at
    want = turned(read)
    assert np.allclose(e.com, robot.com(want), atol=1e-6)
    assert np.allclose(e.base, want[:3], atol=1e-6)
    assert np.linalg.norm(robot.com(q) - robot.com(q_true)) > 0.005  # (the two differ)


def test_filter_converges_to_the_accelerometer_tilt(robot):
    """Started upright while the IMU is still and tilted 6° in pitch, the filter converges
    to the tilt at its gain (time constant 1/k) and keeps the kinematic heading."""
    q, left, _ = standing(robot)
    R_true = pin.rpy.rpyToMatrix(0.0, 0.1047, 0.0)
    est = StateEstimator(robot, 0.2, tilt_gain=2.0)
    est.reset(np.eye(3))
    for _ in range(300):  # 3 s = 6 time constants
        e = est.update(0.01, q[7:], reading(R_true), [("l_sole", left)])
    angle = np.arccos(np.clip(e.rotation[:, 2] @ R_true[:, 2], -1, 1))
    assert angle < np.radians(0.1)
    half = StateEstimator(robot, 0.2, tilt_gain=2.0)
    half.reset(np.eye(3))
    for _ in range(35):  # 0.35 s: 1 − e^(−0.7) ≈ 50 % of the way
        e = half.update(0.01, q[7:], reading(R_true), [("l_sole", left)])
    got = np.arccos(np.clip(e.rotation[2, 2], -1, 1))
    assert 0.4 * 0.1047 < got < 0.6 * 0.1047


def test_gyro_is_integrated(robot):
    """A constant roll rate with the accelerometer ignored (the tilt gain tiny): the
    filter's roll is the integral."""
    q, left, _ = standing(robot)
    est = StateEstimator(robot, 0.2, tilt_gain=1e-9)
    est.reset(np.eye(3))
    for _ in range(50):
        e = est.update(0.01, q[7:], reading(np.eye(3), omega=(0.2, 0.0, 0.0)), [("l_sole", left)])
    assert pin.rpy.matrixToRpy(e.rotation)[0] == pytest.approx(0.1, abs=1e-6)


def test_com_velocity_and_dcm(robot):
    """Joints moving the CoM relative to the stance sole: the filtered velocity converges to
    the CoM's rate; DCM = c + ċ/ω₀; a support switch (same body) makes no velocity jump."""
    q, left, right = standing(robot)
    est = StateEstimator(robot, 0.2, use_imu=False, velocity_cutoff=20.0)
    j = robot.joint_index("l_ankle_roll"), robot.joint_index("r_ankle_roll")
    dt, rate = 0.01, 0.2  # rad/s on both ankle rolls: the body sways sideways
    coms = []
    for k in range(40):
        joints = q[7:].copy()
        joints[list(j)] += rate * dt * k
        e = est.update(dt, joints, None, [("l_sole", left), ("r_sole", right)])
        coms.append(e.com)
    true_vel = (coms[-1] - coms[-2]) / dt
    assert np.allclose(e.com_vel, true_vel, atol=2e-3)
    assert np.linalg.norm(true_vel) > 0.01
    assert np.allclose(e.dcm[:2], e.com[:2] + e.com_vel[:2] / est.omega0)
    assert est.omega0 == pytest.approx(np.sqrt(GRAVITY / 0.2))
    with pytest.raises(ConfigurationError, match="com_height"):
        StateEstimator(robot, 0.0)
    with pytest.raises(ConfigurationError, match="no stance"):
        est.update(dt, q[7:], None, [])


def test_bias_gain_learns_the_gyro_bias_the_tilt_would_keep(robot):
    """A still, upright robot whose gyro reads a pitch-rate bias of 0.05 rad/s (a
    calibration at rest on a rocking robot leaves that much): without ``bias_gain`` the
    filter settles tilted by b / k_a (0.25 rad at the 0.2 /s tilt gain), for good; with it
    the bias is learnt and the tilt error vanishes; the corrected rate is reported."""
    q, left, _ = standing(robot)
    tilt = {}
    for gain in (0.0, 0.05):
        est = StateEstimator(robot, 0.2, bias_gain=gain)
        est.reset(np.eye(3))
        for _ in range(6000):  # 60 s
            e = est.update(0.01, q[7:], reading(np.eye(3), omega=(0.0, 0.05, 0.0)),
                           [("l_sole", left)])  # fmt: skip
        tilt[gain] = np.arccos(np.clip(e.rotation[2, 2], -1, 1))
        if gain:
            assert np.abs(e.angular_velocity).max() < 0.005  # the bias taken off the rate
        else:
            assert e.angular_velocity == pytest.approx([0.0, 0.05, 0.0])
    assert tilt[0.0] == pytest.approx(0.05 / 0.2, rel=0.05)
    assert tilt[0.05] < np.radians(1.0)
    with pytest.raises(ConfigurationError, match="bias_gain"):
        StateEstimator(robot, 0.2, bias_gain=-1.0)


def test_kin_gain_holds_the_tilt_to_the_stance_legs_kinematics(robot):
    """A still robot standing flat whose gyro reads a pitch-rate bias of 0.05 rad/s: with
    only the accelerometer's pull (k_a = 0.2 /s) the estimate settles b / k_a = 0.25 rad off
    the true torso; with ``kin_gain`` k the stance legs' kinematics (the sole flat) pull too,
    and it settles b / (k_a + k) off (a tenth at k = 1.8 /s)."""
    q, left, _ = standing(robot)
    R_true = robot.frame_placement(q, "torso").rotation
    off = {}
    for gain in (0.0, 1.8):
        est = StateEstimator(robot, 0.2, kin_gain=gain)
        est.reset(R_true)
        for _ in range(3000):  # 30 s: settled
            e = est.update(0.01, q[7:], reading(R_true, omega=(0.0, 0.05, 0.0)),
                           [("l_sole", left)])  # fmt: skip
        off[gain] = np.linalg.norm(pin.log3(e.rotation @ R_true.T))
    assert off[0.0] == pytest.approx(0.05 / 0.2, rel=0.05)
    assert off[1.8] == pytest.approx(0.05 / 2.0, rel=0.05)
    with pytest.raises(ConfigurationError, match="kin_gain"):
        StateEstimator(robot, 0.2, kin_gain=-1.0)


@pytest.mark.parametrize("use_imu", [False, True])
def test_a_sole_landing_off_its_plan_is_anchored_where_it_landed(robot, use_imu):
    """``anchor_band``: the right sole enters the support 30 mm ahead of its planned placement
    (a pushed robot's step landing long): anchored at the plan, the base and CoM estimates jump
    by half of it (double support averages the soles) and stay 30 mm behind once it is the
    only stance sole; anchored where it landed, they stay the true ones. Inside the band (5 mm
    off) the plan's placement is used; once it lifts, its next landing is judged anew."""
    q, left, right = standing(robot)
    R = robot.frame_placement(q, "torso").rotation
    imu = reading(R) if use_imu else None
    for band, off, expect in ((0.0, 0.03, 0.015), (0.01, 0.03, 0.0), (0.01, 0.005, 0.0025)):
        est = StateEstimator(robot, 0.2, use_imu=use_imu, anchor_band=band)
        for _ in range(3):
            est.update(0.01, q[7:], imu, [("l_sole", left)])
        planned = pin.SE3(right.rotation, right.translation + [off, 0.0, 0.0])
        e = est.update(0.01, q[7:], imu, [("l_sole", left), ("r_sole", planned)])
        assert e.base[0] - q[0] == pytest.approx(expect, abs=1e-9), (band, off)
        assert e.com[0] - robot.com(q)[0] == pytest.approx(expect, abs=1e-9)
        e = est.update(0.01, q[7:], imu, [("r_sole", planned)])  # the left sole lifts
        assert e.base[0] - q[0] == pytest.approx(2 * expect, abs=1e-9), (band, off)
    est = StateEstimator(robot, 0.2, use_imu=use_imu, anchor_band=0.01)
    est.update(0.01, q[7:], imu, [("l_sole", left)])
    est.update(0.01, q[7:], imu, [("l_sole", left), ("r_sole", planned)])
    est.update(0.01, q[7:], imu, [("l_sole", left)])  # the right sole lifts again ...
    e = est.update(0.01, q[7:], imu, [("l_sole", left), ("r_sole", right)])  # ... lands on plan
    assert e.base[0] == pytest.approx(q[0], abs=1e-9)
    with pytest.raises(ConfigurationError, match="anchor_band"):
        StateEstimator(robot, 0.2, anchor_band=-0.01)


def lifted_left(robot, a: float = 0.15):
    """The standing pose on the right sole with the left one lifted flat (hip, knee, ankle
    pitched: 11.8 mm up at ``a`` = 0.15 rad)."""
    names = list(robot.joint_names)
    q = robot.configuration("stand")
    for joint, k in (("l_hip_pitch", -1.0), ("l_knee", 2.0), ("l_ankle_pitch", -1.0)):
        q[7 + names.index(joint)] += k * a
    return robot.place_on_ground(q, "r_sole")


def test_a_landed_sole_is_judged_once_it_is_down_with_anchor_down(robot):
    """``anchor_down``: the robot stands on the right sole, the left 11.8 mm up, when the plan
    puts the left in the support 30 mm ahead of it. Without ``anchor_down`` it is judged at
    once (anchored where the estimate puts it: the base estimate the true one); with 3 mm it
    is not judged while it is up (the plan's placement: the double support's base half the
    30 mm ahead), and is judged at the first tick the joints put it down."""
    q = lifted_left(robot)
    left, right = robot.frame_placement(q, "l_sole"), robot.frame_placement(q, "r_sole")
    plan_left = pin.SE3(left.rotation, left.translation * [1.0, 1.0, 0.0] + [0.03, 0.0, 0.0])
    imu = reading(robot.frame_placement(q, "torso").rotation)
    for down, expect in ((0.0, 0.0), (0.003, 0.015)):
        est = StateEstimator(robot, 0.2, anchor_band=0.01, anchor_down=down)
        for _ in range(3):
            est.update(0.01, q[7:], imu, [("r_sole", right)])
        e = est.update(0.01, q[7:], imu, [("r_sole", right), ("l_sole", plan_left)])
        assert e.base[0] - q[0] == pytest.approx(expect, abs=1e-6), down
    assert "l_sole" not in est._landed  # (not judged yet)
    q_down = q.copy()
    q_down[7:] = robot.configuration("stand")[7:]  # the left leg straightened: down
    est.update(0.01, q_down[7:], imu, [("r_sole", right), ("l_sole", plan_left)])
    assert est._landed["l_sole"] is not None  # judged: 30 mm off its plan, anchored
    with pytest.raises(ConfigurationError, match="anchor_down"):
        StateEstimator(robot, 0.2, anchor_down=-0.01)


@pytest.mark.parametrize("band", [0.0, 0.004])
def test_the_support_the_soles_heights_show(robot, band):
    """``contact_band``: the plan stands on the left sole and swings the right; the robot
    stands on the right, the left lifted 11.8 mm (a pushed robot still on the sole the plan
    swings). From the IMU's rotation and the joints, the left sole's lowest point is found
    above the right's: the right carries the weight, anchored where the last estimate put it
    (on the floor): the CoM estimate is the true one. Anchored on the plan's lifted left
    sole (band 0: off), it reads 11.8 mm low, the right sole below the floor. Standing
    still on both soles, nothing changes."""
    from wbc.walking.loop import sole_pack

    q = lifted_left(robot)
    left, right = robot.frame_placement(q, "l_sole"), robot.frame_placement(q, "r_sole")
    assert left.translation[2] > 0.011
    plan_left = pin.SE3(left.rotation, left.translation * [1.0, 1.0, 0.0])  # on the floor
    swing = pin.SE3(right.rotation, right.translation + [0.02, 0.0, 0.015])  # planned mid-air
    imu = reading(robot.frame_placement(q, "torso").rotation)
    est = StateEstimator(robot, 0.2, contact_band=band)
    est.update(0.01, q[7:], imu, [("l_sole", plan_left)])
    select, pack = est.contact(8, sole_pack(plan_left, swing), q[7:], None)
    if band == 0:
        assert select == 8 and est.carrying == (True, True)
        e = est.update(0.01, q[7:], imu, [("l_sole", plan_left)])
        assert e.com[2] - robot.com(q)[2] == pytest.approx(-left.translation[2], abs=1e-6)
        return
    assert select == 9 and est.carrying == (False, True)
    assert est.heights[0] - est.heights[1] == pytest.approx(left.translation[2], abs=1e-3)
    anchor = pin.SE3(pack[16:32].reshape(4, 4))
    assert anchor.translation == pytest.approx(right.translation * [1.0, 1.0, 0.0], abs=1e-6)
    e = est.update(0.01, q[7:], imu, [("r_sole", anchor)])
    assert e.com == pytest.approx(robot.com(q), abs=1e-6)
    again = est.contact(8, sole_pack(plan_left, swing), q[7:], None)  # kept while it carries
    assert again[0] == 9 and np.array_equal(again[1], pack)
    q, left, right = standing(robot)  # both down: the plan's support, the plan's pack
    imu = reading(robot.frame_placement(q, "torso").rotation)
    est = StateEstimator(robot, 0.2, contact_band=band)
    est.update(0.01, q[7:], imu, [("l_sole", left), ("r_sole", right)])
    soles = sole_pack(left, right)
    assert est.contact(12, soles, q[7:], None)[1] is soles
    with pytest.raises(ConfigurationError, match="contact_band"):
        StateEstimator(robot, 0.2, contact_band=-0.01)


def test_the_constants_are_read_at_their_named_offsets(robot):
    """The compiled estimate reads its gains at named offsets of the constants (the tail of
    the model array): each constructor argument lands where its name says."""
    from wbc.balance import estimator as E

    est = StateEstimator(robot, 0.2, tilt_gain=0.3, velocity_cutoff=5.0, gyro_heading=True,
                         bias_gain=0.07, kin_gain=0.4, joint_lag=True)  # fmt: skip
    consts = est._model[len(est._model) - E._C_SIZE :]
    assert consts[E._C_LAG] == 1.0
    assert consts[E._C_TILT] == 0.3 and consts[E._C_CUTOFF] == 5.0
    assert consts[E._C_OMEGA0] == est.omega0 and consts[E._C_HEADING] == 1.0
    assert consts[E._C_KIN] == 0.4 and consts[E._C_BIAS] == 0.07
    assert np.array_equal(consts[E._C_TORSO : E._C_TORSO + 9], est.torso_b.ravel())


def test_joint_lag_reads_the_joints_with_the_rotation_of_their_tick(robot):
    """The body swaying about its left ankle (the sole flat: ankle pitch θ(t) = 0.05 sin(2π
    4 t)), the joints read a tick before the IMU sample (as the deployment reads them): with
    ``joint_lag`` the estimate's CoM is the true CoM of the joints' tick (the filter's
    rotation of that tick with them: within a fiftieth of the error without it); without it
    the fresh rotation on the stale joints moves the CoM by ω dt × (c − p_sole), ~2.5 mm
    (ω 1.26 rad/s), and its velocity follows."""
    q0, _, _ = standing(robot)
    ankle = robot.joint_index("l_ankle_pitch")
    dt = 0.01

    def at(k: int) -> np.ndarray:
        q = q0.copy()
        q[7 + ankle] += 0.05 * np.sin(2 * np.pi * 4.0 * k * dt)
        return robot.place_on_ground(q, "l_sole", at=robot.frame_placement(q0, "l_sole"))

    left = robot.frame_placement(at(0), "l_sole")
    off = {}
    for lag in (False, True):
        est = StateEstimator(robot, 0.2, tilt_gain=1e-9, joint_lag=lag)
        est.reset(robot.frame_placement(at(0), "torso").rotation)
        worst = 0.0
        for k in range(1, 60):
            R = robot.frame_placement(at(k), "torso").rotation
            R_prev = robot.frame_placement(at(k - 1), "torso").rotation
            w = np.zeros(3)
            log3_into(np.ascontiguousarray(R_prev.T @ R), w)
            e = est.update(dt, at(k - 1)[7:], reading(R, omega=w / dt), [("l_sole", left)])
            worst = max(worst, float(np.linalg.norm(e.com - robot.com(at(k - 1)))))
        off[lag] = worst
    assert off[False] > 1e-3
    assert off[True] < 0.02 * off[False]
