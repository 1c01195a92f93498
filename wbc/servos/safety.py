"""Deployment safety: joint-limit clamp, rate limit in time, soft start, watchdog, health
schedule, checks.

Every goal sent to the servos passes :class:`GoalLimiter`, in integer commands (ticks, µs):

1. joint limits: ``cmd = clip(round(c(q)), lo, hi)`` with ``[lo, hi]`` from
   :meth:`Codec.safe_range` (commands that decode inside the URDF limits); targets outside
   the URDF limits are counted per joint with their worst excess;
2. rate, by the time elapsed since the last goal sent (a token bucket per joint)::

       avail_j = credit_j + s_j · (t - t_prev)      step_j <= floor(avail_j)
       credit_j = min(avail_j - |step_j|, 1)

   with ``s_j`` the joint's speed in command units per second. At most one command unit of
   credit is carried, so between any two goals sent at ``t_a < t_b``::

       |cmd_b - cmd_a| <= s_j · (t_b - t_a) + 1

   whatever the tick timing: a late tick moves no further than its elapsed time allows and a
   tick that follows it closely moves less (never a burst); the mean speed never exceeds
   ``s_j``, also below one unit per tick (a soft start at 0.5 rad/s and 100 Hz);
3. the servo's own top speed ``h_j`` (``hard_speed``), rounding included: each goal's step
   from the previous one is at most ``floor(h_j · (t - t_prev))``, so no two consecutive
   goals ask for more than the servo can do (the carried credit never adds a unit there).

:class:`Watchdog` turns servo statuses into a :class:`Trip` (which servo, why) on N
consecutive failed exchanges or an error bit of the trip set. :class:`HealthSchedule` picks
the servos to check each tick so that any fault trips within a stated bound.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ConfigurationError, ServoError, TrajectoryError
from .bus import COMM_OK, Codec, ServoStatus

TRIP_FAULTS = ("overload", "overheating", "input_voltage", "angle_limit")
TRIP_FAULTS += ("electrical_shock", "encoder")  # X-series hardware errors (wbc.xseries)


def command_speed(codec: Codec, v_max: np.ndarray | float) -> np.ndarray:
    """Per-joint speed in command units per second: ``v_max · |scale|``."""
    v = np.broadcast_to(np.asarray(v_max, dtype=float), codec.scale.shape)
    if not np.all(np.isfinite(v)) or np.any(v <= 0):
        raise ConfigurationError(f"rate limit needs positive finite speeds, got v={v}")
    return v * np.abs(codec.scale)


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
    """The single gate of every goal: clamp to the joint limits, then limit the speed by the
    time elapsed since the joint's last goal change (module docstring)."""

    def __init__(
        self,
        codec: Codec,
        q_min: np.ndarray,
        q_max: np.ndarray,
        speed: np.ndarray,
        names: Sequence[str],
        hard_speed: np.ndarray | float | None = None,
    ) -> None:
        self.codec = codec
        self.q_min = np.asarray(q_min, dtype=float)
        self.q_max = np.asarray(q_max, dtype=float)
        self.names = tuple(names)
        self.lo, self.hi = codec.safe_range(self.q_min, self.q_max, self.names)
        self.speed = np.broadcast_to(np.asarray(speed, dtype=float), self.lo.shape).copy()
        if not np.all(np.isfinite(self.speed)) or np.any(self.speed <= 0):
            raise ConfigurationError(
                f"speed must be positive and finite per joint, got {self.speed}"
            )
        self.hard_speed = None  # command units/s, the servos' own maximum (rule 3)
        if hard_speed is not None:
            h = np.broadcast_to(np.asarray(hard_speed, dtype=float), self.lo.shape).copy()
            if np.any(np.isnan(h)) or np.any(h <= 0):
                raise ConfigurationError(f"hard_speed must be positive per joint, got {h}")
            self.hard_speed = np.where(np.isfinite(h), h, np.inf)
        n = len(self.names)
        self.report = LimitReport(self.names, np.zeros(n, int), np.zeros(n), np.zeros(n, int))
        self.prev: np.ndarray | None = None
        self.sent_at = 0.0  # time of the last goal
        self.credit = np.zeros(n)  # command units carried (< 1 after a full step, at most 1)

    def reset(self, cmds: np.ndarray, now: float) -> np.ndarray:
        """Start from commands (e.g. read present positions) at time ``now`` (s), clipped into
        the safe range."""
        c = np.asarray(cmds, dtype=float)
        if c.shape != self.lo.shape or not np.all(np.isfinite(c)):
            raise ServoError(f"limiter reset needs {self.lo.size} finite commands, got {c}")
        self.prev = np.clip(np.rint(c), self.lo, self.hi).astype(int)
        self.sent_at = now
        self.credit[:] = 0.0
        return self.prev.copy()

    def _available(self, now: float, speed: np.ndarray | float | None) -> np.ndarray:
        s = self.speed if speed is None else np.minimum(self.speed, speed)
        return self.credit + s * max(now - self.sent_at, 0.0)

    def allowed(self, now: float, speed: np.ndarray | float | None = None) -> np.ndarray:
        """Largest command change per joint for a goal sent at ``now``."""
        return self._steps(self._available(now, speed), now)

    def _steps(self, avail: np.ndarray, now: float) -> np.ndarray:
        step = np.floor(avail + 1e-9)
        if self.hard_speed is not None:  # rule 3: never above the servo's top speed
            step = np.minimum(step, np.floor(self.hard_speed * max(now - self.sent_at, 0.0)))
        return step.astype(int)

    def limit_cmd(
        self, target: np.ndarray, now: float, speed: np.ndarray | float | None = None
    ) -> np.ndarray:
        """Integer commands toward ``target`` (commands, float) for a goal sent at ``now``:
        clipped into ``[lo, hi]``, then within :meth:`allowed` of the previous goal. ``speed``
        (command units/s) lowers the limit (soft start, crouch) and is not counted."""
        if self.prev is None:
            raise ServoError("GoalLimiter: reset() with the present positions first")
        avail = self._available(now, speed)
        step = self._steps(avail, now)
        c = np.clip(np.rint(np.asarray(target, dtype=float)), self.lo, self.hi).astype(int)
        limited = np.clip(c, self.prev - step, self.prev + step)
        if speed is None:
            self.report.rate_limited += limited != c
            self.report.ticks += 1
        self.credit = np.clip(avail - np.abs(limited - self.prev), 0.0, 1.0)
        self.sent_at = max(now, self.sent_at)
        self.prev = limited
        return limited.copy()

    def __call__(self, q: np.ndarray, now: float) -> np.ndarray:
        """Commands for joint targets (rad, model order) sent at ``now``; counts clamps and
        rate limiting."""
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
        return self.limit_cmd(self.codec.encode_float(q), now)


def soft_start_target(
    start: np.ndarray, goal: np.ndarray, speed: np.ndarray | float, t: float
) -> np.ndarray:
    """Straight line in command space from ``start`` to ``goal`` at time ``t`` (s), every joint
    arriving together at ``T = max_j |goal_j - start_j| / speed_j``, none faster than its
    ``speed`` (command units/s)."""
    start = np.asarray(start, dtype=float)
    goal = np.asarray(goal, dtype=float)
    duration = float(np.max(np.abs(goal - start) / np.asarray(speed, dtype=float), initial=0.0))
    w = 1.0 if duration <= 0 else min(max(t / duration, 0.0), 1.0)
    return start + (goal - start) * w


@dataclass(frozen=True)
class Trip:
    """Why the motion stopped: the servo (None for the whole bus), the reason and, for a
    servo's error bits, their names (``faults``); ``comm`` is True for a communication fault."""

    index: int | None
    servo: str
    reason: str
    faults: tuple[str, ...] = ()
    comm: bool = False

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
            raise ConfigurationError(f"watchdog needs max_failures >= 1, got {self.max_failures}")
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
                    comm=True,
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
                tuple(bad),
            )
        return None

    def failing(self) -> list[int]:
        """Servos with a failure streak, the longest first (to check them again at once)."""
        f = self.failures[:-1]
        return [int(i) for i in np.argsort(-f, kind="stable") if f[i] > 0]


@dataclass
class HealthSchedule:
    """Which servos to check each tick so that a fault stops the motion within ``bound_s``.

    A servo is checked at least every ``rotation`` ticks ``R``; a failure streak is checked
    again every tick, so silence or late replies trip after ``max_failures`` = F consecutive
    failed checks. A fault appearing at any time t0 is first seen within R ticks and trips
    within F - 1 more; the last goal is sent in the tripping tick, so on schedule::

        last goal - t0 <= (R + F - 1) / rate      (error bits: <= R / rate)

    ``R = floor(bound_s · rate) - F`` (at least 1): one tick of the bound is kept for the
    lateness of ticks on a loaded host (at 50 Hz: R = 2, 80 ms on schedule, 20 ms margin).
    ``polls_per_tick = ceil(n / R) + 1`` (one spare for a failing servo), at most n. Below
    ``(F + 1) / bound_s`` Hz (40 Hz for 3 failures and 100 ms) every servo is checked every
    tick and the bound is ``F / rate``. Without per-servo health (one board): one poll.
    Order within a tick, by risk: failing servos (longest streak first), then the servos
    checked longest ago, ties broken by the last temperature, then the last |load|.
    """

    n: int
    rate: float
    max_failures: int = 3
    bound_s: float = 0.1
    per_servo: bool = True
    last_checked: np.ndarray = field(init=False)
    temperature: np.ndarray = field(init=False)
    load: np.ndarray = field(init=False)
    tick: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        self.last_checked = np.full(self.n, -(10**9))
        self.temperature = np.zeros(self.n)
        self.load = np.zeros(self.n)

    @property
    def rotation(self) -> int:
        if not self.per_servo:
            return 1
        return max(1, math.floor(self.bound_s * self.rate + 1e-9) - self.max_failures)

    @property
    def polls_per_tick(self) -> int:
        if not self.per_servo:
            return 1
        r = self.rotation
        return min(self.n, math.ceil(self.n / r) + (1 if r > 1 else 0))

    @property
    def detection_s(self) -> float:
        """Worst time from a fault to the last goal (module docstring), s."""
        return (self.rotation + self.max_failures - 1) / self.rate

    def pick(self, watchdog: Watchdog) -> list[int]:
        """The servos to check this tick (see the class docstring)."""
        if not self.per_servo:
            return [0]
        chosen = watchdog.failing()[: self.polls_per_tick]
        rest = [i for i in range(self.n) if i not in chosen]
        rest.sort(key=lambda i: (self.last_checked[i], -self.temperature[i], -abs(self.load[i])))
        chosen += rest[: self.polls_per_tick - len(chosen)]
        self.last_checked[chosen] = self.tick
        self.tick += 1
        return chosen

    def note(self, status: ServoStatus) -> None:
        """Remember a reply's temperature and load (risk order)."""
        if status.index is None:
            return
        if status.temperature is not None:
            self.temperature[status.index] = status.temperature
        if status.load is not None:
            self.load[status.index] = status.load


def check_trajectory(
    joints: np.ndarray,
    q_min: np.ndarray,
    q_max: np.ndarray,
    names: Sequence[str],
    tol: float = 1e-3,
    t: np.ndarray | None = None,
    what: str = "trajectory",
    first_tick: int = 0,
) -> None:
    """Refuse a (N, n) joint trajectory with NaN/inf or values beyond the limits by > tol,
    naming the first offending tick (counted from ``first_tick``: a chunk of a stream) and
    joint."""
    if not tol >= 0:  # NaN would silently disable the refusal (inf: clamp only, by intent)
        raise ConfigurationError(f"{what}: limit tolerance must be a number >= 0, got {tol}")
    joints = np.asarray(joints, dtype=float)
    if joints.ndim != 2 or joints.shape[1] != len(names):
        raise TrajectoryError(
            f"{what}: expected (N, {len(names)}) joint values, got shape {joints.shape}"
        )

    def when(k: int) -> str:
        return f"tick {first_tick + k}" + (f" (t = {t[k]:.3f} s)" if t is not None else "")

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
