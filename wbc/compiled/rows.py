"""Task rows in compiled code: the same errors and Jacobians as the task classes' ``fill``.

Each task of a block is described by one row of an integer ``spec`` table (its kind, frame
slot, target offset, output rows and mask) so that one call fills every row of a block from
Pinocchio's buffers: ``data.J`` (joint Jacobians, world frame), the frames' world placements,
the CoM and its Jacobian. The tests check every kind against its Python task to 1e-12.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit

from ._cache import refresh
from .layout import (
    COM,
    FRAME,
    KIND,
    ORIENTATION,
    POSE,
    POSITION,
    POSTURE,
    ROW,
    ROWS,
    SEL,
    SWING_AXES,
    TARGET,
    TORSO_AXIS,
)

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


@njit(cache=True)
def jlog3(theta: float, v: np.ndarray, out: np.ndarray) -> None:
    """out = Jlog3 at log = v (angle theta): the Jacobian of the SO(3) logarithm (Pinocchio's
    convention), I·θ cot(θ/2)/2 + (1/θ² − cot(θ/2)/(2θ)) v vᵀ + [v]ₓ/2."""
    if theta < 1e-4:  # Taylor expansions of both coefficients
        t2 = theta * theta
        diag = 1.0 - t2 / 12.0
        alpha = 1.0 / 12.0 + t2 / 720.0
    else:
        st = math.sin(theta)
        ct = math.cos(theta)
        st_1mct = st / (1.0 - ct)
        diag = 0.5 * theta * st_1mct
        alpha = 1.0 / (theta * theta) - 0.5 * st_1mct / theta
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
def _rotation_error(target: np.ndarray, R: np.ndarray, Jf: np.ndarray, e: np.ndarray, J) -> None:
    """e = log(R* Rᵀ) and J = Jlog3(R* Rᵀ) J_ω (R* row-major in ``target``)."""
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
def fill_rows(
    spec: np.ndarray,
    sel: np.ndarray,
    targets: np.ndarray,
    frame_R: tuple,
    frame_p: tuple,
    frame_support: np.ndarray,
    Jw: np.ndarray,
    com: np.ndarray,
    Jcom: np.ndarray,
    joints: np.ndarray,
    sqrt_w: np.ndarray,
    gain_sqrt_w: np.ndarray,
    J_out: np.ndarray,
    E_out: np.ndarray,
    b_out: np.ndarray,
) -> None:
    """Every task of a block: J_out = √w J, E_out = e (raw, masked), b_out = α √w e.

    ``frame_R``/``frame_p``: per frame slot, the world rotation and position (views into
    Pinocchio's data); ``frame_support[slot]`` its joint support.
    """
    nv = Jw.shape[1]
    nj = joints.shape[0]
    Jf = np.empty((6, nv))
    Jfull = np.empty((max(nv, 6), nv))
    efull = np.empty(max(nv, 6))
    for t in range(spec.shape[0]):
        kind = spec[t, KIND]
        f = spec[t, FRAME]
        o = spec[t, TARGET]
        if kind == COM:
            for i in range(3):
                efull[i] = targets[o + i] - com[i]
                for k in range(nv):
                    Jfull[i, k] = Jcom[i, k]
        elif kind == POSITION or kind == POSE:
            p = frame_p[f]
            frame_jacobian(Jw, frame_support[f], p, Jf)
            for i in range(3):
                efull[i] = targets[o + i] - p[i]
                for k in range(nv):
                    Jfull[i, k] = Jf[i, k]
            if kind == POSE:
                _rotation_error(targets[o + 3 : o + 12], frame_R[f], Jf, efull[3:6], Jfull[3:6])
        elif kind == ORIENTATION:
            frame_jacobian(Jw, frame_support[f], frame_p[f], Jf)
            _rotation_error(targets[o : o + 9], frame_R[f], Jf, efull[0:3], Jfull[0:3])
        elif kind == SWING_AXES or kind == TORSO_AXIS:
            # the thesis's errors 1 − a·b_f (eqs. 4.3, 4.4), Jacobian (b_f × a)ᵀ J_ω
            R = frame_R[f]
            frame_jacobian(Jw, frame_support[f], frame_p[f], Jf)
            n_axes = 2 if kind == SWING_AXES else 1
            for i in range(n_axes):
                if kind == SWING_AXES:  # sole z then x axes against the target rotation's
                    c = 2 if i == 0 else 0
                    a0, a1, a2 = targets[o + c], targets[o + 3 + c], targets[o + 6 + c]
                else:  # torso z axis against the target axis
                    c = 2
                    a0, a1, a2 = targets[o], targets[o + 1], targets[o + 2]
                b0, b1, b2 = R[0, c], R[1, c], R[2, c]
                efull[i] = 1.0 - (a0 * b0 + a1 * b1 + a2 * b2)
                x0 = b1 * a2 - b2 * a1
                x1 = b2 * a0 - b0 * a2
                x2 = b0 * a1 - b1 * a0
                for k in range(nv):
                    Jfull[i, k] = x0 * Jf[3, k] + x1 * Jf[4, k] + x2 * Jf[5, k]
        elif kind == POSTURE:
            for i in range(nj):
                efull[i] = targets[o + i] - joints[i]
                for k in range(nv):
                    Jfull[i, k] = 0.0
                Jfull[i, nv - nj + i] = 1.0
        else:  # DAMPING
            for i in range(nv):
                efull[i] = 0.0
                for k in range(nv):
                    Jfull[i, k] = 0.0
                Jfull[i, i] = 1.0
        r0 = spec[t, ROW]
        s0 = spec[t, SEL]
        for j in range(spec[t, ROWS]):
            src = sel[s0 + j]
            r = r0 + j
            e = efull[src]
            E_out[r] = e
            b_out[r] = gain_sqrt_w[r] * e
            w = sqrt_w[r]
            for k in range(nv):
                J_out[r, k] = w * Jfull[src, k]


# numba caches these on rows.py alone: flush them when the layout constants change
refresh(
    [log3, jlog3, frame_jacobian, _rotation_error, fill_rows],
    [Path(__file__).with_name("layout.py")],
)
