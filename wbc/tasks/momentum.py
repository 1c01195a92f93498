"""The whole body's turn about the vertical through its centre of mass (1-D): the centroidal
angular momentum's vertical row, as an angle.

A walker's stance sole must supply the vertical moment ``dL_z/dt`` that the body's motion asks
for (the swing leg's forward swing beside the body, the torso's turn): on an edge, or a floor
without torsional friction, a sole that cannot supply it pivots. The task asks the step ``Δq``
for a given turn of the *locked* body,

    e = ψ*,   J = A_z / I_zz,

with ``A_z`` the vertical row of the centroidal momentum matrix (``L_z = A_z v``, about the
CoM, world axes) and ``I_zz = A_z u`` the body's composite yaw inertia at this configuration
(``u`` the base's angular velocity that is a unit turn about the world's vertical). ``J Δq``
is the average turn of every link about the vertical through the CoM (``I_zz⁻¹ L_z dt``); the
row is an angle (rad), robot-agnostic, weighted as an orientation's rows are. ``ψ* = 0`` (the
default) asks the step for no vertical angular momentum: what the swing leg makes, the arms
and the torso give back (the counter-swing of a human's arms).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..exceptions import TaskError
from ..model import Robot
from .task import Task, check_vector


@njit(cache=True)
def yaw_momentum_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    """e = ψ*, J = A_z / I_zz (the base's quaternion q[3:7] = x, y, z, w)."""
    x, y, z, w = q[3], q[4], q[5], q[6]
    # u = Rᵀ e_z: the third row of the base's rotation
    u0, u1, u2 = 2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)
    izz = Ag[5, 3] * u0 + Ag[5, 4] * u1 + Ag[5, 5] * u2
    e[0] = target[0]
    for k in range(Ag.shape[1]):
        J[0, k] = Ag[5, k] / izz


class YawMomentumTask(Task):
    """e = ψ*, J = A_z / I_zz: the step's turn of the locked body about the vertical through
    its centre of mass (rad), ψ* = :attr:`target` (default 0: no vertical angular momentum;
    ``follow``: the walk's yaw step, set by the walking controller). Needs a floating base
    (its quaternion gives the vertical in the base's frame)."""

    dim = 1
    row_kernel = staticmethod(yaw_momentum_rows)
    kernel_inputs = frozenset({"momentum"})
    target_fields = ("target",)
    stack_type = "yaw_momentum"  # its `type` in stack files (wbc.tasks.task.register)
    stack_keys = ("target", "follow")

    def __init__(
        self,
        robot: Robot,
        target: float = 0.0,
        follow: bool = False,
        name: str = "yaw_momentum",
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(name, gain, weight, mask)
        if not isinstance(follow, bool):
            raise TaskError(f"task {name!r}: follow must be true or false, got {follow!r}")
        #: a walking controller sets the target to the reference torso's yaw step each tick
        #: (:class:`~wbc.walking.controller.StackController`): the walk's own turn is asked
        #: of the whole body, the rest of its vertical momentum given back
        self.follow = follow
        self.target = np.zeros(1)
        self.set_target(target)

    def set_target(self, turn: float) -> None:
        """The step's turn asked for (rad; the walk's own yaw step, or 0)."""
        check_vector(self, [turn], 1, out=self.target)
