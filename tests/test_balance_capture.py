"""LIPM capturability bounds (wbc.balance.capture): the one-step law per direction, the
second step away from the swing foot, step timing."""

from __future__ import annotations

import math

import pytest

from wbc.balance.capture import capture_bounds

MID = 92  # walk10: mid first single support (left stance)


def test_capture_bounds_of_walk10(robot, walk10, legs):
    b = capture_bounds(walk10, robot.total_mass, legs)
    w = math.sqrt(9.81 / walk10.com_height)
    xi = walk10.com[MID, :2] + walk10.com_vel[MID, :2] / w
    edge = walk10.plan.start_left.y + 0.5 * walk10.foot.width  # left stance: outer edge
    assert b["away_one_step_ns"] == pytest.approx(robot.total_mass * w * (edge - xi[1]))
    # away from the swing foot, a second step (the stance sole stepping out) catches less
    assert b["away_two_step_ns"] < b["away_one_step_ns"] == b["away_ns"]
    assert b["forward_ns"] > b["forward_planned_ns"] > 0
    assert b["toward_ns"] > b["toward_planned_ns"] > 0
    # with step timing: the best landing time; at the planned one (t) it is the in-time bound
    for d in ("forward", "backward", "toward"):
        assert b[f"{d}_timed_ns"] >= b[f"{d}_in_time_ns"] - 1e-12
        assert 0.05 <= b[f"{d}_timed_s"] <= b["t_swing_left_s"]
        if b[f"{d}_timed_s"] == pytest.approx(b["t_swing_left_s"]):
            assert b[f"{d}_timed_ns"] == pytest.approx(b[f"{d}_in_time_ns"])
    # toward the swing foot (a short reach in time, a long one in all): landing sooner helps
    assert b["toward_timed_ns"] > b["toward_in_time_ns"] + 0.05
    assert b["toward_timed_s"] < b["t_swing_left_s"]
