"""Posture (joint targets) and damping / regularisation tasks."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..model import Kinematics, Robot
from .task import Task, check_vector


@njit(cache=True)
def posture_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    """e = q*_j − q_j, J = [0 I] (the joints are the last coordinates of q and Δq)."""
    nv = Jw.shape[1]
    nj = target.shape[0]
    for i in range(nj):
        e[i] = target[i] - q[q.shape[0] - nj + i]
        for k in range(nv):
            J[i, k] = 0.0
        J[i, nv - nj + i] = 1.0


@njit(cache=True)
def damping_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    """e = 0, J = I (nv)."""
    nv = Jw.shape[1]
    for i in range(nv):
        e[i] = 0.0
        for k in range(nv):
            J[i, k] = 0.0
        J[i, i] = 1.0


class PostureTask(Task):
    """e = q*_j − q_j for the actuated joints; J = [0 I] (n_joints x nv)."""

    blocks_convergence = False
    row_kernel = staticmethod(posture_rows)
    target_fields = ("target",)
    stack_type = "posture"  # its `type` in stack files (wbc.tasks.task.register)

    def __init__(
        self,
        robot: Robot,
        target: Sequence[float] | np.ndarray | None = None,
        name: str = "posture",
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        self.dim = robot.n_joints
        super().__init__(name, gain, weight, mask)
        self.robot = robot
        self.target = np.zeros(robot.n_joints)
        if target is not None:
            self.set_target(target)

    def set_target(self, joints: Sequence[float] | np.ndarray) -> None:
        """Joint targets in model order (a full configuration q is accepted too)."""
        j = np.asarray(joints, dtype=float)
        if j.shape == (self.robot.nq,):
            j = j[7:]
        self.target[:] = check_vector(self, j, self.robot.n_joints)

    def set_target_from(self, kin: Kinematics) -> None:
        self.target[:] = kin.q[7:]


class DampingTask(Task):
    """e = 0, J = I (nv): penalises ‖Δq‖², the regularisation of damped least squares.

    ``weight`` may be one value per degree of freedom (6 base + joints), e.g. joint weights.
    """

    blocks_convergence = False
    row_kernel = staticmethod(damping_rows)
    stack_type = "damping"  # its `type` in stack files (wbc.tasks.task.register)

    def __init__(
        self,
        robot: Robot,
        name: str = "damping",
        weight: float | Sequence[float] = 1e-6,
        mask: Sequence[bool] | None = None,
    ) -> None:
        self.dim = robot.nv
        super().__init__(name, 1.0, weight, mask)
