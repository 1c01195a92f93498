"""StanceIK: torso and soles to reachable world placements, on any robot."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.pose_ik import StanceIK


@pytest.mark.parametrize("seed", range(4))
def test_reachable_stances_are_reached_on_the_bioloid(robot, seed):
    """Targets made by forward kinematics of a random configuration (legs within their limits
    shrunk by 0.2 rad, near Walk Ready) are met to 1e-9 from Walk Ready, inside the limits."""
    rng = np.random.default_rng(seed)
    q0 = robot.configuration("stand")
    truth = q0.copy()
    truth[7:] += rng.uniform(-0.2, 0.2, robot.n_joints)
    truth[7:] = np.clip(truth[7:], robot.q_min + 0.01, robot.q_max - 0.01)
    truth[:3] += rng.uniform(-0.01, 0.01, 3)
    ik = StanceIK(robot)
    targets = {f: robot.frame_placement(truth, f) for f in ("torso", "l_sole", "r_sole")}
    assert ik.residual(q0, targets) > 1e-3  # the start is not the answer
    res = ik.solve(targets, q0)
    assert res.converged
    assert ik.residual(res.q, targets) < 1e-9
    assert robot.within_limits(res.q, tol=1e-9)
