"""Support-polygon margin of the real CoP (convex hull of the contact points)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

pytest.importorskip("mujoco")

from wbc.geometry import convex_hull
from wbc.sim.log import hull_margin


def test_margin_of_a_rectangle():
    pts = np.array([[0, 0], [0.1, 0], [0.1, 0.06], [0, 0.06], [0.05, 0.03]])
    assert len(convex_hull(pts)) == 4
    assert hull_margin(pts, [0.05, 0.03]) == pytest.approx(0.03)
    assert hull_margin(pts, [0.09, 0.03]) == pytest.approx(0.01)
    assert hull_margin(pts, [0.12, 0.03]) == pytest.approx(-0.02)
    assert hull_margin(pts[:2], [0.05, 0.0]) == 0.0  # an edge: tipping


@given(
    st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1)), min_size=3, max_size=12),
    st.lists(st.floats(0.01, 1.0), min_size=12, max_size=12),
)
def test_a_weighted_mean_of_the_points_is_never_outside(points, weights):
    pts = np.array(points)
    w = np.array(weights[: len(pts)])
    cop = (pts * w[:, None]).sum(axis=0) / w.sum()
    assert hull_margin(pts, cop) >= -1e-9
    for p in pts:  # every point is inside or on the hull
        assert hull_margin(pts, p) >= -1e-9
    for v in convex_hull(pts):  # the hull's vertices lie on its edge
        assert hull_margin(pts, v) == pytest.approx(0.0, abs=1e-7)
