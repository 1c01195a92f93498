"""Servo map: exact tick <-> angle round trips, Walk Ready = Annex A, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc import ServoMap, ServoMapError, ServoSpec, load_robot
from wbc.servo_map import DEG_PER_TICK, ServoSettings

# Annex A start pose of the thesis (servo degrees from tick 512), by Robotis ID (facts §8)
ANNEX_A_START = {
    1: -81.15,
    3: -68.26,
    5: -14.65,
    2: 80.86,
    4: 67.97,
    6: -14.65,
    7: -45.12,
    9: -1.46,
    11: -50.01,
    13: -79.69,
    15: 39.55,
    17: -1.46,
    8: 45.8,
    10: 1.17,
    12: 49.8,
    14: 79.39,
    16: -39.84,
    18: 1.17,
}


@given(st.lists(st.integers(0, 1023), min_size=18, max_size=18))
def test_ticks_angles_ticks_round_trip_is_exact(robot, ticks):
    sm = robot.servo_map
    t = np.array(ticks)
    assert np.array_equal(sm.angles_to_ticks(sm.ticks_to_angles(t)), t)


def test_every_servo_round_trips_its_full_range(robot):
    sm = robot.servo_map
    for i, spec in enumerate(sm.specs):
        for tick in range(0, 1024):
            t = sm.zero_ticks.round().astype(int).clip(0, 1023)
            t[i] = tick
            back = sm.angles_to_ticks(sm.ticks_to_angles(t))
            assert back[i] == tick, spec.joint


def test_walk_ready_ticks_angles_ticks_exact(robot):
    sm = robot.servo_map
    ticks = sm.pose_ticks("walk_ready")
    assert np.array_equal(sm.angles_to_ticks(sm.ticks_to_angles(ticks)), ticks)


def test_walk_ready_equals_thesis_annex_a_start_pose(robot):
    """The thesis's start pose, converted back to ticks, is the official Walk Ready.

    Two printed values differ: j9 (ID 6) = -14.65 is a sign slip (the thesis's own j9 limits
    mirror j12's, and Walk Ready has ID 6 = 561 = 1023 - 462, the mirror of ID 5), and
    j6 (ID 8) = 45.8 deg is 2 ticks from Walk Ready's 666 = 1024 - 358, the mirror of ID 7.
    """
    sm = robot.servo_map
    ticks = sm.pose_ticks("walk_ready")
    for servo_id, start_deg in ANNEX_A_START.items():
        tick = ticks[sm.index_of_id(servo_id)]
        thesis_tick = 512 + start_deg / DEG_PER_TICK
        if servo_id == 6:
            assert abs(512 - ANNEX_A_START[6] / DEG_PER_TICK - tick) < 1.0
        elif servo_id == 8:
            assert abs(thesis_tick - tick) < 2.5
            assert tick == 1024 - ticks[sm.index_of_id(7)]
        else:
            assert round(thesis_tick) == tick, servo_id


def test_angle_outside_servo_range_is_rejected(robot):
    sm = robot.servo_map
    q = sm.ticks_to_angles(sm.pose_ticks("walk_ready"))
    i = robot.joint_index("r_knee")
    q[i] += np.radians(200)
    with pytest.raises(ServoMapError, match=r"r_knee \(id 13\)"):
        sm.angles_to_ticks(q)
    with pytest.raises(ServoMapError, match="outside the servo range"):
        sm.ticks_to_angles(np.full(18, 1024))
    with pytest.raises(ServoMapError, match="expected 18 values"):
        sm.angles_to_ticks(np.zeros(17))
    with pytest.raises(ServoMapError, match="non-finite"):
        sm.angles_to_ticks(np.full(18, np.nan))


def test_malformed_servo_maps(tmp_path):
    with pytest.raises(ServoMapError, match="duplicate servo id 3"):
        ServoMap([ServoSpec("a", 3, 1, 512), ServoSpec("b", 3, 1, 512)])
    with pytest.raises(ServoMapError, match="sign must be 1 or -1"):
        ServoMap([ServoSpec("a", 3, 2, 512)])
    with pytest.raises(ServoMapError, match="zero_tick 2000"):
        ServoMap([ServoSpec("a", 3, 1, 2000)])
    with pytest.raises(ServoMapError, match="id 300"):
        ServoMap([ServoSpec("a", 300, 1, 512)])
    with pytest.raises(ServoMapError, match="servo map not found"):
        ServoMap.from_file(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[joints\n")
    with pytest.raises(ServoMapError, match="not valid TOML"):
        ServoMap.from_file(bad)
    bad.write_text("[joints]\na = { id = 1, sign = 1 }\n")
    with pytest.raises(ServoMapError, match="lacks 'zero_tick'"):
        ServoMap.from_file(bad)


def test_settings_are_read_with_per_joint_overrides():
    robot = load_robot("bioloid")
    settings = robot.servo_map.settings
    names = list(robot.servo_map.joint_names)
    assert settings.compliance_slope[names.index("l_hip_roll")] == 32
    assert settings.compliance_slope[names.index("r_shoulder_pitch")] == 128
    assert settings.compliance_slope[names.index("l_ankle_roll")] == 64
    assert np.all(settings.compliance_margin == 1)
    assert np.all(settings.torque_limit == 1023)
    assert settings.alarm_shutdown == 36


@pytest.mark.parametrize(
    "table, message",
    [
        ({"compliance_slope": 0}, "compliance_slope = 0: must be an integer in 1..254"),
        ({"punch": "hard"}, "punch = 'hard'"),
        ({"stiffness": 3}, "unknown keys ['stiffness']"),
        ({"joints": {"nope": {"punch": 40}}}, "unknown joint 'nope'"),
        ({"joints": {"a": {"slope": 40}}}, "unknown key 'slope'"),
    ],
)
def test_bad_settings_name_the_key(table, message):
    with pytest.raises(ServoMapError) as err:
        ServoSettings.from_table(table, ["a", "b"], "x.toml")
    assert message in str(err.value)
    assert "x.toml" in str(err.value)
