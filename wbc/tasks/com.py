"""Centre-of-mass position task (3-D, world frame)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..model import Kinematics, Robot
from .task import Task, check_vector


@njit(cache=True)
def com_rows(target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J) -> None:
    """e = c* − c, J = J_com."""
    for i in range(3):
        e[i] = target[i] - com[i]
        for k in range(Jcom.shape[1]):
            J[i, k] = Jcom[i, k]


class ComTask(Task):
    """e = c* − c(q), J = J_com (3 x nv); the thesis's Δx = x* − x with J_T (sec. 1.5.4).

    ``target=None`` leaves the target unset (NaN), not at the world origin: set it
    (:meth:`set_target`, or :meth:`set_target_from` for the current CoM) before a solve,
    which otherwise raises :class:`~wbc.exceptions.TaskError` naming the task.
    """

    dim = 3
    row_kernel = staticmethod(com_rows)
    target_fields = ("target",)
    length_rows = 3
    stack_type = "com"  # its `type` in stack files (wbc.tasks.task.register)

    def __init__(
        self,
        robot: Robot,
        target: Sequence[float] | np.ndarray | None = None,
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

    def set_target(self, target: Sequence[float] | np.ndarray) -> None:
        """Set the CoM target (world, m), copied in place."""
        check_vector(self, target, 3, out=self.target)

    def set_target_from(self, kin: Kinematics) -> None:
        """Target = the current CoM."""
        self.target[:] = kin.com
