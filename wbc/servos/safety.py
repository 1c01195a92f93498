"""Deployment safety: joint-limit clamp, per-tick rate limit, soft start, watchdog, checks.

Every goal sent to the servos passes :class:`GoalLimiter`, in integer commands (ticks, µs):

1. joint limits: ``cmd = clip(round(c(q)), lo, hi)`` with ``[lo, hi]`` from
   :meth:`Codec.safe_range` (commands that decode inside the URDF limits); targets outside
   the URDF limits are counted per joint with their worst excess;
2. rate: ``|cmd_k - cmd_{k-1}| <= step = floor(v_max · dt · |scale|)`` per joint (v_max from
   the servo speed), counted per joint.

:class:`Watchdog` turns servo statuses into a :class:`Trip` (which servo, why) on N
consecutive failed exchanges or an error bit of the trip set.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ServoError, TrajectoryError
from .bus import COMM_OK, Codec, ServoStatus

TRIP_FAULTS = ("overload", "overheating", "input_voltage", "angle_limit")
ON_FAULT_CHOICES = ("hold", "torque-off")


def max_step(codec: Codec, v_max: np.ndarray | float, dt: float) -> np.ndarray:
    """Largest command change per tick: ``floor(v_max · dt · |scale|)``, at least 1."""
    v = np.broadcast_to(np.asarray(v_max, dtype=float), codec.scale.shape)
    if not np.all(np.isfinite(v)) or np.any(v <= 0) or not dt > 0:
        raise ServoError(f"rate limit needs positive speeds and period, got v={v}, dt={dt}")
    return np.maximum(1, np.floor(v * dt * np.abs(codec.scale) + 1e-9)).astype(int)


@dataclass
class LimitReport:
    """What the limiter changed: per-joint clamp and rate-limit counts, worst excess (rad)."""

    names: tuple[str, ...]
    clamped: np.ndarray
    worst_excess: np.ndarray
    rate_limited: np.ndarray
    ticks: int = 0

    def lines(self) -> list[str]:
        out = []
        for j in np.flatnonzero(self.clamped):
            out.append(
                f"clamped {self.names[j]} to its joint limits on {self.clamped[j]} of "
                f"{self.ticks} ticks (worst {math.degrees(self.worst_excess[j]):.2f} deg outside)"
            )
        for j in np.flatnonzero(self.rate_limited):
            out.append(f"rate-limited {self.names[j]} on {self.rate_limited[j]} ticks")
        return out


class GoalLimiter:
    """The single gate of every goal: clamp to the joint limits, then limit the step."""

    def __init__(
        self,
        codec: Codec,
        q_min: np.ndarray,
        q_max: np.ndarray,
        step: np.ndarray,
        names: Sequence[str],
    ) -> None:
        self.codec = codec
        self.q_min = np.asarray(q_min, dtype=float)
        self.q_max = np.asarray(q_max, dtype=float)
        self.names = tuple(names)
        self.lo, self.hi = codec.safe_range(self.q_min, self.q_max, self.names)
        self.step = np.asarray(step, dtype=int)
        if self.step.shape != self.lo.shape or np.any(self.step < 1):
            raise ServoError(f"step must be >= 1 per joint, got {self.step}")
        n = len(self.names)
        self.report = LimitReport(self.names, np.zeros(n, int), np.zeros(n), np.zeros(n, int))
        self.prev: np.ndarray | None = None

    def reset(self, cmds: np.ndarray) -> np.ndarray:
        """Start from commands (e.g. read present positions), clipped into the safe range."""
        c = np.asarray(cmds, dtype=float)
        if c.shape != self.lo.shape or not np.all(np.isfinite(c)):
            raise ServoError(f"limiter reset needs {self.lo.size} finite commands, got {c}")
        self.prev = np.clip(np.rint(c), self.lo, self.hi).astype(int)
        return self.prev.copy()

    def limit_cmd(self, target: np.ndarray, step: np.ndarray | int | None = None) -> np.ndarray:
        """Integer commands toward ``target`` (commands, float): clipped into ``[lo, hi]``,
        then within ``step`` (default: the rate limit) of the previous command."""
        if self.prev is None:
            raise ServoError("GoalLimiter: reset() with the present positions first")
        s = self.step if step is None else np.minimum(self.step, step)
        c = np.clip(np.rint(np.asarray(target, dtype=float)), self.lo, self.hi).astype(int)
        limited = np.clip(c, self.prev - s, self.prev + s)
        if step is None:
            self.report.rate_limited += limited != c
            self.report.ticks += 1
        self.prev = limited
        return limited.copy()

    def __call__(self, q: np.ndarray) -> np.ndarray:
        """Commands for joint targets (rad, model order); counts clamps and rate limiting."""
        q = np.asarray(q, dtype=float)
        if q.shape != self.q_min.shape:
            raise ServoError(f"expected {self.q_min.size} joint targets, got shape {q.shape}")
        bad = ~np.isfinite(q)
        if np.any(bad):
            raise ServoError(
                f"non-finite joint targets for {[self.names[i] for i in np.flatnonzero(bad)]}"
            )
        excess = np.maximum(self.q_min - q, q - self.q_max)
        out = excess > 1e-12
        self.report.clamped += out
        self.report.worst_excess = np.maximum(self.report.worst_excess, np.where(out, excess, 0))
        return self.limit_cmd(self.codec.encode_float(q))


def soft_start_targets(start: np.ndarray, goal: np.ndarray, step: np.ndarray) -> list[np.ndarray]:
    """Straight line in command space from ``start`` to ``goal``, every joint arriving together,
    no joint moving more than ``step`` per tick (before rounding)."""
    start = np.asarray(start, dtype=float)
    goal = np.asarray(goal, dtype=float)
    n = int(np.max(np.ceil(np.abs(goal - start) / np.asarray(step, dtype=float)), initial=0))
    return [start + (goal - start) * (k / n) for k in range(1, n + 1)]


@dataclass(frozen=True)
class Trip:
    """Why the watchdog stopped the motion: the servo (None for the whole bus) and reason."""

    index: int | None
    servo: str
    reason: str

    def __str__(self) -> str:
        return f"{self.servo}: {self.reason}"


@dataclass
class Watchdog:
    """Trip on ``max_failures`` consecutive failed exchanges with one servo (timeout,
    corrupt status packet) or on any error bit of ``trip_faults``."""

    labels: Sequence[str]
    max_failures: int = 3
    trip_faults: tuple[str, ...] = TRIP_FAULTS
    bus_label: str = "bus"
    failures: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        if self.max_failures < 1:
            raise ServoError(f"watchdog needs max_failures >= 1, got {self.max_failures}")
        self.failures = np.zeros(len(self.labels) + 1, int)  # last entry: the bus / board

    def observe(self, status: ServoStatus) -> Trip | None:
        """A trip if this status completes a failure streak or carries a trip error bit."""
        i = status.index
        k = len(self.labels) if i is None else i
        label = self.bus_label if i is None else self.labels[i]
        if status.comm != COMM_OK:
            self.failures[k] += 1
            if self.failures[k] >= self.max_failures:
                who = "board" if i is None else "servo"
                return Trip(
                    i,
                    label,
                    f"{self.failures[k]} consecutive failed exchanges ({status.comm}): "
                    f"{who} missing or not answering",
                )
            return None
        self.failures[k] = 0
        bad = [f for f in status.faults if f in self.trip_faults]
        if bad:
            extra = []
            if status.temperature is not None:
                extra.append(f"{status.temperature:.0f} degC")
            if status.voltage is not None:
                extra.append(f"{status.voltage:.1f} V")
            more = f"; {', '.join(extra)}" if extra else ""
            return Trip(
                i,
                label,
                f"error bits 0x{status.error_byte:02X} ({', '.join(bad)}){more}",
            )
        return None

    def failing(self) -> int | None:
        """The servo with the most consecutive failures (to poll it again), if any."""
        servo_failures = self.failures[:-1]
        if not np.any(servo_failures):
            return None
        return int(np.argmax(servo_failures))


def check_trajectory(
    joints: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    names: Sequence[str],
    tol: float = 1e-3,
    t: np.ndarray | None = None,
    what: str = "trajectory",
) -> None:
    """Refuse a (N, n) joint trajectory with NaN/inf or values beyond the limits by > tol,
    naming the first offending tick and joint."""
    joints = np.asarray(joints, dtype=float)
    if joints.ndim != 2 or joints.shape[1] != len(names):
        raise TrajectoryError(
            f"{what}: expected (N, {len(names)}) joint values, got shape {joints.shape}"
        )

    def when(k: int) -> str:
        return f"tick {k}" + (f" (t = {t[k]:.3f} s)" if t is not None else "")

    bad = ~np.isfinite(joints)
    if np.any(bad):
        k, j = np.argwhere(bad)[0]
        raise TrajectoryError(f"{what}: {when(k)}: joint {names[j]} is {joints[k, j]}")
    below = joints < q_min - tol
    above = joints > q_max + tol
    if np.any(below | above):
        k, j = np.argwhere(below | above)[0]
        side, lim = ("below its lower", q_min[j]) if below[k, j] else ("above its upper", q_max[j])
        raise TrajectoryError(
            f"{what}: {when(k)}: joint {names[j]} = {joints[k, j]:.4f} rad is {side} limit "
            f"{lim:.4f} rad (by {abs(joints[k, j] - lim):.4f} rad; tolerance {tol} rad)"
        )
