"""The thesis's orientation tasks (com-control-thesis ch. 4, eqs. 4.3 and 4.4).

Both measure alignment of unit axes by dot products: 1 − a·b is zero when a and b coincide.
With ω the frame's angular velocity, d(a·b_f)/dt = a·(ω × b_f) = (b_f × a)·ω, so the
Jacobian of ``a·b_f`` is ``(b_f × a)ᵀ J_ω``. The error 1 − a·b_f is quadratic in the angle, so
its Jacobian vanishes at alignment: faithful to the thesis, including that weakness.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..compiled.rows import frame_jacobian
from ..model import Kinematics, Robot
from .frame_task import FrameTask
from .task import TaskError, check_rotation, check_vector

#: the columns (x, z) and rows of :func:`_axis_row`'s calls, int64 scalars: a global numba
#: reads as a plain int64, not a literal, so that it compiles once, not once per call
_X, _Z, _ROW0, _ROW1 = np.int64(0), np.int64(2), np.int64(0), np.int64(1)


@njit(cache=True)
def _axis_row(a0, a1, a2, R, c, Jf, e, J, i) -> None:
    """Row i: e = 1 − a·b_f with b_f = R[:, c], J = (b_f × a)ᵀ J_ω."""
    b0, b1, b2 = R[0, c], R[1, c], R[2, c]
    e[i] = 1.0 - (a0 * b0 + a1 * b1 + a2 * b2)
    x0 = b1 * a2 - b2 * a1
    x1 = b2 * a0 - b0 * a2
    x2 = b0 * a1 - b1 * a0
    for k in range(Jf.shape[1]):
        J[i, k] = x0 * Jf[3, k] + x1 * Jf[4, k] + x2 * Jf[5, k]


@njit(cache=True)
def swing_axes_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    """[1 − k·k_f, 1 − i·i_f] (target: R* row-major, k = its z column, i = its x column)."""
    f = slots[0]
    frame_jacobian(Jw, supports[f], ps[f], Jf)
    _axis_row(target[2], target[5], target[8], Rs[f], _Z, Jf, e, J, _ROW0)
    _axis_row(target[0], target[3], target[6], Rs[f], _X, Jf, e, J, _ROW1)


@njit(cache=True)
def torso_axis_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    """1 − a·k_t (target: the axis a)."""
    f = slots[0]
    frame_jacobian(Jw, supports[f], ps[f], Jf)
    _axis_row(target[0], target[1], target[2], Rs[f], _Z, Jf, e, J, _ROW0)


class SwingFootOrientationTask(FrameTask):
    """Δx_of = [1 − k·k_f, 1 − i·i_f] (eq. 4.3): sole z and x axes aligned with the target's."""

    dim = 2
    row_kernel = staticmethod(swing_axes_rows)
    target_fields = ("target",)
    stack_type = "swing_foot_orientation"  # its `type` in stack files (wbc.tasks.task.register)

    def __init__(
        self,
        robot: Robot,
        frame: str,
        target: np.ndarray | None = None,
        name: str | None = None,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(robot, frame, name or f"thesis_orientation_{frame}", gain, weight, mask)
        self.target = np.eye(3)
        if target is not None:
            self.set_target(target)

    def set_target(self, rotation: np.ndarray) -> None:
        """Target axes k = R*[:, 2], i = R*[:, 0]."""
        check_rotation(self, rotation, out=self.target)

    def set_target_from(self, kin: Kinematics) -> None:
        self.target[:] = kin.rotation(self.frame_id)


class TorsoOrientationTask(FrameTask):
    """Δx_ot = 1 − k·k_t (eq. 4.4): the torso's z axis vertical (or along ``axis``)."""

    dim = 1
    row_kernel = staticmethod(torso_axis_rows)
    target_fields = ("axis",)
    stack_type = "torso_orientation"  # its `type` in stack files (wbc.tasks.task.register)
    stack_keys = ("axis",)

    def __init__(
        self,
        robot: Robot,
        frame: str = "torso",
        axis: Sequence[float] = (0.0, 0.0, 1.0),
        name: str | None = None,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(robot, frame, name or "thesis_torso_orientation", gain, weight, mask)
        self.axis = np.zeros(3)
        self.set_axis(axis)

    def set_axis(self, axis: Sequence[float]) -> None:
        """The target axis (world), normalised and copied in place."""
        a = check_vector(self, axis, 3, "axis")
        norm = float(np.linalg.norm(a))
        if norm < 1e-12:
            raise TaskError(f"task {self.name!r}: axis must not be zero")
        self.axis[:] = a / norm
