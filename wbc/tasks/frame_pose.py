"""Full 6-D frame pose task: position and SO(3) log orientation error."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ..model import Kinematics, Robot
from .frame_task import FrameTask, jlog3, log3
from .task import TaskError, check_rotation, check_vector


class FramePoseTask(FrameTask):
    """e = [p* − p; log(R* Rᵀ)] (world axes), J = [J_v; Jlog3(R* Rᵀ) J_ω] (6 x nv).

    J_v, J_ω: the frame Jacobian with world-aligned axes at the frame origin; see
    :class:`~wbc.tasks.FrameOrientationTask` for the orientation rows.
    """

    dim = 6

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
        self.target_position = np.zeros(3)
        self.target_rotation = np.eye(3)
        if target is not None:
            self.set_target(target)

    def set_target(self, target: pin.SE3) -> None:
        if not isinstance(target, pin.SE3):
            raise TaskError(f"task {self.name!r}: target must be a pinocchio.SE3")
        self.set_position_target(target.translation)
        self.set_rotation_target(target.rotation)

    def set_position_target(self, position: Sequence[float]) -> None:
        self.target_position[:] = check_vector(self, position, 3, "target position")

    def set_rotation_target(self, rotation: np.ndarray) -> None:
        self.target_rotation[:] = check_rotation(self, rotation)

    def set_target_from(self, kin: Kinematics) -> None:
        self.target_position[:] = kin.translation(self.frame_id)
        self.target_rotation[:] = kin.rotation(self.frame_id)

    @property
    def target(self) -> pin.SE3:
        return pin.SE3(self.target_rotation, self.target_position)

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        e = np.empty(6)
        np.subtract(self.target_position, kin.translation(self.frame_id), out=e[:3])
        e[3:] = log3(self.target_rotation @ kin.rotation(self.frame_id).T)
        return e

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        J = kin.frame_jacobian(self.frame_id).copy()
        A = self.target_rotation @ kin.rotation(self.frame_id).T
        J[3:] = jlog3(A) @ J[3:]
        return J

    def fill(self, kin: Kinematics, J_out: np.ndarray, e_out: np.ndarray) -> None:
        if not self._all:
            return super().fill(kin, J_out, e_out)
        A = self.target_rotation @ kin.rotation(self.frame_id).T
        np.subtract(self.target_position, kin.translation(self.frame_id), out=e_out[:3])
        e_out[3:] = log3(A)
        J = kin.frame_jacobian(self.frame_id)
        J_out[:3] = J[:3]
        np.dot(jlog3(A), J[3:], out=J_out[3:])
        self.last_error = e_out
        return None
