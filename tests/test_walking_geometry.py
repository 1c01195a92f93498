"""Foot rectangles, support polygons, signed distances (wbc.walking.geometry)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from wbc.walking.geometry import (
    Foot,
    convex_hull,
    foot_rectangle,
    halfplanes,
    polygon_area,
    polygon_distance,
    shrink_polygon,
    signed_distance,
    support_polygon,
)

#: a foot the size of the Bioloid's (101 x 61 mm)
FOOT = Foot(0.101, 0.061)
FOOT_LENGTH, FOOT_WIDTH = FOOT.length, FOOT.width


def test_foot_rectangle_is_the_foot():
    r = foot_rectangle([0.01, 0.02], 0.3, FOOT_LENGTH, FOOT_WIDTH)
    assert polygon_area(r) == pytest.approx(FOOT_LENGTH * FOOT_WIDTH)  # ccw -> positive
    np.testing.assert_allclose(r.mean(axis=0), [0.01, 0.02])
    edges = np.linalg.norm(np.roll(r, -1, axis=0) - r, axis=1)
    np.testing.assert_allclose(
        sorted(edges), sorted([FOOT_LENGTH, FOOT_LENGTH, FOOT_WIDTH, FOOT_WIDTH])
    )
    # the long side points along the heading
    long_edge = r[0] - r[1]
    np.testing.assert_allclose(long_edge / np.linalg.norm(long_edge), [np.cos(0.3), np.sin(0.3)])


def test_double_support_polygon_is_the_hull_of_both_feet():
    l_xy, r_xy = np.array([0.0, 0.0414]), np.array([0.03, -0.0414])
    poly = support_polygon(SUPPORT_DOUBLE, l_xy, 0.0, r_xy, 0.0, FOOT)
    assert polygon_area(poly) > 2 * FOOT_LENGTH * FOOT_WIDTH
    for corner in np.vstack(
        [
            foot_rectangle(l_xy, 0.0, FOOT_LENGTH, FOOT_WIDTH),
            foot_rectangle(r_xy, 0.0, FOOT_LENGTH, FOOT_WIDTH),
        ]
    ):
        assert signed_distance(poly, corner) > -1e-12
    np.testing.assert_allclose(
        polygon_area(support_polygon(SUPPORT_LEFT, l_xy, 0.0, r_xy, 0.0, FOOT)),
        FOOT_LENGTH * FOOT_WIDTH,
    )
    right = support_polygon(SUPPORT_RIGHT, l_xy, 0.0, r_xy, 0.0, FOOT)
    assert signed_distance(right, r_xy) == pytest.approx(FOOT_WIDTH / 2)


def test_signed_distance():
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    assert signed_distance(sq, [0.5, 0.5]) == pytest.approx(0.5)
    assert signed_distance(sq, [0.9, 0.5]) == pytest.approx(0.1)
    assert signed_distance(sq, [1.5, 0.5]) == pytest.approx(-0.5)
    assert signed_distance(sq, [2.0, 2.0]) == pytest.approx(-np.sqrt(2))  # corner: Euclidean
    np.testing.assert_allclose(signed_distance(sq, np.array([[0.5, 0.5], [-1, 0.5]])), [0.5, -1.0])


@given(st.floats(-0.2, 0.2), st.floats(-0.2, 0.2), st.floats(-3, 3), st.floats(0, 0.02))
def test_halfplanes_and_shrink(x, y, yaw, margin):
    r = foot_rectangle([x, y], yaw, FOOT_LENGTH, FOOT_WIDTH)
    A, b = halfplanes(r, margin)
    np.testing.assert_allclose(np.linalg.norm(A, axis=1), 1.0)
    assert np.all(A @ np.array([x, y]) <= b + 1e-12)  # centre inside while margin < half width
    inner = shrink_polygon(r, margin)
    assert polygon_area(inner) == pytest.approx(
        (FOOT_LENGTH - 2 * margin) * (FOOT_WIDTH - 2 * margin), rel=1e-9
    )
    assert np.all(signed_distance(r, inner) >= margin - 1e-12)
    assert shrink_polygon(r, 0.05).shape == (0, 2)  # wider than the half width: nothing left


def test_polygon_distance():
    a = foot_rectangle([0, 0.0414], 0.0, FOOT_LENGTH, FOOT_WIDTH)
    b = foot_rectangle([0, -0.0414], 0.0, FOOT_LENGTH, FOOT_WIDTH)
    assert polygon_distance(a, b) == pytest.approx(0.0828 - FOOT_WIDTH)
    assert polygon_distance(a, a) == pytest.approx(-FOOT_WIDTH)  # full overlap
    c = foot_rectangle([0.0, 0.0], 0.0, FOOT_LENGTH, FOOT_WIDTH)
    assert polygon_distance(a, c) == pytest.approx(0.0414 - FOOT_WIDTH)  # negative: overlap
    # corner to corner: Euclidean distance, not the separating-axis value
    d = foot_rectangle([FOOT_LENGTH + 0.03, FOOT_WIDTH + 0.04], 0.0, FOOT_LENGTH, FOOT_WIDTH)
    e = foot_rectangle([0, 0], 0.0, FOOT_LENGTH, FOOT_WIDTH)
    assert polygon_distance(d, e) == pytest.approx(0.05)
    # yaw brings the heels together
    l_turn = foot_rectangle([0, 0.0414], -0.4, FOOT_LENGTH, FOOT_WIDTH)
    assert polygon_distance(l_turn, b) < polygon_distance(a, b)


def test_convex_hull_drops_inner_and_collinear_points():
    pts = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [0, 1], [1, 0.5]], float)
    hull = convex_hull(pts)
    assert len(hull) == 4
    assert polygon_area(hull) == pytest.approx(2.0)


def test_foot_validation():
    with pytest.raises(ValueError):
        Foot(0.0, 0.06)
