"""The thesis's one step (ch. 4): 100 poses, double support first, CoM over the left sole,
then the right sole swings forward (wbc.walking.thesis_step)."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.exceptions import TrajectoryError
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT
from wbc.walking import (
    ThesisStepParams,
    check_reference,
    thesis_lipm_step,
    thesis_step,
)


@pytest.fixture(scope="module")
def ref(start):
    return thesis_step(start)


def pose(p):  # thesis poses are 1-based
    return p - 1


def test_hundred_poses_and_support_schedule(ref):
    assert ref.n == 100 and ref.gait == "static"
    assert np.all(ref.support[: pose(40)] == SUPPORT_DOUBLE)  # poses 1-39
    assert np.all(ref.support[pose(40) : pose(100)] == SUPPORT_LEFT)  # right foot swings
    assert ref.support[pose(100)] == SUPPORT_DOUBLE  # landed: the step ends
    assert ref.swing_side(pose(50)) == "right" and ref.swing_side(pose(10)) is None


def test_com_shifts_over_the_left_sole_before_the_swing(ref, start):
    np.testing.assert_allclose(ref.com[0], start.com, atol=1e-12)
    left = ref.l_sole[0, :2]
    # by pose 30 the CoM is over the left sole, as near its centre as the hips allow
    # (LegGeometry.max_com_lateral), and stays there
    legs = start.legs
    half = 0.5 * (start.left.y - start.right.y)
    mid = 0.5 * (start.left.y + start.right.y)
    target_y = mid + legs.max_com_lateral(start.com[2], half) - 5e-5
    assert ref.com[pose(30), 1] == pytest.approx(target_y, abs=1e-6)
    assert np.all(np.linalg.norm(ref.com[pose(30) :] - ref.com[pose(30)], axis=1) < 1e-12)
    # it moves monotonically toward the left sole during the shift
    d = np.linalg.norm(ref.com[: pose(30) + 1, :2] - left, axis=1)
    assert np.all(np.diff(d) <= 1e-12)
    # constant height
    np.testing.assert_allclose(ref.com[:, 2], start.com[2], atol=1e-12)
    # the static criterion: CoM inside the support polygon with the margin, every pose;
    # from pose 40 the polygon is the left foot alone
    m = ref.com_margin()
    assert m.min() >= ref.margin
    single = ref.support == SUPPORT_LEFT
    assert np.all(m[single] >= ref.margin)
    assert np.all(m[single] < ref.foot.width / 2)  # not at the centre: the hips forbid it
    # the stance hip is within its roll limit, and at it
    rolls = legs.leg_rolls(ref.com, ref.torso_yaw, ref.l_sole, ref.r_sole)
    assert -rolls[:, 0].min() <= legs.max_adduction - legs.roll_margin
    assert -rolls[:, 0].min() > legs.max_adduction - legs.roll_margin - 2e-3


def test_com_over_the_sole_centre_is_out_of_the_hips_reach(start):
    with pytest.raises(TrajectoryError, match="unreachable"):
        thesis_step(start, ThesisStepParams(com_target=(0.0, 0.0)))


def test_swing_shape(ref, start):
    p = ThesisStepParams()
    r = ref.r_sole
    np.testing.assert_allclose(r[: pose(40) + 1], np.tile(start.right.position, (pose(40) + 1, 1)))
    apex_pose = int(np.argmax(r[:, 2]))
    assert pose(66) <= apex_pose <= pose(74)  # apex halfway through the swing (poses 40-100)
    assert r[apex_pose, 2] == pytest.approx(p.apex, abs=5e-4)
    assert r[:, 2].min() >= 0.0  # never below the ground
    assert np.all(np.diff(r[pose(40) :, 0]) >= -1e-12)  # forward only
    np.testing.assert_allclose(r[-1, 0] - start.right.x, p.step_length, atol=1e-3)
    assert abs(r[-1, 1] - start.right.y) < 1e-3 and r[-1, 2] == 0.0
    # flat soles: yaw constant, the reference has no roll/pitch by construction
    assert np.ptp(ref.r_sole_yaw) == 0.0 and np.ptp(ref.l_sole_yaw) == 0.0
    R = ref.sole_placement(pose(70), "right").rotation
    np.testing.assert_allclose(R[:, 2], [0, 0, 1], atol=1e-12)
    # the left (support) sole never moves
    assert np.ptp(ref.l_sole, axis=0).max() == 0.0


def test_parameters(start):
    ref = thesis_step(
        start, ThesisStepParams(step_length=0.02, apex=0.015, n_poses=60, duration=2.0)
    )
    assert ref.n == 60 and ref.t[-1] == pytest.approx(2.0)
    assert ref.r_sole[:, 2].max() == pytest.approx(0.015, abs=1e-3)
    assert ref.r_sole[-1, 0] - start.right.x == pytest.approx(0.02, abs=1e-3)
    higher = thesis_step(start, ThesisStepParams(com_height=0.178))
    assert higher.com[-1, 2] == pytest.approx(0.178)
    assert check_reference(higher, legs=start.legs).com_margin >= higher.margin
    # a lower CoM bends the legs: the hips' roll limit then keeps the CoM off the foot
    with pytest.raises(TrajectoryError, match="CoM is -"):
        thesis_step(start, ThesisStepParams(com_height=0.165))


def test_lipm_variant_of_the_thesis_step(start):
    """Sec. 4.1.2: same pose grid, CoM from the 3-D LIPM (a dynamic gait)."""
    ref = thesis_lipm_step(start)
    p = ThesisStepParams()
    assert ref.dt == pytest.approx(p.dt) and ref.gait == "dynamic"
    assert np.all(ref.support[: pose(40)] == SUPPORT_DOUBLE)
    assert np.all(ref.support[pose(40) : pose(100)] == SUPPORT_LEFT)
    assert ref.support[pose(100)] == SUPPORT_DOUBLE
    np.testing.assert_allclose(ref.r_sole[pose(100), 0] - start.right.x, p.step_length, atol=2e-4)
    # during single support the LIPM pivots on one point of the left sole (its ZMP) ...
    ss = slice(pose(40), pose(100))
    pivot = ref.zmp[pose(40)]
    np.testing.assert_allclose(ref.zmp[ss], np.tile(pivot, (60, 1)), atol=1e-9)
    assert ref.signed_distance(pose(50), pivot) >= ref.margin
    # ... and its CoM obeys c'' = (g / zc)(c - pivot) there, eq. (1.63)-(1.64)
    rel = ref.com[ss, :2] - pivot
    np.testing.assert_allclose(ref.com_acc[ss, :2], 9.81 / ref.com_height * rel, atol=1e-9)
    np.testing.assert_allclose(ref.com_vel[0], 0.0, atol=1e-12)
