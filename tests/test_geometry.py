"""wbc.geometry's angle helpers, the one wrap and the one mean of two angles (the polygons
are tested with the walking geometry)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from hypothesis import given
from hypothesis import strategies as st

from wbc.geometry import heading_free, mean_angle, relative_pose, rot2, wrap_angle, yaw_of

ANGLES = st.floats(-1e4, 1e4)


def _exact_wrap(a: float) -> float:
    """``a − 2πk`` in (−π, π] without rounding (fmod is exact, so is the one correction)."""
    r = math.fmod(a, 2.0 * math.pi)
    if r > math.pi:
        r -= 2.0 * math.pi
    elif r <= -math.pi:
        r += 2.0 * math.pi
    return r


def _distance(a: float, b: float) -> float:
    """Distance on the circle (rad, in [0, π])."""
    return abs(_exact_wrap(a - b))


@given(ANGLES)
def test_wrap_angle_is_in_the_half_open_range_and_the_same_direction(angle):
    """(−π, π], and a whole number of turns away from the angle."""
    w = wrap_angle(angle)
    assert -math.pi < w <= math.pi
    turns = (angle - w) / (2.0 * math.pi)
    assert abs(turns - round(turns)) < 1e-9


@given(ANGLES)
def test_wrap_angle_is_within_one_ulp_of_the_exact_wrap(angle):
    """The one rounding of ``π − a``: one ulp of max(π, |a|) from the exact ``a − 2πk``."""
    w, exact = wrap_angle(angle), _exact_wrap(angle)
    assert _distance(w, exact) <= math.ulp(max(math.pi, abs(angle)))


@given(st.lists(ANGLES, min_size=1, max_size=8))
def test_wrap_angle_of_an_array_is_the_scalar_wrap_of_each_element_bit_for_bit(angles):
    got = wrap_angle(np.array(angles))
    assert isinstance(got, np.ndarray) and got.shape == (len(angles),)
    assert got.tolist() == [wrap_angle(a) for a in angles]


def test_wrap_angle_ends():
    assert wrap_angle(math.pi) == math.pi
    assert wrap_angle(-math.pi) == math.pi
    assert wrap_angle(0.0) == 0.0
    assert abs(wrap_angle(3 * math.pi / 2) + math.pi / 2) < 1e-15


def test_wrap_angle_just_above_pi_is_not_minus_pi():
    """``(π − a) mod 2π`` rounds up to 2π for ``a`` one ulp above π: the wrap would give −π,
    outside (−π, π]; it gives π (4.4e-16 from the exact value, like any wrap's rounding)."""
    above = math.nextafter(math.pi, 4.0)
    assert wrap_angle(above) == math.pi
    assert wrap_angle(np.array([above, -math.pi]))[0] == math.pi


@given(ANGLES)
def test_mean_of_an_angle_with_itself_is_the_angle(a):
    assert mean_angle(a, a) == a


@given(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3))
def test_mean_angle_is_equidistant_on_the_short_arc(a, b):
    """Half-way: as far from ``a`` as from ``b`` on the circle, within a quarter turn of both."""
    m = mean_angle(a, b)
    tol = 1e-12
    assert abs(_distance(m, a) - _distance(m, b)) <= tol
    assert _distance(m, a) <= 0.5 * math.pi + tol
    assert abs(2.0 * _distance(m, a) - _distance(a, b)) <= tol


@given(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3))
def test_mean_angle_is_symmetric(a, b):
    """mean(a, b) and mean(b, a) are the same heading (unless a and b are opposite, where
    both half-way headings are equally right)."""
    if abs(_distance(a, b) - math.pi) < 1e-9:
        return
    assert _distance(mean_angle(a, b), mean_angle(b, a)) <= 1e-12


@given(st.lists(st.tuples(ANGLES, ANGLES), min_size=1, max_size=8))
def test_mean_angle_of_arrays_is_the_scalar_mean_of_each_pair_bit_for_bit(pairs):
    a, b = (np.array(x) for x in zip(*pairs, strict=True))
    assert mean_angle(a, b).tolist() == [mean_angle(x, y) for x, y in pairs]


def test_mean_angle_goes_the_short_way_round():
    assert abs(mean_angle(3.0, -3.0) - math.pi) < 1e-15  # not 0: across ±π
    assert mean_angle(0.0, 0.5) == 0.25
    assert abs(mean_angle(-0.1, 0.1)) < 1e-16


@given(st.floats(-math.pi + 1e-6, math.pi - 1e-6), st.floats(-1.2, 1.2))
def test_yaw_of_is_the_heading_of_a_rotation_whatever_its_pitch(yaw: float, pitch: float) -> None:
    """yaw_of(Rz(ψ) Ry(θ)) = ψ for |θ| < π/2 (the x axis keeps its ground direction)."""
    c, s, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    Ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    assert abs(yaw_of(Rz @ Ry) - yaw) < 1e-12


@given(
    st.floats(-3.1, 3.1),
    st.floats(-1.4, 1.4),
    st.floats(-1.4, 1.4),
)
def test_heading_free_removes_the_heading_and_keeps_the_tilt(
    yaw: float, pitch: float, roll: float
) -> None:
    """heading_free(Rz(ψ) Ry(θ) Rx(φ)) = Ry(θ) Rx(φ): no heading left, the same tilt."""
    tilt = pin.rpy.rpyToMatrix(roll, pitch, 0.0)
    R = pin.rpy.rpyToMatrix(0.0, 0.0, yaw) @ tilt
    free = heading_free(R)
    assert abs(yaw_of(free)) < 1e-12
    np.testing.assert_allclose(free, tilt, atol=1e-12)


@given(
    frame=st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(-4, 4)),
    pose=st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(-4, 4)),
)
def test_relative_pose_put_back_in_its_frame_is_the_pose(frame, pose):
    """``p = p_f + Rz(ψ_f) d`` and ``ψ ≡ ψ_f + dψ`` for ``(d, dψ) = relative_pose(f, p)``,
    ``dψ`` within (−π, π]."""
    d = relative_pose(frame, pose)
    back = np.asarray(frame[:2]) + rot2(frame[2]) @ d[:2]
    np.testing.assert_allclose(back, pose[:2], atol=1e-12)
    assert -math.pi < d[2] <= math.pi
    assert abs(wrap_angle(frame[2] + d[2] - pose[2])) < 1e-12
