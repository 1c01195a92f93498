"""Full 6-D frame pose task: position and SO(3) log orientation error."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numba import njit

from ..compiled.checks import copy_pose
from ..compiled.checks import entry as check_entry
from ..compiled.rows import frame_jacobian, rotation_rows
from ..model import Kinematics, Robot
from .frame_task import FrameTask
from .task import ROTATION_TOL, TaskError, check_rotation, check_vector

#: a pose target's check and copy in one compiled call (:meth:`FramePoseTask.set_target`)
_copy_pose = check_entry(copy_pose)
_F8 = np.dtype(np.float64)


@njit(cache=True)
def pose_rows(target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J) -> None:
    """e = [p* − p; log(R* Rᵀ)], J = [J_v; Jlog3(R* Rᵀ) J_ω] (target: p*, then R* row-major)."""
    f = slots[0]
    p = ps[f]
    frame_jacobian(Jw, supports[f], p, Jf)
    for i in range(3):
        e[i] = target[i] - p[i]
        for k in range(Jf.shape[1]):
            J[i, k] = Jf[i, k]
    rotation_rows(target[3:12], Rs[f], Jf, e[3:6], J[3:6])


class FramePoseTask(FrameTask):
    """e = [p* − p; log(R* Rᵀ)] (world axes), J = [J_v; Jlog3(R* Rᵀ) J_ω] (6 x nv).

    J_v, J_ω: the frame Jacobian with world-aligned axes at the frame origin; see
    :class:`~wbc.tasks.FrameOrientationTask` for the orientation rows.
    """

    dim = 6
    row_kernel = staticmethod(pose_rows)
    target_fields = ("target_position", "target_rotation")
    length_rows = 3
    stack_type = "frame_pose"  # its `type` in stack files (wbc.tasks.task.register)

    def __init__(
        self,
        robot: Robot,
        frame: str,
        target: pin.SE3 | None = None,
        name: str | None = None,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(robot, frame, name, gain, weight, mask)
        packed = np.zeros(12)  # (both in one array: the compiled tick copies one source)
        self.target_position = packed[:3]
        self.target_rotation = packed[3:].reshape(3, 3)
        self.target_rotation[:] = np.eye(3)
        if target is not None:
            self.set_target(target)

    def set_target(self, target: pin.SE3) -> None:
        """Position and rotation, checked as their setters check them. In one compiled call
        when those setters are this class's own (a support switch anchors its contacts so:
        ~10 µs less at a switch to double support); a target that fails a check goes
        through the setters, which raise."""
        if not isinstance(target, pin.SE3):
            raise TaskError(f"task {self.name!r}: target must be a pinocchio.SE3")
        cls, p, R = type(self), self.target_position, self.target_rotation
        if (
            cls.set_position_target is FramePoseTask.set_position_target
            and cls.set_rotation_target is FramePoseTask.set_rotation_target
            and p.dtype is _F8
            and R.dtype is _F8
            and p.shape == (3,)
            and R.shape == (3, 3)
            and _copy_pose(target.translation, target.rotation, p, R, ROTATION_TOL) <= ROTATION_TOL
        ):
            return
        self.set_position_target(target.translation)
        self.set_rotation_target(target.rotation)

    def set_position_target(self, position: Sequence[float]) -> None:
        check_vector(self, position, 3, "target position", out=self.target_position)

    def set_rotation_target(self, rotation: np.ndarray) -> None:
        check_rotation(self, rotation, out=self.target_rotation)

    def set_target_from(self, kin: Kinematics) -> None:
        self.target_position[:] = kin.translation(self.frame_id)
        self.target_rotation[:] = kin.rotation(self.frame_id)

    @property
    def target(self) -> pin.SE3:
        return pin.SE3(self.target_rotation, self.target_position)
