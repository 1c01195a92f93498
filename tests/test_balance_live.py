"""The closed loop on a user's own bus and IMU: the documented example runs (short)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "closed_loop_own_robot.py"


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("closed_loop_own_robot", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_example_walks_closed_loop(example):
    """0.6 s of walk10 on the example's toy simulator, through the deployment, closed loop:
    it completes, the loop's time is a share of the tick, the estimator sees the toy body's
    lean, and no goal ever left a joint limit. (The off switch: test_balance_stabilizer.)"""
    closed = example.main(duration=0.6, closed=True)
    assert closed["completed"] and closed["ticks"] >= 55
    assert 0 < closed["feedback_share"] < 1
    assert closed["goal_limit_excess_rad"] <= 0
    assert closed["estimated_tilt_max_deg"] > 0  # the toy body leans; the estimator sees it
