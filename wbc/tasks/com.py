"""Centre-of-mass position task (3-D, world frame)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model import Kinematics, Robot
from .task import Task, check_vector


class ComTask(Task):
    """e = c* − c(q), J = J_com (3 x nv); the thesis's Δx = x* − x with J_T (sec. 1.5.4).

    ``target=None`` leaves the target unset (NaN), not at the world origin: set it
    (:meth:`set_target`, or :meth:`set_target_from` for the current CoM) before a solve,
    which otherwise raises :class:`~wbc.exceptions.TaskError` naming the task.
    """

    dim = 3

    def __init__(
        self,
        robot: Robot,
        target: Sequence[float] | None = None,
        name: str = "com",
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(name, gain, weight, mask)
        #: None: unset (NaN) until set_target/set_target_from; a solve before raises TaskError
        self.target = np.full(3, np.nan)
        if target is not None:
            self.set_target(target)

    def set_target(self, target: Sequence[float]) -> None:
        """Set the CoM target (world, m), copied in place."""
        self.target[:] = check_vector(self, target, 3)

    def set_target_from(self, kin: Kinematics) -> None:
        """Target = the current CoM."""
        self.target[:] = kin.com

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        return self.target - kin.com

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        return kin.com_jacobian

    def fill(self, kin: Kinematics, J_out: np.ndarray, e_out: np.ndarray) -> None:
        if not self._all:
            return super().fill(kin, J_out, e_out)
        J_out[:] = kin.com_jacobian
        np.subtract(self.target, kin.com, out=e_out)
        self.last_error = e_out
        return None
