"""The NLP accuracy reference: casadi kinematics vs pinocchio, the pose NLP, its controller."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc import load_robot

pytest.importorskip("casadi")  # the NLP's optional package: pip install "wbc[mpc]"

from wbc.bench.casadi_kinematics import CasadiKinematics, parse_urdf
from wbc.bench.nlp import NlpController, PoseNLP, PoseTargets
from wbc.exceptions import ModelError, TaskError
from wbc.geometry import heading_free
from wbc.recording import SUPPORT_DOUBLE
from wbc.stacks import load_stack
from wbc.walking import StandingState, forward_walk
from wbc.walking.loop import RunOptions, StackController, TickTargets, run

FRAMES = ("l_sole", "r_sole", "torso", "l_hand", "r_hand", "l_knee", "r_shin", "l_sole_fixed")
seeds = st.integers(min_value=0, max_value=2**32 - 1)


def random_q(robot, seed: int, spread: float = 0.3) -> np.ndarray:
    """Joints anywhere within limits (and a bit beyond), random base pose."""
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    q[7:] += spread * rng.standard_normal(robot.n_joints)
    q[:3] = rng.normal(scale=0.5, size=3)
    quat = rng.normal(size=4)
    q[3:7] = quat / np.linalg.norm(quat)
    return q


@pytest.fixture(scope="module")
def kin(robot):
    return CasadiKinematics(robot)


@pytest.fixture(scope="module")
def fk(kin):
    return {f: kin.frame_placement_function(f) for f in FRAMES}, kin.com_function()


# ---------------------------------------------------------------------- kinematics
@given(seed=seeds)
def test_placements_and_com_equal_pinocchio(robot, fk, seed):
    placements, com = fk
    q = random_q(robot, seed)
    for frame, fun in placements.items():
        p, R = fun(q)
        M = robot.frame_placement(q, frame)
        np.testing.assert_allclose(np.array(p).ravel(), M.translation, rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.array(R), M.rotation, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.array(com(q)).ravel(), robot.com(q), rtol=0, atol=1e-12)


GENERIC_URDF = """<?xml version="1.0"?>
<robot name="generic">
  <link name="base"><inertial><origin xyz="0.01 -0.02 0.03" rpy="0.3 0.1 -0.2"/>
    <mass value="1.5"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.03"/>
  </inertial></link>
  <link name="a"><inertial><origin xyz="0.1 0 -0.05" rpy="0 0 0"/><mass value="0.4"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>
  <link name="b"><inertial><origin xyz="0 0.07 0.02" rpy="0.5 0 0"/><mass value="0.3"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>
  <link name="c"><inertial><origin xyz="0.03 0.01 0" rpy="0 0 0"/><mass value="0.2"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>
  <link name="tip"/>
  <link name="d"><inertial><origin xyz="0 0 -0.1" rpy="0 0 0"/><mass value="0.25"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0.1 0.2 -0.3" rpy="0.4 -0.7 1.1"/><axis xyz="0.6 0 0.8"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j2" type="prismatic"><parent link="a"/><child link="b"/>
    <origin xyz="0 0.05 0" rpy="-0.3 0.2 0"/><axis xyz="0 1 0"/>
    <limit lower="-0.1" upper="0.1" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="b"/><child link="c"/>
    <origin xyz="0.02 0 0.04" rpy="0 0 0.9"/><axis xyz="0 0 -1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="tip_fixed" type="fixed"><parent link="c"/><child link="tip"/>
    <origin xyz="0.05 -0.01 0.02" rpy="1.2 0.3 -0.4"/></joint>
  <joint name="j4" type="revolute"><parent link="base"/><child link="d"/>
    <origin xyz="-0.1 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
</robot>
"""


def test_generic_urdf_with_rpy_unaligned_axes_prismatic_and_fixed_frames(tmp_path):
    path = tmp_path / "generic.urdf"
    path.write_text(GENERIC_URDF)
    robot = load_robot(path)
    kin = CasadiKinematics(robot)
    funs = {f: kin.frame_placement_function(f) for f in ("a", "b", "c", "tip", "d", "j3")}
    com = kin.com_function()
    for seed in range(10):
        q = random_q(robot, seed, spread=0.0)
        for frame, fun in funs.items():
            p, R = fun(q)
            M = robot.frame_placement(q, frame)
            np.testing.assert_allclose(np.array(p).ravel(), M.translation, atol=1e-12)
            np.testing.assert_allclose(np.array(R), M.rotation, atol=1e-12)
        np.testing.assert_allclose(np.array(com(q)).ravel(), robot.com(q), atol=1e-12)


def test_bad_urdfs_are_named(tmp_path, robot):
    bad = tmp_path / "bad.urdf"
    bad.write_text(GENERIC_URDF.replace('type="prismatic"', 'type="planar"'))
    with pytest.raises(ModelError, match="planar"):
        parse_urdf(bad)
    bad.write_text(GENERIC_URDF.replace('<child link="d"/>', '<child link="nowhere"/>'))
    with pytest.raises(ModelError, match="nowhere"):
        parse_urdf(bad)
    with pytest.raises(ModelError, match="unknown frame"):
        CasadiKinematics(robot).frame_placement_function("l_foot_typo")


# ---------------------------------------------------------------------- the pose NLP
@pytest.fixture(scope="module")
def nlp(robot):
    return PoseNLP(robot)


@pytest.fixture(scope="module")
def hard_nlp(robot):
    return PoseNLP(robot, hard_com_and_swing=True)


def ready_targets(robot, com_shift=(0.0, 0.0, 0.0), **kw) -> tuple[np.ndarray, PoseTargets]:
    q0 = robot.configuration("walk_ready")
    targets = PoseTargets(
        com=robot.com(q0) + np.asarray(com_shift),
        l_sole=robot.frame_placement(q0, "l_sole"),
        r_sole=robot.frame_placement(q0, "r_sole"),
        torso=heading_free(robot.frame_placement(q0, "torso").rotation),
        posture=q0[7:].copy(),
        **kw,
    )
    return q0, targets


def hard_residual(robot, q, frame, target: pin.SE3) -> float:
    M = robot.frame_placement(q, frame)
    return max(
        np.abs(M.translation - target.translation).max(),
        np.abs(pin.log3(target.rotation @ M.rotation.T)).max(),
    )


@given(seed=seeds)
def test_variables_round_trip(robot, nlp, seed):
    q = random_q(robot, seed, spread=0.0)
    x, R_ref = nlp.to_variables(q)
    back = nlp.to_configuration(x, R_ref)
    np.testing.assert_allclose(back[:3], q[:3], atol=1e-15)
    np.testing.assert_allclose(back[7:], q[7:], atol=0)
    sign = np.sign(back[3:7] @ q[3:7])
    np.testing.assert_allclose(sign * back[3:7], q[3:7], atol=1e-14)
    r = np.random.default_rng(seed).normal(size=3)  # a base rotation off R_ref
    x[3:6] = r
    back = nlp.to_configuration(x, R_ref)
    theta = 2 * np.arctan(np.linalg.norm(r))  # the Cayley map rotates by 2 atan |r| about r
    expected = R_ref @ pin.exp3(theta * r / np.linalg.norm(r))
    M = pin.XYZQUATToSE3(back[:7])
    np.testing.assert_allclose(M.rotation, expected, atol=1e-14)
    x2, R2 = nlp.to_variables(back)
    np.testing.assert_allclose(R2, expected, atol=1e-14)
    np.testing.assert_allclose(x2[6:], x[6:], atol=0)


def test_com_shift_double_support_holds_soles_and_beats_the_qp_stacks(robot, nlp):
    q0, targets = ready_targets(robot, (0.0, 0.01, 0.0))  # 1 cm over the left foot
    sol = nlp.solve(q0, targets)
    assert sol.success, sol.status
    for sole in ("l_sole", "r_sole"):
        assert hard_residual(robot, sol.q, sole, targets.sole(sole)) <= 1e-8
    assert robot.within_limits(sol.q)
    # the weighted optimum trades a little CoM error for torso and posture
    assert np.linalg.norm(robot.com(sol.q) - targets.com) < 1e-4
    torso = heading_free(robot.frame_placement(q0, "torso").rotation)
    swing = targets.r_sole
    tick = TickTargets(
        0, 0.0, "double", "l_sole", "r_sole", targets.com, targets.l_sole, targets.r_sole, 0.0,
        torso, swing.translation.copy(), swing.rotation.copy(),
    )  # fmt: skip
    for kind in ("hierarchical", "weighted"):
        qp = StackController(load_stack("walk", robot, solver=kind))
        qp.start(robot, q0, None)
        q_qp, _ = qp.converge(q0, tick, 1e-9, 300, True)
        for sole in ("l_sole", "r_sole"):  # a feasible point of the NLP
            assert hard_residual(robot, q_qp, sole, targets.sole(sole)) <= 1e-8
        assert robot.within_limits(q_qp)
        assert sol.objective <= nlp.objective(q_qp, targets) + 1e-12, kind


def test_hard_com_is_met_exactly(robot, hard_nlp):
    q0, targets = ready_targets(robot, (0.0, 0.01, 0.0))
    sol = hard_nlp.solve(q0, targets)
    assert sol.success, sol.status
    assert np.abs(robot.com(sol.q) - targets.com).max() <= 1e-8
    for sole in ("l_sole", "r_sole"):
        assert hard_residual(robot, sol.q, sole, targets.sole(sole)) <= 1e-8
    assert robot.within_limits(sol.q)


def test_hard_torso_holds_the_torso_orientation(robot):
    nlp = PoseNLP(robot, hard_com_and_swing=True, hard_torso=True)
    q0, targets = ready_targets(robot, (0.0, 0.005, -0.003))
    targets.torso = pin.rpy.rpyToMatrix(0.0, 0.05, 0.1) @ targets.torso
    sol = nlp.solve(q0, targets)
    assert sol.success, sol.status
    R = robot.frame_placement(sol.q, "torso").rotation
    assert np.abs(pin.log3(targets.torso @ R.T)).max() <= 1e-8
    assert np.abs(robot.com(sol.q) - targets.com).max() <= 1e-8


def test_single_support_hard_swing_and_exact_bounds(robot, hard_nlp):
    """Lift the right sole 2 cm with the CoM over the left foot: the CoM and swing position
    are met exactly; a far CoM target pins a joint at its limit, never beyond."""
    q0, targets = ready_targets(robot, (0.0, 0.035, -0.005), phase="single", support="l_sole")
    targets.r_sole = pin.SE3(targets.r_sole.rotation, targets.r_sole.translation + [0, 0, 0.02])
    sol = hard_nlp.solve(q0, targets)
    assert sol.success, sol.status
    assert np.abs(robot.com(sol.q) - targets.com).max() <= 1e-8
    swing = robot.frame_placement(sol.q, "r_sole").translation
    assert np.abs(swing - targets.r_sole.translation).max() <= 1e-8
    assert hard_residual(robot, sol.q, "l_sole", targets.l_sole) <= 1e-8
    assert robot.within_limits(sol.q)
    # unreachable: the residual says so, and the joints still respect their bounds
    targets.com = targets.com + [0, 0.2, 0]
    far = hard_nlp.solve(sol.q, targets)
    assert far.violation > 1e-3
    assert robot.within_limits(far.q)


def test_bounds_are_respected_exactly_when_active(robot, nlp):
    q0, targets = ready_targets(robot, (0.0, 0.06, -0.01))  # CoM far left, soles held
    sol = nlp.solve(q0, targets)
    assert sol.success, sol.status
    j = sol.q[7:]
    assert np.all(j >= robot.q_min) and np.all(j <= robot.q_max)
    margin = np.minimum(j - robot.q_min, robot.q_max - j)
    assert margin.min() < 1e-6  # some joint is at its limit: the bounds did work
    for sole in ("l_sole", "r_sole"):
        assert hard_residual(robot, sol.q, sole, targets.sole(sole)) <= 1e-8


def test_bad_targets_are_named(robot, nlp):
    q0, targets = ready_targets(robot, phase="triple")
    with pytest.raises(TaskError, match="phase"):
        nlp.solve(q0, targets)
    q0, targets = ready_targets(robot, com_polygon=(np.zeros((3, 3)), np.zeros(3)))
    with pytest.raises(TaskError, match="com_polygon"):
        nlp.solve(q0, targets)
    q0, targets = ready_targets(robot)
    targets.torso = 2 * np.eye(3)
    with pytest.raises(TaskError, match="rotation"):
        nlp.solve(q0, targets)


# ---------------------------------------------------------------------- the controller
def short_reference(robot, n: int = 20):
    """A one-step forward walk subsampled to ``n`` uniformly spaced ticks (the reference's own
    reach checks are skipped: whether the poses are reachable is what the NLP tells)."""
    ref = forward_walk(StandingState.from_robot(robot), n_steps=1, check=False)
    stride = ref.n // n
    idx = np.arange(n) * stride
    fields = {}
    for f in dataclasses.fields(ref):
        v = getattr(ref, f.name)
        if isinstance(v, np.ndarray) and v.shape[:1] == (ref.n,):
            fields[f.name] = v[idx]
    return dataclasses.replace(ref, name="forward-1-sub", **fields)


def test_controller_runs_a_walk_in_converged_mode(robot):
    ref = short_reference(robot)
    assert ref.n == 20
    assert np.any(ref.support == SUPPORT_DOUBLE) and np.any(ref.support != SUPPORT_DOUBLE)
    controller = NlpController(hard_com_and_swing=True)
    rec = run(controller, robot, ref, options=RunOptions(mode="converge"))
    ch = rec.channels
    assert not ch["failed"].any()
    assert np.all(ch["iterations"] >= 0) and ch["iterations"].max() < 300
    assert np.abs(ch["com"] - ch["com_ref"]).max() <= 1e-8
    single = ref.support != SUPPORT_DOUBLE
    assert np.abs(ch["swing"][single] - ch["swing_ref"][single]).max() <= 1e-8
    assert ch["limit_margin"].min() >= 0
    assert rec.meta["controller"] == "nlp-ipopt-hard" and rec.meta["family"] == "nlp"
    # the weighted reference in per-tick mode (track = converge), with walk.toml's CoM margin
    soft = NlpController()
    rec = run(soft, robot, ref, options=RunOptions(mode="tick"))
    ch = rec.channels
    assert not ch["failed"].any()
    assert np.abs(ch["com"] - ch["com_ref"]).max() < 1e-2
    assert ch["com_margin"].min() >= 0.01 - 1e-8
    assert ch["swing_lowest"].min() >= -1e-9
    for i in range(ref.n):  # the support sole is held
        side = "right" if ch["swing_is_left"][i] else "left"
        target = ref.sole_placement(i, side)
        assert hard_residual(robot, rec.q[i], f"{side[0]}_sole", target) <= 1e-8
