"""q ⊕ Δq in the compiled tick (:func:`integrate`): the free-flyer base's SE(3) exponential and
the joints clipped to their box and limits, as :meth:`wbc.solvers.base.StackSolver.integrate`."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: a joint within this (rad) outside a limit after a step back towards it is put at the
#: limit by :func:`integrate` (the step's rounding, not a position)
LIMIT_ROUNDING = 1e-12


@njit(cache=True)
def integrate(
    q: np.ndarray,
    dq: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    out: np.ndarray,
) -> None:
    """out = q ⊕ Δq for a free-flyer root and revolute joints, as
    :meth:`wbc.solvers.base.StackSolver.integrate`: the joint increments clipped to the box
    [lower, upper], the joints to [min(q_min, q_j), max(q_max, q_j)], the base moved by the
    SE(3) exponential of its local twist Δq[:6] (Pinocchio's free-flyer integration)."""
    vx, vy, vz = dq[0], dq[1], dq[2]
    wx, wy, wz = dq[3], dq[4], dq[5]
    t2 = wx * wx + wy * wy + wz * wz
    t = math.sqrt(t2)
    # V(ω) v = v + a (ω × v) + b (ω × (ω × v)), a = (1 − cos t)/t², b = (t − sin t)/t³
    if t < 1e-4:
        a = 0.5 - t2 / 24.0
        b = 1.0 / 6.0 - t2 / 120.0
        half = 0.5 - t2 / 48.0  # sin(t/2)/t
        cw = 1.0 - t2 / 8.0  # cos(t/2)
    else:
        a = (1.0 - math.cos(t)) / t2
        b = (t - math.sin(t)) / (t2 * t)
        half = math.sin(0.5 * t) / t
        cw = math.cos(0.5 * t)
    cx = wy * vz - wz * vy
    cy = wz * vx - wx * vz
    cz = wx * vy - wy * vx
    ux = vx + a * cx + b * (wy * cz - wz * cy)
    uy = vy + a * cy + b * (wz * cx - wx * cz)
    uz = vz + a * cz + b * (wx * cy - wy * cx)
    # base rotation from its quaternion (x, y, z, w)
    qx, qy, qz, qw = q[3], q[4], q[5], q[6]
    r00 = 1.0 - 2.0 * (qy * qy + qz * qz)
    r01 = 2.0 * (qx * qy - qz * qw)
    r02 = 2.0 * (qx * qz + qy * qw)
    r10 = 2.0 * (qx * qy + qz * qw)
    r11 = 1.0 - 2.0 * (qx * qx + qz * qz)
    r12 = 2.0 * (qy * qz - qx * qw)
    r20 = 2.0 * (qx * qz - qy * qw)
    r21 = 2.0 * (qy * qz + qx * qw)
    r22 = 1.0 - 2.0 * (qx * qx + qy * qy)
    out[0] = q[0] + r00 * ux + r01 * uy + r02 * uz
    out[1] = q[1] + r10 * ux + r11 * uy + r12 * uz
    out[2] = q[2] + r20 * ux + r21 * uy + r22 * uz
    # q ⊗ exp(ω/2), normalised
    ex, ey, ez, ew = half * wx, half * wy, half * wz, cw
    nx = qw * ex + qx * ew + qy * ez - qz * ey
    ny = qw * ey - qx * ez + qy * ew + qz * ex
    nz = qw * ez + qx * ey - qy * ex + qz * ew
    nw = qw * ew - qx * ex - qy * ey - qz * ez
    norm = math.sqrt(nx * nx + ny * ny + nz * nz + nw * nw)
    out[3] = nx / norm
    out[4] = ny / norm
    out[5] = nz / norm
    out[6] = nw / norm
    nb = dq.shape[0] - q_min.shape[0]
    for j in range(q_min.shape[0]):
        d = min(max(dq[nb + j], lower[nb + j]), upper[nb + j])
        qj = q[7 + j]
        v = min(max(qj + d, min(q_min[j], qj)), max(q_max[j], qj))
        # a joint coming back from outside that lands a rounding error short of its limit
        # (q + (q_min − q) != q_min in floating point) is at it: 4e-16 rad outside made the
        # next tick a start outside the limits, another problem (issue 28: the two paths'
        # Δq, 1e-15 apart, then differed by 1e-3)
        if v < q_min[j] and q_min[j] - v <= LIMIT_ROUNDING:
            v = q_min[j]
        elif v > q_max[j] and v - q_max[j] <= LIMIT_ROUNDING:
            v = q_max[j]
        out[7 + j] = v
