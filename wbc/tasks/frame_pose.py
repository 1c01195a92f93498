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
        #: the position and rotation (row-major) targets in one array (never re-bound)
        self.target_packed = packed
        self.target_position = packed[:3]
        self.target_rotation = packed[3:].reshape(3, 3)
        self.target_rotation[:] = np.eye(3)
        if target is not None:
            self.set_target(target)

    def set_target(self, target: pin.SE3, packed: np.ndarray | None = None) -> None:
        """Position and rotation, checked as their setters check them. In one compiled call
        when those setters are this class's own (a support switch anchors its contacts so:
        ~10 µs less at a switch to double support); a target that fails a check goes
        through the setters, which raise. ``packed``: :meth:`pack_target` of ``target``, made
        ahead (a loop's idle part: a landing's anchor), copied as it is (checked there)."""
        if not isinstance(target, pin.SE3):
            raise TaskError(f"task {self.name!r}: target must be a pinocchio.SE3")
        whole = self.target_packed
        if (
            packed is not None
            and self._packed_setters()
            and self.target_position.base is whole
            and self.target_rotation.base is whole
        ):
            np.copyto(whole, packed)
            return
        if self._packed_setters() and self._copy(
            target, self.target_position, self.target_rotation
        ):
            return
        self.set_position_target(target.translation)
        self.set_rotation_target(target.rotation)

    def pack_target(self, target: pin.SE3) -> np.ndarray | None:
        """``target`` checked as :meth:`set_target` checks it, in a new array laid out as
        :attr:`target_packed` (position, rotation row-major), for a later ``set_target(target,
        packed)``: None where the setters must run (a subclass's own, or a check fails)."""
        packed = np.empty(12)
        if self._packed_setters() and self._copy(target, packed[:3], packed[3:].reshape(3, 3)):
            return packed
        return None

    def _packed_setters(self) -> bool:
        """Whether the targets go in by one compiled check and copy: the setters this class's
        own, the target arrays float64 views of :attr:`target_packed`."""
        cls, p, R = type(self), self.target_position, self.target_rotation
        return (
            cls.set_position_target is FramePoseTask.set_position_target
            and cls.set_rotation_target is FramePoseTask.set_rotation_target
            and p.dtype is _F8
            and R.dtype is _F8
            and p.shape == (3,)
            and R.shape == (3, 3)
        )

    @staticmethod
    def _copy(target: pin.SE3, p: np.ndarray, R: np.ndarray) -> bool:
        """``target`` checked and copied into ``p``, ``R`` (:func:`wbc.compiled.checks.copy_pose`);
        False (nothing copied) if a check fails."""
        return _copy_pose(target.translation, target.rotation, p, R, ROTATION_TOL) <= ROTATION_TOL

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
