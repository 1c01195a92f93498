"""Robot folders: a bare URDF works, ``wbc robot init`` scaffolds, ``wbc robot check`` finds."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest

from wbc import ModelError, load_robot
from wbc.cli import main
from wbc.paths import robots_dir
from wbc.robot_folder import check_folder

BIOLOID_URDF = robots_dir() / "bioloid" / "bioloid.urdf"


@pytest.fixture()
def bare_urdf(tmp_path):
    path = tmp_path / "src" / "my.urdf"
    path.parent.mkdir()
    shutil.copyfile(BIOLOID_URDF, path)
    return path


def _levels(findings, level):
    return [f.message for f in findings if f.level == level]


def test_a_bare_urdf_stands_in_the_zero_pose_with_one_note_per_missing_part(robot, bare_urdf):
    bare = load_robot(bare_urdf)
    assert bare.servo_map is None and bare.poses == {} and bare.default_stack is None
    assert len(bare.notes) == 2
    assert "servos.toml missing" in bare.notes[0] and "zero pose" in bare.notes[1]
    q = bare.configuration("walk_ready")
    np.testing.assert_array_equal(q[7:], 0.0)
    np.testing.assert_allclose(q, robot.configuration("zero"), atol=1e-12)
    with pytest.raises(ModelError, match="unknown configuration 'crouch'"):
        bare.configuration("crouch")
    # the complete Bioloid folder has nothing to note
    assert robot.notes == []


def test_init_scaffolds_a_folder_that_checks_clean_and_loads(bare_urdf, tmp_path, capsys):
    out = tmp_path / "my_robot"
    assert main(["robot", "init", str(bare_urdf), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    for name in ("my_robot.urdf", "servos.toml", "poses.toml", "stack.toml", "README.md"):
        assert (out / name).is_file(), name
        assert str(out / name) in printed
    assert (out / "my_robot.urdf").read_bytes() == bare_urdf.read_bytes()
    # the servo template is inert: commented out, so no servo map (deploy refuses)
    assert all(
        line.startswith("#") or not line.strip()
        for line in (out / "servos.toml").read_text().splitlines()
    )
    robot = load_robot(out)
    assert robot.servo_map is None and robot.default_stack == out / "stack.toml"
    assert set(robot.poses) == {"walk_ready"}
    assert robot.within_limits(robot.configuration("walk_ready"))
    assert any("unfilled template" in n for n in robot.notes)
    assert not any("zero pose" in n for n in robot.notes)  # poses.toml defines walk_ready
    findings = check_folder(out)
    assert _levels(findings, "error") == [] and _levels(findings, "warning") == []
    assert any("frames torso, l_sole, r_sole present" in m for m in _levels(findings, "ok"))
    assert any("stack.toml" in m for m in _levels(findings, "ok"))
    # the folder works with the tools
    assert main(["demo", "--robot", str(out)]) == 0
    assert "mass 1.9144 kg" in capsys.readouterr().out
    # and init refuses to overwrite it
    assert main(["robot", "init", str(bare_urdf), "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err


def test_check_bioloid_has_no_errors(capsys):
    assert main(["robot", "check", "bioloid"]) == 0
    out = capsys.readouterr().out
    assert "servo map" in out and "total mass 1.9144 kg" in out
    assert out.rstrip().endswith("0 error(s), 0 warning(s)")


def _break(urdf_text: str) -> str:
    # l_knee: lower > upper; r_knee: no velocity; l_elbow: effort 0
    text = re.sub(
        r'(<joint name="l_knee".*?<limit )lower="[^"]*" upper="[^"]*"',
        r'\1lower="1.0" upper="-1.0"',
        urdf_text,
        flags=re.S,
    )
    text = re.sub(r'(<joint name="r_knee".*?velocity=)"[^"]*"', r'\1"0"', text, flags=re.S)
    text = re.sub(r'(<joint name="l_elbow".*?effort=)"[^"]*"', r'\1"0"', text, flags=re.S)
    # rename the right sole: a frame the stacks need goes missing
    return text.replace('"r_sole"', '"r_foot_plate"')


def test_check_a_broken_folder_names_every_problem(bare_urdf, tmp_path, capsys):
    folder = tmp_path / "broken"
    folder.mkdir()
    (folder / "broken.urdf").write_text(_break(bare_urdf.read_text()))
    servo = (robots_dir() / "bioloid" / "servos.toml").read_text()
    (folder / "servos.toml").write_text(servo.replace("l_elbow ", "l_elbow_x "))
    findings = check_folder(folder)
    errors = _levels(findings, "error")
    # the servo map does not match: the robot cannot even load, and check says why
    assert len(errors) == 1 and "does not match the robot model" in errors[0]
    assert "l_elbow_x" in errors[0]

    (folder / "servos.toml").unlink()
    (folder / "poses.toml").write_text("[poses.walk_ready]\nl_knee = 3.0\n")
    assert main(["robot", "check", str(folder)]) == 1
    out = capsys.readouterr().out
    assert "joint l_knee: lower limit 1 >= upper -1 rad" in out
    assert "joint r_knee: velocity limit 0 rad/s" in out
    assert "joint l_elbow: effort limit 0 N·m" in out
    assert "frames ['r_sole'] missing" in out and "r_foot_plate" in out
    assert "pose 'walk_ready' is outside the joint limits at ['l_knee']" in out
    assert re.search(r"^note +.*servos.toml is missing", out, flags=re.M)
    # its standing pose (the knee at 3 rad) folds the shin into the thigh: boxes overlap
    warnings = re.findall(r"^warning +(.*)$", out, flags=re.M)
    assert warnings and all(re.match(r"self-collision: .* boxes overlap", w) for w in warnings)
    assert out.rstrip().endswith(f"5 error(s), {len(warnings)} warning(s)")


def test_robot_toml_maps_standard_frame_names(bare_urdf, tmp_path):
    folder = tmp_path / "renamed"
    folder.mkdir()
    (folder / "renamed.urdf").write_text(bare_urdf.read_text().replace('"l_sole"', '"left_sole"'))
    assert any("['l_sole']" in n for n in load_robot(folder).notes)
    (folder / "robot.toml").write_text('[frames]\nl_sole = "left_sole"\n')
    robot = load_robot(folder)
    assert robot.frame_id("l_sole") == robot.model.getFrameId("left_sole")
    assert not any("frames" in n for n in robot.notes)
    (folder / "robot.toml").write_text('[frames]\nl_sole = "nowhere"\n')
    with pytest.raises(ModelError, match="mapped to 'nowhere'"):
        load_robot(folder)
    (folder / "robot.toml").write_text('[frames]\nleft = "left_sole"\n')
    with pytest.raises(ModelError, match=r"robot.toml: \[frames\] has unknown keys \['left'\]"):
        load_robot(folder)


@pytest.mark.parametrize(
    "text, match",
    [
        ("[poses.p]\nl_kneee = 0.1\n", "names unknown joint 'l_kneee'"),
        ('[poses.p]\nl_knee = "bent"\n', r"l_knee = 'bent': must be a number \(rad\)"),
        ("[poses]\np = 1\n", r"\[poses.p\] must be a table"),
        ("[stance]\n", r"unknown keys \['stance'\]"),
    ],
)
def test_bad_poses_file_names_file_and_key(bare_urdf, text, match):
    (bare_urdf.parent / "poses.toml").write_text(text)
    with pytest.raises(ModelError, match=match) as exc:
        load_robot(bare_urdf)
    assert "poses.toml" in str(exc.value)


def test_check_reports_a_massless_body_and_the_total(bare_urdf, robot):
    text = bare_urdf.read_text()
    text = re.sub(
        r'(<link name="l_forearm">.*?<mass value=)"[^"]*"(/>\s*<inertia )[^/]*/>',
        r'\1"0"\2ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>',
        text,
        count=1,
        flags=re.S,
    )
    bare_urdf.write_text(text)
    light = load_robot(bare_urdf)
    findings = check_folder(bare_urdf)
    (warning,) = _levels(findings, "warning")
    assert "body of joint l_elbow: massless" in warning
    assert any(f"total mass {light.total_mass:.4f} kg" in m for m in _levels(findings, "ok"))
    assert light.total_mass == pytest.approx(robot.total_mass - 0.0767, abs=1e-9)


def test_check_lists_the_self_collision_pairs_left_out_and_warns_of_overlaps(bare_urdf):
    """`wbc robot check` says how many pairs the self-collision limit checks, lists the link
    pairs adjacent through a zero-length link (a Bioloid's shin and foot, through the ankle
    pitch), and warns about boxes that overlap at the standing pose (here the soles made 4 cm
    wider, into each other at the zero pose of a bare URDF): left out, not silently pushed
    apart by hard rows."""
    findings = check_folder(robots_dir() / "bioloid")
    checked = re.compile(r"self-collision: \d+ pairs of collision boxes checked")
    assert any(checked.match(m) for m in _levels(findings, "ok"))
    shin_foot = "l_shin / l_foot not checked: adjacent through the zero-length link of l_ankle"
    assert any(shin_foot in m for m in _levels(findings, "note"))
    assert not [m for m in _levels(findings, "warning") if "self-collision" in m]
    text = bare_urdf.read_text()
    sole = '<box size="0.101 0.061 0.009"/>'
    assert text.count(sole) == 4  # (visual and collision, each foot)
    bare_urdf.write_text(text.replace(sole, '<box size="0.101 0.101 0.009"/>'))
    warnings = [m for m in _levels(check_folder(bare_urdf), "warning") if "self-collision" in m]
    overlap = re.compile(
        r"self-collision: l_foot / r_foot not checked: boxes overlap by \d+\.\d mm at the "
        r"standing pose"
    )
    assert any(overlap.match(m) for m in warnings), warnings


def test_init_proposes_a_standing_pose(bare_urdf, tmp_path):
    """Soles flat where they are at the zero pose, torso upright, hips lowered until
    hip-to-ankle is STAND_HEIGHT_FRACTION of the leg length, knees bent forward."""
    import numpy as np

    from wbc.robot_folder import STAND_HEIGHT_FRACTION, standing_pose

    out = tmp_path / "my_robot"
    assert main(["robot", "init", str(bare_urdf), "--out", str(out)]) == 0
    assert "Proposed by `wbc robot init`" in (out / "poses.toml").read_text()
    robot = load_robot(out)
    q = robot.configuration("walk_ready")
    zero = robot.configuration("zero")
    for sole in ("l_sole", "r_sole"):
        placed = robot.frame_placement(q, sole)
        assert abs(placed.translation[2]) < 1e-6 and np.allclose(
            placed.rotation, np.eye(3), atol=1e-5
        )
    knee = robot.joint_index(robot.roles.joint("left", "knee"))
    assert q[7 + knee] > 0.3  # bent, the way the Bioloid's knee flexes
    drop = (
        robot.frame_placement(zero, "torso").translation[2]
        - robot.frame_placement(q, "torso").translation[2]
    )
    legs = 0.07639 + 0.07247  # the Bioloid's hip-to-ankle (robots/bioloid/robot.toml [legs])
    assert drop == pytest.approx((1 - STAND_HEIGHT_FRACTION) * legs, abs=2e-4)
    assert np.allclose(standing_pose(robot), robot.joints(q), atol=1e-5)
