"""Joint position and velocity limits as bounds on Δq."""

from __future__ import annotations

import numpy as np

from ..model import Kinematics, Robot
from .limit import Bounds, BoxLimit


class JointPositionLimit(BoxLimit):
    """q_min − q <= Δq_j <= q_max − q for every actuated joint (base unbounded).

    If a joint starts outside its range (servo readings do that), the bound forces Δq to
    bring it back inside instead of making the problem infeasible.
    """

    name = "joint_position_limit"

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self._lower = np.full(robot.nv, -np.inf)
        self._upper = np.full(robot.nv, np.inf)

    def bounds(self, kin: Kinematics, dt: float | None) -> Bounds:
        j = kin.q[7:]
        np.subtract(self.robot.q_min, j, out=self._lower[6:])
        np.subtract(self.robot.q_max, j, out=self._upper[6:])
        return Bounds(self._lower, self._upper)


class JointVelocityLimit(BoxLimit):
    """|Δq_j| <= v_max · dt (servo speed); inactive when iterating without a time step."""

    name = "joint_velocity_limit"

    def __init__(self, robot: Robot, scale: float = 1.0) -> None:
        self.robot = robot
        self.scale = scale
        self._lower = np.full(robot.nv, -np.inf)
        self._upper = np.full(robot.nv, np.inf)

    def bounds(self, kin: Kinematics, dt: float | None) -> Bounds:
        if dt is None:
            self._lower[6:] = -np.inf
            self._upper[6:] = np.inf
        else:
            np.multiply(self.robot.v_max, self.scale * dt, out=self._upper[6:])
            np.negative(self._upper[6:], out=self._lower[6:])
        return Bounds(self._lower, self._upper)


def intersect_bounds(
    position: Bounds, others: list[Bounds], lower: np.ndarray, upper: np.ndarray
) -> None:
    """Intersect box limits into ``lower``/``upper`` (in place).

    Position bounds come first; where another box (e.g. velocity) leaves no room, the result
    moves as far towards the position range as that box allows, so a joint that starts
    outside its range is brought back at the servo's speed instead of failing.
    """
    lower[:] = position.lower
    upper[:] = position.upper
    for b in others:
        np.maximum(lower, b.lower, out=lower)
        np.minimum(upper, b.upper, out=upper)
    empty = lower > upper
    if empty.any():
        # the non-position box wins, clipped towards the position range
        for b in others:
            lo = np.minimum(np.maximum(position.lower, b.lower), b.upper)
            hi = np.maximum(np.minimum(position.upper, b.upper), b.lower)
            lower[empty] = lo[empty]
            upper[empty] = hi[empty]
