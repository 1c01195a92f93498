"""Footstep plans and the errors raised before any motion (wbc.walking.footsteps, gait)."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.exceptions import TrajectoryError
from wbc.walking import (
    Footstep,
    FootstepPlan,
    GaitTiming,
    SwingParams,
    ThesisStepParams,
    forward_walk,
    plan_footsteps,
    thesis_step,
    walk,
)


def test_start_state_from_walk_ready(start):
    assert start.left.y == pytest.approx(0.0414, abs=2e-4)
    assert start.right.y == pytest.approx(-0.0414, abs=2e-4)
    assert start.com[2] == pytest.approx(0.173, abs=2e-3)
    assert abs(start.left.z) < 1e-3 and abs(start.right.z) < 1e-3


def test_forward_plan(start):
    plan = plan_footsteps(start.left, start.right, 10, (0.035, 0.0, 0.0))
    sides = [s.side for s in plan.steps]
    assert sides == ["right", "left"] * 5  # the thesis's first swing: right
    x0 = 0.5 * (start.left.x + start.right.x)
    for k, s in enumerate(plan.steps[:-1]):
        assert s.x == pytest.approx(x0 + 0.035 * (k + 1), abs=1e-3)
    last, before = plan.steps[-1], plan.steps[-2]
    assert last.x == pytest.approx(before.x, abs=1e-4)  # closing step: side by side
    assert last.side == "left"
    assert last.y - before.y == pytest.approx(start.left.y - start.right.y, abs=1e-3)
    plan.validate(start.foot, start.legs, com_height=start.com[2])
    back = plan_footsteps(start.left, start.right, 4, (-0.03, 0.0, 0.0))
    assert all(b.x < start.left.x + 1e-3 for b in back.steps)


def test_lateral_plan_opens_and_closes(start):
    w2 = start.left.y - start.right.y
    plan = plan_footsteps(start.left, start.right, 6, (0.0, 0.02, 0.0))
    assert plan.steps[0].side == "left"  # leading foot first
    widths = [left.y - right.y for left, right in plan.placements()[1:]]
    np.testing.assert_allclose(widths, [w2 + 0.04, w2] * 2 + [w2 + 0.04, w2], atol=1e-3)
    # 5 steps of the leading/trailing pattern plus the closing one: 6 x 0.02 to the left
    assert plan.steps[-1].y == pytest.approx(start.right.y + 0.02 * 6, abs=1e-3)


def test_turning_plan(start):
    plan = plan_footsteps(start.left, start.right, 6, (0.02, 0.0, 0.2))
    assert plan.steps[0].side == "left"
    yaws = [s.yaw for s in plan.steps]
    np.testing.assert_allclose(np.diff(yaws[:-1]), 0.2, atol=1e-9)
    assert yaws[-1] == pytest.approx(yaws[-2])
    plan.validate(start.foot)


def test_plan_bad_input(start):
    with pytest.raises(TrajectoryError, match="n_steps"):
        plan_footsteps(start.left, start.right, 0)
    with pytest.raises(TrajectoryError, match="stride"):
        plan_footsteps(start.left, start.right, 2, (np.nan, 0, 0))
    with pytest.raises(TrajectoryError, match="side"):
        Footstep("middle", 0.0, 0.0)
    with pytest.raises(TrajectoryError, match="non-finite"):
        Footstep("left", np.inf, 0.0)


def _plan(start, *steps):
    return FootstepPlan(start.left, start.right, tuple(steps))


def test_validation_errors(start):
    foot, legs, h = start.foot, start.legs, float(start.com[2])
    with pytest.raises(TrajectoryError, match="twice in a row"):
        _plan(start, Footstep("right", 0.03, -0.0414), Footstep("right", 0.06, -0.0414)).validate(
            foot
        )
    with pytest.raises(TrajectoryError, match="crossed feet"):
        _plan(start, Footstep("left", 0.0, -0.15)).validate(foot)
    with pytest.raises(TrajectoryError, match="apart"):  # overlapping feet
        _plan(start, Footstep("left", 0.0, 0.0)).validate(foot)
    with pytest.raises(TrajectoryError, match="headings differ"):
        _plan(start, Footstep("left", 0.0, 0.06, 0.8)).validate(foot)
    with pytest.raises(TrajectoryError, match="unreachable"):
        _plan(start, Footstep("right", 0.2, -0.0414)).validate(foot, legs, com_height=h)
    with pytest.raises(TrajectoryError, match="unreachable"):  # too wide a step
        _plan(start, Footstep("left", 0.0, 0.25)).validate(foot, legs, com_height=h)
    # the same steps without the reach check are fine geometrically
    _plan(start, Footstep("right", 0.2, -0.0414)).validate(foot)


def test_swing_path_collision(start):
    left = Footstep("left", 0.2, 0.0)
    right = Footstep("right", 0.0, -0.0414)
    plan = FootstepPlan(left, right, (Footstep("left", -0.2, 0.0),))
    with pytest.raises(TrajectoryError, match="swinging foot passes"):
        plan.validate(start.foot)


def test_walk_rejects_bad_input_before_motion(start):
    with pytest.raises(TrajectoryError, match="step_time must be positive"):
        forward_walk(start, 2, timing=GaitTiming(step_time=0.0))
    with pytest.raises(TrajectoryError, match="start_time must be positive"):
        forward_walk(start, 2, timing=GaitTiming(start_time=-1.0))
    with pytest.raises(TrajectoryError, match="dt must be positive"):
        forward_walk(start, 2, timing=GaitTiming(dt=0.0))
    with pytest.raises(TrajectoryError, match="double_support_ratio"):
        forward_walk(start, 2, timing=GaitTiming(double_support_ratio=1.0))
    with pytest.raises(TrajectoryError, match="apex"):
        forward_walk(start, 2, swing=SwingParams(apex=-0.01))
    with pytest.raises(TrajectoryError, match="out of the legs' reach"):
        forward_walk(start, 2, com_height=0.26)
    with pytest.raises(TrajectoryError, match="out of the legs' reach"):
        forward_walk(start, 2, com_height=0.05)
    with pytest.raises(TrajectoryError, match="unreachable"):
        forward_walk(start, 4, step_length=0.1)
    with pytest.raises(TrajectoryError, match="generator"):
        forward_walk(start, 2, generator="magic")
    with pytest.raises(TrajectoryError, match="start placement of the left sole"):
        walk(start, plan_footsteps(Footstep("left", 0.0, 0.1), start.right, 2))
    with pytest.raises(TrajectoryError, match="duration"):
        thesis_step(start, ThesisStepParams(duration=0.0))
    with pytest.raises(TrajectoryError, match="out of the legs' reach"):
        thesis_step(start, ThesisStepParams(com_height=0.3))
    with pytest.raises(TrajectoryError, match="unreachable"):
        thesis_step(start, ThesisStepParams(step_length=0.09))
