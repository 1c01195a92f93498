"""Robot data (``robot.toml``): poses, standing pose, feet, frame names; bad input."""

from __future__ import annotations

import pytest

from wbc import load_robot
from wbc.exceptions import ModelError
from wbc.paths import robots_dir
from wbc.robot_data import RobotData

KOKONE = robots_dir() / "kokone"


@pytest.fixture(scope="module")
def kokone():
    return load_robot("kokone")


def test_bioloid_keeps_walk_ready_and_its_feet(robot):
    assert robot.stand_pose == "walk_ready"
    assert robot.foot_size == pytest.approx((0.101, 0.061))
    assert (robot.configuration("stand") == robot.configuration("walk_ready")).all()


def test_robot_data_bad_input(tmp_path, kokone):
    robot_file, poses_file = tmp_path / "robot.toml", tmp_path / "poses.toml"
    poses_file.write_text("[poses.crouch]\nl_knee = 0.5\n")
    robot_file.write_text('stand = "sit"\n')
    with pytest.raises(ModelError, match=r"stand = 'sit' is not 'zero' or a pose of poses.toml"):
        RobotData.from_folder(tmp_path, kokone.joint_names)
    robot_file.write_text("[feet]\nlength = 7\n")
    with pytest.raises(ModelError, match=r"\[feet\] length = 7: must be in \(0, 1\) m"):
        RobotData.from_folder(tmp_path, kokone.joint_names)
    robot_file.write_text("[feat]\nlength = 0.1\n")
    with pytest.raises(ModelError, match=r"unknown keys \['feat'\]; allowed: balance, feet, fr"):
        RobotData.from_folder(tmp_path, kokone.joint_names)
    for text, message in (
        ("[balance]\nstepping = 0.04\n", r"\[balance\] holds tables: stepping"),
        ("[balance.steping]\nband_x = 0.04\n", r"unknown table \[balance.steping\]; allowed"),
        ("[balance.stepping]\nband = 0.04\n", r"\[balance.stepping\] has unknown keys \['band'\]"),
        (
            "[balance.stepping]\nband_x = 2\n",
            r"\[balance.stepping\] band_x = 2: must be in \[0, 1\) m",
        ),
        (
            "[balance.stepping]\ntrigger_jump = -0.1\n",
            r"\[balance.stepping\] trigger_jump = -0.1: must be in \[0, 1\) m",
        ),
        ("[walking]\nfit_torque = 1\n", r"\[walking\] fit_torque = 1: true or false"),
    ):
        robot_file.write_text(text)
        with pytest.raises(ModelError, match=message):
            RobotData.from_folder(tmp_path, kokone.joint_names)
    robot_file.write_text("[balance.stepping]\nband_y = 0.03\ntrigger_jump = 0.02\n")
    assert RobotData.from_folder(tmp_path, kokone.joint_names).balance == {
        "stepping": {"band_y": 0.03, "trigger_jump": 0.02}
    }
    robot_file.unlink()
    poses_file.write_text("[poses.x]\nl_kne = 0.1\n")
    with pytest.raises(ModelError, match=r"pose 'x' names unknown joints \['l_kne'\]"):
        RobotData.from_folder(tmp_path, kokone.joint_names)
    poses_file.write_text('[poses.x]\nl_knee = "bent"\n')
    with pytest.raises(ModelError, match=r"pose 'x' l_knee = 'bent': not a number"):
        RobotData.from_folder(tmp_path, kokone.joint_names)


def test_frame_names_map_through_robot_data(tmp_path, kokone):
    """A URDF whose frames are named otherwise works through ``[frames]`` of robot.toml, next
    to the standing pose and the feet of the same file."""
    import shutil

    folder = tmp_path / "kokone2"
    folder.mkdir()
    shutil.copy(KOKONE / "kokone.urdf", folder / "kokone2.urdf")
    (folder / "robot.toml").write_text('[frames]\ntorso = "l_hand"\n[feet]\nwidth = 0.03\n')
    r = load_robot(folder)
    assert r.frame_id("torso") == kokone.frame_id("l_hand")
    assert r.stand_pose == "zero"  # no servo map, no stand: the zero pose, not Walk Ready
    assert r.foot_size[1] == 0.03
    (folder / "robot.toml").write_text('[frames]\ntorso = "pelvis"\n')
    with pytest.raises(ModelError, match=r"'torso' is mapped to 'pelvis', which is not a frame"):
        load_robot(folder)


def test_servo_and_imu_tables_are_checked(tmp_path, kokone):
    """``[servo]`` / ``[imu]``: tables, checked by ``wbc robot check`` in one line each."""
    import shutil

    from wbc.robot_folder import check_folder

    folder = tmp_path / "kokone"
    shutil.copytree(KOKONE, folder)
    text = (folder / "robot.toml").read_text()
    assert kokone.robot_data.servo["law"] == "hobby_pwm" and kokone.robot_data.imu == {}
    ok = [f.message for f in check_folder(folder) if "simulator" in f.message]
    assert ok == ["simulator: Blue-Bird BMS-380MAX servos on every joint, IMU at 'torso'"]
    (folder / "robot.toml").write_text('servo = "bms380"\n' + text.split("[feet]")[0])
    with pytest.raises(ModelError, match=r"\[servo\] must be a table"):
        RobotData.from_folder(folder, kokone.joint_names)
    bad = {
        'law = "hobby_pwm"': 'law = "stepper"',
        "proportional_band_us = 40.0": "proportional_band_us = 0.0",
    }
    for old, new in bad.items():
        (folder / "robot.toml").write_text(text.replace(old, new))
        errors = [f.message for f in check_folder(folder) if f.level == "error"]
        assert len(errors) == 1 and "[servo]" in errors[0], errors
    (folder / "robot.toml").write_text(text + '\n[imu]\nframe = "nowhere"\n')
    errors = [f.message for f in check_folder(folder) if f.level == "error"]
    assert len(errors) == 1 and "[imu]: frame = 'nowhere'" in errors[0]


def _bioloid_without_left_sole_box(folder, toml: str = ""):
    """The Bioloid's URDF with no collision box on the left foot, and ``toml`` as robot.toml."""
    import re

    text = (robots_dir() / "bioloid" / "bioloid.urdf").read_text()
    start = text.index('<link name="l_foot"')
    end = text.index("</link>", start)
    foot = re.sub(r"<collision>.*?</collision>", "", text[start:end], flags=re.S)
    folder.mkdir()
    (folder / f"{folder.name}.urdf").write_text(text[:start] + foot + text[end:])
    if toml:
        (folder / "robot.toml").write_text(toml)
    return folder


def test_a_sole_without_a_box_is_refused_naming_what_to_add(tmp_path):
    """No Bioloid fallback: a robot's foot is its sole link's collision box or robot.toml
    [feet]; with neither, one line says what to add (and the walks say the same)."""
    from wbc.bench.trajectories import build

    robot = load_robot(_bioloid_without_left_sole_box(tmp_path / "boxless"))
    with pytest.raises(ModelError, match=r"no collision box at the sole; state \[feet\]") as exc:
        _ = robot.foot_size
    assert "\n" not in str(exc.value)
    with pytest.raises(ModelError, match=r"state \[feet\] length and width in robot.toml"):
        build("walk10", robot)
    # half a [feet] table is not enough: the other half would come from the missing box
    half = load_robot(_bioloid_without_left_sole_box(tmp_path / "half", "[feet]\nwidth = 0.05\n"))
    with pytest.raises(ModelError, match="no collision box at the sole"):
        _ = half.foot_size
    stated = "[feet]\nlength = 0.09\nwidth = 0.05\n"
    assert load_robot(_bioloid_without_left_sole_box(tmp_path / "fed", stated)).foot_size == (
        0.09,
        0.05,
    )
