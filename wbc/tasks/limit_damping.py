"""Damping weighted by the thesis's joint-limit weights (Chan & Dubey 1995, eqs. 1.52-1.54)."""

from __future__ import annotations

import numpy as np

from ..limits.joint_costs import ChanDubeyWeights
from ..model import Kinematics, Robot
from .task import Task

#: largest Chan–Dubey weight used (1 at mid-range; 1e4 ≈ within ~1% of the range from a limit)
WEIGHT_CAP = 1e4


class JointLimitDampingTask(Task):
    """e = 0, J = diag(√w(q)) on the joints: penalises Σ w_i(q) Δq_i².

    w(q) are the Chan–Dubey weights the thesis adopts for VATL/CJL: 1 + |∂H/∂θ_i| while joint
    i moves towards a limit (its Zghal gradient grows), 1 otherwise. They are updated at every
    solve (one update per control tick or per iteration, as in the thesis), so this is the QP
    counterpart of the thesis's weighted pseudo-inverse W⁻¹ with limit weights. ``weight``
    scales the whole term.
    """

    blocks_convergence = False
    stack_type = "joint_limit_damping"  # its `type` in stack files (wbc.tasks.task.register)

    def __init__(
        self, robot: Robot, name: str = "joint_limit_damping", weight: float = 1e-3
    ) -> None:
        self.dim = robot.n_joints
        super().__init__(name, 1.0, weight, None)
        self.chan_dubey = ChanDubeyWeights(robot.q_min, robot.q_max)
        self._J = np.zeros((robot.n_joints, robot.nv))
        self._diag = np.arange(robot.n_joints)
        self._e = np.zeros(robot.n_joints)

    def reset(self) -> None:
        """Forget the previous gradients (at the start of a new motion)."""
        self.chan_dubey.reset()

    def compute_error(self, kin: Kinematics) -> np.ndarray:
        return self._e

    def compute_jacobian(self, kin: Kinematics) -> np.ndarray:
        w = self.chan_dubey.update(np.clip(kin.q[7:], self.chan_dubey.lower, self.chan_dubey.upper))
        # the weight is infinite at a limit; the QP's bounds already hold the joint there, so a
        # cap keeps the Hessian well conditioned (DAQP stops with exit -4 otherwise)
        self._J[self._diag, 6 + self._diag] = np.sqrt(np.minimum(w, WEIGHT_CAP))
        return self._J
