"""Support-sole rooting, principal masses (3.1-3.11) and the thesis's joint data."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc import Kinematics
from wbc.exceptions import ConfigurationError, ModelError
from wbc.pinv import PrincipalMasses, SoleRooted, annex_b_weights
from wbc.pinv.principal_masses import com_mass_matrix, principal_mass_targets
from wbc.pinv.thesis_data import THESIS_JOINT_IDS, thesis_joint_index
from wbc.tasks import FramePositionTask


# ------------------------------------------------------------------ thesis joints, Annex B
def test_thesis_joints_map_onto_distinct_model_joints(robot):
    index = thesis_joint_index(robot)
    assert sorted(index) == list(range(1, 19))
    assert sorted(index.values()) == list(range(robot.n_joints))
    # bioloid-facts §8: j3 = ID 14 = left knee, j16 = ID 13 = right knee, j10 = ID 1
    assert robot.joint_names[index[3]] == "l_knee"
    assert robot.joint_names[index[16]] == "r_knee"
    assert robot.joint_names[index[10]] == "r_shoulder_pitch"
    assert len(set(THESIS_JOINT_IDS.values())) == 18


def test_annex_b_weights_by_name_and_mirrored_for_a_right_support(robot):
    w = dict(zip(robot.joint_names, annex_b_weights(robot, "l_sole"), strict=True))
    # support (left) leg: ankle and knee mobile, hip stiff; swing leg: hip pitch and knee mobile
    assert w["l_ankle_roll"] == w["l_ankle_pitch"] == w["l_knee"] == 0.1
    assert w["l_hip_roll"] == w["l_hip_pitch"] == w["l_hip_yaw"] == 10.0
    assert w["r_hip_pitch"] == w["r_knee"] == 0.1
    assert w["r_hip_yaw"] == w["r_hip_roll"] == w["r_ankle_pitch"] == w["r_ankle_roll"] == 10.0
    assert w["l_shoulder_pitch"] == w["r_shoulder_pitch"] == 0.1
    assert w["l_elbow"] == w["r_shoulder_roll"] == 10.0
    m = dict(zip(robot.joint_names, annex_b_weights(robot, "r_sole"), strict=True))
    for name in robot.joint_names:
        other = {"l": "r", "r": "l"}[name[0]] + name[1:]
        assert m[name] == w[other]
    with pytest.raises(ModelError, match="support"):
        annex_b_weights(robot, "torso")


# ------------------------------------------------------------------ sole-rooted coordinates
def test_rooted_increments_keep_the_support_sole_anchored(robot, rng):
    q = robot.configuration("walk_ready")
    root = SoleRooted(robot, "l_sole")
    with pytest.raises(ConfigurationError, match="anchor"):
        root.update(q)
    root.anchor(q)
    sole0 = root.kin.placement(robot.frame_id("l_sole")).copy()
    for _ in range(5):
        q = root.integrate(0.05 * rng.normal(size=robot.n_joints))
        root.update(q)
    sole = root.kin.placement(robot.frame_id("l_sole"))
    np.testing.assert_allclose(sole.translation, sole0.translation, atol=1e-12)
    np.testing.assert_allclose(sole.rotation, sole0.rotation, atol=1e-12)
    assert root.contact_error() < 1e-12


def test_rooted_jacobian_predicts_the_task_motion_relative_to_the_support_sole(robot, rng):
    q = robot.configuration("walk_ready")
    root = SoleRooted(robot, "l_sole")
    root.anchor(q)
    task = FramePositionTask(robot, "r_hand")
    J = root.reduce(task.compute(root.kin)[0])
    dqj = 1e-6 * rng.normal(size=robot.n_joints)
    p0 = root.kin.placement(task.frame_id).translation.copy()
    root.update(root.integrate(dqj))
    p1 = root.kin.placement(task.frame_id).translation
    np.testing.assert_allclose(p1 - p0, J @ dqj, atol=1e-11)


# ------------------------------------------------------------------ principal masses
def test_principal_masses_add_up_to_the_robot(robot):
    pm = PrincipalMasses(robot, "l_sole", "r_sole")
    names = [[robot.joint_names[j] for j in c.joints] for c in pm.chains]
    assert all(n.startswith("l_") and ("hip" in n or "knee" in n or "ankle" in n)
               for n in names[0])  # fmt: skip
    assert all(n.startswith("r_") and ("shoulder" in n or "elbow" in n) for n in names[1])
    assert all(n.startswith("l_") for n in names[2]) and all(n.startswith("r_") for n in names[3])
    assert [len(n) for n in names] == [6, 3, 3, 6]
    assert pm.masses.sum() == pytest.approx(robot.total_mass)
    q = robot.random_configuration(np.random.default_rng(0), margin=0.1)
    kin = Kinematics(robot, q)
    _, J = pm.compute(kin)
    np.testing.assert_allclose(pm.com(), kin.com, atol=1e-12)  # (3.1)
    np.testing.assert_allclose(np.einsum("k,kij->ij", pm.masses, J) / pm.masses.sum(),
                               kin.com_jacobian, atol=1e-12)  # fmt: skip


def test_principal_mass_jacobians_match_finite_differences(robot, rng):
    pm = PrincipalMasses(robot, "r_sole", "l_sole")
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    x0, J = (a.copy() for a in pm.compute(kin))
    dq = 1e-7 * rng.normal(size=robot.nv)
    kin.update(robot.integrate(q, dq))
    x1, _ = pm.compute(kin)
    np.testing.assert_allclose(x1 - x0, J @ dq, atol=1e-12)


def test_principal_masses_need_four_distinct_limbs(robot):
    with pytest.raises(ModelError, match="distinct"):
        PrincipalMasses(robot, "l_sole", "l_sole")


def test_com_mass_matrix_maps_mass_displacements_to_the_com():
    m = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    Jc = com_mass_matrix(m)
    assert Jc.shape == (3, 15)
    dx = np.arange(15.0)
    np.testing.assert_allclose(Jc @ dx, m @ dx.reshape(5, 3) / m.sum())


@given(st.integers(0, 2**32 - 1))
def test_principal_mass_targets_place_the_com(seed):
    rng = np.random.default_rng(seed)
    m = rng.uniform(0.05, 1.0, 5)
    x = rng.normal(size=(5, 3))
    target = rng.normal(size=3)
    targets, iterations = principal_mass_targets(m, x, target)
    np.testing.assert_allclose(m @ targets / m.sum(), target, atol=1e-12)
    assert iterations == 1  # J_c is linear: one step of (3.9) is exact
    moves = np.linalg.norm(targets - x, axis=1)
    np.testing.assert_allclose(moves / m, moves[0] / m[0])  # Δx_k ∝ m_k (minimum norm)
