"""Pre-motion checks (wbc.walking.checks): each failure is caught with a clear message."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wbc.exceptions import TrajectoryError
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT
from wbc.walking import LegGeometry, check_reference, forward_walk, thesis_step
from wbc.walking.legs import ANKLE_HEIGHT, HIP_HALF_WIDTH, SHIN, THIGH


@pytest.fixture(scope="module")
def ref(start):
    return forward_walk(start, 4, generator="preview")


def test_leg_geometry_from_robot(robot):
    legs = LegGeometry.from_robot(robot)
    assert legs.thigh == pytest.approx(THIGH, abs=1e-5)
    assert legs.shin == pytest.approx(SHIN, abs=1e-5)
    assert legs.hip_half_width == pytest.approx(HIP_HALF_WIDTH, abs=1e-6)
    assert legs.ankle_height == pytest.approx(ANKLE_HEIGHT, abs=1e-6)
    default = LegGeometry()
    np.testing.assert_allclose(legs.hip_offset, default.hip_offset, atol=5e-4)
    assert legs.min_reach == pytest.approx(default.min_reach, abs=1e-3)
    # at Walk Ready the estimated hip-ankle distance is the model's
    q = robot.configuration("walk_ready")
    import pinocchio as pin

    pin.forwardKinematics(robot.model, robot.data, q)
    hip = robot.data.oMi[robot.model.getJointId("l_hip_pitch")].translation
    ankle = robot.data.oMi[robot.model.getJointId("l_ankle_pitch")].translation
    sole = robot.frame_placement(q, "l_sole").translation
    est = legs.leg_lengths(robot.com(q)[None], np.zeros(1), sole[None], sole[None])[0, 0]
    assert est == pytest.approx(np.linalg.norm(hip - ankle), abs=1e-3)


def test_valid_references_pass(ref, start):
    report = check_reference(ref)
    assert report.zmp_margin >= ref.margin
    assert report.foot_clearance >= 0.005
    assert report.min_sole_height >= -1e-12
    assert report.max_leg_length <= LegGeometry().max_reach
    assert check_reference(thesis_step(start)).com_margin >= 0.0


def test_zmp_outside_polygon(ref):
    com = ref.com.copy()
    i = int(np.argmax(ref.support == SUPPORT_LEFT)) + 5
    acc = ref.com_acc.copy()
    acc[i, 1] += 20.0  # ZMP thrown ~0.35 m sideways
    bad = dataclasses.replace(ref, com=com, com_acc=acc)
    with pytest.raises(TrajectoryError, match=rf"tick {i} .*ZMP"):
        check_reference(bad)


def test_static_gait_checks_the_com(start):
    ref = thesis_step(start)
    com = ref.com.copy()
    com[60:, 1] = ref.r_sole[0, 1]  # CoM over the swinging right foot
    with pytest.raises(TrajectoryError, match="CoM"):
        check_reference(dataclasses.replace(ref, com=com))


def test_sole_below_ground(ref):
    r = ref.r_sole.copy()
    swing = np.flatnonzero(ref.support == SUPPORT_LEFT)[10]
    r[swing, 2] = -0.002
    with pytest.raises(TrajectoryError, match="below the ground"):
        check_reference(dataclasses.replace(ref, r_sole=r))


def test_feet_collide(ref):
    r = ref.r_sole.copy()
    swing = np.flatnonzero(ref.support == SUPPORT_LEFT)[10]
    r[swing, 1] = ref.l_sole[swing, 1] - 0.05  # 11 mm overlap with the left foot
    with pytest.raises(TrajectoryError, match="feet are"):
        check_reference(dataclasses.replace(ref, r_sole=r))
    # yaw alone can make the feet collide (heels turned in)
    yaw = ref.r_sole_yaw.copy()
    yaw[swing] = 0.9
    with pytest.raises(TrajectoryError, match="feet are"):
        check_reference(dataclasses.replace(ref, r_sole_yaw=yaw))


def test_contact_sole_must_not_move(ref):
    l_pos = ref.l_sole.copy()
    ds = np.flatnonzero(ref.support == SUPPORT_DOUBLE)[5]
    l_pos[ds:, 0] += 0.003
    with pytest.raises(TrajectoryError, match="while in contact"):
        check_reference(dataclasses.replace(ref, l_sole=l_pos))


def test_unreachable_reference(ref):
    com = ref.com.copy()
    com[:, 2] += 0.02  # legs would have to stretch beyond their reach
    with pytest.raises(TrajectoryError, match="unreachable"):
        check_reference(dataclasses.replace(ref, com=com))
    assert check_reference(dataclasses.replace(ref, com=com), check_reach=False)


def test_bad_margin(ref):
    with pytest.raises(TrajectoryError, match="margin"):
        check_reference(ref, margin=-0.01)


def test_hip_roll_limit(ref):
    """The Bioloid's hips roll only 5.6 deg inward: a CoM 10 mm further out over the stance
    foot is out of reach even though it is well inside the foot."""
    legs = LegGeometry()
    com = ref.com.copy()
    ss = np.flatnonzero(ref.support == SUPPORT_LEFT)
    com[ss, 1] += 0.01
    with pytest.raises(TrajectoryError, match="left hip would roll"):
        check_reference(dataclasses.replace(ref, com=com))
    rolls = legs.leg_rolls(ref.com, ref.torso_yaw, ref.l_sole, ref.r_sole)
    assert -rolls.min() <= legs.max_adduction - legs.roll_margin


def test_lateral_bounds_match_the_roll_estimate(rng):
    legs = LegGeometry()
    for _ in range(200):
        heading = rng.uniform(-np.pi, np.pi)
        l_xy, r_xy = rng.uniform(-0.05, 0.05, 2), rng.uniform(-0.05, 0.05, 2)
        l_xy += 0.04 * np.array([-np.sin(heading), np.cos(heading)])
        r_xy -= 0.04 * np.array([-np.sin(heading), np.cos(heading)])
        com = np.array([*rng.uniform(-0.03, 0.03, 2), 0.17])
        heights = np.full(2, 0.17 + legs.hip_offset[1] - legs.ankle_height)
        G, h = legs.lateral_com_bounds(heading, l_xy, r_xy, heights)
        ok_linear = np.all(G @ com[:2] <= h)
        rolls = legs.leg_rolls(
            com[None], np.array([heading]), np.array([[*l_xy, 0.0]]), np.array([[*r_xy, 0.0]])
        )[0]
        ok_roll = np.all(rolls >= -(legs.max_adduction - legs.roll_margin)) and np.all(
            rolls <= legs.max_abduction - legs.roll_margin
        )
        assert ok_linear == ok_roll


def test_max_com_lateral(robot):
    legs = LegGeometry.from_robot(robot)
    assert legs.max_adduction == pytest.approx(np.radians(5.57), abs=1e-3)  # Annex A
    # the pelvis moves ~1.3x the CoM (legs lag): measured, and the default
    assert legs.pelvis_gain == pytest.approx(LegGeometry().pelvis_gain, abs=0.01)
    assert 1.2 < legs.pelvis_gain < 1.45
    reach = legs.max_com_lateral(0.173, 0.0414)
    assert 0.009 < reach < 0.013  # ~11 mm from the mid-stance, ~30 mm short of the sole
