"""Shared part of the tasks attached to one frame of the robot."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pinocchio as pin

from ..model import Robot
from .task import Task, bump_structure

#: within this of π, the logarithm's branch is chosen by a fixed rule, not by rounding (the
#: compiled kernels' :data:`wbc.compiled.rows.PI_BRANCH_TOL`, the same rule)
PI_BRANCH_TOL = 1e-9


def log3(M: np.ndarray) -> np.ndarray:
    """log(M) ∈ so(3) (Pinocchio's), with one branch at an angle of π: there the axis's sign
    is rounding noise, and the rule is the largest component positive (on every path)."""
    v = pin.log3(M)
    theta = math.sqrt(v.dot(v))
    if theta > math.pi - PI_BRANCH_TOL and v[np.argmax(np.abs(v))] < 0.0:
        v = -v
    return v


def jlog3(M: np.ndarray) -> np.ndarray:
    """Jacobian of :func:`log3` at M (Pinocchio's Jlog3; at π, of the branch log3 picks)."""
    v = pin.log3(M)
    theta = math.sqrt(v.dot(v))
    if theta <= math.pi - PI_BRANCH_TOL:
        return pin.Jlog3(M)
    v = log3(M)  # Jlog3 = θ cot(θ/2)/2 I + (1/θ² − cot(θ/2)/(2θ)) v vᵀ + [v]ₓ/2
    half_cot = 0.5 * math.sin(theta) / (1.0 - math.cos(theta))
    J = (1.0 / theta**2 - half_cot / theta) * np.outer(v, v) + theta * half_cot * np.eye(3)
    return J + 0.5 * pin.skew(v)


class FrameTask(Task):
    """A task on frame ``frame`` of ``robot``; the frame can be re-bound (e.g. swing foot)."""

    def __init__(
        self,
        robot: Robot,
        frame: str,
        name: str | None,
        gain: float,
        weight: float | Sequence[float],
        mask: Sequence[bool] | None,
    ) -> None:
        self.robot = robot
        self.set_frame(frame)
        super().__init__(
            name or f"{type(self).__name__.removesuffix('Task').lower()}_{frame}",
            gain,
            weight,
            mask,
        )

    def set_frame(self, frame: str) -> None:
        """Attach the task to another frame (raises ModelError for unknown names)."""
        frame_id = self.robot.frame_id(frame)
        if frame_id != getattr(self, "frame_id", None):
            bump_structure()  # compiled plans hold the frame's placement views
        self.frame_id = frame_id
        self.frame = frame
