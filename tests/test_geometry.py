"""wbc.geometry's angle wrap (the polygons are tested with the walking geometry)."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from wbc.geometry import wrap_angle


@given(st.floats(-1e4, 1e4))
def test_wrap_angle_is_in_the_half_open_range_and_the_same_direction(angle):
    """(−π, π], and a whole number of turns away from the angle."""
    w = wrap_angle(angle)
    assert -math.pi < w <= math.pi
    turns = (angle - w) / (2.0 * math.pi)
    assert abs(turns - round(turns)) < 1e-9


def test_wrap_angle_ends():
    assert wrap_angle(math.pi) == math.pi
    assert wrap_angle(-math.pi) == math.pi
    assert wrap_angle(0.0) == 0.0
    assert abs(wrap_angle(3 * math.pi / 2) + math.pi / 2) < 1e-15
