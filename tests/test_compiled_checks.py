"""The compiled input checks of the hot path (wbc.compiled.checks): the same verdicts as numpy,
and checked copies that copy everything or nothing."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from wbc.compiled.checks import copy_finite, copy_pose, finite, outside, quaternion_defect
from wbc.exceptions import TaskError
from wbc.tasks import ContactTask


@pytest.mark.parametrize("seed", range(20))
def test_outside_agrees_with_numpy(robot, random_configuration, seed):
    lo, hi = robot.q_min, robot.q_max
    q = random_configuration(seed)
    expected = bool(((q[7:] < lo) | (q[7:] > hi)).any())
    assert outside(q, lo, hi) == expected


def test_finite_checks_every_entry_even_when_the_squares_overflow():
    assert finite(np.array([1e200, -1e200, 3.0]))  # Σ v² overflows; every entry is finite
    assert not finite(np.array([1e200, np.inf, 3.0]))
    assert not finite(np.array([0.0, np.nan]))
    out = np.zeros(2)
    assert copy_finite(np.array([1e200, 2.0]), out) and out[0] == 1e200
    assert quaternion_defect(np.array([1e200, 0, 0, 0, 0, 0, 1.0])) == 0.0
    assert quaternion_defect(np.array([np.nan, 0, 0, 0, 0, 0, 1.0])) == np.inf


def test_copy_pose_copies_both_or_neither():
    R = pin.rpy.rpyToMatrix(0.1, -0.2, 0.3)
    p = np.array([0.01, -0.02, 0.03])
    out_p, out_R = np.full(3, 7.0), np.full((3, 3), 7.0)
    assert copy_pose(p, R, out_p, out_R, 1e-6) <= 1e-6
    assert np.array_equal(out_p, p) and np.array_equal(out_R, R)
    for bad_p, bad_R in [
        (np.array([np.nan, 0.0, 0.0]), R),
        (p, 2.0 * R),  # not a rotation
        (p, np.diag([1.0, 1.0, -1.0])),  # a reflection
        (p, np.full((3, 3), np.inf)),
    ]:
        out_p[:], out_R[:] = 7.0, 7.0
        assert copy_pose(bad_p, bad_R, out_p, out_R, 1e-6) > 1e-6
        assert (out_p == 7.0).all() and (out_R == 7.0).all()


def test_pose_target_in_one_call_or_through_the_setters(robot):
    """FramePoseTask.set_target: the compiled check and copy, the setters' errors when it
    fails, and a subclass's own setter honoured."""
    task = ContactTask(robot, "l_sole")
    handle_p, handle_R = task.target_position, task.target_rotation
    M = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.1, 0.2), np.array([0.1, 0.2, 0.3]))
    task.set_target(M)
    assert task.target_position is handle_p and task.target_rotation is handle_R
    assert np.array_equal(handle_p, M.translation) and np.array_equal(handle_R, M.rotation)
    bad = pin.SE3(M.rotation, np.array([np.nan, 0.0, 0.0]))
    with pytest.raises(TaskError, match="non-finite"):
        task.set_target(bad)
    assert np.array_equal(handle_R, M.rotation)  # the rotation is untouched
    skewed = pin.SE3.Identity()
    skewed.rotation = np.diag([1.0, 1.0, -1.0])
    with pytest.raises(TaskError, match="not a rotation"):
        task.set_target(skewed)

    class Offset(ContactTask):
        def set_position_target(self, position) -> None:
            super().set_position_target(np.asarray(position) + [0.0, 0.0, 0.01])

    offset = Offset(robot, "r_sole")
    offset.set_target(M)
    assert np.array_equal(offset.target_position, M.translation + [0.0, 0.0, 0.01])
