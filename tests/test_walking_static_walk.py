"""The whole-body static walk (wbc.walking.static_walk)."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.bench import trajectories as traj
from wbc.exceptions import TrajectoryError
from wbc.walking.feasibility import kinematic_feasibility
from wbc.walking.static_walk import StaticWalkParams, static_walk
from wbc.walking.window import BalanceWindow


def test_com_15mm_inside_the_stance_sole_in_single_support(robot, window, start):
    ref = static_walk(start, window, StaticWalkParams(n_steps=2))
    single = ref.support != 0
    assert single.any()
    assert ref.com_margin()[single].min() >= 0.015
    assert ref.gait == "static"
    # the CoM is at rest in single support (a static gait)
    assert np.abs(ref.com_vel[single]).max() < 1e-9
    rep = kinematic_feasibility(robot, ref, hold_arms=False)
    assert rep.feasible, rep


def test_the_legs_alone_cannot_do_it(start):
    """Without a torso lean (a zero-lean window) the CoM cannot reach 15 mm inside."""
    flat = BalanceWindow(
        offsets=np.array([0.0, 0.0115]),
        rolls=np.zeros(2),
        max_lateral=0.0115,
        upright=0.0115,
        max_lean=0.0,
        com_height=float(start.com[2]),
        half_width=0.0414,
    )
    with pytest.raises(TrajectoryError, match="balance window"):
        static_walk(start, flat, StaticWalkParams(n_steps=1))


def test_bad_parameters(start, window):
    with pytest.raises(TrajectoryError, match="n_steps"):
        static_walk(start, window, StaticWalkParams(n_steps=0))
    with pytest.raises(TrajectoryError, match="swing_time"):
        static_walk(start, window, StaticWalkParams(swing_time=-1.0))


def test_named_static_walk(robot):
    ref = traj.build("static_walk", robot)
    assert ref.name == "static_walk"
    assert ref.com_margin()[ref.support != 0].min() >= 0.015
