"""3-D Linear Inverted Pendulum (thesis sec. 1.8.1, eqs. 1.62-1.68; Kajita et al. 2001).

The CoM moves on the constraint plane (1.62), written relative to the pivot ``(px, py)`` on
the ground,

    z = kx (x - px) + ky (y - py) + zc,

and its horizontal motion obeys (1.63)-(1.64) ``x'' = (g / zc) x`` (x measured from the
pivot), solved by (1.65)-(1.68) with ``Tc = sqrt(zc / g)``:

    x(t)  = x(0) cosh(t/Tc) + Tc x'(0) sinh(t/Tc)
    x'(t) = x(0)/Tc sinh(t/Tc) + x'(0) cosh(t/Tc)        (and the same for y).

The thesis's procedure (sec. 4.1.2) picks ``x(0), y(0), zc`` and a cycle time, then solves
the initial velocities: :meth:`Lipm3D.initial_velocity` (reach a given point at time T) and
:meth:`Lipm3D.cycle_velocity` (the symmetric walking cycle: x passes over the pivot to the
mirror point, y swings back to where it started).

For multi-step walking the pivot (the ZMP) moves from foot to foot; with a piecewise-linear
ZMP ``p(t)`` the same closed form holds per phase around ``p(t)``.
:func:`lipm_com_for_zmp` chains the phases: each phase's initial velocity is solved so that
the divergent component of motion ``xi = c + Tc c'`` lands on the next phase's value
(backward from rest over the final ZMP), which is the two-point boundary problem of the
thesis solved for every phase at once; the CoM is continuous in position and velocity and
its ZMP ``c - Tc^2 c''`` is exactly ``p(t)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import TrajectoryError
from .schedule import sample_knots
from .spline import QuinticSegment

GRAVITY = 9.81


@dataclass(frozen=True)
class LipmTrajectory:
    """Sampled LIPM motion: times (N,) and CoM position, velocity, acceleration (N, 3)."""

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray


@dataclass(frozen=True)
class Lipm3D:
    """3-D LIPM with constraint plane ``z = kx x + ky y + zc`` (relative to the pivot)."""

    zc: float
    kx: float = 0.0
    ky: float = 0.0
    g: float = GRAVITY

    def __post_init__(self) -> None:
        if not (np.isfinite(self.zc) and self.zc > 0):
            raise TrajectoryError(f"LIPM: the plane height zc must be positive, got {self.zc}")
        if not (np.isfinite(self.g) and self.g > 0):
            raise TrajectoryError(f"LIPM: gravity must be positive, got {self.g}")
        if not (np.isfinite(self.kx) and np.isfinite(self.ky)):
            raise TrajectoryError("LIPM: plane slopes kx, ky must be finite")

    @property
    def tc(self) -> float:
        """Time constant ``Tc = sqrt(zc / g)`` (s)."""
        return float(np.sqrt(self.zc / self.g))

    def height(self, x_rel: np.ndarray, y_rel: np.ndarray) -> np.ndarray:
        """CoM height on the constraint plane (1.62) at pivot-relative ``x, y``."""
        return self.kx * np.asarray(x_rel) + self.ky * np.asarray(y_rel) + self.zc

    def trajectory(
        self,
        t: np.ndarray,
        p0: np.ndarray,
        v0: np.ndarray,
        pivot: np.ndarray = (0.0, 0.0),
    ) -> LipmTrajectory:
        """Closed-form motion (1.65)-(1.68) from horizontal position ``p0`` and velocity ``v0``.

        ``p0`` and the result are in world coordinates; the pivot is on the ground (z = 0).
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        piv = np.asarray(pivot, dtype=float)[:2]
        r0 = np.asarray(p0, dtype=float)[:2] - piv
        v0 = np.asarray(v0, dtype=float)[:2]
        tc = self.tc
        ch, sh = np.cosh(t / tc)[:, None], np.sinh(t / tc)[:, None]
        rel = r0 * ch + tc * v0 * sh  # (1.65), (1.67)
        vel = r0 / tc * sh + v0 * ch  # (1.66), (1.68)
        acc = rel / tc**2  # (1.63), (1.64)
        k = np.array([self.kx, self.ky])
        pos3 = np.column_stack([rel + piv, self.zc + rel @ k])
        vel3 = np.column_stack([vel, vel @ k])
        acc3 = np.column_stack([acc, acc @ k])
        return LipmTrajectory(t, pos3, vel3, acc3)

    def initial_velocity(
        self, p0: np.ndarray, p_end: np.ndarray, duration: float, pivot: np.ndarray = (0.0, 0.0)
    ) -> np.ndarray:
        """Initial horizontal velocity that takes the CoM from ``p0`` to ``p_end`` in ``duration``.

        From (1.65): ``x'(0) = (x(T) - x(0) cosh(T/Tc)) / (Tc sinh(T/Tc))`` (pivot-relative).
        """
        _check_duration(duration)
        piv = np.asarray(pivot, dtype=float)[:2]
        r0 = np.asarray(p0, dtype=float)[:2] - piv
        r1 = np.asarray(p_end, dtype=float)[:2] - piv
        tc = self.tc
        return (r1 - r0 * np.cosh(duration / tc)) / (tc * np.sinh(duration / tc))

    def cycle_velocity(
        self, p0: np.ndarray, cycle_time: float, pivot: np.ndarray = (0.0, 0.0)
    ) -> np.ndarray:
        """Initial velocity of the symmetric walking cycle of length ``cycle_time``.

        Sagittal: the CoM passes over the pivot and ends at the mirror point, ``x(T) = -x(0)``
        (pivot-relative), hence ``x'(0) = -x(0) coth(T / 2Tc) / Tc``. Lateral: it swings
        toward the pivot and back, ``y(T) = y(0)``, hence ``y'(0) = -y(0) tanh(T / 2Tc) / Tc``.
        Either way the end velocity is the start velocity with x kept and y reversed, so
        cycles on alternating feet chain with a continuous velocity.
        """
        _check_duration(cycle_time)
        piv = np.asarray(pivot, dtype=float)[:2]
        r0 = np.asarray(p0, dtype=float)[:2] - piv
        half = cycle_time / (2.0 * self.tc)
        return np.array([-r0[0] / np.tanh(half), -r0[1] * np.tanh(half)]) / self.tc


def _check_duration(duration: float) -> None:
    if not (np.isfinite(duration) and duration > 0):
        raise TrajectoryError(f"LIPM: the cycle time must be positive, got {duration}")


def lipm_com_for_zmp(
    knot_times: np.ndarray,
    zmp_knots: np.ndarray,
    com0: np.ndarray,
    tc: float,
    t: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CoM (pos, vel, acc), each (N, d), of the LIPM whose ZMP follows a piecewise-linear path.

    ``zmp_knots`` (K, d) at non-decreasing ``knot_times`` (K,) define ``p(t)`` (a repeated
    time is a jump: support exchange without double support). The CoM starts at ``com0``;
    the divergent component ``xi = c + Tc c'`` ends at rest over the last knot and, on each
    segment, ``u = xi - p - Tc p'`` grows as ``exp(tau / Tc)``: solved backward, this gives
    every segment's initial velocity ``c'(0) = (xi(0) - c(0)) / Tc``. With ``e = c - p``,
    ``e(tau) = u0/2 exp(tau/Tc) + (e0 - u0/2) exp(-tau/Tc)`` — the thesis's (1.65) around a
    moving pivot — evaluated in a form that never overflows. The last segment should hold
    the ZMP still (the CoM then settles over it).
    """
    T = np.asarray(knot_times, dtype=float)
    P = np.asarray(zmp_knots, dtype=float).reshape(len(T), -1)
    if len(T) < 2 or np.any(np.diff(T) < 0) or not T[-1] > T[0]:
        raise TrajectoryError("LIPM: ZMP knot times must be non-decreasing and span time")
    if not tc > 0:
        raise TrajectoryError(f"LIPM: Tc must be positive, got {tc}")
    seg = np.flatnonzero(np.diff(T) > 0)  # segment s runs from knot seg[s] to seg[s] + 1
    t0, dur = T[seg], T[seg + 1] - T[seg]
    p0, p1 = P[seg], P[seg + 1]
    pdot = (p1 - p0) / dur[:, None]
    decay_full = np.exp(-dur / tc)[:, None]
    n = len(seg)
    u_end = np.zeros_like(p0)
    xi = P[-1].copy()  # at rest over the final ZMP
    for i in range(n - 1, -1, -1):
        u_end[i] = xi - p1[i] - tc * pdot[i]
        xi = p0[i] + tc * pdot[i] + u_end[i] * decay_full[i]
    u0 = u_end * decay_full
    e0 = np.zeros_like(p0)
    c = np.asarray(com0, dtype=float)[: P.shape[1]].copy()
    for i in range(n):
        e0[i] = c - p0[i]
        c = p1[i] + 0.5 * u_end[i] + (e0[i] - 0.5 * u0[i]) * decay_full[i]
    t = np.asarray(t, dtype=float)
    i = np.clip(np.searchsorted(t0, t, side="right") - 1, 0, n - 1)
    tau = np.maximum(t - t0[i], 0.0)
    tau_in = np.minimum(tau, dur[i])[:, None]
    up = 0.5 * u_end[i] * np.exp((tau_in - dur[i][:, None]) / tc)  # u0/2 exp(tau/Tc)
    down = (e0[i] - 0.5 * u0[i]) * np.exp(-tau[:, None] / tc)
    moving = (tau <= dur[i])[:, None]
    pdot_t = np.where(moving, pdot[i], 0.0)
    e = up + down
    pos = p0[i] + pdot[i] * tau_in + e
    vel = pdot_t + (up - down) / tc
    acc = e / tc**2
    return pos, vel, acc


def lipm_walk_com(
    knot_times: np.ndarray,
    zmp_knots: np.ndarray,
    com0: np.ndarray,
    tc: float,
    t: np.ndarray,
    start_time: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Like :func:`lipm_com_for_zmp`, but starting exactly at rest.

    An unbounded LIPM at rest cannot follow a ZMP that starts moving (its CoM would need
    an initial velocity), so on ``[0, start_time]`` the CoM is a quintic from rest at
    ``com0`` to the LIPM state at ``start_time``; the free CoM position ``c1`` there (its
    velocity and acceleration follow from the LIPM) is chosen by least squares so that the
    quintic's ZMP ``c - Tc^2 c''`` follows the planned ZMP on the start phase.
    """
    T = np.asarray(knot_times, dtype=float)
    P = np.asarray(zmp_knots, dtype=float).reshape(len(T), -1)
    t = np.asarray(t, dtype=float)
    com0 = np.asarray(com0, dtype=float)[: P.shape[1]]
    if not (T[0] < start_time < T[-1]):
        raise TrajectoryError("LIPM: start_time must lie inside the ZMP path")

    later = T > start_time
    p_s = sample_knots(T, P, np.array([start_time]))[0]
    T2 = np.concatenate([[start_time], T[later]])
    P2 = np.vstack([p_s, P[later]])

    def state_at_start(c1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pos, vel, acc = lipm_com_for_zmp(T2, P2, c1, tc, np.array([start_time]))
        return pos[0], vel[0], acc[0]

    blend = t < start_time
    tb = t[blend]
    zero = np.zeros_like(com0)

    # ZMP of the start quintic is affine in c1: z = alpha + beta * c1 (per axis).
    def start_zmp(c1: np.ndarray) -> np.ndarray:
        pos1, vel1, acc1 = state_at_start(c1)
        q = QuinticSegment(com0, zero, zero, pos1, vel1, acc1, start_time)
        pos, _, acc = q.evaluate(tb)
        return pos - tc**2 * acc

    alpha = start_zmp(zero)
    beta = start_zmp(np.ones_like(com0)) - alpha
    zref = sample_knots(T, P, tb)
    c1 = np.sum(beta * (zref - alpha), axis=0) / np.maximum(np.sum(beta * beta, axis=0), 1e-300)
    pos1, vel1, acc1 = state_at_start(c1)
    pos = np.empty((t.size, P.shape[1]))
    vel = np.empty_like(pos)
    acc = np.empty_like(pos)
    q = QuinticSegment(com0, zero, zero, pos1, vel1, acc1, start_time)
    pos[blend], vel[blend], acc[blend] = q.evaluate(tb)
    pos[~blend], vel[~blend], acc[~blend] = lipm_com_for_zmp(T2, P2, c1, tc, t[~blend])
    return pos, vel, acc
