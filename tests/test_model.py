"""Model layer: loading, Jacobians against finite differences, Walk Ready, bad input."""

from __future__ import annotations

import gc

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc import ConfigurationError, Kinematics, ModelError, ServoMapError, load_robot

FRAMES = ["torso", "l_sole", "r_sole", "l_hand", "r_hand"]


def random_q(robot, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    q[:3] = rng.uniform(-0.2, 0.2, 3)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-1, 1, 3))).coeffs()
    return q


def test_model_basics(robot):
    assert robot.n_joints == 18
    assert robot.nq == 25 and robot.nv == 24
    assert 1.7 <= robot.total_mass <= 2.1
    assert len(set(robot.joint_names)) == 18
    for side in "lr":
        for j in (
            "hip_yaw",
            "hip_roll",
            "hip_pitch",
            "knee",
            "ankle_pitch",
            "ankle_roll",
            "shoulder_pitch",
            "shoulder_roll",
            "elbow",
        ):
            assert f"{side}_{j}" in robot.joint_names
    for f in FRAMES:
        robot.frame_id(f)
    assert np.all(robot.q_min < robot.q_max)
    # AX-12A: 59 rpm no-load speed at 12 V, 1.5 N·m stall torque
    assert np.allclose(robot.v_max, 59 * 2 * np.pi / 60, rtol=1e-6)
    assert np.allclose(robot.model.effortLimit[6:], 1.5)


def test_servo_map_order_matches_model(robot):
    assert robot.servo_map is not None
    assert robot.servo_map.joint_names == robot.joint_names
    assert sorted(robot.servo_map.ids) == list(range(1, 19))


@given(seed=st.integers(0, 2**31 - 1), frame=st.sampled_from(FRAMES))
def test_frame_jacobian_matches_finite_differences(robot, seed, frame):
    q = random_q(robot, seed)
    J = robot.frame_jacobian(q, frame)  # local-world-aligned: [v_origin (world); omega (world)]
    M0 = robot.frame_placement(q, frame)
    eps = 1e-6
    J_fd = np.zeros_like(J)
    for i in range(robot.nv):
        dq = np.zeros(robot.nv)
        dq[i] = eps
        M1 = robot.frame_placement(robot.integrate(q, dq), frame)
        J_fd[:3, i] = (M1.translation - M0.translation) / eps
        J_fd[3:, i] = pin.log3(M1.rotation @ M0.rotation.T) / eps
    assert np.allclose(J, J_fd, atol=1e-5)


@given(seed=st.integers(0, 2**31 - 1))
def test_com_jacobian_matches_finite_differences(robot, seed):
    q = random_q(robot, seed)
    J = robot.com_jacobian(q)
    c0 = robot.com(q)
    eps = 1e-6
    J_fd = np.column_stack(
        [(robot.com(robot.integrate(q, eps * e)) - c0) / eps for e in np.eye(robot.nv)]
    )
    assert np.allclose(J, J_fd, atol=1e-5)


def test_kinematics_cache_equals_one_off_calls(robot, rng):
    q = random_q(robot, 7)
    kin = Kinematics(robot, q)
    for f in FRAMES:
        fid = robot.frame_id(f)
        assert np.allclose(kin.placement(fid).homogeneous, robot.frame_placement(q, f).homogeneous)
        assert np.allclose(kin.frame_jacobian(fid), robot.frame_jacobian(q, f))
    assert np.allclose(kin.com, robot.com(q))
    assert np.allclose(kin.com_jacobian, robot.com_jacobian(q))


def test_kinematics_update_fills_what_joint_jacobians_would(robot):
    """update's one pass (jacobianCenterOfMass with q) gives the joints' placements and
    Jacobians of computeJointJacobians bitwise (what frame Jacobians, collision geometry and
    the compiled tick read), the frames of updateFramePlacements and the CoM and its Jacobian
    of jacobianCenterOfMass after them."""
    import pinocchio as pin

    kin = Kinematics(robot, random_q(robot, 1))
    kin.data.J[:] = np.nan  # stale values would survive a pass that does not write J
    for seed in (8, 9):
        q = random_q(robot, seed)
        kin.update(q)
        data = robot.model.createData()
        pin.computeJointJacobians(robot.model, data, q)
        pin.updateFramePlacements(robot.model, data)
        pin.jacobianCenterOfMass(robot.model, data, False)
        assert np.array_equal(kin.data.J, data.J)
        for a, b in [
            *zip(kin.data.oMi, data.oMi, strict=True),
            *zip(kin.data.oMf, data.oMf, strict=True),
        ]:
            assert np.array_equal(a.homogeneous, b.homogeneous)
        assert np.array_equal(kin.com, data.com[0])
        assert np.array_equal(kin.com_jacobian, data.Jcom)


def test_frame_placements_are_views_that_follow_updates(robot):
    kin = Kinematics(robot, random_q(robot, 3))
    views = kin.frame_placements()
    assert views is not None  # this Pinocchio's layout (else the compiled tick copies them)
    R, p = views
    for seed in (4, 5):
        kin.update(random_q(robot, seed))
        for fid in range(robot.model.nframes):
            assert np.array_equal(R[fid], kin.placement(fid).rotation)
            assert np.array_equal(p[fid], kin.placement(fid).translation)


def test_walk_ready_stands_flat_and_parallel(robot):
    q = robot.configuration("walk_ready")
    assert robot.within_limits(q)
    left = robot.frame_placement(q, "l_sole")
    right = robot.frame_placement(q, "r_sole")
    z = np.array([0, 0, 1.0])
    # flat: both sole normals vertical within one servo tick (0.29 deg)
    for sole in (left, right):
        assert np.degrees(np.arccos(sole.rotation[:, 2] @ z)) < 0.35
        assert abs(sole.translation[2]) < 0.5e-3
    # parallel: the official ticks leave 0.29 deg of pitch (the mirrored pitch ticks differ
    # by one) and ~0.2 deg of toe-in per foot (hip roll x torso pitch coupling)
    assert np.degrees(np.linalg.norm(pin.log3(left.rotation.T @ right.rotation))) < 0.75
    # feet about 77 mm apart laterally (hip spacing 77 mm; Walk Ready rolls each leg ~1.3 deg out)
    lateral = left.translation[1] - right.translation[1]
    assert 70e-3 < lateral < 85e-3
    assert abs(left.translation[0] - right.translation[0]) < 2e-3
    # torso leaning about 10 degrees forward
    torso = robot.frame_placement(q, "torso")
    pitch = np.degrees(np.arctan2(torso.rotation[0, 2], torso.rotation[2, 2]))
    assert 8.0 < pitch < 12.0
    # CoM above the support polygon (convex hull of the two 101 x 61 mm feet)
    com = robot.com(q)
    assert -50.5e-3 < com[0] < 50.5e-3
    assert right.translation[1] - 30.5e-3 < com[1] < left.translation[1] + 30.5e-3


def test_place_on_ground_puts_sole_flat_at_zero(robot):
    q = random_q(robot, 3)
    for sole in ("l_sole", "r_sole"):
        qg = robot.place_on_ground(q, sole)
        M = robot.frame_placement(qg, sole)
        assert abs(M.translation[2]) < 1e-12
        assert np.allclose(M.rotation[:, 2], [0, 0, 1], atol=1e-12)
        # joints untouched
        assert np.array_equal(qg[7:], q[7:])


def test_zero_configuration_is_straight_and_within_limits(robot):
    q = robot.configuration("zero")
    assert robot.within_limits(q)
    left = robot.frame_placement(q, "l_sole")
    torso = robot.frame_placement(q, "torso")
    assert np.allclose(torso.rotation, np.eye(3))
    assert np.allclose(left.rotation, np.eye(3))
    # legs straight: the sole lies right under the hip (293.7 mm below the shoulder axis)
    assert torso.translation[2] == pytest.approx(0.2937, abs=1e-9)


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros(24), "size nq=25"),
        (np.r_[np.zeros(6), 1.0, np.full(18, np.nan)], "non-finite"),
    ],
)
def test_bad_configuration_is_rejected(robot, bad, match):
    with pytest.raises(ConfigurationError, match=match):
        robot.com(bad)


def test_unknown_names_are_rejected(robot):
    q = robot.neutral()
    with pytest.raises(ModelError, match="unknown frame 'l_foot_tip'"):
        robot.frame_placement(q, "l_foot_tip")
    with pytest.raises(ModelError, match="unknown joint 'l_wrist'"):
        robot.joint_index("l_wrist")
    with pytest.raises(ModelError, match="unknown configuration"):
        robot.configuration("crouch")
    with pytest.raises(ModelError, match="unknown robot"):
        load_robot("nao")


def test_missing_and_malformed_urdf(tmp_path):
    with pytest.raises(ModelError, match="URDF not found"):
        load_robot(tmp_path / "missing.urdf")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot")
    with pytest.raises(ModelError, match="malformed URDF"):
        load_robot(bad)


def test_servo_map_inconsistent_with_urdf(tmp_path, robot):
    urdf = tmp_path / "bioloid.urdf"
    urdf.write_text(robot.urdf_path.read_text())
    text = (robot.urdf_path.parent / "servos.toml").read_text()
    (tmp_path / "servos.toml").write_text(text.replace("r_elbow  ", "r_wrist  "))
    with pytest.raises(ServoMapError, match="missing joints \\['r_elbow'\\]"):
        load_robot(urdf)


def test_com_of_a_temporary_kinematics_stays_valid():
    robot = load_robot("bioloid")
    q = robot.configuration("walk_ready")
    c = Kinematics(robot, q).com
    gc.collect()
    junk = [np.random.default_rng(0).random(1000) for _ in range(50)]  # reuse freed memory
    assert np.allclose(c, robot.com(q), atol=1e-12), (c, robot.com(q))
    del junk


def test_placements_in_a_frame_are_the_frames_placements_relative_to_it(robot):
    """One forward kinematics pass gives each frame's placement in the base frame: the same
    numbers as the one-off placements, related (bit for bit)."""
    q = robot.configuration("walk_ready")
    q[7:] += np.linspace(-0.1, 0.1, robot.n_joints)
    torso, l_sole = robot.placements_in(q, "r_sole", ["torso", "l_sole"])
    base = robot.frame_placement(q, "r_sole")
    for got, frame in ((torso, "torso"), (l_sole, "l_sole")):
        assert np.array_equal(
            got.homogeneous, base.actInv(robot.frame_placement(q, frame)).homogeneous
        )
    assert not np.allclose(l_sole.translation, 0.0)
