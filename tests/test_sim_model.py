"""The MuJoCo model built from the URDF sees the same robot as pinocchio (the Bioloid and
Kokone: nothing in the model building is Bioloid-specific)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("mujoco")

from wbc import load_robot
from wbc.sim.model import ModelParams, build_model, build_spec, link_names
from wbc.sim.simulator import Simulation


@pytest.fixture(scope="module", params=["bioloid", "kokone"])
def robot(request):
    return load_robot(request.param)


@pytest.fixture(scope="module")
def mj_model(robot):
    return build_model(robot)


def _body_of_joint(robot, mj, m, joint: int) -> int:
    """MuJoCo body moved by pinocchio joint ``joint`` (1 = the free flyer = root link)."""
    import mujoco

    if joint == 1:
        return int(m.jnt_bodyid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "base")])
    name = robot.model.names[joint]
    return int(m.jnt_bodyid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)])


def test_masses_coms_and_inertias_equal_pinocchios(robot, mj_model):
    m = mj_model
    assert m.body_mass.sum() == pytest.approx(robot.total_mass, abs=1e-9)
    for joint in range(1, robot.model.njoints):
        b = _body_of_joint(robot, None, m, joint)
        inertia = robot.model.inertias[joint]
        assert m.body_mass[b] == pytest.approx(inertia.mass, abs=1e-12), robot.model.names[joint]
        np.testing.assert_allclose(m.body_ipos[b], inertia.lever, atol=1e-12)
        R = pin.Quaternion(*m.body_iquat[b]).toRotationMatrix()  # (w, x, y, z)
        full = R @ np.diag(m.body_inertia[b]) @ R.T  # MuJoCo keeps principal axes
        np.testing.assert_allclose(full, inertia.inertia, atol=1e-10)


def test_collision_boxes_equal_pinocchios(robot, mj_model):
    import mujoco

    m = mj_model
    geoms = pin.buildGeomFromUrdf(robot.model, str(robot.urdf_path), pin.GeometryType.COLLISION)
    ours = sorted(
        (int(_body_of_joint(robot, None, m, g.parentJoint)), *np.round(g.geometry.halfSide, 6),
         *np.round(g.placement.translation, 6))
        for g in geoms.geometryObjects
    )  # fmt: skip
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    theirs = sorted(
        (int(m.geom_bodyid[k]), *np.round(m.geom_size[k], 6), *np.round(m.geom_pos[k], 6))
        for k in range(m.ngeom)
        if k != floor
    )
    assert all(m.geom_type[k] == mujoco.mjtGeom.mjGEOM_BOX for k in range(m.ngeom) if k != floor)
    assert ours == theirs
    assert len(ours) == geoms.ngeoms  # visual geoms were discarded, none added


def test_frames_agree_with_pinocchio_at_random_configurations(robot, rng):
    sim = Simulation(robot)
    for _ in range(3):
        q = robot.random_configuration(rng)
        q[:3] = rng.uniform(-0.1, 0.1, 3) + [0, 0, 1.0]
        q[3:7] = pin.Quaternion(pin.exp3(rng.normal(0, 0.5, 3))).coeffs()
        sim.reset(q)
        np.testing.assert_allclose(sim.q(), q, atol=1e-12)
        for frame in ("torso", "l_sole", "r_sole", "l_hand", "r_hand"):
            M = robot.frame_placement(q, frame)
            S = sim.site_pose(frame)
            np.testing.assert_allclose(S.translation, M.translation, atol=1e-9)
            np.testing.assert_allclose(S.rotation, M.rotation, atol=1e-9)
        np.testing.assert_allclose(sim.com(), robot.com(q), atol=1e-9)
        # the IMU sits at the torso frame (robot.toml [imu] default), axes aligned with it
        imu, T = sim.site_pose("imu"), robot.frame_placement(q, "torso")
        np.testing.assert_allclose(imu.translation, T.translation, atol=1e-9)
        np.testing.assert_allclose(imu.rotation, T.rotation, atol=1e-9)


def test_joint_properties_are_the_robots_servos(robot, mj_model):
    """Armature, back-EMF damping (stall / no-load speed) and gear friction of every joint
    come from the robot's servo model: the AX-12A's, or Kokone's BMS-380MAX."""
    from wbc.sim.actuator import nominal_servo

    servo = nominal_servo(robot)
    sim = Simulation(robot)
    np.testing.assert_allclose(mj_model.dof_armature[sim.vadr], servo.armature)
    np.testing.assert_allclose(mj_model.dof_frictionloss[sim.vadr], servo.friction_loss)
    np.testing.assert_allclose(sim.damping, servo.damping)
    expected = 1.5 / (59 * 2 * np.pi / 60) if robot.name == "bioloid" else 0.412 / 6.545
    assert servo.damping == pytest.approx(expected, rel=1e-3)


def test_randomised_masses_and_coms(robot):
    import mujoco

    names = link_names(build_spec(robot))
    assert len(names) == robot.model.njoints - 1  # one massive link per pinocchio joint
    n = len(names)
    scale = np.linspace(0.9, 1.1, n)
    offset = np.zeros((n, 3))
    offset[0] = [0.003, 0.0, -0.002]
    m = build_model(robot, ModelParams(mass_scale=scale, com_offset=offset))
    nominal = build_model(robot)
    for k, name in enumerate(names):
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        assert m.body_mass[b] == pytest.approx(nominal.body_mass[b] * scale[k])
        np.testing.assert_allclose(m.body_inertia[b], nominal.body_inertia[b] * scale[k])
        np.testing.assert_allclose(m.body_ipos[b], nominal.body_ipos[b] + offset[k], atol=1e-15)


def test_missing_mujoco_is_one_clear_line(monkeypatch):
    import builtins

    from wbc.exceptions import ConfigurationError
    from wbc.sim import mujoco_module

    real_import = builtins.__import__

    def fake(name, *args, **kwargs):
        if name == "mujoco":
            raise ModuleNotFoundError("No module named 'mujoco'", name="mujoco")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake)
    with pytest.raises(ConfigurationError, match=r"pip install 'wbc\[physics\]'"):
        mujoco_module()


def test_imu_placement_comes_from_robot_data(tmp_path):
    """``robot.toml`` ``[imu]``: the IMU site at a frame plus an offset in that frame."""
    import shutil

    from wbc.paths import robots_dir

    folder = tmp_path / "kokone"
    shutil.copytree(robots_dir() / "kokone", folder)
    with open(folder / "robot.toml", "a") as f:
        f.write('\n[imu]\nframe = "l_hand"\noffset = [0.01, -0.02, 0.03]\n')
    robot = load_robot(folder)
    sim = Simulation(robot)
    q = sim.q()
    expected = robot.frame_placement(q, "l_hand").act(np.array([0.01, -0.02, 0.03]))
    np.testing.assert_allclose(sim.site_pose("imu").translation, expected, atol=1e-9)
    np.testing.assert_allclose(
        sim.site_pose("imu").rotation, robot.frame_placement(q, "l_hand").rotation, atol=1e-9
    )


def test_contact_options_reach_the_model():
    import mujoco

    robot = load_robot("bioloid")
    m = build_model(robot)  # MuJoCo's defaults unless asked
    assert m.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert m.opt.impratio == 1.0 and m.opt.noslip_iterations == 0
    m = build_model(
        robot, ModelParams(friction_cone="elliptic", impratio=10.0, noslip_iterations=3)
    )
    assert m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert m.opt.impratio == 10.0 and m.opt.noslip_iterations == 3


def test_the_floors_condim_reaches_the_model():
    """3 (MuJoCo's default) unless asked; 4: the floor's contacts get torsional friction."""
    import mujoco

    robot = load_robot("bioloid")
    floor = lambda m: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")  # noqa: E731
    m = build_model(robot)
    assert m.geom_condim[floor(m)] == 3
    m = build_model(robot, ModelParams(condim=4))
    assert m.geom_condim[floor(m)] == 4


@pytest.mark.parametrize(
    "bad, match",
    [({"friction_cone": "round"}, "friction_cone"), ({"impratio": 0.0}, "impratio"),
     ({"noslip_iterations": -1}, "noslip_iterations"), ({"condim": 2}, "condim")],
)  # fmt: skip
def test_bad_contact_options_are_one_clear_line(bad, match):
    from wbc.exceptions import ModelError

    with pytest.raises(ModelError, match=match):
        build_model(load_robot("bioloid"), ModelParams(**bad))


def _creep_mm(params: ModelParams, heading_deg: float = 0.0) -> float:
    """How far the standing Bioloid's soles slide in 3 s with its base pushed horizontally
    at 0.1 of its weight (friction used ~0.1 of the floor's 0.8: dry friction sticks)."""
    robot = load_robot("bioloid")
    sim = Simulation(robot, params)
    sim.set_torque(True)
    sim.advance(1.0)
    w = float(sim.model.body_subtreemass[sim.root]) * 9.81
    a = np.radians(heading_deg)
    before = [sim.site_pose(s).translation[:2].copy() for s in ("l_sole", "r_sole")]
    sim.push([0.1 * w * np.cos(a), 0.1 * w * np.sin(a), 0.0], 3.0)
    sim.advance(3.0)
    after = [sim.site_pose(s).translation[:2] for s in ("l_sole", "r_sole")]
    moved = [b - a for a, b in zip(before, after, strict=True)]
    return 1e3 * float(np.linalg.norm(np.mean(moved, axis=0)))


def test_stiff_friction_stops_the_soft_contacts_creep():
    """MuJoCo's soft friction lets a sole pushed well inside the friction cone creep (~1.3
    mm/s on the Bioloid with the defaults: what drifted the driven walks' leg odometry,
    benchmarks/drive.md); the elliptic cone with impratio 100 or the noslip pass stop it."""
    assert _creep_mm(ModelParams()) > 2.0
    assert _creep_mm(ModelParams(friction_cone="elliptic", impratio=100.0), 45.0) < 0.1
    assert _creep_mm(ModelParams(noslip_iterations=10)) < 0.1
