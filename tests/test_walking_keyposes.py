"""The Kokone thesis's key-pose static walk: pose structure, support schedule, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.exceptions import TrajectoryError
from wbc.recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from wbc.walking.footsteps import Footstep
from wbc.walking.geometry import Foot
from wbc.walking.keyposes import KeyPoseParams, key_poses, keypose_walk
from wbc.walking.reference import StandingState

START = StandingState(
    np.array([0.0, 0.0, 0.2]), Footstep("left", 0.0, 0.0225), Footstep("right", 0.0, -0.0225)
)
PARAMS = KeyPoseParams(stride=0.04, clearance=0.012, inset=0.005, n_cycles=2)


def test_poses_4_plus_8_per_cycle_and_the_com_over_the_stance_foot():
    poses = key_poses(START, PARAMS)
    assert len(poses) == 4 + 8 * 2
    # pose 2: CoM over the right sole, 5 mm toward the left one; pose 3 lifts the left sole
    assert poses[1].com_xy == pytest.approx([0.0, -0.0175])
    assert poses[2].lifted == "left" and poses[2].left[2] == pytest.approx(0.012)
    assert poses[3].left == pytest.approx([0.02, 0.0225, 0.0])  # half a stride
    for p in poses:  # every lifted pose: CoM over the other (stance) sole, feet flat
        if p.lifted is not None:
            stance = p.right if p.lifted == "left" else p.left
            assert abs(p.com_xy[1] - stance[1]) == pytest.approx(0.005)
            assert p.com_xy[0] == pytest.approx(stance[0])
    # after two cycles both soles have advanced by 2 strides (left: + a half stride)
    assert poses[-1].right[0] == pytest.approx(2 * 0.04)
    assert poses[-1].left[0] == pytest.approx(0.02 + 2 * 0.04)


def test_reference_support_and_static_stability():
    ref = keypose_walk(START, PARAMS, Foot(0.07, 0.04), check=False)
    per = round(PARAMS.pose_time / PARAMS.dt)
    assert ref.n == (20 - 1) * per + 1 and ref.gait == "static"
    assert set(np.unique(ref.support)) == {SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT}
    single = ref.support != SUPPORT_DOUBLE
    lifted = np.maximum(ref.l_sole[:, 2], ref.r_sole[:, 2]) > 1e-12
    assert np.all(single[lifted])  # a sole in the air only in single support
    assert ref.com_margin().min() == pytest.approx(0.015)  # 20 mm half width - 5 mm inset
    assert len(ref.plan.steps) == 1 + 2 * 2


def test_bad_parameters_are_refused_in_one_line():
    with pytest.raises(TrajectoryError, match="stride must be positive"):
        keypose_walk(START, KeyPoseParams(stride=-0.01))
    with pytest.raises(TrajectoryError, match="dt must be at most pose_time / 4"):
        keypose_walk(START, KeyPoseParams(dt=0.5))
    turned = StandingState(START.com, Footstep("left", 0.0, 0.02, 0.3), START.right)
    with pytest.raises(TrajectoryError, match="must face"):
        keypose_walk(turned, foot=Foot(0.07, 0.04))
