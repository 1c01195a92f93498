"""Cubic splines and quintic profiles (wbc.walking.spline)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.interpolate as si
from hypothesis import given
from hypothesis import strategies as st

from wbc.exceptions import TrajectoryError
from wbc.walking.spline import CubicSpline, QuinticSegment, min_jerk, smoothstep


@st.composite
def waypoints(draw):
    n = draw(st.integers(2, 8))
    gaps = draw(st.lists(st.floats(0.05, 2.0), min_size=n - 1, max_size=n - 1))
    knots = np.concatenate([[draw(st.floats(-1, 1))], np.cumsum(gaps)])
    knots[1:] += knots[0]
    values = np.array(draw(st.lists(st.floats(-1, 1), min_size=3 * n, max_size=3 * n))).reshape(
        n, 3
    )
    return knots, values


@given(waypoints(), st.sampled_from(["clamped", "natural"]))
def test_interpolates_waypoints(wp, boundary):
    knots, values = wp
    s = CubicSpline(knots, values, boundary)
    np.testing.assert_allclose(s(knots), values, atol=1e-12)


@given(waypoints(), st.sampled_from(["clamped", "natural"]))
def test_position_velocity_acceleration_continuous_at_knots(wp, boundary):
    knots, values = wp
    s = CubicSpline(knots, values, boundary)
    eps = 1e-7
    inner = knots[1:-1]
    if inner.size == 0:
        return
    for k in range(3):
        left = s.evaluate(inner - eps)[k]
        right = s.evaluate(inner + eps)[k]
        scale = 1.0 + np.abs(s.evaluate(inner)[k])
        # jumps at a knot would be O(1); continuous functions differ by O(eps * derivative)
        assert np.all(np.abs(left - right) <= 1e-4 * scale * (10**k))


@given(waypoints())
def test_matches_scipy(wp):
    knots, values = wp
    v0, v1 = np.array([0.3, -0.2, 0.0]), np.array([0.1, 0.0, -0.4])
    mine = CubicSpline(knots, values, "clamped", v0, v1)
    ref = si.CubicSpline(knots, values, bc_type=((1, v0), (1, v1)))
    t = np.linspace(knots[0], knots[-1], 57)
    pos, vel, acc = mine.evaluate(t)
    np.testing.assert_allclose(pos, ref(t), atol=1e-9)
    np.testing.assert_allclose(vel, ref(t, 1), atol=1e-8)
    np.testing.assert_allclose(acc, ref(t, 2), atol=1e-7)
    nat = CubicSpline(knots, values, "natural")
    np.testing.assert_allclose(
        nat(t), si.CubicSpline(knots, values, bc_type="natural")(t), atol=1e-9
    )


def test_boundary_conditions_and_derivatives():
    knots = [0.0, 0.4, 1.0, 1.7]
    values = [0.0, 1.0, -0.5, 0.2]
    s = CubicSpline(knots, values, "clamped", start_velocity=0.5, end_velocity=-1.0)
    _, vel, _ = s.evaluate(np.array([0.0, 1.7]))
    np.testing.assert_allclose(vel, [0.5, -1.0], atol=1e-12)
    n = CubicSpline(knots, values, "natural")
    _, _, acc = n.evaluate(np.array([0.0, 1.7]))
    np.testing.assert_allclose(acc, [0.0, 0.0], atol=1e-12)
    # velocity and acceleration are the derivatives of position (central differences)
    t = np.linspace(0.01, 1.69, 200)
    h = 1e-5
    pos_p, pos_m = s(t + h), s(t - h)
    _, vel, acc = s.evaluate(t)
    np.testing.assert_allclose((pos_p - pos_m) / (2 * h), vel, atol=1e-6)
    vp, vm = s.evaluate(t + h)[1], s.evaluate(t - h)[1]
    np.testing.assert_allclose((vp - vm) / (2 * h), acc, atol=1e-4)
    # scalar in, scalar out; held outside the knots
    assert np.ndim(s(0.2)) == 0
    p, v, a = s.evaluate(5.0)
    assert p == pytest.approx(0.2) and v == 0.0 and a == 0.0


def test_bad_input():
    with pytest.raises(TrajectoryError, match="increasing"):
        CubicSpline([0.0, 1.0, 1.0], [0, 1, 2])
    with pytest.raises(TrajectoryError, match="waypoints"):
        CubicSpline([0.0, 1.0], [0, 1, 2])
    with pytest.raises(TrajectoryError, match="2 knots"):
        CubicSpline([0.0], [0])
    with pytest.raises(TrajectoryError, match="boundary"):
        CubicSpline([0.0, 1.0], [0, 1], boundary="periodic")
    with pytest.raises(TrajectoryError, match="finite"):
        CubicSpline([0.0, 1.0], [0, np.nan])


@pytest.mark.parametrize("profile", [min_jerk, smoothstep])
def test_profiles(profile):
    s = np.linspace(0, 1, 1001)
    p, dp, ddp = profile(s)
    assert p[0] == 0 and p[-1] == pytest.approx(1.0)
    assert np.all(np.diff(p) >= 0)  # monotone
    assert dp[0] == pytest.approx(0) and dp[-1] == pytest.approx(0)
    np.testing.assert_allclose(np.gradient(p, s)[1:-1], dp[1:-1], atol=2e-3)
    np.testing.assert_allclose(np.gradient(dp, s)[5:-5], ddp[5:-5], atol=2e-2)
    if profile is min_jerk:
        assert ddp[0] == pytest.approx(0) and ddp[-1] == pytest.approx(0)


def test_quintic_segment_boundaries():
    q = QuinticSegment([0.0, 1.0], [0.0, -1.0], [0.0, 2.0], [1.0, 0.0], [0.5, 0.0], [0.0, 0.0], 0.8)
    p, v, a = q.evaluate(np.array([0.0, 0.8]))
    np.testing.assert_allclose(p, [[0.0, 1.0], [1.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(v, [[0.0, -1.0], [0.5, 0.0]], atol=1e-12)
    np.testing.assert_allclose(a, [[0.0, 2.0], [0.0, 0.0]], atol=1e-10)
    with pytest.raises(TrajectoryError):
        QuinticSegment(0, 0, 0, 1, 0, 0, 0.0)
