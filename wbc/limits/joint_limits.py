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

    def joint_bounds_into(self, joints: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> None:
        """The joint rows only, written in place (the solvers' hot path)."""
        np.subtract(self.robot.q_min, joints, out=lower)
        np.subtract(self.robot.q_max, joints, out=upper)

    def bounds(self, kin: Kinematics, dt: float | None) -> Bounds:
        self.joint_bounds_into(kin.q[7:], self._lower[6:], self._upper[6:])
        return Bounds(self._lower, self._upper)


class JointVelocityLimit(BoxLimit):
    """|Δq_j| <= scale · v_max · dt (servo speed); inactive when iterating without a time step."""

    name = "joint_velocity_limit"

    def __init__(self, robot: Robot, scale: float = 1.0) -> None:
        self.robot = robot
        self.scale = scale
        self._lower = np.full(robot.nv, -np.inf)
        self._upper = np.full(robot.nv, np.inf)
        self._dt: float | None = None
        self._step = np.zeros(robot.n_joints)
        self._neg_step = np.zeros(robot.n_joints)

    def _steps(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        if dt != self._dt:
            np.multiply(self.robot.v_max, self.scale * dt, out=self._step)
            np.negative(self._step, out=self._neg_step)
            self._dt = dt
        return self._step, self._neg_step

    def step(self, dt: float) -> np.ndarray:
        """The largest joint increment in one time step, scale · v_max · dt (cached)."""
        return self._steps(dt)[0]

    def clip_joint_bounds(self, dt: float, lower: np.ndarray, upper: np.ndarray) -> None:
        """Clip joint position bounds into [−v dt, v dt] in place.

        The two never cross: a joint outside its range gets lower = upper = ±v dt, i.e. it
        moves back towards its range at the servo's full speed.
        """
        step, neg = self._steps(dt)
        np.minimum(np.maximum(lower, neg, out=lower), step, out=lower)
        np.minimum(np.maximum(upper, neg, out=upper), step, out=upper)

    def bounds(self, kin: Kinematics, dt: float | None) -> Bounds:
        if dt is None:
            self._lower[6:] = -np.inf
            self._upper[6:] = np.inf
        else:
            step, neg = self._steps(dt)
            self._upper[6:] = step
            self._lower[6:] = neg
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
