"""Playback: a :class:`TargetSource` on a :class:`ServoBus` at a fixed rate, safely.

::

    open -> identify (PING all, adapter round trip) -> configure (limits, alarm shutdown,
    compliance, punch, torque limit, return delay 0; read back) -> read present positions
    -> goal := present, slow moving speed, torque on (acknowledged per servo)
    -> soft start to the first target -> playback (goals + health checks) -> end

Every tick sends one set of goals, then checks servos: with ``read`` all present positions,
else the :class:`HealthSchedule`'s polls. Any servo fault (error bit, silence, late replies)
stops the motion within :attr:`HealthSchedule.detection_s` (100 ms at 50 Hz). The *safe
stop* then sends no more motion and, by ``on_fault``:

* ``auto`` (default): overheating or overload -> ``crouch``; a fall detected by the closed
  loop (:class:`wbc.balance.fall.FallDetector`) -> ``fall`` (:meth:`Deployment.safe_fall`:
  torque limit lowered, protective posture, verified torque-off); anything else
  (communication faults, other error bits, Ctrl-C, a bad target) -> ``hold``;
* ``hold``: keep the last goal, torque on;
* ``torque-off``: torque off per servo, acknowledged and read back (register 24);
* ``crouch``: a slow move (soft speed) to the crouch pose, then ``torque-off``.

A start-up that fails once any torque may be on (torque enable) always ends in a verified
torque-off. Bad input is refused before any torque is enabled.
"""

from __future__ import annotations

import math
import signal
import threading
from array import array
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import ConfigurationError, FallDetected, ServoError
from ..model import Robot
from .bus import COMM_OK, WALL_CLOCK, Clock, ServoBus
from .config import DeployConfig
from .plan import overload_warning
from .safety import (
    GoalLimiter,
    HealthSchedule,
    LimitReport,
    Trip,
    Watchdog,
    check_trajectory,
    command_speed,
    soft_start_target,
)
from .sources import TargetSource

EXIT_OK = 0
EXIT_REFUSED = 2
EXIT_SAFE_STOP = 3
EXIT_INTERRUPTED = 130  # 128 + SIGINT; another stop signal exits with 128 + its number
#: signals that end a deployment in the safe stop (as Ctrl-C does): ``kill``, ``systemctl
#: stop`` (SIGTERM), a closed terminal or SSH session (SIGHUP), Ctrl-\\ (SIGQUIT)
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)
SIGNAL_REASONS: dict[int, str] = {
    signal.SIGINT: "interrupted (Ctrl-C)",
    signal.SIGTERM: "terminated (SIGTERM)",
    signal.SIGHUP: "hang-up (SIGHUP: terminal or session closed)",
    signal.SIGQUIT: "quit (SIGQUIT)",
}
#: the servos' own bus watchdog (where they have one): this many ticks without an
#: instruction, at least WATCHDOG_MIN_S, and they stop (:meth:`ServoBus.arm_watchdog`)
WATCHDOG_TICKS = 10
WATCHDOG_MIN_S = 0.2
#: error bits after which ``on_fault = auto`` crouches and cuts torque
CROUCH_FAULTS = ("overheating", "overload")
#: the safe fall (:meth:`Deployment.safe_fall`): share of the servos' maximum torque during
#: the fall, and s in the protective posture before torque off
FALL_TORQUE_LIMIT = 0.3
FALL_SETTLE_S = 0.6


class Interrupted(KeyboardInterrupt):
    """A stop signal (:data:`STOP_SIGNALS`) raised where no torque can be on (start-up), or a
    second one while the loop stops: ``signum`` says which."""

    def __init__(self, signum: int) -> None:
        super().__init__(SIGNAL_REASONS.get(signum, f"signal {signum}"))
        self.signum = signum


def signal_exit_code(signum: int | None) -> int:
    """``128 + signum`` (the shell's convention): 130 for Ctrl-C, 143 for SIGTERM."""
    return EXIT_INTERRUPTED if signum is None else 128 + int(signum)


@dataclass
class TimingStats:
    """Loop timing: achieved rate, lateness of tick starts (jitter), work per tick."""

    rate: float
    starts: np.ndarray
    lateness: np.ndarray  # start - scheduled start (s)
    work: np.ndarray  # s spent in the tick
    overruns: int = 0  # late ticks that skipped slots
    missed: int = 0  # slots skipped

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
            f"{self.overruns} overruns ({self.missed} ticks skipped, never caught up)",
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
    exchanges: list[str] = field(default_factory=list)
    health: str = ""
    signum: int | None = None  # the stop signal of an interrupted run

    @property
    def exit_code(self) -> int:
        if self.completed:
            return EXIT_OK
        return signal_exit_code(self.signum) if self.interrupted else EXIT_SAFE_STOP


#: s of margin before a slot's deadline with which :meth:`Ticker.wait` calls its ``warm`` (a
#: source's ``warm()``: the tick's code and arrays brought back into the caches the wait left
#: cold), on top of the shortest of the last :data:`WARM_KEPT` warm-ups' durations; the rest
#: of the wait is spun, not slept: a sleep lets the machine's other processes run, which evict
#: what the warm-up brought in (walk10 at 50 Hz, load ~25: the tick 0.54× its time without a
#: warm-up with 0.5 ms slept after it, 0.41–0.43× spun; benchmarks/self_collision.md,
#: twenty-first session)
WARM_LEAD_S = 2e-4
#: how many of the last warm-ups' durations :meth:`Ticker.wait` keeps (their shortest: the
#: warm-up's own time, a preempted one's left out)
WARM_KEPT = 8
#: s taken as the first warm-up's duration (none measured yet)
WARM_FIRST_S = 1e-3


class Ticker:
    """Absolute-deadline scheduler on the wall clock: slot ``k`` starts at ``t0 + k·period``.

    A slot that would start more than half a period late, or less than half a period after
    the last goal was sent (:attr:`last_sent`, set by the caller), is skipped: never caught
    up in a burst. :meth:`wait` returns the slot; ``wait(warm)`` calls ``warm()`` the
    warm-up's own time (the shortest of the last :data:`WARM_KEPT`) plus :data:`WARM_LEAD_S`
    before the slot's deadline, then spins to it, when it waits longer than that on the wall
    clock (a simulated clock's sleep runs the physics: not split, no warm-up).
    """

    def __init__(self, period: float, clock: Clock | None = None) -> None:
        self.period = period
        # a bus may bring its own clock (the simulator's: ``sleep`` runs the physics)
        self.clock = clock or WALL_CLOCK
        self.t0: float | None = None
        self.k = 0
        # per tick, 8 bytes each (a float list costs 32: 173 MB for 10 hours at 50 Hz)
        self.starts = array("d")
        self.lateness = array("d")
        self.work = array("d")
        self.overruns = 0
        self.missed = 0
        self.last_sent: float | None = None  # perf_counter time of the last goal sent
        self.warm_times: deque[float] = deque(maxlen=WARM_KEPT)  # s, the last warm-ups'

    def wait(self, warm: Callable[[], None] | None = None) -> int:
        now = self.clock.now()
        if self.t0 is None:
            self.t0 = now
        p = self.period
        # the slot must start at most p/2 late and at least p/2 after the last goal was sent
        earliest = now - 0.5 * p
        if self.last_sent is not None:
            earliest = max(earliest, self.last_sent + 0.5 * p)
        k = max(self.k, math.ceil((earliest - self.t0) / p - 1e-9))
        if k > self.k:
            self.overruns += 1
            self.missed += k - self.k
            self.k = k
        deadline = self.t0 + self.k * p
        if warm is not None and self.clock is WALL_CLOCK:
            now = self._warm(warm, deadline, now)
        if deadline > now:
            self.clock.sleep(deadline - now)
            now = self.clock.now()
        late = now - deadline
        slot = self.k
        self.starts.append(now)
        self.lateness.append(late)
        self.k += 1
        return slot

    def _warm(self, warm: Callable[[], None], deadline: float, now: float) -> float:
        """``warm()`` its own time plus :data:`WARM_LEAD_S` before ``deadline`` (nothing if
        the wait is shorter), then a spin to the deadline; the clock's time after it."""
        lead = WARM_LEAD_S + min(self.warm_times, default=WARM_FIRST_S)
        if deadline - now <= lead:
            return now
        clock = self.clock
        clock.sleep(deadline - lead - now)
        start = clock.now()
        warm()
        now = clock.now()
        self.warm_times.append(now - start)
        while now < deadline:  # (spun: a sleep hands the caches to other processes)
            now = clock.now()
        return now

    def done(self) -> None:
        self.work.append(self.clock.now() - self.starts[-1])

    def stats(self, rate: float) -> TimingStats:
        return TimingStats(
            rate,
            np.array(self.starts),
            np.array(self.lateness),
            np.array(self.work),
            self.overruns,
            self.missed,
        )


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
            raise ConfigurationError("source joint order differs from the robot's model order")
        if self.config.read and not bus.can_read:
            raise ConfigurationError(f"the {bus.name} backend cannot read servo positions (--read)")
        self.period = 1.0 / self.config.rate
        # a bus may bring its own clock (a lockstep simulator's); real buses run on the wall clock
        self.clock: Clock = bus.clock or WALL_CLOCK
        v = np.minimum(robot.v_max, bus.servo_speed)
        if self.config.max_speed is not None:
            v = np.minimum(v, self.config.max_speed)
        self.v_max = v
        hard = None  # the servos' own top speed, rounding included (GoalLimiter rule 3)
        if math.isfinite(bus.servo_speed):
            hard = command_speed(bus.codec, bus.servo_speed)
        self.limiter = GoalLimiter(
            bus.codec, robot.q_min, robot.q_max, command_speed(bus.codec, v), robot.joint_names,
            hard_speed=hard,
        )  # fmt: skip
        self.soft_speed = min(self.config.soft_speed, float(np.min(v)))
        self.soft_cmd_speed = command_speed(bus.codec, self.soft_speed)
        bus.set_command_limits(self.limiter.lo, self.limiter.hi)
        self.watchdog = Watchdog(bus.labels, self.config.max_failures, bus_label=f"{bus.name} bus")
        self.health = HealthSchedule(
            bus.n,
            self.config.rate,
            self.config.max_failures,
            self.config.fault_bound_s,
            bus.health_per_servo,
        )
        self.ticker = Ticker(self.period, self.clock)
        self.warnings: list[str] = []
        self.crouch_cmd = self._crouch_cmd()
        if self.crouch_cmd is None and self.config.on_fault in ("auto", "crouch"):
            self.warn(
                f"no crouch pose {self.config.crouch_pose!r} (--crouch-pose; the robot's poses: "
                f"{self.robot.pose_names()}): "
                "a safe stop that should crouch will cut torque where the robot stands"
            )
        self._rate_check()
        self._signum: int | None = None  # the stop signal received (flag, checked per tick)
        self._phase = "start-up"  # start-up (a signal raises), play (flags), stop (flags)
        self._torque_phase = False  # torque enable in progress: a failure cuts torque
        self._log_t: list[float] = []
        self._log_goal: list[np.ndarray] = []
        self._log_present: list[np.ndarray] = []
        self._log_phase: list[int] = []  # 0 soft start, 1 playback, 2 crouch
        self.last_present: np.ndarray | None = None  # rad, NaN unread (with config.read)
        n = robot.n_joints
        self._err_sq = np.zeros(n)
        self._err_n = np.zeros(n, int)
        self._err_max = np.zeros(n)

    def warn(self, text: str) -> None:
        """Record a warning and show it at once (before the motion it concerns)."""
        self.warnings.append(text)
        self.out(f"warning: {text}")

    def _crouch_cmd(self) -> np.ndarray | None:
        name = self.config.crouch_pose
        if name not in self.robot.pose_names():
            return None
        q = self.robot.configuration(name)[7:]
        c = np.rint(self.bus.codec.encode_float(q))
        return np.clip(c, self.limiter.lo, self.limiter.hi).astype(int)

    def _rate_check(self) -> None:
        text = overload_warning(self.bus, self.config, self.bus.turnaround_s)
        if text:
            self.warn(text)

    def health_line(self) -> str:
        h = self.health
        if self.config.read:
            return (
                f"health: all {self.bus.n} positions read every tick; a fault stops motion "
                f"within {self.config.max_failures / self.config.rate * 1e3:.0f} ms "
                "(+ tick lateness)"
            )
        if not self.bus.health_per_servo:
            return (
                "health: one board query per tick (no per-servo status on "
                f"this bus); silence stops motion within {h.detection_s * 1e3:.0f} ms "
                "(+ tick lateness)"
            )
        what = "servos"
        return (
            f"health: {h.polls_per_tick} {what} checked per tick, each servo at least every "
            f"{h.rotation} ticks; a fault stops motion within {h.detection_s * 1e3:.0f} ms "
            "(+ tick lateness)"
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
        for k in range(2):  # retries for replies lost on a loaded machine, after a pause
            failed = [s.index for s in statuses if s.comm != COMM_OK]
            if not failed:
                break
            self.clock.sleep(0.005 * 2**k)
            again = {s.index: s for s in bus.read_positions(failed)}
            statuses = [again.get(s.index, s) for s in statuses]
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
    def _tick(self, cmd: np.ndarray, sent_at: float, phase: int) -> Trip | None:
        bus = self.bus
        if bus.write_goals(cmd) != COMM_OK:
            return Trip(None, f"{bus.name} bus", "writing the goal positions failed", comm=True)
        if self.config.log_path:
            self._log_t.append(sent_at)
            self._log_goal.append(cmd.copy())
            self._log_phase.append(phase)
        present = np.full(cmd.shape, np.nan)
        trip = None
        if self.config.read:
            statuses = bus.read_positions()
        else:
            statuses = (bus.poll(i) for i in self.health.pick(self.watchdog))
        for s in statuses:
            if s.index is not None and s.position is not None:
                present[s.index] = s.position
            self.health.note(s)
            trip = self.watchdog.observe(s)
            if trip is not None:
                break  # stop checking: the safe stop comes first
        if self.config.read:
            ok = np.isfinite(present)
            self.last_present = np.where(ok, bus.codec.decode(np.where(ok, present, 0)), np.nan)
            err = np.where(ok, self.last_present - bus.codec.decode(cmd), 0)
            self._err_sq += err**2
            self._err_n += ok
            self._err_max = np.maximum(self._err_max, np.abs(err))
        if self.config.log_path:
            self._log_present.append(present)
        return trip

    # ------------------------------------------------------------------ stiffness
    def _follow_stiffness(self) -> None:
        """The source's servo stiffness (its optional ``stiffness`` attribute: factors of the
        configured stiffness, :meth:`ServoBus.set_stiffness`), written when it changes."""
        want = getattr(self.source, "stiffness", None)
        if want is None:
            return
        want = np.broadcast_to(np.asarray(want, dtype=float), (self.bus.n,))
        if not np.array_equal(want, self.bus.stiffness):
            self.bus.set_stiffness(want)

    def _restore_stiffness(self) -> None:
        """The configured stiffness back (a source changed it): the motion's end and every
        safe stop leave the servos as ``servos.toml`` sets them."""
        if self.bus.can_set_stiffness and np.any(self.bus.stiffness != 1.0):
            try:
                self.bus.set_stiffness(1.0)
            except ServoError as exc:  # the stop goes on; the report says it
                self.warn(f"stiffness not restored: {exc}")

    # ------------------------------------------------------------------ safe stop
    def stop_action(self, trip: Trip) -> str:
        """``hold``, ``torque-off`` or ``crouch`` for a trip (module docstring)."""
        if self._torque_phase:
            return "torque-off"
        mode = self.config.on_fault
        if mode == "auto":
            if "fall" in trip.faults:  # wbc.balance.fall: the protective fall
                return "fall"
            return "crouch" if set(trip.faults) & set(CROUCH_FAULTS) else "hold"
        return mode

    def _safe_stop(self, trip: Trip) -> str:
        self._phase = "stop"  # a stop signal now only cuts a crouch short, never raises
        self._signum = None
        action = self.stop_action(trip)
        try:
            reset = getattr(self.bus, "reset", None)
            if reset is not None:
                reset()
            self._restore_stiffness()  # every stop acts at the configured stiffness
            if action == "hold":
                return "hold"
            done = action
            if action == "fall":
                return "fall: " + self.safe_fall()
            if action == "crouch":
                crouched = self._crouch(trip.index)
                done = "crouch, torque-off" if crouched else "crouch cut short, torque-off"
            unconfirmed = self.bus.torque_off()
            if unconfirmed:
                self.warn("torque-off not confirmed by " + ", ".join(unconfirmed))
                return f"{done} (not confirmed: {', '.join(unconfirmed)})"
            return done
        except BaseException as exc:  # report, never raise from the safe stop
            self.warn(f"safe stop: {type(exc).__name__}: {exc}")
            return f"{action} (failed: {exc})"

    def safe_fall(
        self, torque_limit: float = FALL_TORQUE_LIMIT, settle_s: float = FALL_SETTLE_S
    ) -> str:
        """The protective stop of a detected fall (from the safe stop): lower the torque limit
        to ``torque_limit`` of the maximum (the servos give way on impact instead of
        stalling), go to the crouch pose at the servos' speed, hold ``settle_s``, verified
        torque off. Returns what was done (for the report)."""
        bus, lim = self.bus, self.limiter
        done = []
        set_limit = getattr(bus, "set_torque_limit", None)
        if set_limit is not None:
            set_limit(torque_limit)
            done.append(f"torque limit {100 * torque_limit:.0f} %")
        target = self.crouch_cmd
        if target is not None and lim.prev is not None:
            ticker = Ticker(self.period, self.clock)
            end = self.clock.now() + settle_s
            while self.clock.now() < end:
                ticker.wait()
                now = self.clock.now()
                cmd = lim.limit_cmd(target, now, None)
                ticker.last_sent = now
                bus.write_goals(cmd)
            done.append("protective posture")
        unconfirmed = bus.torque_off()
        if unconfirmed:
            self.warn("torque-off not confirmed by " + ", ".join(unconfirmed))
            done.append(f"torque-off (not confirmed: {', '.join(unconfirmed)})")
        else:
            done.append("torque-off")
        return ", ".join(done)

    def _crouch(self, faulted: int | None = None) -> bool:
        """Move slowly (soft speed) to the crouch pose; False if impossible or cut short. The
        ``faulted`` servo receives no goal (it keeps its last one): only the others move."""
        bus, lim = self.bus, self.limiter
        target = self.crouch_cmd
        if target is None or lim.prev is None:
            self.warn(f"no crouch pose {self.config.crouch_pose!r} in the servo map")
            return False
        if faulted is not None:
            target = target.copy()
            target[faulted] = lim.prev[faulted]
            bus.excluded = bus.excluded | {faulted}
        ticker = Ticker(self.period, self.clock)
        duration = float(np.max(np.abs(target - lim.prev) / self.soft_cmd_speed, initial=0.0))
        t_end = self.clock.now() + duration + 1.0
        while not np.array_equal(lim.prev, target):
            ticker.wait()
            now = self.clock.now()
            if self._signum is not None or now > t_end:
                return False
            cmd = lim.limit_cmd(target, now, self.soft_cmd_speed)
            ticker.last_sent = now
            if bus.write_goals(cmd) != COMM_OK:
                return False
            if self.config.log_path:
                self._log_t.append(now)
                self._log_goal.append(cmd.copy())
                self._log_present.append(np.full(cmd.shape, np.nan))
                self._log_phase.append(2)
        return True

    # ------------------------------------------------------------------ run
    def run(self) -> DeployResult:
        bus, lim = self.bus, self.limiter
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
        previous = self._install_handlers()
        try:
            return self._run_open(first_cmd)
        finally:
            for signum, handler in previous.items():
                signal.signal(signum, handler)

    def _install_handlers(self) -> dict:
        """Every stop signal takes the safe stop (main thread only: Python's rule)."""
        if threading.current_thread() is not threading.main_thread():
            return {}
        previous = {}
        for signum in STOP_SIGNALS:
            try:
                previous[signum] = signal.signal(signum, self._on_signal)
            except (OSError, ValueError):  # pragma: no cover - a platform without it
                pass
        return previous

    def _run_open(self, first_cmd: np.ndarray) -> DeployResult:
        bus, lim = self.bus, self.limiter
        self._phase = "start-up"
        bus.open()
        try:
            for w in getattr(bus, "warnings", []):
                self.warn(w)
            bus.identify()
            for note in getattr(bus, "notes", []):  # e.g. the adapter's measured round trip
                self.out(f"note: {note}")
            bus.configure()
            start = lim.reset(self._start_positions(first_cmd), self.clock.now())
            if bus.write_goals(start) != COMM_OK:  # hold where they are when torque comes on
                raise ServoError(f"{bus.name}: writing the start goals failed")
            bus.set_speed(self.soft_speed)
            self.out(self.health_line())
            return self._play_guarded(start, first_cmd)
        finally:
            bus.close()

    def _on_signal(self, signum, frame) -> None:
        """A stop signal: at start-up (torque off) stop at once; while torque may be on only
        set a flag, so the loop stops at the next tick boundary, never inside an exchange
        (a second signal there stops at once); in the safe stop, cut a crouch short."""
        if self._phase == "start-up":
            raise Interrupted(signum)
        if self._phase == "play" and self._signum is not None:
            raise Interrupted(self._signum)
        self._signum = signum

    def _play_guarded(self, start: np.ndarray, first_cmd: np.ndarray) -> DeployResult:
        """From torque enable on, a stop signal only sets a flag (:meth:`_on_signal`)."""
        self._phase = "play"
        return self._play(start, first_cmd)

    def _check_interrupt(self) -> None:
        if self._signum is not None:
            raise Interrupted(self._signum)

    def _play(self, start: np.ndarray, first_cmd: np.ndarray) -> DeployResult:
        bus, lim, cfg = self.bus, self.limiter, self.config
        trip: Trip | None = None
        interrupted = False
        signum: int | None = None
        soft_ticks = 0
        completed = False
        try:
            self._torque_phase = True
            bus.set_torque(True)
            # where the servos have one (Protocol 2.0 X series): their own bus watchdog stops
            # them if this process dies, even by kill -9 (the AX-12A has none: docs)
            watchdog_s = max(WATCHDOG_TICKS * self.period, WATCHDOG_MIN_S)
            if bus.arm_watchdog(watchdog_s):
                self.out(f"note: servo bus watchdog armed: {watchdog_s * 1e3:.0f} ms")
            self._torque_phase = False
            soft_ticker = Ticker(self.period, self.clock)
            t_soft = None
            while trip is None and not np.array_equal(lim.prev, first_cmd):
                soft_ticker.wait()
                self._check_interrupt()
                now = self.clock.now()
                t_soft = now if t_soft is None else t_soft
                target = soft_start_target(start, first_cmd, self.soft_cmd_speed, now - t_soft)
                cmd = lim.limit_cmd(target, now, self.soft_cmd_speed)
                soft_ticker.last_sent = now
                trip = self._tick(cmd, now, 0)
                soft_ticker.done()
                soft_ticks += 1
            if trip is None:
                bus.set_speed(float(np.min(self.v_max)))
            idle = getattr(self.source, "idle", None)  # (after each tick's goals: TargetSource)
            warm = getattr(self.source, "warm", None)  # (just before each tick's deadline)
            first_target = self.source(0, 0.0)  # before the clock starts: a live controller's
            while trip is None:  # first solve may be slow (compilation)
                tick = self.ticker.wait(warm)
                self._check_interrupt()
                q = first_target if tick == 0 else self.source(tick, tick * self.period)
                if q is None:
                    self.ticker.starts.pop()
                    self.ticker.lateness.pop()
                    completed = True
                    break
                now = self.clock.now()
                try:
                    cmd = lim(q, now)
                except ServoError as exc:
                    trip = Trip(None, "source", f"bad target at tick {tick}: {exc}")
                    break
                self._follow_stiffness()
                self.ticker.last_sent = now
                trip = self._tick(cmd, now, 1)
                self.ticker.done()
                if idle is not None and trip is None:
                    idle()
        except KeyboardInterrupt as exc:
            interrupted = True
            signum = getattr(exc, "signum", signal.SIGINT)
            trip = Trip(None, "operator", SIGNAL_REASONS.get(signum, f"signal {signum}"))
        except BaseException as exc:  # a crash mid-motion still ends in the safe stop
            faults = ("fall",) if isinstance(exc, FallDetected) else ()
            trip = Trip(None, "deploy", f"{type(exc).__name__}: {exc}", faults)
            signum = None
        action = None
        if trip is None:
            self._restore_stiffness()
        if trip is not None:
            action = self._safe_stop(trip)
        elif cfg.at_end == "torque-off":
            self._phase = "stop"
            try:
                unconfirmed = bus.torque_off()
            except BaseException as exc:  # never raise past the report
                unconfirmed = [f"all ({type(exc).__name__}: {exc})"]
            if unconfirmed:
                self.warn("torque-off not confirmed by " + ", ".join(unconfirmed))
        try:
            self._write_log()
        except Exception as exc:  # the stop is done; say the log is missing, in one line
            self.warn(f"--log {cfg.log_path} not written: {type(exc).__name__}: {exc}")
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
            bus.exchange_lines(),
            self.health_line(),
            signum if interrupted else None,
        )

    def _write_log(self) -> None:
        if not self.config.log_path or not self._log_t:
            return
        rtt = getattr(getattr(self.bus, "log", None), "rtt", [])
        np.savez(
            self.config.log_path,
            t=np.array(self._log_t) - self._log_t[0],
            goal=np.array(self._log_goal),
            present=np.array(self._log_present),
            phase=np.array(self._log_phase),
            rtt=np.array(rtt, dtype=float),
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


def report_lines(result: DeployResult, robot: Robot) -> list[str]:
    """The end-of-run report."""
    lines = []
    if result.completed:
        lines.append(f"completed: soft start {result.soft_start_ticks} ticks, then playback")
    else:
        lines.append(f"SAFE STOP ({result.stop_action}): {result.trip}")
    lines += result.timing.lines()
    if result.health:
        lines.append(result.health)
    lines += result.exchanges
    lines += result.limits.lines() or ["no goal was clamped or rate-limited"]
    if result.tracking_rms is not None:
        j = int(np.argmax(result.tracking_max))
        lines.append(
            f"tracking error (present - goal): RMS over joints "
            f"{math.degrees(float(np.sqrt(np.mean(result.tracking_rms**2)))):.2f} deg, "
            f"max {math.degrees(float(result.tracking_max[j])):.2f} deg ({robot.joint_names[j]})"
        )
    return lines
