"""Relative frame position task: where one frame is, seen from another (3-D).

For a biped this places the swing sole relative to the support sole (a footstep in the
support foot's frame), independently of where the floating base has drifted to.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..compiled.rows import frame_jacobian
from ..model import Kinematics, Robot
from .task import Task, check_vector


@njit(cache=True)
def relative_position_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    """e = x* − R_aᵀ (p_b − p_a), J = R_aᵀ (J_v,b − J_v,a + [d]ₓ J_ω,a) with d = p_b − p_a.

    ``slots``: [frame b, reference frame a]. ``J`` is used as scratch for frame b's rows.
    """
    b, a = slots[0], slots[1]
    Ra, pa, pb = Rs[a], ps[a], ps[b]
    d0, d1, d2 = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
    for i in range(3):
        e[i] = target[i] - (Ra[0, i] * d0 + Ra[1, i] * d1 + Ra[2, i] * d2)
    nv = Jw.shape[1]
    frame_jacobian(Jw, supports[b], pb, Jf)
    for i in range(3):  # J[:3] = J_v,b
        for k in range(nv):
            J[i, k] = Jf[i, k]
    frame_jacobian(Jw, supports[a], pa, Jf)
    for k in range(nv):
        # v = J_v,b − J_v,a + d × ω_a (the rate of d seen in rotating axes), then R_aᵀ v
        w0, w1, w2 = Jf[3, k], Jf[4, k], Jf[5, k]
        v0 = J[0, k] - Jf[0, k] + d1 * w2 - d2 * w1
        v1 = J[1, k] - Jf[1, k] + d2 * w0 - d0 * w2
        v2 = J[2, k] - Jf[2, k] + d0 * w1 - d1 * w0
        for i in range(3):
            J[i, k] = Ra[0, i] * v0 + Ra[1, i] * v1 + Ra[2, i] * v2


class RelativeFramePositionTask(Task):
    """e = x* − x with x = R_aᵀ (p_b − p_a): the origin of ``frame`` in the axes and origin of
    ``reference`` (e.g. the swing sole seen from the support sole); 3 x nv.

    With d = p_b − p_a, ẋ = R_aᵀ (ḋ − ω_a × d) = R_aᵀ (J_v,b − J_v,a + [d]ₓ J_ω,a) v.
    """

    dim = 3
    row_kernel = staticmethod(relative_position_rows)
    target_fields = ("target",)
    #: in a stack file: ``{ type = "relative_position", frame = "r_sole", reference = "l_sole",
    #: target = [0.0, -0.074, 0.0] }`` (frame names, not roles)
    length_rows = 3
    stack_type = "relative_position"
    stack_keys = ("reference", "target")

    def __init__(
        self,
        robot: Robot,
        frame: str,
        reference: str,
        target: Sequence[float] | None = None,
        name: str | None = None,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        self.robot = robot
        self.set_frames(frame, reference)
        super().__init__(name or f"relative_{frame}_in_{reference}", gain, weight, mask)
        self.target = np.zeros(3)
        if target is not None:
            self.set_target(target)

    def set_frames(self, frame: str, reference: str) -> None:
        """Re-attach the task (e.g. at a support change); ModelError for unknown names."""
        ids = (self.robot.frame_id(frame), self.robot.frame_id(reference))
        changed = ids != getattr(self, "_ids", None)
        self._ids = ids
        self.frame, self.reference = frame, reference
        if changed:
            self._restructured()  # compiled plans hold the frames' placement views

    def frame_ids(self) -> tuple[int, ...]:
        return self._ids

    def set_target(self, target: Sequence[float]) -> None:
        """x* (m, in the reference frame's axes), copied in place."""
        check_vector(self, target, 3, out=self.target)

    def set_target_from(self, kin: Kinematics) -> None:
        """Target = the current relative position."""
        b, a = self._ids
        self.target[:] = kin.rotation(a).T @ (kin.translation(b) - kin.translation(a))
