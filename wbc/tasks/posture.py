"""Posture (joint targets) and damping / regularisation tasks."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model import Kinematics, Robot
from .task import Task, check_vector


class PostureTask(Task):
    """e = q*_j − q_j for the actuated joints; J = [0 I] (n_joints x nv)."""

    blocks_convergence = False

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
        self._J = np.zeros((robot.n_joints, robot.nv))
        self._J[:, 6:] = np.eye(robot.n_joints)
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

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        return self.target - kin.q[7:]

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        return self._J

    def fill(self, kin: Kinematics, J_out: np.ndarray, e_out: np.ndarray) -> None:
        if not self._all:
            return super().fill(kin, J_out, e_out)
        J_out[:] = self._J
        np.subtract(self.target, kin.q[7:], out=e_out)
        self.last_error = e_out
        return None


class DampingTask(Task):
    """e = 0, J = I (nv): penalises ‖Δq‖², the regularisation of damped least squares.

    ``weight`` may be one value per degree of freedom (6 base + joints), e.g. joint weights.
    """

    blocks_convergence = False

    def __init__(
        self,
        robot: Robot,
        name: str = "damping",
        weight: float | Sequence[float] = 1e-6,
        mask: Sequence[bool] | None = None,
    ) -> None:
        self.dim = robot.nv
        super().__init__(name, 1.0, weight, mask)
        self._J = np.eye(robot.nv)
        self._e = np.zeros(robot.nv)

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        return self._e

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        return self._J
