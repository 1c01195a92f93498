"""The compliance feed-forward's load split over a walking double support
(wbc.drive.compensate.LoadRamp, ComplianceCompensator.torques' share)."""

from __future__ import annotations

import numpy as np
import pytest

from wbc import load_robot
from wbc.balance.compliance import ComplianceCompensator
from wbc.drive.compensate import LoadRamp
from wbc.drive.walker import Walker
from wbc.exceptions import ConfigurationError
from wbc.stacks import load_stack
from wbc.types import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from wbc.walking import GaitTiming, SwingParams
from wbc.walking.engine import EngineParams, VelocityLimits
from wbc.walking.loop import StackController


@pytest.fixture(scope="module")
def robot():
    return load_robot("bioloid")


def test_a_walking_double_support_moves_the_load_from_the_old_stance_to_the_new():
    """After a left single support the right sole lands: the left share falls from 1 to 0
    over the ramp's ticks, monotone and min-jerk (symmetric about the middle), and stays at
    0 past them; the next landing ramps it back up."""
    ramp = LoadRamp(10)
    assert ramp.update(SUPPORT_LEFT, "l_sole") is None  # (single support: one sole carries)
    shares = [ramp.update(SUPPORT_DOUBLE, "r_sole") for _ in range(12)]
    assert all(s is not None for s in shares)
    s = np.array(shares, dtype=float)
    assert 0.95 < s[0] < 1.0 and np.all(np.diff(s[:10]) < 0) and s[9] == 0.0 and s[11] == 0.0
    assert np.allclose(s[:9] + s[8::-1], 1.0)  # (min-jerk: odd about the middle)
    assert ramp.update(SUPPORT_RIGHT, "r_sole") is None
    back = [ramp.update(SUPPORT_DOUBLE, "l_sole") for _ in range(10)]
    assert back[-1] == 1.0 and back[0] is not None and back[0] < 0.05


def test_a_double_support_that_is_no_walks_transfer_is_split_by_the_com():
    """Standing, the start (no single support before) and the end (the support sole the
    last single support's): None, the compensator's own split by the CoM."""
    ramp = LoadRamp(10)
    assert ramp.update(SUPPORT_DOUBLE, "l_sole") is None  # (standing, the start)
    ramp.update(SUPPORT_LEFT, "l_sole")
    assert [ramp.update(SUPPORT_DOUBLE, "l_sole") for _ in range(3)] == [None] * 3


@pytest.mark.parametrize("ticks", [0, -1, 2.5])
def test_a_ramp_of_no_whole_positive_ticks_is_refused(ticks):
    with pytest.raises(ConfigurationError, match="ticks"):
        LoadRamp(ticks)  # type: ignore[arg-type]


def test_the_share_given_moves_the_static_load_between_the_legs(robot):
    """``torques(..., share)``: None is the CoM's split; a larger left share loads the
    left knee more and the right knee less; one sole's support ignores it."""
    comp = ComplianceCompensator(robot)
    q = robot.configuration("stand")[7:]
    left, right = robot.joint_names.index("l_knee"), robot.joint_names.index("r_knee")
    by_com = comp.torques(q, SUPPORT_DOUBLE)
    lo, hi = comp.torques(q, SUPPORT_DOUBLE, share=0.1), comp.torques(q, SUPPORT_DOUBLE, share=0.9)
    assert abs(hi[left]) > abs(by_com[left]) * 1.2 > abs(lo[left]) * 1.2
    assert abs(lo[right]) > abs(hi[right]) * 1.5
    single = comp.torques(q, SUPPORT_LEFT)
    assert np.allclose(comp.torques(q, SUPPORT_LEFT, share=0.1), single)


def test_the_walker_ramps_the_load_only_when_asked(robot):
    """``Walker(load_ramp=False)`` (the default): no ramp; True: one over the gait's
    double support in walk ticks, read through :meth:`Walker._load_share`."""
    params = EngineParams(timing=GaitTiming(), swing=SwingParams(apex=0.015),
                          zmp_offset=(0.0, 0.0285), transfer=1.0)  # fmt: skip
    kw = dict(params=params, limits=VelocityLimits(0.08, 0.06, 0.03, 0.5), window=None)
    controller = StackController(load_stack("walk", robot, solver="weighted"))
    assert Walker(robot, controller, **kw).load_ramp is None
    on = Walker(robot, controller, load_ramp=True, **kw)
    assert isinstance(on.load_ramp, LoadRamp)
    assert on.load_ramp.ticks == round(params.timing.double_support_time / on.engine.dt)
    assert on._load_share(0.0) is None  # (no walk tick yet)
