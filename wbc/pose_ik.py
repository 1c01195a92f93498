"""Stance inverse kinematics: torso and soles to given world placements, for any robot.

The Kokone thesis's IK problem (hip pose + both foot poses -> leg joints, its eqs. 4.37-4.42)
posed to the project's own solver: one hard level holds the three frame poses (6 rows each),
a second level keeps the other joints near a reference posture, joint limits are hard bounds,
and :meth:`HierarchicalQP.solve_pose` iterates Gauss-Newton steps to convergence.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pinocchio as pin

from .model import Robot
from .solvers import HierarchicalQP, PoseResult, TaskStack
from .tasks import FramePoseTask, PostureTask


class StanceIK:
    """Reusable solver for ``{frame: world placement}`` targets (built once, re-targeted)."""

    def __init__(
        self, robot: Robot, frames: tuple[str, ...] = ("torso", "l_sole", "r_sole")
    ) -> None:
        self.robot = robot
        self.stack = TaskStack(robot, velocity_limits=False)
        self.tasks = {f: self.stack.add(FramePoseTask(robot, f, name=f), level=0) for f in frames}
        self.posture = self.stack.add(PostureTask(robot, robot.neutral()), level=1)
        self.solver = HierarchicalQP(self.stack, backend="daqp")

    def solve(
        self,
        targets: Mapping[str, pin.SE3],
        q0: np.ndarray,
        tol: float = 1e-11,
        max_iterations: int = 100,
    ) -> PoseResult:
        """Joint angles (and base) putting every frame at its target; starts from ``q0``."""
        for name, task in self.tasks.items():
            task.set_target(targets[name])
        self.posture.set_target(q0)
        return self.solver.solve_pose(q0, tol=tol, max_iterations=max_iterations)

    def residual(self, q: np.ndarray, targets: Mapping[str, pin.SE3]) -> float:
        """Largest |log(target⁻¹ · placement)| component over the frames (m and rad)."""
        return max(
            float(np.max(np.abs(pin.log6(targets[f].actInv(self.robot.frame_placement(q, f))))))
            for f in self.tasks
        )
