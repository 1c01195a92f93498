"""Backend-independent servo bus: angle <-> command codec, servo status and the bus interface.

Every backend (Dynamixel AX-12A, Lynxmotion SSC-32, the dry-run simulator) drives the joints in
the robot model's order with integer *commands* (AX ticks, SSC-32 pulse widths in µs). A
:class:`Codec` is the per-joint affine map between joint angle and command::

    cmd = offset + scale * q          q = (cmd - offset) / scale

:meth:`Codec.safe_range` turns URDF joint limits into the integer command interval whose every
command decodes to an angle inside the limits (and inside the hardware range); the safety layer
never lets a command out of it and :meth:`ServoBus.write_goals` checks it again before sending.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol, TypeVar

import numpy as np

from ..exceptions import ServoError
from .portlock import PortLock, open_locked

T = TypeVar("T")

# a command this close (in command units) to an exact limit counts as on the limit (float noise)
_LIMIT_EPS = 1e-6

COMM_OK = "ok"
COMM_TIMEOUT = "timeout"
COMM_CORRUPT = "corrupt"
COMM_TX_FAIL = "tx_fail"


@dataclass(frozen=True)
class Codec:
    """Per-joint affine map joint angle (rad) <-> integer command, and the hardware range."""

    offset: np.ndarray
    scale: np.ndarray  # command units per radian, signed
    cmd_min: int
    cmd_max: int
    unit: str = "tick"

    def encode_float(self, q: np.ndarray) -> np.ndarray:
        """Unrounded commands for joint angles (model order)."""
        return self.offset + self.scale * np.asarray(q, dtype=float)

    def decode(self, cmd: np.ndarray) -> np.ndarray:
        """Joint angles (rad) of commands (model order)."""
        return (np.asarray(cmd, dtype=float) - self.offset) / self.scale

    def safe_range(
        self, q_min: np.ndarray, q_max: np.ndarray, names: Sequence[str]
    ) -> tuple[np.ndarray, np.ndarray]:
        """Integer command bounds ``(lo, hi)`` whose commands all decode inside the limits.

        ``lo = ceil(min(c(q_min), c(q_max)))``, ``hi = floor(max(...))``, intersected with the
        hardware range. Raises :class:`ServoError` naming the joint if the interval is empty.
        """
        a = self.encode_float(q_min)
        b = self.encode_float(q_max)
        lo = np.ceil(np.minimum(a, b) - _LIMIT_EPS).astype(int)
        hi = np.floor(np.maximum(a, b) + _LIMIT_EPS).astype(int)
        lo = np.maximum(lo, self.cmd_min)
        hi = np.minimum(hi, self.cmd_max)
        bad = np.flatnonzero(lo > hi)
        if bad.size:
            parts = [
                f"{names[i]}: limits [{q_min[i]:.4f}, {q_max[i]:.4f}] rad map to "
                f"[{min(a[i], b[i]):.1f}, {max(a[i], b[i]):.1f}] {self.unit}s"
                for i in bad
            ]
            raise ServoError(
                f"joint limits fall outside the servo range {self.cmd_min}..{self.cmd_max} "
                f"{self.unit}s: " + "; ".join(parts)
            )
        return lo, hi


@dataclass
class ServoStatus:
    """What one exchange with one servo told us (``comm`` is ``ok`` when a valid reply came).

    ``index`` is the servo's position in model joint order, or None for the bus/board itself.
    """

    index: int | None
    comm: str = COMM_OK
    faults: tuple[str, ...] = ()
    error_byte: int = 0
    position: float | None = None  # command units
    voltage: float | None = None  # volt
    temperature: float | None = None  # degC
    load: float | None = None  # fraction of max torque, signed

    @property
    def ok(self) -> bool:
        return self.comm == COMM_OK and not self.faults


@dataclass(frozen=True)
class BudgetItem:
    """One kind of bus transaction in a control tick."""

    what: str
    count: int
    bytes_out: int  # per transaction, host -> servos
    bytes_in: int  # per transaction, servos -> host (status packet), 0 if none
    replies: int  # status packets per transaction (each costs return delay + turnaround)


@dataclass(frozen=True)
class BusBudget:
    """Bus time of one control tick: wire bytes at the baud rate plus per-reply delays.

    ``t = Σ count · ((bytes_out + bytes_in) · bits_per_byte / baud + replies · (delay + turn))``
    where ``delay`` is the servos' return delay and ``turn`` the host's reply turnaround
    (e.g. the USB latency of an FTDI adapter; 0 for a bus driven directly by a UART).
    """

    name: str
    baud: int
    items: tuple[BudgetItem, ...]
    bits_per_byte: int = 10
    return_delay_s: float = 0.0

    @property
    def bytes_per_tick(self) -> int:
        return sum(i.count * (i.bytes_out + i.bytes_in) for i in self.items)

    @property
    def replies_per_tick(self) -> int:
        return sum(i.count * i.replies for i in self.items)

    def wire_time(self) -> float:
        """Seconds the bytes of one tick occupy the wire."""
        return self.bytes_per_tick * self.bits_per_byte / self.baud

    def tick_time(self, turnaround_s: float = 0.0) -> float:
        """Seconds of bus time per tick with a host turnaround per reply."""
        return self.wire_time() + self.replies_per_tick * (self.return_delay_s + turnaround_s)

    def max_rate(self, turnaround_s: float = 0.0) -> float:
        """Highest tick rate (Hz) the bus allows."""
        return 1.0 / self.tick_time(turnaround_s)


class Clock(Protocol):
    """Where a deployment reads time and waits: the wall clock for real servos, simulated time
    for a lockstep simulator (whose ``sleep`` runs the physics)."""

    def now(self) -> float: ...

    def sleep(self, seconds: float) -> None: ...


class WallClock:
    """The wall clock: ``time.perf_counter`` and ``time.sleep``."""

    def now(self) -> float:
        return time.perf_counter()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


WALL_CLOCK = WallClock()


class ServoBus(ABC):
    """A bus of servos driven in the robot model's joint order with integer commands.

    Life cycle used by the deployment: ``open`` -> ``identify`` -> ``configure`` ->
    ``read_positions`` (if ``can_read``) -> ``set_speed`` / ``set_torque(True)`` ->
    ``write_goals`` + ``poll`` / ``read_positions`` each tick -> ``set_torque(False)`` or hold
    -> ``close``. Communication problems come back as :class:`ServoStatus` values (the
    watchdog decides); set-up problems and bad arguments raise :class:`ServoError`.
    """

    name: str = "bus"
    can_read: bool = False
    servo_speed: float = float("inf")  # rad/s, the servos' own top speed
    turnaround_s: float = 0.0  # host delay per status reply (e.g. USB latency), for budgets
    health_per_servo: bool = True  # poll(i) checks servo i (False: the board, whatever i)
    #: where the deployment reads time and waits; None = the wall clock (a lockstep simulator
    #: brings its own, whose ``sleep`` runs the physics)
    clock: Clock | None = None
    #: the bus can change the servos' stiffness while they run (:meth:`set_stiffness`)
    can_set_stiffness: bool = False
    #: the clock of reply deadlines (s): the wall clock. A test replaces it with an emulator's
    #: device clock (:class:`wbc.servos.pty_runner.DeviceClock`), which first
    #: waits until the emulator has handled every byte sent to it, so that a deadline measures
    #: the emulated device, not the test machine's load
    reply_clock: Callable[[], float] = staticmethod(time.perf_counter)

    def __init__(self, codec: Codec, labels: Sequence[str]) -> None:
        self.codec = codec
        self.labels = tuple(labels)
        self.cmd_lo: np.ndarray | None = None
        self.cmd_hi: np.ndarray | None = None
        self.port_lock: PortLock | None = None
        #: servos (model indices) that receive no more goals: a faulted servo while the safe
        #: stop's crouch moves the others (a backend that cannot omit a servo from its goal
        #: transaction sends its unchanged last goal, which the deployment keeps)
        self.excluded: frozenset[int] = frozenset()
        #: the servos' stiffness, per joint, as a factor of the configured one (1: as
        #: ``servos.toml`` ``[settings]`` says, what :meth:`configure` writes)
        self.stiffness = np.ones(len(self.labels))

    # ------------------------------------------------------------------ one owner per bus
    def open_port(
        self,
        port: str,
        opener: Callable[[], T],
        fileno: Callable[[T], int],
        close: Callable[[T], None],
    ) -> T:
        """Open ``port`` as its one owner (:func:`wbc.servos.portlock.open_locked`): every
        backend's :meth:`open` does; :class:`ServoError` naming the holder if it is taken."""
        device, self.port_lock = open_locked(port, opener, fileno, close)
        return device

    def unlock_port(self) -> None:
        """Release the port lock (call before closing the device; safe to call twice)."""
        lock, self.port_lock = self.port_lock, None
        if lock is not None:
            lock.release()

    # ------------------------------------------------------------------ hardware watchdog
    def arm_watchdog(self, timeout_s: float) -> bool:
        """Arm the servos' own bus watchdog (torque off after ``timeout_s`` without a valid
        instruction), so a killed process leaves limp servos; False if the servos have none
        (AX-12A, Protocol 1.0; the X series' Bus Watchdog, address 98, is Protocol 2.0)."""
        return False

    @property
    def n(self) -> int:
        return len(self.labels)

    def set_command_limits(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """The command interval ``write_goals`` enforces (from :meth:`Codec.safe_range`)."""
        lo = np.asarray(lo, dtype=int)
        hi = np.asarray(hi, dtype=int)
        if lo.shape != (self.n,) or hi.shape != (self.n,) or np.any(lo > hi):
            raise ServoError(f"{self.name}: invalid command limits {lo} .. {hi}")
        self.cmd_lo, self.cmd_hi = lo, hi

    def check_goals(self, cmds: np.ndarray) -> np.ndarray:
        """Last line of defence before the wire: integer commands inside the safe range."""
        cmds = np.asarray(cmds)
        if self.cmd_lo is None or self.cmd_hi is None:
            raise ServoError(f"{self.name}: goals written before the command limits were set")
        if cmds.shape != (self.n,):
            raise ServoError(f"{self.name}: expected {self.n} goals, got shape {cmds.shape}")
        if not np.issubdtype(cmds.dtype, np.integer):
            raise ServoError(f"{self.name}: goals must be integer commands, got {cmds.dtype}")
        bad = np.flatnonzero((cmds < self.cmd_lo) | (cmds > self.cmd_hi))
        if bad.size:
            parts = [
                f"{self.labels[i]} -> {cmds[i]} (allowed {self.cmd_lo[i]}..{self.cmd_hi[i]})"
                for i in bad
            ]
            raise ServoError(f"{self.name}: refusing goals outside the limits: " + "; ".join(parts))
        return cmds

    # ------------------------------------------------------------------ life cycle
    @abstractmethod
    def open(self) -> None:
        """Open the port; :class:`ServoError` naming the port or baud rate if impossible."""

    @abstractmethod
    def close(self) -> None:
        """Close the port (safe to call twice)."""

    @abstractmethod
    def identify(self) -> None:
        """Check that every servo (or the board) answers; :class:`ServoError` if not."""

    @abstractmethod
    def configure(self) -> None:
        """Write start-up settings (limits in servo memory, return delay); torque stays off."""

    # ------------------------------------------------------------------ motion
    @abstractmethod
    def set_torque(self, enabled: bool) -> None:
        """Enable or disable torque on every servo."""

    @abstractmethod
    def set_speed(self, rad_per_s: float) -> None:
        """Servo-side speed limit (a second line behind the software rate limit)."""

    @abstractmethod
    def write_goals(self, cmds: np.ndarray) -> str:
        """Send all goals in one bus transaction; returns a COMM_* result."""

    # ------------------------------------------------------------------ feedback
    def read_positions(self, indices: Sequence[int] | None = None) -> list[ServoStatus]:
        """Present positions (command units) of the given servos (default: all)."""
        raise ServoError(f"{self.name}: this bus cannot read servo positions")

    @abstractmethod
    def poll(self, index: int) -> ServoStatus:
        """A health check of one servo (or of the board)."""

    def budget(self, read_positions: bool) -> BusBudget:
        """Bus time of one tick (see :class:`BusBudget`)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ with defaults
    def tick_budget(self, read_positions: bool, polls_per_tick: int) -> BusBudget:
        """Bus time of one tick with ``polls_per_tick`` health polls (default: ``budget``)."""
        return self.budget(read_positions)

    def set_stiffness(self, factors: float | Sequence[float] | np.ndarray) -> None:
        """Each servo's stiffness (its position controller's gain) ``factors`` times the
        configured one (model order, or one factor for all; 1 restores the configuration).
        A backend that can (``can_set_stiffness``) translates it into its registers (AX-12A:
        the compliance slopes, X series: the position P gain) and refuses, naming the servo,
        a factor its registers cannot hold."""
        raise ServoError(f"{self.name}: this bus cannot change the servos' stiffness")

    def torque_off(self) -> list[str]:
        """Torque off on every servo, verified where the bus can; returns the labels of the
        servos whose torque-off is not confirmed (default: ``set_torque(False)``, none)."""
        self.set_torque(False)
        return []

    def exchange_lines(self) -> list[str]:
        """Summary of the exchanges (round-trip times, late replies) for the report."""
        return []

    def __enter__(self) -> ServoBus:
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def stiffness_factors(factors: float | Sequence[float] | np.ndarray, n: int) -> np.ndarray:
    """``factors`` as ``n`` finite positive stiffness factors (a scalar for all); raises
    :class:`ServoError` otherwise."""
    f = np.asarray(factors, dtype=float)
    if f.ndim == 0:
        f = np.full(n, float(f))
    if f.shape != (n,):
        raise ServoError(f"stiffness: expected {n} factors (one per servo), got shape {f.shape}")
    if not np.all(np.isfinite(f) & (f > 0)):
        raise ServoError(f"stiffness factors must be finite and > 0, got {f.tolist()}")
    return f.astype(float).copy()


def stiffness_registers(
    configured: np.ndarray,
    factors: np.ndarray,
    labels: Sequence[str],
    what: str,
    allowed: tuple[int, int],
    inverse: bool,
) -> np.ndarray:
    """Register values for stiffness ``factors``: ``round(configured / f)`` for a register
    the stiffness falls with (``inverse``: the AX-12A's compliance slope), else
    ``round(configured · f)`` (the X series' P gain); :class:`ServoError` in one line naming
    the servos whose value falls outside ``allowed``."""
    c = np.asarray(configured, dtype=float)
    raw = c / factors if inverse else c * factors
    regs = np.rint(raw).astype(int)
    lo, hi = allowed
    bad = np.flatnonzero((regs < lo) | (regs > hi))
    if bad.size:
        parts = [f"{labels[i]} x{factors[i]:g} -> {what} {raw[i]:.1f}" for i in bad]
        raise ServoError(f"stiffness out of range ({what} allowed {lo}..{hi}): " + "; ".join(parts))
    return regs


class DryRunBus(ServoBus):
    """In-memory ideal servos for ``--dry-run``: goals are reached at once, nothing fails."""

    name = "dry-run"
    can_read = True

    def __init__(self, codec: Codec, labels: Sequence[str], start_cmds: np.ndarray) -> None:
        super().__init__(codec, labels)
        self.positions = np.asarray(start_cmds, dtype=float).copy()
        self.torque = False
        self.goals_written = 0

    def open(self) -> None:
        pass

    def close(self) -> None:
        pass

    def identify(self) -> None:
        pass

    def configure(self) -> None:
        pass

    def set_torque(self, enabled: bool) -> None:
        self.torque = enabled

    def set_speed(self, rad_per_s: float) -> None:
        pass

    def write_goals(self, cmds: np.ndarray) -> str:
        cmds = self.check_goals(cmds)
        if self.torque:
            self.positions = cmds.astype(float)
        self.goals_written += 1
        return COMM_OK

    def read_positions(self, indices: Sequence[int] | None = None) -> list[ServoStatus]:
        idx = range(self.n) if indices is None else indices
        return [ServoStatus(i, position=float(self.positions[i])) for i in idx]

    def poll(self, index: int) -> ServoStatus:
        return ServoStatus(index, position=float(self.positions[index]))

    def budget(self, read_positions: bool) -> BusBudget:
        return BusBudget("dry-run", 1_000_000, ())
