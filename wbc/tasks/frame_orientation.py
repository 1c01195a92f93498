"""Frame orientation task as the full SO(3) log error (3-D, world axes)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..compiled.rows import frame_jacobian, rotation_rows
from ..model import Kinematics, Robot
from .frame_task import FrameTask
from .task import check_rotation


@njit(cache=True)
def orientation_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    """e = log(R* Rᵀ), J = Jlog3(R* Rᵀ) J_ω."""
    f = slots[0]
    frame_jacobian(Jw, supports[f], ps[f], Jf)
    rotation_rows(target[0:9], Rs[f], Jf, e[0:3], J[0:3])


class FrameOrientationTask(FrameTask):
    """e = log(R* Rᵀ) (world axes), J = Jlog3(R* Rᵀ) J_ω.

    R(q ⊕ Δq) ≈ exp(J_ω Δq) R, so R* R(q ⊕ Δq)ᵀ ≈ (R* Rᵀ) exp(−J_ω Δq) and, with the
    Jacobian of the SO(3) logarithm, e(q ⊕ Δq) ≈ e − Jlog3(R* Rᵀ) J_ω Δq: the Jacobian is exact
    at any error, not only near the target (where Jlog3 = I).
    """

    dim = 3
    row_kernel = staticmethod(orientation_rows)
    target_fields = ("target",)
    stack_type = "frame_orientation"  # its `type` in stack files (wbc.tasks.task.register)

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
        check_rotation(self, rotation, out=self.target)

    def set_target_from(self, kin: Kinematics) -> None:
        self.target[:] = kin.rotation(self.frame_id)
