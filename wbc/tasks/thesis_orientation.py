"""The thesis's orientation tasks (com-control-thesis ch. 4, eqs. 4.3 and 4.4).

Both measure alignment of unit axes by dot products: 1 − a·b is zero when a and b coincide.
With ω the frame's angular velocity, d(a·b_f)/dt = a·(ω × b_f) = (b_f × a)·ω, so the
Jacobian of ``a·b_f`` is ``(b_f × a)ᵀ J_ω``. The error 1 − a·b_f is quadratic in the angle, so
its Jacobian vanishes at alignment: faithful to the thesis, including that weakness.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model import Kinematics, Robot
from .frame_task import FrameTask
from .task import check_rotation


class SwingFootOrientationTask(FrameTask):
    """Δx_of = [1 − k·k_f, 1 − i·i_f] (eq. 4.3): sole z and x axes aligned with the target's."""

    dim = 2

    def __init__(
        self,
        robot: Robot,
        frame: str,
        target: np.ndarray | None = None,
        name: str | None = None,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(robot, frame, name or f"thesis_orientation_{frame}", gain, weight, mask)
        self.target = np.eye(3)
        if target is not None:
            self.set_target(target)
        self._J = np.zeros((2, robot.nv))

    def set_target(self, rotation: np.ndarray) -> None:
        """Target axes k = R*[:, 2], i = R*[:, 0]."""
        self.target[:] = check_rotation(self, rotation)

    def set_target_from(self, kin: Kinematics) -> None:
        self.target[:] = kin.rotation(self.frame_id)

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        R = kin.rotation(self.frame_id)
        return np.array([1.0 - self.target[:, 2] @ R[:, 2], 1.0 - self.target[:, 0] @ R[:, 0]])

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        R = kin.rotation(self.frame_id)
        Jw = kin.frame_jacobian(self.frame_id)[3:]
        np.dot(np.cross(R[:, 2], self.target[:, 2]), Jw, out=self._J[0])
        np.dot(np.cross(R[:, 0], self.target[:, 0]), Jw, out=self._J[1])
        return self._J


class TorsoOrientationTask(FrameTask):
    """Δx_ot = 1 − k·k_t (eq. 4.4): the torso's z axis vertical (or along ``axis``)."""

    dim = 1

    def __init__(
        self,
        robot: Robot,
        frame: str = "torso",
        axis: Sequence[float] = (0.0, 0.0, 1.0),
        name: str | None = None,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(robot, frame, name or "thesis_torso_orientation", gain, weight, mask)
        self.axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        self._J = np.zeros((1, robot.nv))

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        kt = kin.rotation(self.frame_id)[:, 2]
        return np.array([1.0 - self.axis @ kt])

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        kt = kin.rotation(self.frame_id)[:, 2]
        Jw = kin.frame_jacobian(self.frame_id)[3:]
        np.dot(np.cross(kt, self.axis), Jw, out=self._J[0])
        return self._J
