"""Frame orientation task as the full SO(3) log error (3-D, world axes)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model import Kinematics, Robot
from .frame_task import FrameTask, jlog3, log3
from .task import check_rotation


class FrameOrientationTask(FrameTask):
    """e = log(R* Rᵀ) (world axes), J = Jlog3(R* Rᵀ) J_ω.

    R(q ⊕ Δq) ≈ exp(J_ω Δq) R, so R* R(q ⊕ Δq)ᵀ ≈ (R* Rᵀ) exp(−J_ω Δq) and, with the
    Jacobian of the SO(3) logarithm, e(q ⊕ Δq) ≈ e − Jlog3(R* Rᵀ) J_ω Δq: the Jacobian is exact
    at any error, not only near the target (where Jlog3 = I).
    """

    dim = 3

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
        super().__init__(robot, frame, name, gain, weight, mask)
        self.target = np.eye(3)
        if target is not None:
            self.set_target(target)

    def set_target(self, rotation: np.ndarray) -> None:
        self.target[:] = check_rotation(self, rotation)

    def set_target_from(self, kin: Kinematics) -> None:
        self.target[:] = kin.rotation(self.frame_id)

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        return log3(self.target @ kin.rotation(self.frame_id).T)

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        R = kin.rotation(self.frame_id)
        return jlog3(self.target @ R.T) @ kin.frame_jacobian(self.frame_id)[3:]
