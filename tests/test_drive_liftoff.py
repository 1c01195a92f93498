"""A lift-off held while the soles are not flat on each other (wbc.drive.liftoff,
``Walker(flat_liftoff=deg)``), and the path a command sequence walks
(wbc.drive.commands.walked)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wbc import load_robot
from wbc.drive.commands import Command, walked
from wbc.drive.liftoff import FLAT_LIFTOFF_TICKS, FlatLiftoff, soles_tilt
from wbc.drive.walker import Walker
from wbc.exceptions import ConfigurationError
from wbc.stacks import load_stack
from wbc.walking import GaitTiming, SwingParams
from wbc.walking.engine import EngineParams, VelocityLimits
from wbc.walking.loop import StackController


@pytest.fixture(scope="module")
def robot():
    return load_robot("bioloid")


def tilted(robot, deg: float) -> np.ndarray:
    """The standing configuration with the left ankle pitched ``deg``."""
    q = robot.configuration("stand").copy()
    q[7 + robot.joint_names.index("l_ankle_pitch")] += math.radians(deg)
    return q


def test_the_soles_tilt_is_the_angle_between_their_normals(robot):
    """Standing: 0.3° (the stand's own); one ankle pitched by a: a (within the stand's)."""
    stand = math.degrees(soles_tilt(robot, robot.configuration("stand")))
    assert stand < 0.5
    for deg in (3.0, 8.0, -5.0):
        got = math.degrees(soles_tilt(robot, tilted(robot, deg)))
        assert got == pytest.approx(abs(deg), abs=stand + 1e-6)


def test_a_lift_off_waits_while_tilted_and_no_longer_than_its_ticks(robot):
    flat, bent = robot.configuration("stand"), tilted(robot, 8.0)
    guard = FlatLiftoff(robot, 4.0, ticks=3)
    guard.landed(flat)  # flat at the landing's record: no wait
    assert not guard.hold(bent)
    guard.landed(bent)  # tilted: waits while tilted, at most 3 ticks
    assert [guard.hold(bent) for _ in range(5)] == [True, True, True, False, False]
    guard.landed(bent)  # flat again after one tick: the lift-off goes
    assert [guard.hold(bent), guard.hold(flat), guard.hold(bent)] == [True, False, False]
    guard.landed(None)  # unread: no wait
    assert not guard.hold(bent)
    assert (guard.lift_offs_held, guard.held) == (2, 4)
    small = FlatLiftoff(robot, 10.0)  # below the threshold: no wait
    small.landed(bent)
    assert not small.hold(bent)


@pytest.mark.parametrize("deg", [-1.0, math.nan, math.inf])
def test_a_bad_threshold_is_refused(robot, deg):
    with pytest.raises(ConfigurationError, match="flat_liftoff"):
        FlatLiftoff(robot, deg)


def _walk(robot, present: np.ndarray, flat_liftoff: float, ticks: int = 260):
    params = EngineParams(timing=GaitTiming(), swing=SwingParams(apex=0.015),
                          zmp_offset=(0.0, 0.0285), transfer=1.0)  # fmt: skip
    walker = Walker(robot, StackController(load_stack("walk", robot, solver="weighted")),
                    params=params, limits=VelocityLimits(0.08, 0.06, 0.03, 0.5), window=None,
                    flat_liftoff=flat_liftoff)  # fmt: skip
    walker.present = lambda: present[7:]
    walker.command(0.05, 0.0, 0.0)
    walker.start()
    for _ in range(ticks):
        walker.tick()
    return walker


def test_the_walker_holds_each_tilted_lift_off_and_the_command_moves_on(robot):
    """Soles read tilted 8° throughout: each lift-off waits its 10 ticks (the engine that
    much behind the walker's time), the commanded pose as far as without the option; read
    flat, the walk is the option off's tick for tick."""
    off = _walk(robot, robot.configuration("stand"), 0.0)
    assert off.flat_liftoff is None
    flat = _walk(robot, robot.configuration("stand"), 4.0)
    assert flat.engine.k == off.engine.k and flat.flat_liftoff.held == 0
    assert np.array_equal(flat.q, off.q)
    bent = _walk(robot, tilted(robot, 8.0), 4.0)
    guard = bent.flat_liftoff
    assert guard.lift_offs_held >= 2
    assert guard.held == FLAT_LIFTOFF_TICKS * guard.lift_offs_held
    assert bent.engine.k == off.engine.k - guard.held
    assert np.allclose(bent.engine.pose_cmd, off.engine.pose_cmd)


def test_walked_sums_the_path_and_the_unsigned_turn():
    cmds = [Command(2.0, 0.03, 0.04), Command(1.0, 0.0, 0.0, -0.5), (3.0, -0.02, 0.0, 0.2)]
    path, turn = walked(cmds)
    assert path == pytest.approx(2.0 * 0.05 + 3.0 * 0.02)
    assert turn == pytest.approx(0.5 + 0.6)
