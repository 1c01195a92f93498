"""The loaded joints' sag integrated into their goals (``Gains.j_i``, issue 30): it grows
on the loaded leg toward the encoders' sag, bounded and leaking, lets go on a swinging leg,
holds on unread joints, keeps every goal's change within the speed limits; off (the
default), the stabilizer adds nothing."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.balance.joint_integral import JointIntegral
from wbc.balance.stabilizer import Gains, Stabilizer
from wbc.model import load_robot


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def _knee(robot, side: str) -> int:
    return robot.joint_names.index(robot.roles.joint(side, "knee"))


def test_the_stance_legs_sag_is_integrated_bounded_and_let_go_when_it_swings(robot):
    ji = JointIntegral(robot)
    q = robot.configuration("stand")[7:]
    k, other = _knee(robot, "left"), _knee(robot, "right")
    present = q.copy()
    present[k] -= 0.02  # (the left knee sags 0.02 rad behind its solved goal)
    present[other] -= 0.02  # (so does the right one, swinging: not integrated)
    v = ji.offsets(q, present, "l_sole", 2.0, 0.1, 0.0, 0.01)
    assert v[k] == pytest.approx(2.0 * 0.01 * 0.02)  # (rate · dt · sag)
    assert v[other] == 0.0 and np.count_nonzero(v) == 1
    for _ in range(199):  # (2 s: rate · sag · t = 0.08, no leak)
        v = ji.offsets(q, present, "l_sole", 2.0, 0.1, 0.0, 0.01)
    assert v[k] == pytest.approx(0.08, abs=1e-9)
    for _ in range(200):
        v = ji.offsets(q, present, "l_sole", 2.0, 0.1, 0.0, 0.01)
    assert v[k] == pytest.approx(0.1)  # (j_i_max)
    for _ in range(2000):  # with the leak: rate · sag / leak = 0.04 rad
        v = ji.offsets(q, present, "l_sole", 2.0, 0.1, 1.0, 0.01)
    assert v[k] == pytest.approx(0.04, abs=1e-6)
    w = ji.offsets(q, present, "r_sole", 2.0, 0.1, 1.0, 0.01)  # the left leg swings
    step = 0.5 * robot.v_max[k] * 0.01
    assert w[k] == pytest.approx(max(0.04 - step, 0.0))  # let go, within the speed
    for _ in range(10):
        w = ji.offsets(q, present, "r_sole", 2.0, 0.1, 1.0, 0.01)
    assert w[k] == 0.0


def test_unread_joints_hold_and_goals_stay_within_the_speed_limits(robot):
    ji = JointIntegral(robot)
    q = robot.configuration("stand")[7:]
    k = _knee(robot, "left")
    present = q - 0.05
    for _ in range(50):
        v = ji.offsets(q, present, "", 50.0, 0.3, 0.0, 0.01)  # (double support: both legs)
    held = v.copy()
    unread = np.full_like(present, np.nan)
    v = ji.offsets(q, unread, "", 50.0, 0.3, 0.0, 0.01)
    np.testing.assert_array_equal(v, held)
    # a fast integral on goals that already move at 0.9 of the speed limit: each goal's
    # change (solved + offset) stays ≤ v_max · dt
    ji2 = JointIntegral(robot)
    last = q.copy()
    for t in range(30):
        solved = q + 0.9 * robot.v_max * 0.01 * t
        v = ji2.offsets(solved, solved - 0.05, "", 500.0, 0.3, 0.0, 0.01)
        assert np.all(np.abs(solved + v - last) <= robot.v_max * 0.01 * (1 + 1e-9))
        last = solved + v
    assert v[k] > 0.05  # (it still grew)


def test_the_stabilizer_adds_the_integral_only_with_j_i(robot):
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    sag = q[7:] - 0.03
    for g, on in ((Gains(hip_kick=0.0), False), (Gains(hip_kick=0.0, j_i=2.0), True)):
        stab = Stabilizer(robot, 0.2, lambda: sag.copy(), None, g)
        stab.last = object()  # (a walk under way: an estimate exists)
        d = stab.joint_offsets(q[7:].copy())
        assert bool(d is not None and np.count_nonzero(d) > 0) is on


def test_a_joint_whose_goal_moves_faster_than_still_holds_its_integral(robot):
    """``j_i_still`` 0.5 rad/s: the left knee's solved goal moving at 1 rad/s (its error
    then the servo's lag) holds its integral; at 0.2 rad/s it integrates; without the
    gate (0) it integrates both."""
    q = robot.configuration("stand")[7:]
    k = _knee(robot, "left")
    for speed, still, grows in ((1.0, 0.5, False), (0.2, 0.5, True), (1.0, 0.0, True)):
        ji = JointIntegral(robot)
        for t in range(20):
            solved = q.copy()
            solved[k] += speed * 0.01 * t
            v = ji.offsets(solved, solved - 0.02, "l_sole", 2.0, 0.1, 0.0, 0.01, still)
        assert bool(v[k] > 0.005) is grows  # (20 ticks: 0.008; the first tick has no last goal)
