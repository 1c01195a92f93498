"""Playing the get-up in the simulator, closed loop (wbc.balance.getup_play)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("mujoco")

from wbc.balance import getup_play as P
from wbc.drive.getup_sim import drop
from wbc.drive.sim import judge, make_sim
from wbc.model import load_robot

ROBOT = load_robot("bioloid")


def test_the_bioloid_gets_up_from_its_front() -> None:
    """Dropped on its front (a random heading), torque off, settled: get_up reads the side
    from the IMU and the joints from the bus, and the robot ends standing, still up 2 s on."""
    sim, bus, imu = make_sim(ROBOT)
    drop(sim, ROBOT, "prone", yaw=0.7)
    assert judge(sim, ROBOT)[0] is False
    lines: list[str] = []
    result = P.get_up(bus, imu, ROBOT, out=lines.append)
    assert result.side == "prone" and result.completed, result
    assert result.plan_failures == 0
    assert lines[0] == "get-up: lying prone"
    ok, why = judge(sim, ROBOT)
    assert ok, why
    sim.advance(2.0)
    ok, why = judge(sim, ROBOT)
    assert ok, why
    # facing where its head pointed on the floor
    R = sim.site_pose("torso").rotation
    assert abs(math.remainder(math.atan2(R[1, 0], R[0, 0]) - 0.7, math.tau)) < 0.35


def test_the_bioloid_gets_up_from_its_back() -> None:
    """Dropped on its back: the sit-up, the crossing onto the feet with the hands behind, the
    rise; standing, still up 2 s on."""
    sim, bus, imu = make_sim(ROBOT)
    drop(sim, ROBOT, "supine", yaw=-1.2)
    assert judge(sim, ROBOT)[0] is False
    result = P.get_up(bus, imu, ROBOT, out=lambda _l: None)
    assert result.side == "supine" and result.completed, result
    assert "cross" in result.phases and result.plan_failures == 0
    sim.advance(2.0)
    ok, why = judge(sim, ROBOT)
    assert ok, why


def test_standing_or_on_its_back_with_supine_off_it_is_left_as_it_is() -> None:
    sim, bus, imu = make_sim(ROBOT)
    result = P.get_up(bus, imu, ROBOT, joints=sim.q()[7:], out=lambda _l: None)
    assert result.side is None and not result.completed and not result.phases
    drop(sim, ROBOT, "supine")
    q = sim.q()
    result = P.get_up(bus, imu, ROBOT, joints=q[7:], out=lambda _l: None, supine=False)
    assert result.side == "supine" and not result.completed and result.reason == P.SUPINE_NOTE
    assert np.array_equal(sim.q(), q)  # nothing moved


def test_placed_puts_the_contacts_where_they_were_planned() -> None:
    from wbc.balance.getup import with_toes

    robot = with_toes(ROBOT)
    q = robot.configuration("stand")
    R = pin.rpy.rpyToMatrix(0.1, 0.2, 0.3)
    anchors = {"l_sole": np.array([0.3, 0.2, 0.0]), "r_sole": np.array([0.3, 0.1, 0.0])}
    placed = P.placed(robot, q[7:], R, anchors)
    got = [robot.frame_placement(placed, f).translation for f in anchors]
    mean = np.mean(got, axis=0)
    assert np.allclose(mean, np.mean(list(anchors.values()), axis=0), atol=1e-9)
    assert np.allclose(robot.frame_placement(placed, "torso").rotation, R, atol=1e-9)
