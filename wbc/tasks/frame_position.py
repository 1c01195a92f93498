"""Frame position task (3-D, world frame)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..compiled.rows import frame_jacobian
from ..model import Kinematics, Robot
from .frame_task import FrameTask
from .task import check_vector


@njit(cache=True)
def position_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    """e = p* − p, J = J_v (world axes at the frame origin)."""
    f = slots[0]
    p = ps[f]
    frame_jacobian(Jw, supports[f], p, Jf)
    for i in range(3):
        e[i] = target[i] - p[i]
        for k in range(Jf.shape[1]):
            J[i, k] = Jf[i, k]


class FramePositionTask(FrameTask):
    """e = p* − p(q) for the origin of a frame; J = linear rows of its world-aligned Jacobian."""

    dim = 3
    row_kernel = staticmethod(position_rows)
    target_fields = ("target",)
    length_rows = 3
    stack_type = "frame_position"  # its `type` in stack files (wbc.tasks.task.register)

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
        check_vector(self, target, 3, out=self.target)

    def set_target_from(self, kin: Kinematics) -> None:
        self.target[:] = kin.translation(self.frame_id)
