"""The get-up plan (wbc.balance.getup): contacts held at the hard level, joint limits and
servo speeds kept, the CoM inside the support polygon; the lying state and side."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from wbc.balance import getup as G
from wbc.exceptions import ConfigurationError
from wbc.geometry import convex_hull, signed_distance
from wbc.model import Kinematics, load_robot

ROBOT = load_robot("bioloid")


def _lying(side: str = "prone") -> np.ndarray:
    """Lying in the standing pose (as the simulator's torque-off fall leaves it), on the back
    with the trunk 10° up off the floor (the knees bent, the heels down, as it settles)."""
    q = ROBOT.configuration("stand")
    pitch = math.pi / 2 if side == "prone" else -math.radians(80)
    R = pin.rpy.rpyToMatrix(0.0, pitch, 0.3)
    return G.lying_state(ROBOT, q[7:], R @ np.eye(3))


@pytest.fixture(scope="module", params=G.SIDES_LYING)
def plans(request) -> list[G.PhasePlan]:
    return G.plan_getup(ROBOT, _lying(request.param), request.param)


def _support_points(robot, kin, phase) -> np.ndarray:
    pts = []
    length, width = ROBOT.foot_size
    for f in (*phase.contacts, *phase.sliding):
        if f in ("l_sole", "r_sole"):
            M = kin.placement(robot.frame_id(f))
            for dx in (-length / 2, length / 2):
                for dy in (-width / 2, width / 2):
                    pts.append(M.act(np.array([dx, dy, 0.0]))[:2])
        elif f != "torso":
            pts.append(kin.translation(robot.frame_id(f))[:2])
    return np.asarray(pts)


def test_the_plan_keeps_its_contacts_limits_and_speeds(plans) -> None:
    robot = G.with_toes(ROBOT)
    names = [p.phase.name for p in plans]
    assert names in ([p.name for p in G.phases_for(ROBOT, side)] for side in G.SIDES_LYING)
    for plan in plans:
        assert plan.failed_solves == 0, plan.phase.name
        joints = plan.q[:, 7:]
        assert np.all(joints >= ROBOT.q_min) and np.all(joints <= ROBOT.q_max), plan.phase.name
        speed = G.joint_speeds(plan)
        assert np.all(speed <= G.GetupParams().speed_scale * ROBOT.v_max + 1e-9), plan.phase.name
        for q in plan.q:
            kin = Kinematics(robot, q)
            for frame in plan.phase.contacts:
                err = np.linalg.norm(kin.translation(robot.frame_id(frame)) - plan.anchors[frame])
                assert err < 2e-3, (plan.phase.name, frame, err)  # first order per 20 ms tick
            for frame in plan.phase.sliding:
                z = kin.translation(robot.frame_id(frame))[2]
                assert abs(z - plan.anchors[frame][2]) < 2e-3, (plan.phase.name, frame)


def test_the_com_stays_inside_the_support_polygon(plans) -> None:
    robot = G.with_toes(ROBOT)
    checked = 0
    for plan in plans:
        if not plan.phase.quasi_static:
            continue
        for q in plan.q:
            kin = Kinematics(robot, q)
            pts = _support_points(robot, kin, plan.phase)
            if len(pts) < 3:  # lying on the torso: the floor holds it
                continue
            margin = signed_distance(convex_hull(pts), kin.com[:2])
            assert margin > 0, (plan.phase.name, margin)
            checked += 1
    assert checked > 100


def test_sliding_hands_never_pass_the_com(plans) -> None:
    """The hands sent along the floor to the feet (past the CoM, which a plan from a measured
    fall did: benchmarks/getup.md): with the hull rows the CoM stays inside the hull of the
    soles and the hands by the margin (to first order); without them it leaves it."""
    side = "supine" if "crab" in [p.phase.name for p in plans] else "prone"
    robot = G.with_toes(ROBOT)
    start = next(p for p in plans if p.phase.name == "feet flat").q[-1]
    ground = G.ground_frame(_lying(side), robot, side)
    kin = Kinematics(robot, start)
    soles = ("l_sole", "r_sole")
    x_feet = np.mean([ground.actInv(kin.translation(robot.frame_id(f)))[0] for f in soles])
    moves = {}
    for f in ("l_hand", "r_hand"):
        moves[f] = (float(x_feet), float(ground.actInv(kin.translation(robot.frame_id(f)))[1]), 0.0)
    phase = G.Phase("hands to the feet", soles, 1.0, sliding=("l_hand", "r_hand"), moves=moves)
    worst = {}
    margin = G.GetupParams().sliding_margin  # the phase's hands slide
    for params in (G.GetupParams(support_margin=None), G.GetupParams()):
        planner = G.PhasePlanner(ROBOT, params)
        planner.floor = {f: -1.0 for f in planner.body_points}
        plan = planner.plan(phase, start, ground)
        inside = []
        for q in plan.q:
            k = Kinematics(robot, q)
            hull = convex_hull(_support_points(robot, k, phase))
            inside.append(signed_distance(hull, k.com[:2]))
        worst[params.support_margin] = min(inside)
    assert worst[None] < -0.005, worst  # the hands passed the CoM
    assert worst[0.005] > margin - 0.002, worst  # the margin, to first order per 20 ms tick


def test_the_plan_ends_standing(plans) -> None:
    q = plans[-1].q[-1]
    stand = ROBOT.configuration(ROBOT.stand_pose)
    assert np.max(np.abs(q[7:] - stand[7:])) < 0.05
    # the torso as upright as in the standing pose on flat feet (the Bioloid's leans ~9 deg)
    standing = ROBOT.place_on_ground(stand)
    up = ROBOT.frame_placement(q, "torso").rotation[2, 2]
    up_stand = ROBOT.frame_placement(standing, "torso").rotation[2, 2]
    assert math.degrees(abs(math.acos(up) - math.acos(up_stand))) < 2.0


def test_lying_side_and_state() -> None:
    prone = pin.rpy.rpyToMatrix(0.0, math.pi / 2, 1.0)
    supine = pin.rpy.rpyToMatrix(0.0, -math.pi / 2, -2.0)
    assert G.lying_side(prone) == "prone"
    assert G.lying_side(supine) == "supine"
    assert G.lying_side(np.eye(3)) is None
    assert G.heading_of(prone, "prone") == pytest.approx(1.0)
    q = _lying()
    assert G.lowest_point(ROBOT, q) == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(
        ROBOT.frame_placement(q, "torso").rotation, pin.rpy.rpyToMatrix(0, math.pi / 2, 0.3)
    )


def test_bad_input_is_one_clear_line() -> None:
    with pytest.raises(ConfigurationError, match="side must be"):
        G.phases_for(ROBOT, "sideways")
    with pytest.raises(ConfigurationError, match="speed_scale"):
        G.GetupParams(speed_scale=2.0).check()
    with pytest.raises(ConfigurationError, match="rate"):
        G.GetupParams(rate=0.0).check()
    with pytest.raises(ConfigurationError, match="hold_s"):
        G.GetupParams(hold_s=-1.0).check()
    with pytest.raises(ConfigurationError, match="support_margin"):
        G.GetupParams(support_margin=-0.01).check()
    with pytest.raises(ConfigurationError, match="sliding_margin"):
        G.GetupParams(sliding_margin=math.nan).check()


def test_static_torques_on_one_sole_are_the_compliance_models() -> None:
    """On one sole the contact wrench is unique: the same torques as the compliance
    feed-forward's inverse statics (wbc.balance.compliance)."""
    from wbc.balance.compliance import ComplianceCompensator
    from wbc.recording import SUPPORT_LEFT

    robot = G.with_toes(ROBOT)
    joints = ROBOT.configuration("stand")[7:] + 0.05
    q = ROBOT.place_on_ground(ROBOT.with_joints(joints), "l_sole")
    phase = G.Phase("one sole", ("l_sole",), 1.0)
    expected = ComplianceCompensator(ROBOT).torques(joints, SUPPORT_LEFT)
    assert np.allclose(G.static_torques(robot, q, phase), expected, atol=1e-9)
    # on the torso alone (lying) the floor holds everything: the joints hold the limbs
    lying = _lying()
    tau = G.static_torques(robot, lying, G.Phase("lying", ("torso",), 1.0))
    assert np.all(np.isfinite(tau)) and np.abs(tau).max() < 0.5
