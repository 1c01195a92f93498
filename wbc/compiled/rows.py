"""Building blocks of the kernels (numba; their signature: :mod:`wbc.compiled.signature`):
the SO(3) logarithm and its Jacobian, a frame's Jacobian from Pinocchio's joint Jacobians
and its velocity, the rotation error rows.

A task's row kernel (see :class:`wbc.tasks.Task`) calls these; the tests check each against
Pinocchio to 1e-12.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: within this of π, the logarithm's branch is chosen by a fixed rule, not by rounding
PI_BRANCH_TOL = 1e-9


@njit(cache=True)
def log3(R: np.ndarray, out: np.ndarray) -> float:
    """out = log(R) ∈ so(3) (axis × angle) through the unit quaternion of R; returns the angle.

    Shepperd's choice of pivot keeps the quaternion accurate at every angle (up to π). At π
    (within :data:`PI_BRANCH_TOL`) the branch has its largest component positive.
    """
    r00, r01, r02 = R[0, 0], R[0, 1], R[0, 2]
    r10, r11, r12 = R[1, 0], R[1, 1], R[1, 2]
    r20, r21, r22 = R[2, 0], R[2, 1], R[2, 2]
    tr = r00 + r11 + r22
    if tr >= r00 and tr >= r11 and tr >= r22:
        s = 2.0 * math.sqrt(max(1.0 + tr, 0.0))
        w = 0.25 * s
        x = (r21 - r12) / s
        y = (r02 - r20) / s
        z = (r10 - r01) / s
    elif r00 >= r11 and r00 >= r22:
        s = 2.0 * math.sqrt(max(1.0 + r00 - r11 - r22, 0.0))
        w = (r21 - r12) / s
        x = 0.25 * s
        y = (r01 + r10) / s
        z = (r02 + r20) / s
    elif r11 >= r22:
        s = 2.0 * math.sqrt(max(1.0 + r11 - r00 - r22, 0.0))
        w = (r02 - r20) / s
        x = (r01 + r10) / s
        y = 0.25 * s
        z = (r12 + r21) / s
    else:
        s = 2.0 * math.sqrt(max(1.0 + r22 - r00 - r11, 0.0))
        w = (r10 - r01) / s
        x = (r02 + r20) / s
        y = (r12 + r21) / s
        z = 0.25 * s
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    n = math.sqrt(x * x + y * y + z * z)
    theta = 2.0 * math.atan2(n, w)
    # theta / n -> 2 / w as n -> 0 (w -> 1): no division by a vanishing n
    k = theta / n if n > 1e-12 else 2.0 / w
    if theta > math.pi - PI_BRANCH_TOL:
        # at π the sign of the axis is rounding noise: one branch on every path (as
        # wbc.tasks.frame_task.log3), the largest component positive
        ax, ay, az = abs(x), abs(y), abs(z)
        big = x if ax >= ay and ax >= az else (y if ay >= az else z)
        if big < 0.0:
            k = -k
    out[0] = k * x
    out[1] = k * y
    out[2] = k * z
    return theta


#: below this angle (rad) :func:`log_coefficients` takes their series (truncation ~θ⁶/30240)
LOG_SERIES_ANGLE = 1e-3


@njit(cache=True)
def log_coefficients(theta: float) -> tuple[float, float]:
    """(a, b) = (θ cot(θ/2)/2, (1 − a)/θ²): the coefficients of the SO(3) logarithm's Jacobian
    Jlog3 = a I + b v vᵀ + [v]ₓ/2 and of log6's V(ω)⁻¹ (Pinocchio's conventions). From
    tan(θ/2), not θ sin θ / (1 − cos θ), whose 1 − cos θ cancels (3e-12 off at 2.5 mrad, 7e-9
    at 0.12 mrad); their series below :data:`LOG_SERIES_ANGLE`."""
    t2 = theta * theta
    if theta < LOG_SERIES_ANGLE:
        return 1.0 - t2 / 12.0 - t2 * t2 / 720.0, 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0
    a = 0.5 * theta / math.tan(0.5 * theta)
    return a, (1.0 - a) / t2


@njit(cache=True)
def jlog3(theta: float, v: np.ndarray, out: np.ndarray) -> None:
    """out = Jlog3 at log = v (angle theta): the Jacobian of the SO(3) logarithm (Pinocchio's
    convention), I·θ cot(θ/2)/2 + (1/θ² − cot(θ/2)/(2θ)) v vᵀ + [v]ₓ/2
    (:func:`log_coefficients`)."""
    diag, alpha = log_coefficients(theta)
    for i in range(3):
        for j in range(3):
            out[i, j] = alpha * v[i] * v[j]
        out[i, i] += diag
    out[0, 1] -= 0.5 * v[2]
    out[0, 2] += 0.5 * v[1]
    out[1, 0] += 0.5 * v[2]
    out[1, 2] -= 0.5 * v[0]
    out[2, 0] -= 0.5 * v[1]
    out[2, 1] += 0.5 * v[0]


@njit(cache=True)
def frame_jacobian(Jw: np.ndarray, support: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """out (6 x nv) = the frame Jacobian with world axes at the frame origin p (Pinocchio's
    LOCAL_WORLD_ALIGNED), from the joint Jacobians ``Jw`` = data.J (spatial, world frame) and
    the frame's joint support (True for the dofs that move it): v_p = v_O + ω × p."""
    for k in range(Jw.shape[1]):
        if support[k]:
            wx, wy, wz = Jw[3, k], Jw[4, k], Jw[5, k]
            out[0, k] = Jw[0, k] + wy * p[2] - wz * p[1]
            out[1, k] = Jw[1, k] + wz * p[0] - wx * p[2]
            out[2, k] = Jw[2, k] + wx * p[1] - wy * p[0]
            out[3, k] = wx
            out[4, k] = wy
            out[5, k] = wz
        else:
            for i in range(6):
                out[i, k] = 0.0


@njit(cache=True)
def rotation_rows(target: np.ndarray, R: np.ndarray, Jf: np.ndarray, e: np.ndarray, J) -> None:
    """e = log(R* Rᵀ) and J = Jlog3(R* Rᵀ) J_ω (R* row-major in ``target``, J_ω = Jf[3:])."""
    A = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            A[i, j] = (
                target[3 * i] * R[j, 0] + target[3 * i + 1] * R[j, 1] + target[3 * i + 2] * R[j, 2]
            )
    theta = log3(A, e)
    Jl = np.empty((3, 3))
    jlog3(theta, e, Jl)
    for k in range(Jf.shape[1]):
        w0, w1, w2 = Jf[3, k], Jf[4, k], Jf[5, k]
        for i in range(3):
            J[i, k] = Jl[i, 0] * w0 + Jl[i, 1] * w1 + Jl[i, 2] * w2


@njit(cache=True)
def frame_velocities(
    Jw: np.ndarray, supports: np.ndarray, ps: np.ndarray, n: int, v: np.ndarray, Jf, vs
) -> None:
    """vs[s] = J_s v for the first ``n`` frame slots: each frame's velocity [linear; angular]
    with world axes at its origin (:func:`frame_jacobian`), the kernels' input ``vs``."""
    for s in range(n):
        frame_jacobian(Jw, supports[s], ps[s], Jf)
        for i in range(6):
            acc = 0.0
            for k in range(v.shape[0]):
                acc += Jf[i, k] * v[k]
            vs[s, i] = acc
