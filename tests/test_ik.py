"""Analytic IK: round trips through Pinocchio forward kinematics, branches, unreachable targets."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc import IKError
from wbc.ik import arm_ik, leg_ik, whole_body_ik

LEG = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
ARM = ("shoulder_pitch", "shoulder_roll", "elbow")
MARGIN = 0.02  # rad kept away from the joint limits in the random draws
SIDES = st.sampled_from(["left", "right"])


def idx(robot, side: str, names) -> np.ndarray:
    return np.array([robot.q_index(f"{side[0]}_{n}") for n in names])


def in_torso(robot, q, frame: str) -> pin.SE3:
    return robot.frame_placement(q, "torso").inverse() * robot.frame_placement(q, frame)


def draw(robot, index, fractions) -> np.ndarray:
    lo = robot.q_min[index - 7] + MARGIN
    hi = robot.q_max[index - 7] - MARGIN
    return lo + np.asarray(fractions) * (hi - lo)


def rotation_error(a: pin.SE3, b: pin.SE3) -> float:
    return float(np.linalg.norm(pin.log3(a.rotation.T @ b.rotation)))


def knee_stretch_angle(robot, side: str) -> float:
    """δ: knee angle at which thigh and shin are aligned (from the model's joint offsets)."""
    m = robot.model
    thigh = m.jointPlacements[m.getJointId(f"{side[0]}_knee")].translation
    shin = m.jointPlacements[m.getJointId(f"{side[0]}_ankle_pitch")].translation
    return math.atan2(-thigh[0], -thigh[2]) - math.atan2(-shin[0], -shin[2])


def hip_centre(robot, side: str) -> np.ndarray:
    return robot.frame_placement(robot.neutral(), f"{side[0]}_hip_pitch").translation


# ------------------------------------------------------------------------------ leg
@given(side=SIDES, fractions=st.lists(st.floats(0, 1), min_size=6, max_size=6))
def test_leg_round_trip(robot, side, fractions):
    index = idx(robot, side, LEG)
    q = robot.neutral()
    q[index] = draw(robot, index, fractions)
    target = in_torso(robot, q, f"{side[0]}_sole")

    sol = leg_ik(robot, side, target)
    q2 = robot.neutral()
    q2[index] = sol
    reached = in_torso(robot, q2, f"{side[0]}_sole")
    assert np.linalg.norm(reached.translation - target.translation) < 1e-9
    assert rotation_error(reached, target) < 1e-9
    assert robot.within_limits(q2)

    delta = knee_stretch_angle(robot, side)
    if q[index[3]] > delta + 0.05:  # knee forward: the returned branch, unique within limits
        np.testing.assert_allclose(sol, q[index], atol=1e-9)
    else:  # knee back: the mirrored knee-forward branch, or the original if that one is invalid
        assert sol[3] == pytest.approx(2 * delta - q[index[3]], abs=1e-6) or np.allclose(
            sol, q[index], atol=1e-6
        )


def test_leg_stretched_at_delta_not_at_zero(robot):
    """The knee offsets make the leg straight at q_knee = δ ≈ 22.5°: that is the max reach."""
    delta = knee_stretch_angle(robot, "left")
    assert delta == pytest.approx(math.radians(22.48), abs=1e-3)

    def hip_ankle(knee: float) -> float:
        q = robot.with_joints({"l_knee": knee})
        ankle = robot.frame_placement(q, "l_ankle_roll").translation
        return float(np.linalg.norm(ankle - hip_centre(robot, "left")))

    reach = (math.hypot(14.5, 75) + math.hypot(14.5, 71)) * 1e-3  # |thigh| + |shin|
    assert hip_ankle(delta) == pytest.approx(reach, abs=1e-12)
    assert hip_ankle(delta) > hip_ankle(0.0) and hip_ankle(delta) > hip_ankle(delta + 0.1)


def test_leg_walk_ready_angles(robot):
    q = robot.configuration("walk_ready")
    for side in ("left", "right"):
        index = idx(robot, side, LEG)
        sol = leg_ik(robot, side, in_torso(robot, q, f"{side[0]}_sole"))
        np.testing.assert_allclose(sol, q[index], atol=1e-12)


def test_leg_knee_back_branch_when_knee_forward_breaks_a_limit(robot):
    q = robot.with_joints({"l_hip_pitch": -2.2, "l_knee": 0.1})
    target = in_torso(robot, q, "l_sole")
    raw = leg_ik(robot, "left", target, check_limits=False)  # knee forward, hip pitch too low
    assert raw[3] > knee_stretch_angle(robot, "left")
    assert raw[2] < robot.q_min[robot.joint_index("l_hip_pitch")]
    sol = leg_ik(robot, "left", target)
    np.testing.assert_allclose(sol, q[idx(robot, "left", LEG)], atol=1e-9)


def sole_below_hip(robot, side: str, distance: float) -> pin.SE3:
    """Flat sole with its ankle centre ``distance`` straight below the hip centre."""
    return pin.SE3(np.eye(3), hip_centre(robot, side) - np.array([0, 0, distance + 0.0322]))


def test_leg_unreachable(robot):
    too_far = r"left leg: hip-ankle distance 0\.160 m exceeds reach 0\.149 m"
    with pytest.raises(IKError, match=too_far):
        leg_ik(robot, "left", sole_below_hip(robot, "left", 0.160))
    with pytest.raises(IKError, match=r"right leg: .*inside the minimum reach 0\.0039 m"):
        leg_ik(robot, "right", sole_below_hip(robot, "right", 0.002))


def test_leg_out_of_limits(robot):
    target = sole_below_hip(robot, "left", 0.030)  # reachable only with the knee folded ~178°
    with pytest.raises(IKError, match=r"left leg: .*l_knee = 3\.\d+ rad outside limits"):
        leg_ik(robot, "left", target)
    raw = leg_ik(robot, "left", target, check_limits=False)
    q = robot.with_joints(dict(zip([f"l_{n}" for n in LEG], raw, strict=True)))
    assert np.linalg.norm(in_torso(robot, q, "l_sole").translation - target.translation) < 1e-9


def test_leg_bad_input(robot):
    good = in_torso(robot, robot.configuration("walk_ready"), "l_sole")
    nan = pin.SE3(good)
    nan.translation = np.array([np.nan, 0.0, -0.2])
    with pytest.raises(IKError, match="non-finite"):
        leg_ik(robot, "left", nan)
    with pytest.raises(IKError, match="unknown side 'middle'"):
        leg_ik(robot, "middle", good)
    with pytest.raises(IKError, match=r"expected a pinocchio\.SE3"):
        leg_ik(robot, "left", good.homogeneous)
    skew = pin.SE3(good)
    skew.rotation = 2.0 * np.eye(3)
    with pytest.raises(IKError, match="not a rotation"):
        leg_ik(robot, "left", skew)


# ------------------------------------------------------------------------------ arm
@given(side=SIDES, fractions=st.lists(st.floats(0, 1), min_size=3, max_size=3))
def test_arm_round_trip(robot, side, fractions):
    index = idx(robot, side, ARM)
    q = robot.neutral()
    q[index] = draw(robot, index, fractions)
    target = in_torso(robot, q, f"{side[0]}_hand").translation

    sol = arm_ik(robot, side, target)
    q2 = robot.neutral()
    q2[index] = sol
    assert np.linalg.norm(in_torso(robot, q2, f"{side[0]}_hand").translation - target) < 1e-9
    assert robot.within_limits(q2)
    # the original angles are one of the (up to four) solutions: the nearest to themselves
    np.testing.assert_allclose(arm_ik(robot, side, target, q_ref=q[index]), q[index], atol=1e-7)


def test_arm_walk_ready_default_branch(robot):
    q = robot.configuration("walk_ready")
    for side in ("left", "right"):
        target = in_torso(robot, q, f"{side[0]}_hand").translation
        np.testing.assert_allclose(
            arm_ik(robot, side, target), q[idx(robot, side, ARM)], atol=1e-12
        )


def test_arm_unreachable_singular_and_out_of_limits(robot):
    with pytest.raises(IKError, match=r"left arm: hand out of reach.*\[0\.0070, 0\.1420\] m"):
        arm_ik(robot, "left", np.array([0.1, 0.4, 0.0]))
    with pytest.raises(IKError, match=r"right arm: singular.*shoulder-pitch axis"):
        arm_ik(robot, "right", np.array([0.0, -0.15, 0.0]))
    near_roll_joint = np.array([0.0, 0.086, -0.014])  # 10 mm from the shoulder-roll joint
    with pytest.raises(IKError, match=r"left arm: no solution within .*l_elbow = "):
        arm_ik(robot, "left", near_roll_joint)
    raw = arm_ik(robot, "left", near_roll_joint, check_limits=False)
    q = robot.with_joints(dict(zip([f"l_{n}" for n in ARM], raw, strict=True)))
    assert np.linalg.norm(in_torso(robot, q, "l_hand").translation - near_roll_joint) < 1e-9


def test_arm_bad_input(robot):
    with pytest.raises(IKError, match="non-finite"):
        arm_ik(robot, "left", np.array([0.0, np.nan, -0.1]))
    with pytest.raises(IKError, match=r"shape \(2,\)"):
        arm_ik(robot, "left", np.array([0.0, 0.1]))
    with pytest.raises(IKError, match="unknown side"):
        arm_ik(robot, "up", np.array([0.0, 0.1, -0.1]))


# ------------------------------------------------------------------------------ whole body
def targets(robot, q, support: str):
    s, w = support[0], "r" if support == "left" else "l"
    sole = robot.frame_placement(q, f"{s}_sole")
    torso = sole.inverse() * robot.frame_placement(q, "torso")
    swing = sole.inverse() * robot.frame_placement(q, f"{w}_sole")
    hands = {
        name: sole.inverse().act(robot.frame_placement(q, f"{name[0]}_hand").translation)
        for name in ("left", "right")
    }
    return sole, torso, swing, hands


@pytest.mark.parametrize("support", ["left", "right"])
def test_whole_body_reproduces_walk_ready(robot, support):
    q0 = robot.configuration("walk_ready")
    sole, torso, swing, hands = targets(robot, q0, support)
    q = whole_body_ik(robot, support, torso, swing, hands, support_in_world=sole)
    np.testing.assert_allclose(q[7:], q0[7:], atol=1e-9)
    assert np.linalg.norm(robot.difference(q0, q)) < 1e-9


@pytest.mark.parametrize("support", ["left", "right"])
def test_whole_body_moved_torso_and_lifted_foot(robot, support):
    q0 = robot.configuration("walk_ready")
    _, torso0, swing, hands = targets(robot, q0, support)
    sway = 0.008 if support == "left" else -0.008  # torso towards the support foot
    shift = np.array([0.01, sway, -0.01])
    torso = pin.SE3(pin.rpy.rpyToMatrix(0.0, -0.05, 0.05), torso0.translation + shift)
    lift = np.array([0.02, 0.0, 0.025])
    swing = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.1, -0.05), swing.translation + lift)
    # hands: carried along with the torso, then moved 1 cm towards the midline (in Walk Ready
    # the arms are stretched to within 1 mm of their reach and near their roll limits)
    move = torso * torso0.inverse()
    inward = {"left": np.array([0.0, -0.01, 0.0]), "right": np.array([0.0, 0.01, 0.0])}
    hands = {k: move.act(v) + inward[k] for k, v in hands.items()}

    q = whole_body_ik(robot, support, torso, swing, hands, q_init=q0)
    assert robot.within_limits(q)
    s, w = support[0], "r" if support == "left" else "l"
    sole = robot.frame_placement(q, f"{s}_sole")
    assert np.linalg.norm(pin.log6(sole).vector) < 1e-9  # support sole at the world origin
    for frame, target in ((f"{w}_sole", swing), ("torso", torso)):
        reached = robot.frame_placement(q, frame)
        assert np.linalg.norm(reached.translation - target.translation) < 1e-9
        assert rotation_error(reached, target) < 1e-9
    for name, target in hands.items():
        reached = robot.frame_placement(q, f"{name[0]}_hand").translation
        assert np.linalg.norm(reached - target) < 1e-9


def test_whole_body_keeps_untargeted_limbs_and_names_failing_limb(robot):
    q0 = robot.configuration("walk_ready")
    _, torso, swing, _ = targets(robot, q0, "left")
    q = whole_body_ik(robot, "left", torso, None, None, q_init=q0)
    np.testing.assert_allclose(q[7:], q0[7:], atol=1e-9)  # everything else from q_init

    far = pin.SE3(swing.rotation, swing.translation - np.array([0.0, 0.0, 0.2]))
    with pytest.raises(IKError, match="right leg: hip-ankle distance"):
        whole_body_ik(robot, "left", torso, far, q_init=q0)
    with pytest.raises(IKError, match="unknown side 'hand'"):
        whole_body_ik(robot, "left", torso, hands_in_support={"hand": [0, 0, 0.2]})
    with pytest.raises(IKError, match="left arm: target has non-finite"):
        whole_body_ik(robot, "left", torso, hands_in_support={"left": [0, np.nan, 0.2]})
