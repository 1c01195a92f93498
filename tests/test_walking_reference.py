"""The reference object the control loop consumes (wbc.walking.reference)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wbc.exceptions import TrajectoryError
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from wbc.walking import forward_walk, thesis_step
from wbc.walking.geometry import polygon_area


@pytest.fixture(scope="module")
def ref(start):
    return forward_walk(start, 4, generator="lipm")


def test_support_helpers(ref):
    seen = set()
    for a, b, s in ref.phases():
        assert np.all(ref.support[a:b] == s)
        seen.add(s)
        i = a
        if s == SUPPORT_DOUBLE:
            assert ref.swing_side(i) is None and ref.stance_side(i) is None
            assert ref.contact_sides(i) == ("left", "right")
        elif s == SUPPORT_LEFT:
            assert ref.swing_side(i) == "right" and ref.contact_sides(i) == ("left",)
        else:
            assert ref.swing_side(i) == "left" and ref.stance_side(i) == "right"
    assert seen == {SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT}
    changes = ref.support_changes()
    assert np.all(ref.support[changes] != ref.support[changes - 1])
    assert np.array_equal(ref.swing_mask("left"), ref.support == SUPPORT_RIGHT)
    sw = ref.swing_position()
    assert np.all(np.isnan(sw[ref.support == SUPPORT_DOUBLE]))
    assert np.all(np.isfinite(sw[ref.support != SUPPORT_DOUBLE]))
    assert ref.index_at(ref.t[17] + 1e-4) == 17 and ref.index_at(-1.0) == 0


def test_support_polygons_and_distances(ref):
    i_ds = 0
    i_ss = int(np.argmax(ref.support == SUPPORT_LEFT))
    ds = ref.support_polygon(i_ds)
    ss = ref.support_polygon(i_ss)
    length, width = ref.foot.length, ref.foot.width  # the robot's (101 x 61 mm)
    assert polygon_area(ss) == pytest.approx(length * width)
    assert polygon_area(ds) > 2 * length * width
    left = ref.l_sole[i_ss, :2]
    assert ref.signed_distance(i_ss, left) == pytest.approx(width / 2)
    assert ref.signed_distance(i_ss, ref.r_sole[i_ss, :2]) < 0  # the swing foot is not support
    shrunk = ref.support_polygon(i_ss, margin=0.01)
    assert polygon_area(shrunk) == pytest.approx((length - 0.02) * (width - 0.02))
    A, b = ref.support_halfplanes(i_ss, 0.01)
    assert np.all(A @ left <= b)
    m = ref.com_margin()
    assert m.shape == (ref.n,)
    assert m[0] == pytest.approx(ref.signed_distance(0, ref.com[0]))


def test_exports(ref):
    ch = ref.to_channels()
    for name in ("com_ref", "zmp_ref", "swing_ref", "l_sole_ref", "r_sole_ref", "support"):
        assert ch[name].shape[0] == ref.n
    q = ch["l_sole_ref"][:, 3:]
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0)
    M = ref.sole_placement(5, "left")
    np.testing.assert_allclose(M.translation, ref.l_sole[5])
    d = ref.describe()
    assert d["ticks"] == ref.n and d["generator"] == "lipm"
    assert ref.meta["check"]["zmp_margin"] >= ref.margin


def test_validation(ref):
    with pytest.raises(TrajectoryError, match="com has shape"):
        dataclasses.replace(ref, com=ref.com[:, :2])
    with pytest.raises(TrajectoryError, match="uniformly"):
        t = ref.t.copy()
        t[5:] += 0.001
        dataclasses.replace(ref, t=t)
    with pytest.raises(TrajectoryError, match="support code"):
        sup = ref.support.copy()
        sup[3] = 7
        dataclasses.replace(ref, support=sup)
    with pytest.raises(TrajectoryError, match="non-finite"):
        com = ref.com.copy()
        com[2, 0] = np.nan
        dataclasses.replace(ref, com=com)


def test_static_reference_has_sole_velocities(start):
    ref = thesis_step(start)
    v = np.gradient(ref.r_sole, ref.t, axis=0)
    np.testing.assert_allclose(ref.r_sole_vel[1:-1], v[1:-1], atol=3e-3)


def test_swing_velocities_match_positions(ref):
    for side in ("left", "right"):
        pos, _ = ref.sole(side)
        vel = ref.sole_velocity(side)
        # the trapezoid rule on the velocities reproduces the displacements
        step = 0.5 * (vel[1:] + vel[:-1]) * ref.dt
        np.testing.assert_allclose(np.diff(pos, axis=0), step, atol=2e-4)
        assert np.all(vel[ref.in_contact(side)] == 0.0)


def test_a_walk_takes_its_robots_foot_and_legs_never_the_bioloids(start):
    """A start made from a robot carries that robot's foot and legs (what a walk uses unless
    given others); a start made by hand has none, and a walk from it says what to pass."""
    from wbc import load_robot
    from wbc.walking import LegGeometry, StandingState
    from wbc.walking.footsteps import Footstep
    from wbc.walking.geometry import Foot
    from wbc.walking.keyposes import keypose_walk

    kokone = load_robot("kokone")
    k_start = StandingState.from_robot(kokone)
    assert k_start.foot == Foot(*kokone.foot_size) != start.foot
    assert k_start.legs == LegGeometry.from_robot(kokone, kokone.configuration("stand"))
    assert keypose_walk(k_start).foot == k_start.foot  # (was the Bioloid's 101 x 61 mm)
    by_hand = StandingState(start.com, Footstep("left", *start.left.xy), start.right)
    with pytest.raises(TrajectoryError, match=r"no foot given.*pass foot=Foot\(length, width\)"):
        forward_walk(by_hand, 2)
    with pytest.raises(TrajectoryError, match=r"no legs given.*LegGeometry.from_robot\(robot\)"):
        forward_walk(by_hand, 2, foot=start.foot)
    assert forward_walk(by_hand, 2, foot=start.foot, legs=start.legs).n > 0
    with pytest.raises(TypeError):
        Foot()  # type: ignore[call-arg]  # (no default foot: a robot's is measured)
