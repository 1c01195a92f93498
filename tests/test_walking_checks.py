"""Pre-motion checks (wbc.walking.checks): each failure is caught with a clear message."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wbc.exceptions import TrajectoryError
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT
from wbc.walking import LegGeometry, check_reference, forward_walk, thesis_step


@pytest.fixture(scope="module")
def ref(start):
    return forward_walk(start, 4, generator="preview")


@pytest.fixture(scope="module")
def legs(start):
    """The Bioloid's legs (measured at its standing pose; its robot.toml states them)."""
    return start.legs


def test_leg_geometry_from_robot(robot):
    legs = LegGeometry.from_robot(robot)
    # the Bioloid's: thigh 76.39 mm, shin 72.47 mm, hips 77 mm apart, ankles 32.2 mm up
    assert legs.thigh == pytest.approx(0.07639, abs=1e-5)
    assert legs.shin == pytest.approx(0.07247, abs=1e-5)
    assert legs.hip_half_width == pytest.approx(0.0385, abs=1e-6)
    assert legs.ankle_height == pytest.approx(0.0322, abs=1e-6)
    np.testing.assert_allclose(legs.hip_offset, (-0.0086, -0.0099), atol=5e-4)
    assert legs.min_reach == pytest.approx(0.036, abs=1e-3)
    # at Walk Ready the estimated hip-ankle distance is the model's
    q = robot.configuration("walk_ready")
    import pinocchio as pin

    pin.forwardKinematics(robot.model, robot.data, q)
    hip = robot.data.oMi[robot.model.getJointId("l_hip_pitch")].translation
    ankle = robot.data.oMi[robot.model.getJointId("l_ankle_pitch")].translation
    sole = robot.frame_placement(q, "l_sole").translation
    est = legs.leg_lengths(robot.com(q)[None], np.zeros(1), sole[None], sole[None])[0, 0]
    assert est == pytest.approx(np.linalg.norm(hip - ankle), abs=1e-3)


def test_valid_references_pass(ref, start, legs):
    report = check_reference(ref, legs=legs)
    assert report.zmp_margin >= ref.margin
    assert report.foot_clearance >= 0.005
    assert report.min_sole_height >= -1e-12
    assert report.max_leg_length <= legs.max_reach
    assert check_reference(thesis_step(start), legs=legs).com_margin >= 0.0


def test_zmp_outside_polygon(ref, legs):
    com = ref.com.copy()
    i = int(np.argmax(ref.support == SUPPORT_LEFT)) + 5
    acc = ref.com_acc.copy()
    acc[i, 1] += 20.0  # ZMP thrown ~0.35 m sideways
    bad = dataclasses.replace(ref, com=com, com_acc=acc)
    with pytest.raises(TrajectoryError, match=rf"tick {i} .*ZMP"):
        check_reference(bad, legs=legs)


def test_static_gait_checks_the_com(start, legs):
    ref = thesis_step(start)
    com = ref.com.copy()
    com[60:, 1] = ref.r_sole[0, 1]  # CoM over the swinging right foot
    with pytest.raises(TrajectoryError, match="CoM"):
        check_reference(dataclasses.replace(ref, com=com), legs=legs)


def test_sole_below_ground(ref, legs):
    r = ref.r_sole.copy()
    swing = np.flatnonzero(ref.support == SUPPORT_LEFT)[10]
    r[swing, 2] = -0.002
    with pytest.raises(TrajectoryError, match="below the ground"):
        check_reference(dataclasses.replace(ref, r_sole=r), legs=legs)


def test_feet_collide(ref, legs):
    r = ref.r_sole.copy()
    swing = np.flatnonzero(ref.support == SUPPORT_LEFT)[10]
    r[swing, 1] = ref.l_sole[swing, 1] - 0.05  # 11 mm overlap with the left foot
    with pytest.raises(TrajectoryError, match="feet are"):
        check_reference(dataclasses.replace(ref, r_sole=r), legs=legs)
    # yaw alone can make the feet collide (heels turned in)
    yaw = ref.r_sole_yaw.copy()
    yaw[swing] = 0.9
    with pytest.raises(TrajectoryError, match="feet are"):
        check_reference(dataclasses.replace(ref, r_sole_yaw=yaw), legs=legs)


def test_contact_sole_must_not_move(ref, legs):
    l_pos = ref.l_sole.copy()
    ds = np.flatnonzero(ref.support == SUPPORT_DOUBLE)[5]
    l_pos[ds:, 0] += 0.003
    with pytest.raises(TrajectoryError, match="while in contact"):
        check_reference(dataclasses.replace(ref, l_sole=l_pos), legs=legs)


def test_unreachable_reference(ref, legs):
    com = ref.com.copy()
    com[:, 2] += 0.02  # legs would have to stretch beyond their reach
    with pytest.raises(TrajectoryError, match="unreachable"):
        check_reference(dataclasses.replace(ref, com=com), legs=legs)
    assert check_reference(dataclasses.replace(ref, com=com), check_reach=False, legs=legs)


def test_bad_margin(ref, legs):
    with pytest.raises(TrajectoryError, match="margin"):
        check_reference(ref, margin=-0.01, legs=legs)


def test_hip_roll_limit(ref, legs):
    """The Bioloid's hips roll only 5.6 deg inward: a CoM 10 mm further out over the stance
    foot is out of reach even though it is well inside the foot."""
    com = ref.com.copy()
    ss = np.flatnonzero(ref.support == SUPPORT_LEFT)
    com[ss, 1] += 0.01
    with pytest.raises(TrajectoryError, match="left hip would roll"):
        check_reference(dataclasses.replace(ref, com=com), legs=legs)
    rolls = legs.leg_rolls(ref.com, ref.torso_yaw, ref.l_sole, ref.r_sole)
    assert -rolls.min() <= legs.max_adduction - legs.roll_margin


def test_lateral_bounds_match_the_roll_estimate(rng, legs):
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
    # the pelvis moves ~1.3x the CoM (legs lag): measured, and what robot.toml states
    assert legs.pelvis_gain == pytest.approx(1.325, abs=0.01)
    assert 1.2 < legs.pelvis_gain < 1.45
    reach = legs.max_com_lateral(0.173, 0.0414)
    assert 0.009 < reach < 0.013  # ~11 mm from the mid-stance, ~30 mm short of the sole
