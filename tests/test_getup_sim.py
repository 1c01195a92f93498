"""The simulator's get-up judge (wbc.drive.getup_sim)."""

from __future__ import annotations

import pinocchio as pin
import pytest

pytest.importorskip("mujoco")

from wbc.drive.getup_sim import drop, judge
from wbc.drive.sim import make_sim
from wbc.model import load_robot

ROBOT = load_robot("bioloid")


def test_standing_is_judged_up_whatever_the_heading_and_lying_is_not() -> None:
    """Standing in Walk Ready (its torso 10 deg from the vertical by design) is up, at any
    heading; lying on the front or back is not."""
    sim, _bus, _imu = make_sim(ROBOT)
    for yaw in (0.0, 2.5):
        q = ROBOT.configuration("stand")
        q[3:7] = pin.Quaternion(pin.rpy.rpyToMatrix(0.0, 0.0, yaw)).coeffs()
        sim.reset(q, torque=True)
        sim.advance(1.0)
        ok, why = judge(sim, ROBOT)
        assert ok, why
    for side in ("prone", "supine"):
        drop(sim, ROBOT, side)
        ok, why = judge(sim, ROBOT)
        assert not ok and "from standing" in why
