"""Frame position task (3-D, world frame)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model import Kinematics, Robot
from .frame_task import FrameTask
from .task import check_vector


class FramePositionTask(FrameTask):
    """e = p* − p(q) for the origin of a frame; J = linear rows of its world-aligned Jacobian."""

    dim = 3

    def __init__(
        self,
        robot: Robot,
        frame: str,
        target: Sequence[float] | np.ndarray | None = None,
        name: str | None = None,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(robot, frame, name, gain, weight, mask)
        self.target = np.zeros(3)
        if target is not None:
            self.set_target(target)

    def set_target(self, target: Sequence[float] | np.ndarray) -> None:
        self.target[:] = check_vector(self, target, 3)

    def set_target_from(self, kin: Kinematics) -> None:
        self.target[:] = kin.translation(self.frame_id)

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        return self.target - kin.translation(self.frame_id)

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        return kin.frame_jacobian(self.frame_id)[:3]
