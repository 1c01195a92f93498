"""``wbc deploy``: play joint targets on the servos at a fixed rate, safely.

Playback pulls joint targets from a :class:`TargetSource` once per tick (a recording here; a
live controller later) and sends them through the one gate of :mod:`wbc.servos.safety`::

    open -> identify (PING all) -> configure (limits in servo memory, return delay 0)
    -> read present positions -> goal := present, slow moving speed, torque on
    -> soft start to the first target -> playback (goals + health poll or position reads)
    -> end (hold or torque off)

A watchdog trip (timeouts, corrupt replies, error bits, a missing servo), a failed write, a
bad live target or Ctrl-C ends in the *safe stop*: no more motion is sent, then the servos
hold their last goal or lose torque (``--on-fault``); the report names the servo and why.
Bad input (port, baud, servo map, NaN or out-of-limit trajectory) is refused before any
torque is enabled.

Examples::

    wbc deploy --plan                                   # bus budget, highest rates
    wbc deploy walk.npz --dry-run                       # whole pipeline, no port
    wbc deploy walk.npz --port /dev/ttyUSB0 --rate 50 --read --on-fault torque-off
    wbc deploy walk.npz --backend ssc32 --port /dev/ttyUSB0 --ssc32-map kokone.toml

Exit codes: 0 played to the end, 2 refused (nothing moved), 3 safe stop after a fault,
130 safe stop after Ctrl-C.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from ..exceptions import ServoError, TrajectoryError, WbcError
from ..model import Robot, load_robot
from ..recording import Recording
from .bus import COMM_OK, BusBudget, DryRunBus, ServoBus
from .safety import (
    ON_FAULT_CHOICES,
    GoalLimiter,
    LimitReport,
    Trip,
    Watchdog,
    check_trajectory,
    max_step,
    soft_start_targets,
)

EXIT_OK = 0
EXIT_REFUSED = 2
EXIT_SAFE_STOP = 3
EXIT_INTERRUPTED = 130
MAX_RATE_HZ = 100.0


# ---------------------------------------------------------------------- sources
class TargetSource(Protocol):
    """Joint targets per tick (rad, in ``joint_names`` order = the robot's model order).

    ``first()`` is where the soft start goes; ``__call__(tick, t)`` gives the target of tick
    ``tick`` at playback time ``t = tick / rate`` (s), or None when the motion is over. A
    live controller implements the same two methods.
    """

    joint_names: tuple[str, ...]

    def first(self) -> np.ndarray: ...

    def __call__(self, tick: int, t: float) -> np.ndarray | None: ...


class RecordingSource:
    """A recording resampled (linear interpolation) at the playback rate, checked up front."""

    def __init__(self, recording: Recording, robot: Robot, tol: float = 1e-3) -> None:
        names = robot.joint_names
        rec_names = tuple(recording.joint_names)
        if set(rec_names) != set(names):
            missing = sorted(set(names) - set(rec_names))
            unknown = sorted(set(rec_names) - set(names))
            raise TrajectoryError(
                f"recording joints do not match {robot.name}: missing {missing}, unknown {unknown}"
            )
        order = [rec_names.index(n) for n in names]
        self.joint_names = names
        self.t = recording.t - recording.t[0]
        self.joints = recording.joints[:, order]
        check_trajectory(
            self.joints, robot.q_min, robot.q_max, names, tol, recording.t, "recording"
        )
        self.duration = float(self.t[-1])

    def first(self) -> np.ndarray:
        return self.joints[0].copy()

    def __call__(self, tick: int, t: float) -> np.ndarray | None:
        if t > self.duration + 1e-9:
            return None
        if self.t.size == 1:
            return self.joints[0].copy()
        i = int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, self.t.size - 2))
        w = (t - self.t[i]) / (self.t[i + 1] - self.t[i])
        w = min(max(w, 0.0), 1.0)
        return (1.0 - w) * self.joints[i] + w * self.joints[i + 1]


class CallableSource:
    """A source from a function ``f(tick, t) -> targets | None`` (e.g. a live controller)."""

    def __init__(
        self,
        f: Callable[[int, float], np.ndarray | None],
        first: np.ndarray,
        joint_names: Sequence[str],
    ) -> None:
        self.f = f
        self._first = np.asarray(first, dtype=float)
        self.joint_names = tuple(joint_names)

    def first(self) -> np.ndarray:
        return self._first.copy()

    def __call__(self, tick: int, t: float) -> np.ndarray | None:
        return self.f(tick, t)


# ---------------------------------------------------------------------- configuration, results
@dataclass
class DeployConfig:
    """Playback and safety settings (speeds in rad/s, tolerances in rad)."""

    rate: float = 50.0
    read: bool = False  # read all present positions each tick (tracking error)
    on_fault: str = "hold"  # or "torque-off"
    at_end: str = "hold"  # or "torque-off"
    max_speed: float | None = None  # default: min(URDF velocity limit, servo speed)
    soft_speed: float = 0.5
    max_failures: int = 3
    start_tol: float = 0.05  # present position may lie this far outside the limits
    log_path: str | None = None

    def validate(self) -> None:
        if not (math.isfinite(self.rate) and 0 < self.rate <= MAX_RATE_HZ):
            raise ServoError(f"rate must be in (0, {MAX_RATE_HZ:g}] Hz, got {self.rate}")
        for name in ("on_fault", "at_end"):
            if getattr(self, name) not in ON_FAULT_CHOICES:
                raise ServoError(
                    f"{name} must be one of {ON_FAULT_CHOICES}, got {getattr(self, name)!r}"
                )
        for name in ("soft_speed", "start_tol"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ServoError(f"{name} must be positive, got {v}")
        if self.max_speed is not None and not (
            math.isfinite(self.max_speed) and self.max_speed > 0
        ):
            raise ServoError(f"max_speed must be positive, got {self.max_speed}")


@dataclass
class TimingStats:
    """Loop timing: achieved rate, lateness of tick starts (jitter), work per tick."""

    rate: float
    starts: np.ndarray
    lateness: np.ndarray  # start - scheduled start (s)
    work: np.ndarray  # s spent in the tick
    overruns: int = 0

    @property
    def ticks(self) -> int:
        return int(self.starts.size)

    @property
    def achieved_rate(self) -> float:
        if self.starts.size < 2:
            return float("nan")
        return (self.starts.size - 1) / (self.starts[-1] - self.starts[0])

    def pct(self, values: np.ndarray, p: float) -> float:
        return float(np.percentile(values, p)) if values.size else float("nan")

    def lines(self) -> list[str]:
        ms = 1e3
        return [
            f"ticks {self.ticks} at {self.rate:g} Hz: achieved {self.achieved_rate:.2f} Hz, "
            f"{self.overruns} overruns",
            f"jitter (tick start lateness) p50 {self.pct(self.lateness, 50) * ms:.3f} ms, "
            f"p99 {self.pct(self.lateness, 99) * ms:.3f} ms, "
            f"max {float(np.max(self.lateness, initial=0)) * ms:.3f} ms",
            f"work per tick p50 {self.pct(self.work, 50) * ms:.3f} ms, "
            f"p99 {self.pct(self.work, 99) * ms:.3f} ms",
        ]


@dataclass
class DeployResult:
    """What happened: completed, or the trip and the safe stop taken."""

    completed: bool
    trip: Trip | None
    stop_action: str | None
    soft_start_ticks: int
    timing: TimingStats
    limits: LimitReport
    tracking_rms: np.ndarray | None = None  # rad per joint
    tracking_max: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)
    interrupted: bool = False

    @property
    def exit_code(self) -> int:
        if self.completed:
            return EXIT_OK
        return EXIT_INTERRUPTED if self.interrupted else EXIT_SAFE_STOP


class _Ticker:
    """Absolute-deadline scheduler; a tick later than one period re-anchors the schedule."""

    def __init__(self, period: float) -> None:
        self.period = period
        self.t0: float | None = None
        self.k = 0
        self.starts: list[float] = []
        self.lateness: list[float] = []
        self.work: list[float] = []
        self.overruns = 0

    def wait(self) -> None:
        now = time.perf_counter()
        if self.t0 is None:
            self.t0 = now
        deadline = self.t0 + self.k * self.period
        if deadline > now:
            time.sleep(deadline - now)
            now = time.perf_counter()
        late = now - deadline
        if late > self.period:
            self.overruns += 1
            self.t0 += late
        self.starts.append(now)
        self.lateness.append(late)
        self.k += 1

    def done(self) -> None:
        self.work.append(time.perf_counter() - self.starts[-1])

    def stats(self, rate: float) -> TimingStats:
        return TimingStats(
            rate, np.array(self.starts), np.array(self.lateness), np.array(self.work), self.overruns
        )


# ---------------------------------------------------------------------- the deployment
class Deployment:
    """One run of a source on a bus (see the module docstring for the sequence)."""

    def __init__(
        self,
        bus: ServoBus,
        source: TargetSource,
        robot: Robot,
        config: DeployConfig | None = None,
        out: Callable[[str], None] = print,
    ) -> None:
        self.bus = bus
        self.source = source
        self.robot = robot
        self.config = config or DeployConfig()
        self.out = out
        self.config.validate()
        if tuple(source.joint_names) != tuple(robot.joint_names):
            raise ServoError("source joint order differs from the robot's model order")
        if self.config.read and not bus.can_read:
            raise ServoError(f"the {bus.name} backend cannot read servo positions (--read)")
        self.period = 1.0 / self.config.rate
        v = np.minimum(robot.v_max, bus.servo_speed)
        if self.config.max_speed is not None:
            v = np.minimum(v, self.config.max_speed)
        self.v_max = v
        self.limiter = GoalLimiter(
            bus.codec,
            robot.q_min,
            robot.q_max,
            max_step(bus.codec, v, self.period),
            robot.joint_names,
        )
        self.soft_step = max_step(
            bus.codec, min(self.config.soft_speed, float(np.min(v))), self.period
        )
        bus.set_command_limits(self.limiter.lo, self.limiter.hi)
        self.watchdog = Watchdog(bus.labels, self.config.max_failures, bus_label=f"{bus.name} bus")
        self.ticker = _Ticker(self.period)
        self.warnings: list[str] = []
        self._rate_check()
        self._poll_next = 0
        self._interrupted = False
        self._log_t: list[float] = []
        self._log_goal: list[np.ndarray] = []
        self._log_present: list[np.ndarray] = []
        n = robot.n_joints
        self._err_sq = np.zeros(n)
        self._err_n = np.zeros(n, int)
        self._err_max = np.zeros(n)

    def warn(self, text: str) -> None:
        """Record a warning and show it at once (before the motion it concerns)."""
        self.warnings.append(text)
        self.out(f"warning: {text}")

    def _rate_check(self) -> None:
        try:
            budget = self.bus.budget(self.config.read)
        except NotImplementedError:
            return
        if not budget.items:
            return
        t = budget.tick_time(self.bus.turnaround_s)
        if t > 0.8 * self.period:
            self.warn(
                f"the {budget.name} bus budget is {t * 1e3:.2f} ms per tick "
                f"({self.bus.turnaround_s * 1e3:g} ms turnaround per reply): "
                f"{self.config.rate:g} Hz ({self.period * 1e3:.2f} ms) leaves no margin; "
                f"expect overruns (max about {budget.max_rate(self.bus.turnaround_s):.0f} Hz)"
            )

    # ------------------------------------------------------------------ start-up
    def _start_positions(self, first_cmd: np.ndarray) -> np.ndarray:
        bus, lim = self.bus, self.limiter
        if not bus.can_read:
            self.warn(
                f"{bus.name}: positions cannot be read; no soft start from the real pose; "
                "place the robot near the first pose before starting"
            )
            for what in getattr(bus, "unchecked", ()):
                self.warn(f"{bus.name}: cannot check {what}")
            return first_cmd.astype(float)
        statuses = bus.read_positions()
        bad = [f"{bus.labels[s.index]}: {s.comm} {list(s.faults)}" for s in statuses if not s.ok]
        if bad:
            raise ServoError("cannot read the start positions: " + "; ".join(bad))
        present = np.array([s.position for s in statuses], dtype=float)
        tol = self.config.start_tol * np.abs(bus.codec.scale)
        outside = np.flatnonzero((present < lim.lo - tol) | (present > lim.hi + tol))
        if outside.size:
            parts = [
                f"{bus.labels[i]} at {present[i]:.0f} {bus.codec.unit}s, limits "
                f"{lim.lo[i]}..{lim.hi[i]}"
                for i in outside
            ]
            raise ServoError(
                "servos start outside their joint limits (move them by hand, torque is off): "
                + "; ".join(parts)
            )
        return present

    # ------------------------------------------------------------------ one tick
    def _tick(self, cmd: np.ndarray) -> Trip | None:
        bus = self.bus
        if bus.write_goals(cmd) != COMM_OK:
            return Trip(None, f"{bus.name} bus", "writing the goal positions failed")
        present = np.full(cmd.shape, np.nan)
        if self.config.read:
            statuses = bus.read_positions()
        else:
            i = self.watchdog.failing()
            if i is None:
                i = self._poll_next
                self._poll_next = (self._poll_next + 1) % bus.n
            statuses = [bus.poll(i)]
        trip = None
        for s in statuses:
            if s.index is not None and s.position is not None:
                present[s.index] = s.position
            trip = trip or self.watchdog.observe(s)
        if self.config.read:
            ok = np.isfinite(present)
            err = np.where(
                ok, bus.codec.decode(np.where(ok, present, 0)) - bus.codec.decode(cmd), 0
            )
            self._err_sq += err**2
            self._err_n += ok
            self._err_max = np.maximum(self._err_max, np.abs(err))
        if self.config.log_path:
            self._log_t.append(time.perf_counter())
            self._log_goal.append(cmd.copy())
            self._log_present.append(present)
        return trip

    # ------------------------------------------------------------------ safe stop
    def _safe_stop(self) -> str:
        main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        try:
            reset = getattr(self.bus, "reset", None)
            if reset is not None:
                reset()
            if self.config.on_fault == "torque-off":
                self.bus.set_torque(False)
                return "torque-off"
            return "hold"
        except Exception as exc:  # report, never raise from the safe stop
            self.warn(f"safe stop: {type(exc).__name__}: {exc}")
            return f"{self.config.on_fault} (failed: {exc})"
        finally:
            if main:
                signal.signal(signal.SIGINT, previous)

    # ------------------------------------------------------------------ run
    def run(self) -> DeployResult:
        bus, lim, cfg = self.bus, self.limiter, self.config
        first = np.asarray(self.source.first(), dtype=float)
        check_trajectory(
            first[None, :],
            self.robot.q_min,
            self.robot.q_max,
            self.robot.joint_names,
            1e-3,
            what="first target",
        )
        first_cmd = np.clip(np.rint(bus.codec.encode_float(first)), lim.lo, lim.hi).astype(int)
        bus.open()
        try:
            for w in getattr(bus, "warnings", []):
                self.warn(w)
            bus.identify()
            bus.configure()
            start = lim.reset(self._start_positions(first_cmd))
            if bus.write_goals(start) != COMM_OK:  # hold where they are when torque comes on
                raise ServoError(f"{bus.name}: writing the start goals failed")
            bus.set_speed(min(cfg.soft_speed, float(np.min(self.v_max))))
            return self._play_guarded(start, first_cmd)
        finally:
            bus.close()

    def _on_sigint(self, signum, frame) -> None:
        if self._interrupted:  # a second Ctrl-C: stop now, even inside an exchange
            raise KeyboardInterrupt
        self._interrupted = True

    def _play_guarded(self, start: np.ndarray, first_cmd: np.ndarray) -> DeployResult:
        """Ctrl-C only sets a flag while torque may be on: the loop stops at the next tick
        boundary, never inside an SDK exchange (which would leave the port marked busy)."""
        if threading.current_thread() is not threading.main_thread():
            return self._play(start, first_cmd)
        previous = signal.signal(signal.SIGINT, self._on_sigint)
        try:
            return self._play(start, first_cmd)
        finally:
            signal.signal(signal.SIGINT, previous)

    def _check_interrupt(self) -> None:
        if self._interrupted:
            raise KeyboardInterrupt

    def _play(self, start: np.ndarray, first_cmd: np.ndarray) -> DeployResult:
        bus, lim, cfg = self.bus, self.limiter, self.config
        trip: Trip | None = None
        interrupted = False
        soft_ticks = 0
        completed = False
        try:
            bus.set_torque(True)
            soft = soft_start_targets(start, first_cmd, self.soft_step)
            soft_ticker = _Ticker(self.period)
            k = 0
            while trip is None:
                target = soft[k] if k < len(soft) else first_cmd
                if k >= len(soft) and np.array_equal(lim.prev, first_cmd):
                    break
                soft_ticker.wait()
                self._check_interrupt()
                cmd = lim.limit_cmd(target, step=self.soft_step)
                trip = self._tick(cmd)
                soft_ticker.done()
                k += 1
            soft_ticks = k
            if trip is None:
                bus.set_speed(float(np.min(self.v_max)))
            tick = 0
            while trip is None:
                self.ticker.wait()
                self._check_interrupt()
                q = self.source(tick, tick * self.period)
                if q is None:
                    self.ticker.starts.pop()
                    self.ticker.lateness.pop()
                    completed = True
                    break
                try:
                    cmd = lim(q)
                except ServoError as exc:
                    trip = Trip(None, "source", f"bad target at tick {tick}: {exc}")
                    break
                trip = self._tick(cmd)
                self.ticker.done()
                tick += 1
        except KeyboardInterrupt:
            interrupted = True
            trip = Trip(None, "operator", "interrupted (Ctrl-C)")
        except Exception as exc:  # a crash mid-motion still ends in the safe stop
            trip = Trip(None, "deploy", f"{type(exc).__name__}: {exc}")
        action = None
        if trip is not None:
            action = self._safe_stop()
        elif cfg.at_end == "torque-off":
            bus.set_torque(False)
        self._write_log()
        rms = max_err = None
        if cfg.read:
            n = np.maximum(self._err_n, 1)
            rms, max_err = np.sqrt(self._err_sq / n), self._err_max
        return DeployResult(
            completed and trip is None,
            trip,
            action,
            soft_ticks,
            self.ticker.stats(cfg.rate),
            lim.report,
            rms,
            max_err,
            self.warnings,
            interrupted,
        )

    def _write_log(self) -> None:
        if not self.config.log_path or not self._log_t:
            return
        np.savez(
            self.config.log_path,
            t=np.array(self._log_t) - self._log_t[0],
            goal=np.array(self._log_goal),
            present=np.array(self._log_present),
            joint_names=np.array(self.robot.joint_names),
            unit=np.array(self.bus.codec.unit),
        )


def deploy(
    bus: ServoBus,
    source: TargetSource,
    robot: Robot,
    config: DeployConfig | None = None,
    out: Callable[[str], None] = print,
) -> DeployResult:
    """Play ``source`` on ``bus`` (see :class:`Deployment`)."""
    return Deployment(bus, source, robot, config, out).run()


# ---------------------------------------------------------------------- reports
def report_lines(result: DeployResult, robot: Robot) -> list[str]:
    lines = []
    if result.completed:
        lines.append(f"completed: soft start {result.soft_start_ticks} ticks, then playback")
    else:
        lines.append(f"SAFE STOP ({result.stop_action}): {result.trip}")
    lines += result.timing.lines()
    lines += result.limits.lines() or ["no goal was clamped or rate-limited"]
    if result.tracking_rms is not None:
        j = int(np.argmax(result.tracking_max))
        lines.append(
            f"tracking error (present - goal): RMS over joints "
            f"{math.degrees(float(np.sqrt(np.mean(result.tracking_rms**2)))):.2f} deg, "
            f"max {math.degrees(float(result.tracking_max[j])):.2f} deg ({robot.joint_names[j]})"
        )
    return lines


def budgets(bus: ServoBus) -> list[BusBudget]:
    """The bus budget per tick without and (if the bus can read) with position reads."""
    out = [bus.budget(read_positions=False)]
    if bus.can_read:
        out.append(bus.budget(read_positions=True))
    return out


def plan_lines(bus: ServoBus, rate: float, turnaround_s: float) -> list[str]:
    """The bus budget per tick and the highest rates, with and without position reads."""
    bs = budgets(bus)
    baud = bs[0].baud
    lines = [
        f"bus budget: {bus.n} servos on {bus.name} at {baud} baud "
        f"({bs[0].bits_per_byte} bits per byte, {bs[0].return_delay_s * 1e6:.0f} us servo "
        f"response per reply)"
    ]
    for b in bs:
        lines.append(f"  {b.name}:")
        for item in b.items:
            nbytes = item.bytes_out + item.bytes_in
            lines.append(
                f"    {item.count:2d} x {item.what}: {nbytes} B = "
                f"{nbytes * b.bits_per_byte / baud * 1e3:.3f} ms each"
            )
        lines.append(
            f"    {b.bytes_per_tick} B per tick, {b.replies_per_tick} replies: wire "
            f"{b.wire_time() * 1e3:.3f} ms + servo response -> {b.tick_time() * 1e3:.3f} ms "
            f"= max {b.max_rate():.0f} Hz; with {turnaround_s * 1e3:g} ms host turnaround per "
            f"reply {b.tick_time(turnaround_s) * 1e3:.3f} ms "
            f"= max {b.max_rate(turnaround_s):.0f} Hz"
        )
    if not bus.can_read:
        lines.append("  write + read: not possible (the backend cannot read positions)")
    usage = ", ".join(f"{b.name} {b.tick_time(turnaround_s) * rate * 100:.0f} %" for b in bs)
    lines.append(f"  at {rate:g} Hz ({1e3 / rate:.2f} ms per tick) the bus is busy: {usage}")
    return lines


# ---------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", nargs="?", help="recording .npz to play (t, q columns)")
    parser.add_argument(
        "--live",
        metavar="STACK",
        help="run this task stack live (e.g. walk) instead of a recording",
    )
    parser.add_argument(
        "--trajectory",
        default="walk10",
        help="--live: the walking reference to follow (see wbc bench --list)",
    )
    parser.add_argument("--robot", default="bioloid", help="robot name or URDF path")
    parser.add_argument("--servo-map", help="servo map TOML (default: the robot's servos.toml)")
    parser.add_argument(
        "--backend",
        "--bus",
        choices=("dynamixel", "ssc32"),
        default="dynamixel",
        help="servo bus (ssc32: the robot folder's ssc32.toml unless --ssc32-map)",
    )
    parser.add_argument("--port", help="serial port, e.g. /dev/ttyUSB0")
    parser.add_argument(
        "--baud", type=int, help="baud rate (default: servo map's, 115200 for ssc32)"
    )
    parser.add_argument("--dry-run", action="store_true", help="no port: simulated ideal servos")
    parser.add_argument(
        "--plan", action="store_true", help="print the bus budget (then play RECORDING if given)"
    )
    parser.add_argument("--rate", type=float, default=50.0, help="playback rate, Hz (<= 100)")
    parser.add_argument("--read", action="store_true", help="read present positions every tick")
    parser.add_argument(
        "--on-fault", choices=ON_FAULT_CHOICES, default="hold", help="safe stop: keep or cut torque"
    )
    parser.add_argument(
        "--at-end", choices=ON_FAULT_CHOICES, default="hold", help="after the last target"
    )
    parser.add_argument("--max-speed", type=float, help="rad/s (default: the servo speed)")
    parser.add_argument("--soft-speed", type=float, default=0.5, help="soft start rad/s")
    parser.add_argument("--max-failures", type=int, default=3, help="consecutive failed replies")
    parser.add_argument("--limit-tol", type=float, default=1e-3, help="rad beyond limits refused")
    parser.add_argument("--start-tol", type=float, default=0.05, help="rad outside limits at start")
    parser.add_argument("--latency-ms", type=float, default=1.0, help="USB latency timer, ms")
    parser.add_argument("--turnaround-ms", type=float, default=1.0, help="--plan: per reply, ms")
    parser.add_argument("--torque-limit", type=int, default=1023, help="AX torque limit 0..1023")
    parser.add_argument("--ssc32-map", help="SSC-32 joint/channel TOML")
    parser.add_argument("--log", help="save per-tick goals / present positions (.npz)")


def make_bus(args: argparse.Namespace, robot: Robot, port: str | None) -> ServoBus:
    """The backend named by ``--backend`` (not opened)."""
    sm = robot.servo_map
    if args.backend == "ssc32":
        from .ssc32 import Ssc32Bus, Ssc32Map

        own = robot.urdf_path.parent / "ssc32.toml"  # the robot folder's map (Kokone)
        if args.ssc32_map or own.is_file():
            ssc_map = Ssc32Map.from_file(args.ssc32_map or own, robot.joint_names)
        elif sm is not None:
            ssc_map = Ssc32Map.default(robot.joint_names, sm.signs.astype(int))
        else:
            raise ServoError(f"robot {robot.name} has no ssc32.toml; give --ssc32-map")
        for warning in ssc_map.range_warnings(robot.q_min, robot.q_max):
            print(f"warning: {warning}", file=sys.stderr)
        move_ms = max(1, round(1000.0 / args.rate))
        return Ssc32Bus(port or "", ssc_map, args.baud or ssc_map.baudrate, move_time_ms=move_ms)
    from .dynamixel import DynamixelBus

    return DynamixelBus(
        port or "",
        sm,
        args.baud or sm.baudrate,
        latency_timer_ms=args.latency_ms,
        torque_limit=args.torque_limit,
    )


def check_servo_map(robot: Robot, tol: float = 1e-3) -> list[str]:
    """Refuse a servo map whose named poses (e.g. Walk Ready) fall outside the URDF limits
    (a wrong sign or zero tick); return warnings for joints whose URDF range the servo's
    0..1023 ticks cut by more than 5 %."""
    sm = robot.servo_map
    if sm is None:
        raise ServoError(f"robot {robot.name} has no servo map (servos.toml); use --servo-map")
    for name in sorted(sm.poses):
        q = sm.ticks_to_angles(sm.pose_ticks(name))
        bad = np.flatnonzero((q < robot.q_min - tol) | (q > robot.q_max + tol))
        if bad.size:
            parts = [
                f"{robot.joint_names[i]} (id {sm.ids[i]}) at {q[i]:.4f} rad, limits "
                f"[{robot.q_min[i]:.4f}, {robot.q_max[i]:.4f}]"
                for i in bad
            ]
            raise ServoError(
                f"servo map {sm.source} is inconsistent with the URDF {robot.urdf_path.name}: "
                f"pose {name!r} puts " + "; ".join(parts) + " (wrong sign or zero tick?)"
            )
    a = sm.angles_to_ticks_float(robot.q_min)
    b = sm.angles_to_ticks_float(robot.q_max)
    span = np.abs(b - a)
    reachable = np.minimum(np.maximum(a, b), 1023) - np.maximum(np.minimum(a, b), 0)
    return [
        f"servo map: only {100 * reachable[i] / span[i]:.0f} % of {robot.joint_names[i]}'s URDF "
        "range lies inside the servo's 0..1023 ticks"
        for i in np.flatnonzero(reachable < 0.95 * span)
    ]


def _dry_bus(bus: ServoBus, robot: Robot) -> DryRunBus:
    """Ideal servos at the robot's standing pose, reading back only what ``bus`` could."""
    if robot.stand_pose != "zero":
        start = bus.codec.encode_float(robot.configuration("stand")[7:])
    else:
        start = bus.codec.encode_float(np.clip(0.0, robot.q_min, robot.q_max))
    start = np.clip(np.rint(start), bus.codec.cmd_min, bus.codec.cmd_max)
    dry = DryRunBus(bus.codec, bus.labels, start)
    dry.can_read = bus.can_read
    dry.name = "dry-run" if bus.can_read else f"dry-run {bus.name}"
    dry.unchecked = getattr(bus, "unchecked", ())
    return dry


def _live_source(args: argparse.Namespace, robot) -> tuple[CallableSource, str, float]:
    """A task stack solved live along a walking reference, one solve per deploy tick."""
    from ..bench.trajectories import build
    from ..stacks import load_stack
    from ..walking.loop import Session, StackController

    ref = build(args.trajectory, robot)
    session = Session(StackController(load_stack(args.live, robot)), robot, ref)

    def targets(tick: int, t: float) -> np.ndarray | None:
        q = session.at_time(t)
        return None if q is None else q[7:].copy()

    source = CallableSource(targets, session.q[7:].copy(), robot.joint_names)
    return source, f"live {args.live} on {args.trajectory}", ref.duration


def run(args: argparse.Namespace) -> int:
    err = sys.stderr
    try:
        robot = load_robot(args.robot, servo_map=args.servo_map)
        if args.backend == "dynamixel" or robot.servo_map is not None:
            for warning in check_servo_map(robot):
                print(f"warning: {warning}", file=err)
        config = DeployConfig(
            rate=args.rate,
            read=args.read,
            on_fault=args.on_fault,
            at_end=args.at_end,
            max_speed=args.max_speed,
            soft_speed=args.soft_speed,
            max_failures=args.max_failures,
            start_tol=args.start_tol,
            log_path=args.log,
        )
        config.validate()
        bus = make_bus(args, robot, args.port)
        if args.plan:
            for line in plan_lines(bus, args.rate, args.turnaround_ms * 1e-3):
                print(line)
            if args.recording is None:
                return EXIT_OK
        if args.recording is None and args.live is None:
            raise TrajectoryError("give a RECORDING.npz to play, --live STACK (or --plan)")
        if args.live is not None:
            source, what, duration = _live_source(args, robot)
        else:
            source = RecordingSource(Recording.load(args.recording), robot, tol=args.limit_tol)
            what, duration = Path(args.recording).name, source.duration
        if args.dry_run:
            bus = _dry_bus(bus, robot)
        elif not args.port:
            raise ServoError("give --port (or --dry-run)")
        print(
            f"deploy {what}: {duration:.2f} s at {args.rate:g} Hz on "
            f"{bus.name}{'' if args.dry_run else ' ' + args.port}"
        )
        result = deploy(bus, source, robot, config)
    except WbcError as exc:
        print(f"wbc deploy: refused before any torque was enabled: {exc}", file=err)
        return EXIT_REFUSED
    except KeyboardInterrupt:
        print("wbc deploy: interrupted before any torque was enabled", file=err)
        return EXIT_INTERRUPTED
    for line in report_lines(result, robot):
        print(line, file=sys.stdout if result.completed else err)
    return result.exit_code
