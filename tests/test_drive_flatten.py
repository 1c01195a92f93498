"""A landed sole flattened from the encoders' tilt (wbc.drive.flatten, ``Walker(flatten=rate)``)
and the tilt vector it reads (wbc.drive.liftoff.tilt_vector)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from test_drive_liftoff import tilted as pitched  # (the standing pose, left ankle pitched)

from wbc import load_robot
from wbc.drive.flatten import SoleFlatten
from wbc.drive.liftoff import soles_tilt, tilt_vector
from wbc.drive.walker import Walker
from wbc.exceptions import ConfigurationError
from wbc.geometry import rot_z
from wbc.stacks import load_stack
from wbc.walking import GaitTiming, SwingParams
from wbc.walking.engine import EngineParams, VelocityLimits
from wbc.walking.loop import StackController, TickTargets


@pytest.fixture(scope="module")
def robot():
    return load_robot("bioloid")


def targets(phase: str, support: str, swing: str, yaw: float = 0.3) -> TickTargets:
    """Both soles' targets flat at heading ``yaw`` (the swing's rotation too)."""
    left = pin.SE3(rot_z(yaw), np.array([0.0, 0.04, 0.0]))
    right = pin.SE3(rot_z(yaw), np.array([0.0, -0.04, 0.0]))
    return TickTargets(0, 0.0, phase, support, swing, np.zeros(3), left, right, yaw, np.eye(3),
                       np.zeros(3), rot_z(yaw))  # fmt: skip


def test_the_tilt_vector_turns_the_normal_and_its_norm_is_the_soles_tilt(robot):
    for deg in (0.0, 8.0, -5.0):
        q = pitched(robot, deg)
        (rel,) = robot.placements_in(q, "r_sole", ["l_sole"])
        v = tilt_vector(rel.rotation)
        assert v[2] == 0.0
        assert float(np.linalg.norm(v)) == pytest.approx(soles_tilt(robot, q), abs=1e-9)
        assert np.allclose(pin.exp3(v) @ np.array([0.0, 0.0, 1.0]), rel.rotation[:, 2])
    assert tilt_vector(np.eye(3)).tolist() == [0.0, 0.0, 0.0]
    # an ankle pitch is a tilt about the sole's y axis, of its sign
    (rel,) = robot.placements_in(pitched(robot, 8.0), "r_sole", ["l_sole"])
    assert math.degrees(tilt_vector(rel.rotation)[1]) == pytest.approx(8.0, abs=0.5)


def test_the_landed_soles_target_takes_the_plants_tilt_away(robot):
    """A plant whose left sole lands pitched 8° more than asked: the loop's correction
    brings the read tilt under 0.5° over a double support; faded out while the sole stands
    (the other one swinging) and, if kept, out of the swing's rotation after its lift-off."""
    flat = SoleFlatten(robot, rate=30.0)
    dt = 0.01
    flat.update(targets("single", "r_sole", "l_sole"), pitched(robot, 0.0), True, dt)
    assert flat.correction == {}
    applied = 0.0  # the pitch (°) the correction asks of the left ankle
    for _ in range(10):
        t = targets("double", "r_sole", "l_sole")
        flat.update(t, pitched(robot, 8.0 - applied), True, dt)
        # the target's tilt against its flat plan: −c (world; the yaw taken out)
        tilt = tilt_vector(t.l_sole.rotation)
        assert np.allclose(tilt, -flat.correction["l_sole"], atol=1e-9)
        assert np.allclose(t.r_sole.rotation, rot_z(0.3))  # the stance sole's plan
        pitch_axis = np.array([-math.sin(0.3), math.cos(0.3), 0.0])  # the sole's y (world)
        applied = math.degrees(flat.correction["l_sole"] @ pitch_axis)
    assert math.degrees(soles_tilt(robot, pitched(robot, 8.0 - applied))) < 0.5
    c = flat.correction["l_sole"].copy()
    # the right lifts: the left's correction fades out as it stands (no other sole to read)
    shares = []
    for _ in range(12):
        t = targets("single", "l_sole", "r_sole")
        flat.update(t, pitched(robot, 8.0), True, dt)
        assert np.allclose(tilt_vector(t.swing_rotation), 0.0)
        shares.append(float(np.linalg.norm(tilt_vector(t.l_sole.rotation)) / np.linalg.norm(c)))
    assert shares[0] == pytest.approx(0.9) and shares[8] == pytest.approx(0.1)
    assert shares[9:] == [0.0, 0.0, 0.0]
    # a correction the left keeps at the right's landing (read flat: none grows on the left)
    flat.correction["l_sole"] = c
    t = targets("double", "l_sole", "r_sole")
    flat.update(t, pitched(robot, 0.0), True, dt)
    assert np.allclose(tilt_vector(t.l_sole.rotation), -c)
    shares = []  # the left lifts: its correction fades out of the swing's rotation
    for _ in range(12):
        t = targets("single", "r_sole", "l_sole")
        flat.update(t, pitched(robot, 0.0), True, dt)
        shares.append(float(np.linalg.norm(tilt_vector(t.swing_rotation))) / np.linalg.norm(c))
    assert "l_sole" not in flat.correction
    assert shares[0] == pytest.approx(10 / 11) and shares[9] == pytest.approx(1 / 11)
    assert shares[10:] == [0.0, 0.0] and all(np.diff(shares) <= 0)


def test_the_correction_is_capped_and_standing_still_holds_it(robot):
    flat = SoleFlatten(robot, rate=100.0, max_deg=5.0)
    flat.update(targets("single", "r_sole", "l_sole"), pitched(robot, 0.0), True, 0.01)
    for _ in range(4):
        flat.update(targets("double", "r_sole", "l_sole"), pitched(robot, 12.0), True, 0.01)
    c = flat.correction["l_sole"]
    assert math.degrees(float(np.linalg.norm(c))) == pytest.approx(5.0)
    assert math.degrees(flat.largest) == pytest.approx(5.0)
    flat.update(targets("double", "r_sole", "l_sole"), pitched(robot, 12.0), False, 0.01)
    flat.update(targets("double", "r_sole", "l_sole"), None, True, 0.01)  # unread
    assert np.array_equal(flat.correction["l_sole"], c)


def test_a_tilt_inside_the_dead_band_is_left_alone(robot):
    """``band_deg`` 5: the soles read 3.5° apart take no correction, 9° apart the excess."""
    flat = SoleFlatten(robot, rate=100.0, band_deg=5.0)
    flat.update(targets("single", "r_sole", "l_sole"), pitched(robot, 0.0), True, 0.01)
    flat.update(targets("double", "r_sole", "l_sole"), pitched(robot, 3.5), True, 0.01)
    assert float(np.linalg.norm(flat.correction["l_sole"])) == 0.0
    q = pitched(robot, 9.0)
    flat.update(targets("double", "r_sole", "l_sole"), q, True, 0.01)
    excess = math.degrees(float(np.linalg.norm(flat.correction["l_sole"])))
    assert excess == pytest.approx(math.degrees(soles_tilt(robot, q)) - 5.0, abs=1e-6)


@pytest.mark.parametrize(
    "kw",
    [
        {"rate": -1.0},
        {"rate": math.nan},
        {"rate": 1.0, "max_deg": 0.0},
        {"rate": 1.0, "fade": 0},
        {"rate": 1.0, "band_deg": -1.0},
    ],
)
def test_bad_arguments_are_refused(robot, kw):
    with pytest.raises(ConfigurationError, match="flatten"):
        SoleFlatten(robot, **kw)


def _walk(robot, pitch_deg: float, flatten: float, ticks: int = 200) -> Walker:
    """A walk on a plant that reads the goals, the left ankle ``pitch_deg`` off them."""
    params = EngineParams(timing=GaitTiming(), swing=SwingParams(apex=0.015),
                          zmp_offset=(0.0, 0.0285), transfer=1.0)  # fmt: skip
    walker = Walker(robot, StackController(load_stack("walk", robot, solver="weighted")),
                    params=params, limits=VelocityLimits(0.08, 0.06, 0.03, 0.5), window=None,
                    flatten=flatten)  # fmt: skip
    off = np.zeros(robot.n_joints)
    off[robot.joint_names.index("l_ankle_pitch")] = math.radians(pitch_deg)
    walker.present = lambda: walker.q[7:] + off
    walker.command(0.05, 0.0, 0.0)
    walker.start()
    for _ in range(ticks):
        walker.tick()
    return walker


def test_the_walker_flattens_only_what_the_encoders_read_tilted(robot):
    """Off: no flattening; a plant that does what it is asked: nothing to flatten (the walk
    as off's); the left ankle 6° off its goals: the left sole's goals pitched against it."""
    off = _walk(robot, 0.0, 0.0)
    assert off.flatten is None
    level = _walk(robot, 0.0, 20.0)
    assert np.max(np.abs(level.q - off.q)) < 1e-4 and level.flatten.largest < 1e-4
    bent = _walk(robot, 6.0, 20.0)
    assert math.degrees(bent.flatten.largest) == pytest.approx(6.0, abs=1.0)
