"""Cubic splines through waypoints (the thesis's trajectory tool) and quintic profiles.

A cubic spline ``S`` through knots ``t_0 < ... < t_n`` with values ``y_i`` is, on
``[t_i, t_i+1]`` with ``h_i = t_i+1 - t_i`` and second derivatives ``M_i``,

    S(t) = M_i (t_i+1 - t)^3 / (6 h_i) + M_i+1 (t - t_i)^3 / (6 h_i)
           + (y_i / h_i - M_i h_i / 6)(t_i+1 - t) + (y_i+1 / h_i - M_i+1 h_i / 6)(t - t_i),

so it is C2. The ``M_i`` solve a tridiagonal system whose end rows are either *clamped*
(given end velocities, zero by default) or *natural* (``M_0 = M_n = 0``). Values may be
vectors: ``y`` is ``(n + 1, d)`` and every evaluation returns ``(len(t), d)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from scipy.linalg import solve_banded

from ..exceptions import TrajectoryError

Boundary = Literal["clamped", "natural"]


class CubicSpline:
    """Interpolating cubic spline, clamped or natural, in any dimension.

    Outside ``[t_0, t_n]`` the spline holds its end values with zero velocity and
    acceleration (a trajectory that has stopped).
    """

    def __init__(
        self,
        knots: Sequence[float] | np.ndarray,
        values: Sequence | np.ndarray,
        boundary: Boundary = "clamped",
        start_velocity: Sequence[float] | np.ndarray | float | None = None,
        end_velocity: Sequence[float] | np.ndarray | float | None = None,
    ) -> None:
        t = np.asarray(knots, dtype=float)
        y = np.asarray(values, dtype=float)
        self.scalar = y.ndim == 1
        y = y.reshape(len(y), -1) if y.ndim >= 1 else y
        if t.ndim != 1 or t.size < 2:
            raise TrajectoryError(f"spline: need at least 2 knots, got {t.size}")
        if y.shape[0] != t.size:
            raise TrajectoryError(f"spline: {t.size} knots but {y.shape[0]} waypoints")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
            raise TrajectoryError("spline: knots and waypoints must be finite")
        h = np.diff(t)
        if np.any(h <= 0):
            raise TrajectoryError("spline: knots must be strictly increasing")
        if boundary not in ("clamped", "natural"):
            raise TrajectoryError(
                f"spline: boundary must be 'clamped' or 'natural', got {boundary!r}"
            )
        d = y.shape[1]
        v0 = np.broadcast_to(np.asarray(0.0 if start_velocity is None else start_velocity), (d,))
        vn = np.broadcast_to(np.asarray(0.0 if end_velocity is None else end_velocity), (d,))
        self.t, self.y, self.h, self.boundary = t, y, h, boundary
        self.m = self._second_derivatives(t, y, h, boundary, v0.astype(float), vn.astype(float))

    @staticmethod
    def _second_derivatives(t, y, h, boundary, v0, vn) -> np.ndarray:
        n = t.size - 1
        slope = np.diff(y, axis=0) / h[:, None]
        ab = np.zeros((3, n + 1))  # banded: super, diag, sub
        rhs = np.zeros((n + 1, y.shape[1]))
        ab[1, 1:n] = 2.0 * (h[:-1] + h[1:])
        ab[0, 2:] = h[1:]  # super-diagonal of rows 1..n-1
        ab[2, : n - 1] = h[:-1]  # sub-diagonal of rows 1..n-1
        rhs[1:n] = 6.0 * (slope[1:] - slope[:-1])
        if boundary == "natural":
            ab[1, 0] = ab[1, n] = 1.0
        else:
            ab[1, 0], ab[0, 1] = 2.0 * h[0], h[0]
            rhs[0] = 6.0 * (slope[0] - v0)
            ab[2, n - 1], ab[1, n] = h[-1], 2.0 * h[-1]
            rhs[n] = 6.0 * (vn - slope[-1])
        return solve_banded((1, 1), ab, rhs)

    @property
    def knots(self) -> np.ndarray:
        return self.t

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def evaluate(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at time(s) ``t``; each ``(len(t), d)``.

        Scalar waypoints and scalar ``t`` give scalar-shaped results.
        """
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        tc = np.clip(tt, self.t[0], self.t[-1])
        i = np.clip(np.searchsorted(self.t, tc, side="right") - 1, 0, self.t.size - 2)
        h = self.h[i][:, None]
        a = (self.t[i + 1][:, None] - tc[:, None]) / h  # weight of knot i
        b = (tc[:, None] - self.t[i][:, None]) / h  # weight of knot i+1
        mi, mj = self.m[i], self.m[i + 1]
        yi, yj = self.y[i], self.y[i + 1]
        pos = a * yi + b * yj + (h**2 / 6.0) * ((a**3 - a) * mi + (b**3 - b) * mj)
        vel = (yj - yi) / h + (h / 6.0) * ((1.0 - 3.0 * a**2) * mi + (3.0 * b**2 - 1.0) * mj)
        acc = a * mi + b * mj
        outside = (tt < self.t[0]) | (tt > self.t[-1])
        vel[outside] = 0.0
        acc[outside] = 0.0
        return self._shape(pos, t), self._shape(vel, t), self._shape(acc, t)

    def __call__(self, t: float | np.ndarray) -> np.ndarray:
        return self.evaluate(t)[0]

    def _shape(self, arr: np.ndarray, t) -> np.ndarray:
        if self.scalar:
            arr = arr[:, 0]
        if np.ndim(t) == 0:
            return arr[0]
        return arr


def min_jerk(s: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quintic minimum-jerk profile ``p(s) = 10 s^3 - 15 s^4 + 6 s^5`` on [0, 1] and its
    first two derivatives with respect to ``s``; ``s`` is clipped to [0, 1] (held outside)."""
    s_arr = np.asarray(s, dtype=float)
    inside = (s_arr >= 0.0) & (s_arr <= 1.0)
    u = np.clip(s_arr, 0.0, 1.0)
    p = u**3 * (10.0 + u * (-15.0 + 6.0 * u))
    dp = np.where(inside, 30.0 * u**2 * (1.0 - u) ** 2, 0.0)
    ddp = np.where(inside, 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u), 0.0)
    return p, dp, ddp


def smoothstep(s: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic profile ``3 s^2 - 2 s^3`` on [0, 1] (clamped cubic between two waypoints)."""
    s_arr = np.asarray(s, dtype=float)
    inside = (s_arr >= 0.0) & (s_arr <= 1.0)
    u = np.clip(s_arr, 0.0, 1.0)
    return (
        u * u * (3.0 - 2.0 * u),
        np.where(inside, 6.0 * u * (1.0 - u), 0.0),
        np.where(inside, 6.0 - 12.0 * u, 0.0),
    )


def smooth(s: float) -> float:
    """The scalar cubic ``3 s^2 - 2 s^3`` of ``s`` clamped to [0, 1] (:func:`smoothstep`'s
    value, without arrays): a blend's weight."""
    s = min(max(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


class QuinticSegment:
    """Quintic polynomial on ``[0, duration]`` matching position, velocity and acceleration
    at both ends (values may be vectors). Held (zero velocity/acceleration) outside."""

    def __init__(self, p0, v0, a0, p1, v1, a1, duration: float) -> None:
        if not (np.isfinite(duration) and duration > 0):
            raise TrajectoryError(f"quintic: the duration must be positive, got {duration}")
        T = float(duration)
        M = np.array(
            [
                [1, 0, 0, 0, 0, 0],
                [0, 1, 0, 0, 0, 0],
                [0, 0, 2, 0, 0, 0],
                [1, T, T**2, T**3, T**4, T**5],
                [0, 1, 2 * T, 3 * T**2, 4 * T**3, 5 * T**4],
                [0, 0, 2, 6 * T, 12 * T**2, 20 * T**3],
            ]
        )
        rhs = np.array(
            [np.atleast_1d(np.asarray(v, dtype=float)) for v in (p0, v0, a0, p1, v1, a1)]
        )
        self.coef = np.linalg.solve(M, rhs)  # (6, d)
        self.duration = T

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity, acceleration at times ``t`` (each (len(t), d))."""
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        tc = np.clip(tt, 0.0, self.duration)[:, None]
        c = self.coef
        pos = sum(c[k] * tc**k for k in range(6))
        vel = sum(k * c[k] * tc ** (k - 1) for k in range(1, 6))
        acc = sum(k * (k - 1) * c[k] * tc ** (k - 2) for k in range(2, 6))
        outside = ((tt < 0) | (tt > self.duration))[:, None]
        return pos, np.where(outside, 0.0, vel), np.where(outside, 0.0, acc)
