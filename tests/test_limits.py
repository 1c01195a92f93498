"""Limits and constraints: bounds, the CoM polygon, ground clearance, linear inequalities."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc import Kinematics, TaskError
from wbc.geometry import convex_hull, halfplanes, signed_distance
from wbc.limits import (
    ComPolygonConstraint,
    GroundClearanceConstraint,
    JointPositionLimit,
    JointVelocityLimit,
    LinearInequality,
    box_bounds,
)


def random_q(robot, seed):
    rng = np.random.default_rng(seed)
    q = robot.random_configuration(rng)
    q[:3] = rng.uniform(-0.1, 0.1, 3)
    q[3:7] = pin.Quaternion(pin.exp3(rng.uniform(-0.4, 0.4, 3))).coeffs()
    return q, rng


@given(seed=st.integers(0, 10_000))
def test_ground_clearance_rows_are_the_linearised_corner_heights(robot, seed):
    q, rng = random_q(robot, seed)
    c = GroundClearanceConstraint(robot, "r_sole", clearance=0.002)
    G, h = c.compute(Kinematics(robot, q))
    dq = rng.normal(size=robot.nv) * 1e-6
    M0 = robot.frame_placement(q, "r_sole")
    z0 = M0.translation[2] + c.corners @ M0.rotation[2]
    M = robot.frame_placement(robot.integrate(q, dq), "r_sole")
    z = M.translation[2] + c.corners @ M.rotation[2]
    # G dq <= h  <=>  corner heights after the step >= clearance (to first order); a corner
    # below the clearance (depth δ) rises by min(ξ δ, max_rise) instead (no jump back)
    depth = np.maximum(0.002 - z0, 0.0)
    rise = np.minimum(c.damping * depth, c.max_rise)
    assert np.allclose(h - G @ dq, z - np.where(depth > 0, z0 + rise, 0.002), atol=1e-11)
    assert c.lowest_point(Kinematics(robot, q)) == pytest.approx(
        robot.frame_placement(q, "r_sole").translation[2]
        + np.min(c.corners @ robot.frame_placement(q, "r_sole").rotation[2])
    )


@given(st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=3, max_size=30))
def test_convex_hull_contains_every_point(points):
    pts = np.array(points)
    hull = convex_hull(pts)
    if len(hull) < 3:
        return
    A, b = halfplanes(hull)
    assert np.all(A @ pts.T <= b[:, None] + 1e-9)


def test_signed_distance_inside_and_outside():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert signed_distance(square, [0.5, 0.5]) == pytest.approx(0.5)
    assert signed_distance(square, [0.5, 0.1]) == pytest.approx(0.1)
    assert signed_distance(square, [2.0, 0.5]) == pytest.approx(-1.0)
    assert signed_distance(square, [2.0, 2.0]) == pytest.approx(-np.sqrt(2.0))


def test_com_polygon_rows_keep_the_com_inside(robot):
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    c = ComPolygonConstraint(robot, ["l_sole"], margin=0.01)
    G, h = c.compute(kin)
    # at Walk Ready the CoM is between the feet: outside the left foot's polygon
    assert np.any(h < 0)
    # rows are A (c + Jc dq) <= b
    A, b = c.polygon.A, c.polygon.b
    dq = np.random.default_rng(1).normal(size=robot.nv) * 1e-3
    assert np.allclose(G @ dq - h, A @ (kin.com[:2] + kin.com_jacobian[:2] @ dq) - b)
    both = ComPolygonConstraint(robot, ["l_sole", "r_sole"], margin=0.01)
    _, h2 = both.compute(kin)
    assert np.all(h2 > 0)  # double support: the CoM is well inside


def test_bounds_move_a_joint_back_inside_at_the_servo_speed(robot):
    q = robot.configuration("walk_ready")
    i = robot.joint_index("r_knee")
    q[7 + i] = robot.q_min[i] - 0.3  # far outside
    kin = Kinematics(robot, q)
    lower, upper = np.empty(robot.nv), np.empty(robot.nv)
    box_bounds([JointPositionLimit(robot), JointVelocityLimit(robot)], kin, 0.01, lower, upper)
    step = robot.v_max[i] * 0.01
    assert lower[6 + i] == pytest.approx(step) and upper[6 + i] == pytest.approx(step)
    assert np.all(lower <= upper)
    assert np.all(np.isinf(lower[:6])) and np.all(np.isinf(upper[:6]))


def test_linear_inequality_validation():
    with pytest.raises(TaskError, match="rows"):
        LinearInequality(np.zeros((2, 24)), np.zeros(3))
    with pytest.raises(TaskError, match="non-finite"):
        LinearInequality(np.full((1, 24), np.nan), np.zeros(1))
