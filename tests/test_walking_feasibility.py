"""References are kinematically feasible within the joint limits (wbc.walking.feasibility):
a bounded IK tracks them to numerical precision, and an infeasible one is detected."""

from __future__ import annotations

import pytest

from wbc.walking import ThesisStepParams, forward_walk, thesis_step
from wbc.walking.feasibility import kinematic_feasibility


@pytest.mark.parametrize("hold_arms", [True, False])
def test_thesis_step_is_feasible(robot, start, hold_arms):
    rep = kinematic_feasibility(robot, thesis_step(start), hold_arms=hold_arms)
    assert rep.feasible, rep
    assert rep.min_limit_margin >= 0.0


@pytest.mark.parametrize("gen", ["preview", "mpc", "lipm"])
def test_walks_are_feasible(robot, start, gen):
    if gen == "mpc":
        pytest.importorskip("casadi")
    rep = kinematic_feasibility(robot, forward_walk(start, 4, generator=gen))
    assert rep.feasible, rep
    assert rep.min_limit_margin >= 0.0


def test_a_com_beyond_the_hips_reach_is_not(robot, start):
    """The CoM 10 mm nearer the sole centre than the hips allow (the checks reject it)."""
    ref = thesis_step(start, ThesisStepParams(com_target=(0.0, -0.02)), check=False)
    rep = kinematic_feasibility(robot, ref)
    assert not rep.feasible
    assert rep.max_com_error > 1e-3
    assert rep.min_limit_margin < 1e-6  # a joint (the hip roll) is on its limit
