"""The swing sole's path (wbc.walking.schedule): the one definition every generator uses."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc.exceptions import TrajectoryError
from wbc.walking import Footstep, SwingParams
from wbc.walking.schedule import _swing_profile
from wbc.walking.spline import min_jerk


def _foot(x: float, z: float) -> Footstep:
    return Footstep("left", x, 0.05, 0.0, z)


@settings(max_examples=60, deadline=None)
@given(
    landing=st.floats(0.05, 0.95),
    apex=st.floats(0.002, 0.05),
    za=st.floats(-0.01, 0.01),
    zb=st.floats(-0.01, 0.01),
    profile=st.sampled_from(["quintic", "cubic"]),
)
def test_the_swing_rises_to_its_apex_at_the_stated_share_and_lands_at_rest(
    landing, apex, za, zb, profile
):
    """z(0) = lift-off, z(1) = landing, the apex ``top`` at s = 1 - landing, never below the
    base line; the height's speed is zero at lift-off, apex and touch-down, and the returned
    derivative is the path's (central differences)."""
    swing = SwingParams(apex=apex, profile=profile, landing=landing)
    a, b = _foot(0.0, za), _foot(0.03, zb)
    s = np.linspace(0.0, 1.0, 2001)
    pos, dpos = _swing_profile(a, b, s, swing)
    top = max(za, zb) + apex
    assert pos[0, 2] == pytest.approx(za, abs=1e-12)
    assert pos[-1, 2] == pytest.approx(zb, abs=1e-12)
    base = za + (zb - za) * (pos[:, 0] - 0.0) / 0.03
    assert np.all(pos[:, 2] >= base - 1e-12)
    apex_s = 1.0 - landing
    top_pos, top_vel = _swing_profile(a, b, np.array([apex_s]), swing)
    assert top_pos[0, 2] == pytest.approx(top, abs=1e-12) and pos[:, 2].max() <= top + 1e-12
    _, vel = _swing_profile(a, b, np.array([0.0, 1.0]), swing)
    assert abs(top_vel[0, 2]) < 1e-9 and np.all(np.abs(vel[:, 2]) < 1e-9)
    inner = (np.abs(s[1:-1] - apex_s) > 2e-3) if profile == "cubic" else slice(None)
    fd = (pos[2:, 2] - pos[:-2, 2]) / (s[2:] - s[:-2])
    # central differences err by h^2/6 |z'''|, |z'''| <= 60 H / L^3 (min-jerk): twice that
    rise, short = top - min(za, zb), min(landing, apex_s)
    tol = 2.0 * (s[1] - s[0]) ** 2 / 6.0 * 60.0 * rise / short**3 + 1e-12
    assert np.allclose(fd[inner], dpos[1:-1, 2][inner], rtol=0.0, atol=tol)


def test_a_half_way_apex_is_the_mirrored_profile_bit_for_bit():
    """landing = 0.5 (the default) is the profile the recorded walks were made with: the
    min-jerk rise over the first half mirrored down over the second."""
    a, b = _foot(0.0, 0.0), _foot(0.035, 0.002)
    s = np.arange(24) / 24
    pos, dpos = _swing_profile(a, b, s, SwingParams(apex=0.012))
    up = s < 0.5
    h, dh, _ = min_jerk(np.where(up, 2.0 * s, 2.0 - 2.0 * s))
    base = a.position[2] + (b.position[2] - a.position[2]) * min_jerk(s)[0]
    dbase = (b.position[2] - a.position[2]) * min_jerk(s)[1]
    top = 0.002 + 0.012
    assert np.array_equal(pos[:, 2], base + (top - base) * h)
    assert np.array_equal(dpos[:, 2], dbase * (1.0 - h) + (top - base) * np.where(up, 2, -2) * dh)


@pytest.mark.parametrize("landing", [0.0, 1.0, -0.2, float("nan")])
def test_a_landing_share_outside_the_swing_is_refused(landing):
    with pytest.raises(TrajectoryError, match="landing"):
        SwingParams(landing=landing).validate()
