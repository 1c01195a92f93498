"""The kernels' one signature (wbc.compiled.signature): a task type written outside the
package that reads the optional inputs (the frames' velocities, the centroidal momentum, the
velocity v) gets Pinocchio's values on both paths, and runs compiled."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from numba import njit

from wbc import Kinematics, TaskError
from wbc.compiled.rows import frame_jacobian
from wbc.solvers import HierarchicalQP, TaskStack, WeightedQP
from wbc.tasks import ContactTask, PostureTask, Task


@njit(cache=True)
def _motion_rows(target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J):
    """e = [v_f* − v_f (linear); h* − h (linear momentum); v*_6 − v_6], J their Jacobians."""
    f = slots[0]
    frame_jacobian(Jw, supports[f], ps[f], Jf)
    for i in range(3):
        e[i] = target[i] - vs[f, i]
        e[3 + i] = target[3 + i] - hg[i]
        for k in range(Jw.shape[1]):
            J[i, k] = Jf[i, k]
            J[3 + i, k] = Ag[i, k]
    e[6] = target[6] - v[6]
    for k in range(Jw.shape[1]):
        J[6, k] = 1.0 if k == 6 else 0.0


class MotionTask(Task):
    """Outside the package: a frame's velocity, the linear momentum and one joint's speed."""

    dim = 7
    row_kernel = staticmethod(_motion_rows)
    target_fields = ("target",)
    kernel_inputs = frozenset({"frame_velocities", "momentum", "velocity"})

    def __init__(self, robot, frame: str, weight: float = 1e-3) -> None:
        super().__init__("motion", weight=weight)
        self.frame_id = robot.frame_id(frame)
        self.target = np.zeros(7)


def test_the_optional_inputs_are_pinocchios(robot):
    rng = np.random.default_rng(3)
    q = robot.configuration("walk_ready")
    kin = Kinematics(robot, q)
    kin.v = rng.normal(size=robot.nv)
    task = MotionTask(robot, "r_sole")
    e = task.compute_error(kin)
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q, kin.v)
    pin.updateFramePlacements(robot.model, data)
    frame_v = pin.getFrameVelocity(robot.model, data, task.frame_id, pin.LOCAL_WORLD_ALIGNED)
    assert np.abs(-e[:3] - frame_v.linear).max() < 1e-12
    momentum = pin.computeCentroidalMomentum(robot.model, data, q, kin.v)
    assert np.abs(-e[3:6] - momentum.linear).max() < 1e-12
    assert -e[6] == kin.v[6]
    assert np.abs(task.compute_jacobian(kin)[3:6] @ kin.v - momentum.linear).max() < 1e-12


def test_undeclared_inputs_are_zero(robot):
    class Undeclared(MotionTask):
        kernel_inputs = frozenset()

    kin = Kinematics(robot, robot.configuration("walk_ready"))
    kin.v = np.ones(robot.nv)
    assert not Undeclared(robot, "r_sole").compute_error(kin).any()  # (targets are 0)


def stack_with(robot, q, task):
    stack = TaskStack(robot)
    kin = Kinematics(robot, q)
    for sole in ("l_sole", "r_sole"):
        contact = stack.add(ContactTask(robot, sole, name=sole), level=0, hard=True)
        contact.set_target_from(kin)
    stack.add(task, level=1)
    posture = stack.add(PostureTask(robot), level=2, weight=1e-2)
    posture.set_target(q)
    return stack


@pytest.mark.parametrize("solver", [WeightedQP, HierarchicalQP])
def test_a_task_reading_every_input_runs_compiled_and_agrees(robot, solver):
    """The compiled tick computes the declared inputs itself (velocities) or from the
    plan (momentum, v): the same step as the numpy path, to 1e-9."""
    q = robot.configuration("walk_ready")
    v = np.random.default_rng(5).normal(size=robot.nv)
    steps = {}
    for compiled in (None, False):
        task = MotionTask(robot, "r_sole")
        task.target[:] = [0.01, 0.0, 0.02, 0.05, 0.0, -0.03, 0.2]
        s = solver(stack_with(robot, q, task), compiled=compiled)
        s.kin.v = v
        steps[compiled] = s.step(q, dt=0.01)
        assert s.compiled_ticks == (1 if compiled is None else 0), s.compiled_reason()
    assert np.abs(steps[None] - steps[False]).max() < 1e-9
    assert np.abs(steps[None] - q).max() > 1e-4  # (the task moved something)


def test_an_unknown_input_is_named():
    with pytest.raises(TaskError, match=r"kernel_inputs.*'speed'"):

        class Bad(MotionTask):
            kernel_inputs = frozenset({"speed"})


def test_a_copied_task_reads_its_own_targets(robot):
    """The numpy path's kernel call reads a task's targets by address: a copy of the task
    (deepcopy, pickle) must not read the original's."""
    import copy

    from wbc.tasks import ComTask

    kin = Kinematics(robot, robot.configuration("walk_ready"))
    task = ComTask(robot, [0.0, 0.0, 0.2])
    e = task.compute_error(kin)
    twin = copy.deepcopy(task)
    twin.set_target([0.1, 0.0, 0.2])
    assert twin.compute_error(kin)[0] - task.compute_error(kin)[0] == pytest.approx(0.1)
    assert np.array_equal(task.compute_error(kin), e)


def test_a_kernel_of_the_old_signature_is_refused_when_its_class_is_defined():
    """A row kernel (or a box limit's bound kernel) with the wrong number of arguments is
    refused in one line naming the class and the signature, not in numba's typing at the
    first compiled tick (a user's 12-argument kernel of the earlier signature did that)."""
    from wbc.exceptions import ModelError
    from wbc.limits import BoxLimit, Constraint

    @njit(cache=False)
    def old_rows(target, slots, Rs, ps, supports, Jw, com, Jcom, q, Jf, e, J):
        e[0] = 0.0

    with pytest.raises(ModelError, match=r"task type Old: row_kernel 'old_rows' takes 12 ") as e:

        class Old(Task):
            dim = 1
            row_kernel = staticmethod(old_rows)

    assert "\n" not in str(e.value) and "(params, slots, Rs, ps, vs," in str(e.value)
    with pytest.raises(ModelError, match=r"box limit type OldBox: bound_kernel 'old_rows'"):

        class OldBox(BoxLimit):
            bound_kernel = staticmethod(old_rows)

    with pytest.raises(ModelError, match=r"constraint type OldRows: row_kernel 'old_rows'"):

        class OldRows(Constraint):
            rows = 1
            row_kernel = staticmethod(old_rows)
