"""A frame held at a placement, its error in the frame's own axes (6-D): ``log6(M⁻¹ M*)``.

The rows of the pre-motion solves (:mod:`wbc.walking.window`, :mod:`wbc.walking.feasibility`):
a sole held at its placement, the torso at an orientation (masked to its last three rows).
:class:`~wbc.tasks.FramePoseTask` states the same goal with world axes and the exact
Jacobian of its rotation error; this one is the body-frame form (Pinocchio's ``log6`` and
``LOCAL`` Jacobian, as pink's frame task).
"""

from __future__ import annotations

from numba import njit

from ..compiled.rows import LOG_SERIES_ANGLE, frame_jacobian, log3, log_coefficients
from .frame_pose import FramePoseTask

#: below this angle (rad) the coefficients of the logarithm's linear part are their series
#: (:func:`wbc.compiled.rows.log_coefficients`)
TAYLOR_ANGLE = LOG_SERIES_ANGLE


@njit(cache=True)
def local_pose_rows(
    target, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, e, J
) -> None:
    """e = log6(M⁻¹ M*) = [V(ω)⁻¹ t; ω] with (R_r, t) = (Rᵀ R*, Rᵀ p* − Rᵀ p) and
    ω = log3(R_r); J = the frame's local Jacobian [Rᵀ J_v; Rᵀ J_ω] (target: p*, then R*
    row-major). ``Jf`` holds R_r before it holds the frame's Jacobian."""
    f = slots[0]
    R, p = Rs[f], ps[f]
    Rr = Jf[0:3, 0:3]
    for i in range(3):
        for j in range(3):
            Rr[i, j] = R[0, i] * target[3 + j] + R[1, i] * target[6 + j] + R[2, i] * target[9 + j]
    theta = log3(Rr, e[3:6])
    t0 = (R[0, 0] * target[0] + R[1, 0] * target[1] + R[2, 0] * target[2]) - (
        R[0, 0] * p[0] + R[1, 0] * p[1] + R[2, 0] * p[2]
    )
    t1 = (R[0, 1] * target[0] + R[1, 1] * target[1] + R[2, 1] * target[2]) - (
        R[0, 1] * p[0] + R[1, 1] * p[1] + R[2, 1] * p[2]
    )
    t2 = (R[0, 2] * target[0] + R[1, 2] * target[1] + R[2, 2] * target[2]) - (
        R[0, 2] * p[0] + R[1, 2] * p[1] + R[2, 2] * p[2]
    )
    # V(ω)⁻¹ t = α t − ½ ω × t + β (ω·t) ω (Pinocchio's log6)
    alpha, beta = log_coefficients(theta)
    w0, w1, w2 = e[3], e[4], e[5]
    bwt = beta * (w0 * t0 + w1 * t1 + w2 * t2)
    e[0] = alpha * t0 - 0.5 * (w1 * t2 - w2 * t1) + bwt * w0
    e[1] = alpha * t1 - 0.5 * (w2 * t0 - w0 * t2) + bwt * w1
    e[2] = alpha * t2 - 0.5 * (w0 * t1 - w1 * t0) + bwt * w2
    frame_jacobian(Jw, supports[f], p, Jf)
    for k in range(Jf.shape[1]):
        a0, a1, a2 = Jf[0, k], Jf[1, k], Jf[2, k]
        b0, b1, b2 = Jf[3, k], Jf[4, k], Jf[5, k]
        for i in range(3):
            J[i, k] = R[0, i] * a0 + R[1, i] * a1 + R[2, i] * a2
            J[3 + i, k] = R[0, i] * b0 + R[1, i] * b1 + R[2, i] * b2


class LocalFramePoseTask(FramePoseTask):
    """e = log6(M⁻¹ M*) (the frame's axes: [linear; angular]), J = the frame's local Jacobian
    (6 x nv; Pinocchio's ``LOCAL``).

    M = (R, p) is the frame's placement, M* = (R*, p*) its target. The rows are the
    Gauss–Newton model ``J Δq = e`` of reaching M*: exact at the target (where the Jacobian
    of ``log6`` is the identity) and first-order near it, as the pre-motion solves use it; for
    large errors :class:`~wbc.tasks.FramePoseTask`'s exact rotation rows converge further.
    The last three rows alone (``mask``) hold an orientation: ``log3(Rᵀ R*)``, ``Rᵀ J_ω``.
    """

    row_kernel = staticmethod(local_pose_rows)  # (targets, dim: FramePoseTask's)
    stack_type = "local_frame_pose"  # its `type` in stack files (wbc.tasks.task.register)
