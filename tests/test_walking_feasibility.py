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


class _Still:
    """A reference stub for :func:`joint_torques`: ``n`` ticks on one support, its ZMP at
    ``zmp``."""

    def __init__(self, sides: tuple[str, ...], zmp, n: int = 3) -> None:
        import numpy as np

        self.n, self.dt, self.sides = n, 0.01, sides
        self.zmp = np.tile(zmp, (n, 1))

    def contact_sides(self, i: int) -> tuple[str, ...]:
        return self.sides


@pytest.mark.parametrize("support", ["left", "right", "double"])
def test_joint_torques_of_a_still_pose_are_the_static_holding_torques(robot, support):
    """Held still, the inverse dynamics with the soles' forces (all on the stance sole; in
    double support split by where the ZMP lies between the soles) give the static torques of
    :meth:`ComplianceCompensator.torques`, the same split by the CoM: computed another way."""
    import numpy as np

    from wbc.balance.compliance import ComplianceCompensator
    from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
    from wbc.walking.feasibility import joint_torques

    code = {"left": SUPPORT_LEFT, "right": SUPPORT_RIGHT, "double": SUPPORT_DOUBLE}[support]
    sides = ("left", "right") if support == "double" else (support,)
    q = robot.place_on_ground(robot.configuration("stand"), f"{sides[0][0]}_sole")
    static = ComplianceCompensator(robot).torques(q[7:], code)
    ref = _Still(sides, np.asarray(robot.com(q))[:2])
    tau = joint_torques(robot, ref, np.tile(q, (ref.n, 1)))
    assert np.allclose(tau, static, atol=1e-9), np.abs(tau - static).max()
    assert np.abs(static).max() > 0.05  # a load to compare


def test_the_report_states_the_peak_torque_share(robot, start):
    """The feasibility report's torque share: the peak |τ| of the tracked motion over the
    joint's stall torque (the URDF's effort), within the share it holds still in single
    support and below the AX-12A's stall on the Bioloid's gentle walk (0.49 measured)."""
    rep = kinematic_feasibility(robot, forward_walk(start, 4), iterations=2)
    assert 0.3 < rep.torque_fraction < 0.8, rep
    assert rep.torque_joint in robot.joint_names
