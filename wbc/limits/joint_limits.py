"""Joint position and velocity limits as bounds on Δq."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..model import Robot
from .limit import BoxLimit


@njit(cache=True)
def position_box(q_min, q_max, q, lower, upper) -> None:
    """The joint position limit's box: q_min − q <= Δq_j <= q_max − q, the base unbounded (one
    definition: :func:`position_bounds`, :func:`~wbc.limits.collision_packed.joint_box`)."""
    nj = q_min.shape[0]
    nb = lower.shape[0] - nj
    for i in range(nb):
        lower[i] = -np.inf
        upper[i] = np.inf
    o = q.shape[0] - nj
    for j in range(nj):
        lower[nb + j] = q_min[j] - q[o + j]
        upper[nb + j] = q_max[j] - q[o + j]


@njit(cache=True)
def speed_box(steps, lower, upper) -> None:
    """The joint velocity limit's box: −s_j <= Δq_j <= s_j, the base unbounded (one
    definition: :func:`velocity_bounds`, :func:`~wbc.limits.collision_packed.joint_box`)."""
    nj = steps.shape[0]
    nb = lower.shape[0] - nj
    for i in range(nb):
        lower[i] = -np.inf
        upper[i] = np.inf
    for j in range(nj):
        lower[nb + j] = -steps[j]
        upper[nb + j] = steps[j]


@njit(cache=True)
def position_bounds(
    params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, lower, upper
):
    """q_min − q <= Δq_j <= q_max − q (params: q_min, then q_max; the base unbounded)."""
    nj = params.shape[0] // 2
    position_box(params[:nj], params[nj:], q, lower, upper)


@njit(cache=True)
def velocity_bounds(
    params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, lower, upper
):
    """−s_j <= Δq_j <= s_j (params: the steps s; the base unbounded)."""
    speed_box(params, lower, upper)


class JointPositionLimit(BoxLimit):
    """q_min − q <= Δq_j <= q_max − q for every actuated joint (base unbounded).

    If a joint starts outside its range (servo readings do that), the bound forces Δq to
    bring it back inside instead of making the problem infeasible.
    """

    name = "joint_position_limit"
    bound_kernel = staticmethod(position_bounds)
    param_fields = ("q_min", "q_max")

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.q_min = robot.q_min
        self.q_max = robot.q_max

    def joint_bounds_into(self, joints: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> None:
        """The joint rows only, written in place (the solvers' projections)."""
        np.subtract(self.q_min, joints, out=lower)
        np.subtract(self.q_max, joints, out=upper)


class JointVelocityLimit(BoxLimit):
    """|Δq_j| <= scale · v_max · dt (servo speed); inactive when iterating without a time step."""

    name = "joint_velocity_limit"
    bound_kernel = staticmethod(velocity_bounds)
    param_fields = ("steps",)

    def __init__(self, robot: Robot, scale: float = 1.0) -> None:
        self.robot = robot
        self.scale = scale
        self._dt: float | None = None
        self._step = np.zeros(robot.n_joints)
        self._neg_step = np.zeros(robot.n_joints)
        #: the bound kernel's parameters: the steps of the last :meth:`prepare` (+inf without
        #: a time step)
        self.steps = np.full(robot.n_joints, np.inf)
        self._prepared: float | None = None  # (the dt of those steps: None, no time step)

    def _steps(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        if dt != self._dt:
            np.multiply(self.robot.v_max, self.scale * dt, out=self._step)
            np.negative(self._step, out=self._neg_step)
            self._dt = dt
        return self._step, self._neg_step

    def step(self, dt: float) -> np.ndarray:
        """The largest joint increment in one time step, scale · v_max · dt (cached)."""
        return self._steps(dt)[0]

    def prepare(self, dt: float | None) -> None:
        """The steps of ``dt`` into :attr:`steps` (+inf: no time step, no bound); nothing to
        do for the ``dt`` of the last call (every compiled tick asks: ~0.1 µs)."""
        if dt == self._prepared:
            return
        if dt is None:
            self.steps.fill(np.inf)
        else:
            np.copyto(self.steps, self.step(dt))
        self._prepared = dt
