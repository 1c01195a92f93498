"""Bus emulators on a pseudo-terminal: 18 AX-12A servos (Protocol 1.0) and an SSC-32 board.

:class:`AX12Emulator` opens a pty; the host opens its slave end (``emulator.port``) like a
USB adapter, e.g. through dynamixel-sdk's ``PortHandler``. A thread answers Protocol 1.0
packets like AX-12A servos: a control table per servo (bioloid-facts §4.2), status packets
with checksum and error bits (§4.3), SYNC_WRITE, and a position that follows the goal as a
first-order lag saturated at the Moving Speed::

    dp/dt = clip((goal - p) / tau, -v, +v),   v = Moving Speed (0 = no-load 59 rpm)

Every goal written (SYNC_WRITE or WRITE to address 30) is recorded with a timestamp in
:attr:`AX12Emulator.goals`. Faults (:class:`Fault`) start after a number of goal SYNC_WRITEs
and/or of packets addressed to the servo: timeouts (silence), late replies (sent a given
delay after they were due, while the other servos go on answering), corrupted checksums,
error bits (with the AX shutdown: an Overload/Overheating bit that is in the Shutdown
register (18) zeroes the torque limit), a missing servo and garbage bytes; ``duplicate_ids``
makes two servos answer at once (a garbled reply). ``on_goal_write`` calls a function at the
n-th goal SYNC_WRITE (e.g. to press Ctrl-C at a known point).

Timing: a pty has no baud rate, bytes arrive at once. With ``timing=True`` the emulator
models the half-duplex wire: each packet occupies the bus for ``bytes · 10 / baud`` s, a
reply comes after the instruction, the Return Delay Time (register 5, 2 µs units) and a
22 µs servo response, and ``usb_latency_s`` is added to every reply (an FTDI adapter's
latency timer). If the host's port is set to another baud rate than the emulated bus, the
servos do not answer (they could not decode the bytes).
"""

from __future__ import annotations

import math
import re
import termios
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from ..exceptions import ConfigurationError
from ..servo_map import RAD_PER_TICK
from .protocol1 import (
    ADDR_ALARM_LED,
    ADDR_BAUD,
    ADDR_CCW_ANGLE_LIMIT,
    ADDR_CW_ANGLE_LIMIT,
    ADDR_FIRMWARE,
    ADDR_GOAL_POSITION,
    ADDR_ID,
    ADDR_MAX_TORQUE,
    ADDR_MAX_VOLTAGE,
    ADDR_MIN_VOLTAGE,
    ADDR_MODEL_NUMBER,
    ADDR_MOVING,
    ADDR_MOVING_SPEED,
    ADDR_PRESENT_LOAD,
    ADDR_PRESENT_POSITION,
    ADDR_PRESENT_SPEED,
    ADDR_PRESENT_TEMPERATURE,
    ADDR_PRESENT_VOLTAGE,
    ADDR_PUNCH,
    ADDR_RETURN_DELAY,
    ADDR_SHUTDOWN,
    ADDR_STATUS_RETURN_LEVEL,
    ADDR_TEMPERATURE_LIMIT,
    ADDR_TORQUE_ENABLE,
    ADDR_TORQUE_LIMIT,
    AX12_MODEL_NUMBER,
    AX12_RESPONSE_S,
    BROADCAST_ID,
    CONTROL_TABLE_SIZE,
    ERR_ANGLE_LIMIT,
    ERR_CHECKSUM,
    ERR_INPUT_VOLTAGE,
    ERR_INSTRUCTION,
    ERR_OVERHEATING,
    ERR_RANGE,
    INST_ACTION,
    INST_PING,
    INST_READ,
    INST_REG_WRITE,
    INST_RESET,
    INST_SYNC_WRITE,
    INST_WRITE,
    RPM_PER_SPEED_UNIT,
    checksum,
    speed_ticks_per_s,
    status_packet,
    take_packet,
)
from .pty_runner import PtyRunner, sleep_until

FAULT_KINDS = ("timeout", "bad_checksum", "error_bits", "missing", "garbage", "late")
_TWO_BYTE = {0, 6, 8, 14, 30, 32, 34, 36, 38, 40, 48}
_READ_ONLY = set(range(0, 3)) | set(range(36, 47))


@dataclass(frozen=True)
class Fault:
    """A fault of one servo, active once ``after_goals`` goal SYNC_WRITEs were received and
    the servo answered ``after_packets`` packets addressed to it (e.g. silence after N).

    ``timeout``: no status packets; ``bad_checksum``: status packets with a wrong checksum;
    ``garbage``: ``data`` sent before each status packet; ``late``: each status packet sent
    ``delay_s`` after it was due (without holding up the other servos' replies, so it lands
    in a later exchange); these four last for ``count`` replies (None = for ever).
    ``error_bits``: ``bits`` set in every status packet from then on. ``missing``: the servo
    is gone (no reply, writes ignored), e.g. a cut cable.
    """

    kind: str
    servo_id: int
    after_goals: int = 0
    count: int | None = None
    bits: int = 0
    data: bytes = b"\x00\x13\x37"
    delay_s: float = 0.0
    after_packets: int = 0

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise ConfigurationError(f"unknown fault kind {self.kind!r}; use one of {FAULT_KINDS}")
        if self.kind == "error_bits" and not 0 < self.bits < 0x80:
            raise ConfigurationError(f"error_bits fault needs bits in 1..0x7F, got {self.bits}")
        if self.kind == "late" and not self.delay_s > 0:
            raise ConfigurationError(f"late fault needs delay_s > 0, got {self.delay_s}")


@dataclass(frozen=True)
class GoalRecord:
    """A goal position a servo received: time (s, ``time.monotonic``), ID, tick, accepted."""

    time: float
    servo_id: int
    tick: int
    accepted: bool
    via: str  # "sync_write" | "write"


@dataclass(frozen=True)
class WriteRecord:
    """Any write a servo received (for checking start-up settings and torque-off)."""

    time: float
    servo_id: int
    address: int
    data: bytes
    via: str


def lag_step(pos: float, goal: float, v: float, tau: float, dt: float) -> tuple[float, float]:
    """One step of the servo response ``dp/dt = clip((goal - p) / tau, -v, +v)``, exact:
    linear at speed v while |e| > v·tau, then exponential. Returns (position, speed)."""
    e = goal - pos
    s = math.copysign(1.0, e)
    if abs(e) > v * tau:
        t1 = (abs(e) - v * tau) / v
        if dt <= t1:
            return pos + s * v * dt, s * v
        pos += s * v * t1
        dt -= t1
        e = goal - pos
    decay = math.exp(-dt / tau)
    return goal - e * decay, e / tau * decay


class AX12:
    """One emulated AX-12A: control table plus the first-order position response."""

    def __init__(self, servo_id: int, position: float, now: float, tau: float) -> None:
        t = bytearray(CONTROL_TABLE_SIZE)
        t[ADDR_MODEL_NUMBER : ADDR_MODEL_NUMBER + 2] = AX12_MODEL_NUMBER.to_bytes(2, "little")
        t[ADDR_FIRMWARE] = 24
        t[ADDR_ID] = servo_id
        t[ADDR_BAUD] = 1
        t[ADDR_RETURN_DELAY] = 250
        t[ADDR_CW_ANGLE_LIMIT : ADDR_CW_ANGLE_LIMIT + 2] = (0).to_bytes(2, "little")
        t[ADDR_CCW_ANGLE_LIMIT : ADDR_CCW_ANGLE_LIMIT + 2] = (1023).to_bytes(2, "little")
        t[ADDR_TEMPERATURE_LIMIT] = 70
        t[ADDR_MIN_VOLTAGE] = 60
        t[ADDR_MAX_VOLTAGE] = 140
        t[ADDR_MAX_TORQUE : ADDR_MAX_TORQUE + 2] = (1023).to_bytes(2, "little")
        t[ADDR_STATUS_RETURN_LEVEL] = 2
        t[ADDR_ALARM_LED] = 36
        t[ADDR_SHUTDOWN] = 36
        t[26] = t[27] = 1  # compliance margins
        t[28] = t[29] = 32  # compliance slopes
        t[ADDR_TORQUE_LIMIT : ADDR_TORQUE_LIMIT + 2] = (1023).to_bytes(2, "little")
        t[ADDR_PRESENT_VOLTAGE] = 120
        t[ADDR_PRESENT_TEMPERATURE] = 35
        t[ADDR_PUNCH : ADDR_PUNCH + 2] = (32).to_bytes(2, "little")
        self.table = t
        self.id = servo_id
        self.pos = float(position)
        self.speed = 0.0  # ticks/s, signed
        self.tau = tau
        self.last = now
        self.set_word(ADDR_GOAL_POSITION, round(position))
        self.injected = 0  # error bits from faults (persistent)
        self.angle_error = False

    def word(self, address: int) -> int:
        return self.table[address] | (self.table[address + 1] << 8)

    def set_word(self, address: int, value: int) -> None:
        self.table[address] = value & 0xFF
        self.table[address + 1] = (value >> 8) & 0xFF

    @property
    def error(self) -> int:
        return self.injected | (ERR_ANGLE_LIMIT if self.angle_error else 0)

    def inject(self, bits: int) -> None:
        """Set fault bits; Overload/Overheating in the Shutdown mask zero the torque limit."""
        self.injected |= bits
        if bits & self.table[ADDR_SHUTDOWN]:
            self.set_word(ADDR_TORQUE_LIMIT, 0)
        if bits & ERR_OVERHEATING:
            self.table[ADDR_PRESENT_TEMPERATURE] = 75
        if bits & ERR_INPUT_VOLTAGE:
            self.table[ADDR_PRESENT_VOLTAGE] = 85

    def advance(self, now: float) -> None:
        """Move toward the goal: linear at speed v while |e| > v·tau, then exponential."""
        dt = now - self.last
        self.last = now
        if dt <= 0:
            return
        if not self.table[ADDR_TORQUE_ENABLE] or self.word(ADDR_TORQUE_LIMIT) == 0:
            self.speed = 0.0
            return
        goal = float(self.word(ADDR_GOAL_POSITION))
        v = speed_ticks_per_s(self.word(ADDR_MOVING_SPEED))
        self.pos, self.speed = lag_step(self.pos, goal, v, self.tau, dt)

    def refresh(self, now: float) -> None:
        """Update the read-only present-state registers."""
        self.advance(now)
        self.set_word(ADDR_PRESENT_POSITION, min(1023, max(0, round(self.pos))))
        units = abs(self.speed) * RAD_PER_TICK * 60.0 / (2.0 * math.pi) / RPM_PER_SPEED_UNIT
        units = min(1023, round(units))
        self.set_word(ADDR_PRESENT_SPEED, units | (0x400 if self.speed < 0 else 0))
        self.set_word(ADDR_PRESENT_LOAD, 0)
        self.table[ADDR_MOVING] = int(abs(self.word(ADDR_GOAL_POSITION) - self.pos) > 0.5)

    def read(self, address: int, length: int, now: float) -> bytes | None:
        """Bytes of the control table, or None if the range is invalid."""
        if length < 1 or address + length > CONTROL_TABLE_SIZE:
            return None
        self.refresh(now)
        return bytes(self.table[address : address + length])

    def write(self, address: int, data: bytes, now: float) -> tuple[int, int | None]:
        """Apply a write; returns (error bits, the goal tick written or None)."""
        end = address + len(data)
        if not data or end > CONTROL_TABLE_SIZE:
            return ERR_RANGE, None
        self.advance(now)
        new = bytearray(self.table)
        new[address:end] = data
        err = 0
        for a in range(address, end):
            if a in _READ_ONLY:
                return ERR_RANGE, None
        for a in _TWO_BYTE:  # two-byte registers are 0..1023
            if address <= a + 1 and a < end and (new[a] | (new[a + 1] << 8)) > 1023:
                return ERR_RANGE, None
        if new[ADDR_RETURN_DELAY] > 254 or new[ADDR_TORQUE_ENABLE] > 1:
            return ERR_RANGE, None
        goal = None
        if address <= ADDR_GOAL_POSITION + 1 and ADDR_GOAL_POSITION < end:
            goal = new[ADDR_GOAL_POSITION] | (new[ADDR_GOAL_POSITION + 1] << 8)
            cw = new[ADDR_CW_ANGLE_LIMIT] | (new[ADDR_CW_ANGLE_LIMIT + 1] << 8)
            ccw = new[ADDR_CCW_ANGLE_LIMIT] | (new[ADDR_CCW_ANGLE_LIMIT + 1] << 8)
            if not cw <= goal <= ccw:  # rejected: the servo keeps its old goal
                new[ADDR_GOAL_POSITION : ADDR_GOAL_POSITION + 2] = self.table[
                    ADDR_GOAL_POSITION : ADDR_GOAL_POSITION + 2
                ]
                self.angle_error = True
                err |= ERR_ANGLE_LIMIT
            else:
                self.angle_error = False
        if new[ADDR_TORQUE_ENABLE] and not self.table[ADDR_TORQUE_ENABLE]:
            self.last = now
        self.table[:] = new
        return err, goal


class ServoBusEmulator(PtyRunner):
    """What the AX-12A (Protocol 1.0) and X-series (Protocol 2.0) emulators share: servos by
    ID, goal and write records, fault injection (:class:`Fault`), SYNC_WRITE and the status
    reply's faults. A subclass gives the protocol: :meth:`_take_packet`, :meth:`_dispatch`,
    :meth:`_sync_header`, :meth:`_status_packet` and ``_goal_address``."""

    _state: tuple[str, ...] = (
        "servos",
        "_to",
        "goals",
        "writes",
        "sync_goal_writes",
        "sync_goal_times",
        "packets",
        "fault_log",
    )
    _goal_address = ADDR_GOAL_POSITION
    _bad_checksum_note = "bad checksum"

    def __init__(
        self,
        servos: dict[int, Any],
        baud: int,
        faults: Iterable[Fault],
        duplicate_ids: Iterable[int],
        timing: bool,
        usb_latency_s: float,
        process: bool,
        on_goal_write: Mapping[int, Callable[[], None]] | None,
    ) -> None:
        super().__init__(process)
        self.on_goal_write = dict(on_goal_write or {})  # n-th goal SYNC_WRITE -> callback
        self.servos = servos
        self.baud = baud
        self.faults = list(faults)
        self.duplicate_ids = set(duplicate_ids)
        self.timing = timing
        self.usb_latency_s = usb_latency_s
        self.goals: list[GoalRecord] = []
        self.writes: list[WriteRecord] = []
        self.sync_goal_writes = 0
        self.sync_goal_times: list[float] = []
        self.packets = 0
        self.fault_log: list[tuple[float, Fault, str]] = []
        self._used: dict[int, int] = {}
        self._to: dict[int, int] = {}  # instruction packets addressed to each servo
        self._buf = bytearray()
        self._bus_free = 0.0
        self._expected_speed = getattr(termios, f"B{baud}", None)

    # ------------------------------------------------------------------ inspection
    def packets_to(self, servo_id: int) -> int:
        """Instruction packets addressed to one servo so far (not broadcasts)."""
        return self._to.get(servo_id, 0)

    def goals_by_id(self) -> dict[int, list[GoalRecord]]:
        out: dict[int, list[GoalRecord]] = {sid: [] for sid in self.servos}
        for g in list(self.goals):
            out.setdefault(g.servo_id, []).append(g)
        return out

    # ------------------------------------------------------------------ faults
    def _active(self, sid: int, kind: str) -> Fault | None:
        for k, f in enumerate(self.faults):
            if f.servo_id != sid or f.kind != kind or self.sync_goal_writes < f.after_goals:
                continue
            if self._to.get(sid, 0) <= f.after_packets:
                continue
            if f.count is not None and self._used.get(k, 0) >= f.count:
                continue
            return f
        return None

    def _consume(self, fault: Fault, now: float, what: str) -> None:
        k = self.faults.index(fault)
        self._used[k] = self._used.get(k, 0) + 1
        self.fault_log.append((now, fault, what))

    def _present(self, sid: int) -> bool:
        return sid in self.servos and self._active(sid, "missing") is None

    def _apply_error_faults(self, sid: int, now: float) -> None:
        f = self._active(sid, "error_bits")
        if f is not None and (self.servos[sid].injected & f.bits) != f.bits:
            self.servos[sid].inject(f.bits)
            self.fault_log.append((now, f, "bits set"))

    # ------------------------------------------------------------------ packets
    def _on_bytes(self, chunk: bytes, now: float) -> None:
        if self._expected_speed is not None and self._host_speed() != self._expected_speed:
            return  # wrong baud: the servos cannot decode these bytes
        self._buf += chunk
        while (pkt := self._take_packet(self._buf)) is not None:
            self._dispatch(pkt, time.monotonic() if self.timing else now)

    def _take_packet(self, buf: bytearray) -> bytes | None:
        """The next whole instruction packet taken off ``buf`` (None: not yet)."""
        raise NotImplementedError

    def _dispatch(self, pkt: bytes, now: float) -> None:
        """Handle one packet and put the replies on the line (with the wire timing)."""
        raise NotImplementedError

    def _sync_header(self, params: bytes) -> tuple[int, int, bytes] | None:
        """SYNC_WRITE parameters: (address, data size, per-servo body) or None if short."""
        raise NotImplementedError

    def _status_packet(self, sid: int, error: int, params: bytes) -> bytes:
        raise NotImplementedError

    def _write(self, sid: int, address: int, data: bytes, now: float, via: str) -> int:
        raise NotImplementedError

    def _sync_write(self, params: bytes, now: float) -> None:
        header = self._sync_header(params)
        if header is None:
            return
        address, size, body = header
        if size == 0 or len(body) % (size + 1):
            return
        if address == self._goal_address:
            self.sync_goal_writes += 1
            self.sync_goal_times.append(now)
            hook = self.on_goal_write.get(self.sync_goal_writes)
            if hook is not None:
                hook()
        for k in range(0, len(body), size + 1):
            sid = body[k]
            if self._present(sid):
                self._apply_error_faults(sid, now)
                self._write(sid, address, body[k + 1 : k + 1 + size], now, "sync_write")

    def _reply(self, sid: int, error: int, params: bytes, now: float) -> tuple[int, bytes]:
        if (silent := self._active(sid, "timeout")) is not None:
            self._consume(silent, now, "no reply")
            return sid, b""
        pkt = self._status_packet(sid, error, params)
        bad = self._active(sid, "bad_checksum")
        if bad is not None:
            self._consume(bad, now, self._bad_checksum_note)
            pkt = pkt[:-1] + bytes([pkt[-1] ^ 0x5A])
        junk = self._active(sid, "garbage")
        if junk is not None:
            self._consume(junk, now, "garbage")
            pkt = junk.data + pkt
        if sid in self.duplicate_ids:  # two servos drive the line at once, a bit apart
            pkt = bytes(a & b for a, b in zip(pkt, b"\xff" + pkt, strict=False))
        late = self._active(sid, "late")
        if late is not None:
            self._consume(late, now, "late")
            self._schedule(time.monotonic() + late.delay_s, pkt)
            return sid, b""
        return sid, pkt


class AX12Emulator(ServoBusEmulator):
    """18 (by default) AX-12A servos on a pseudo-terminal; see the module docstring.

    With ``process=True`` the servos run in a forked process (no GIL shared with the host,
    like real hardware); records and servo states are then available after :meth:`stop`.
    """

    _state = (*ServoBusEmulator._state, "checksum_errors")
    servos: dict[int, AX12]

    def __init__(
        self,
        ids: Iterable[int] = range(1, 19),
        positions: Mapping[int, float] | None = None,
        baud: int = 1_000_000,
        faults: Iterable[Fault] = (),
        duplicate_ids: Iterable[int] = (),
        timing: bool = False,
        usb_latency_s: float = 0.0,
        time_constant_s: float = 0.03,
        process: bool = False,
        on_goal_write: Mapping[int, Callable[[], None]] | None = None,
    ) -> None:
        now = time.monotonic()
        positions = dict(positions or {})
        servos = {sid: AX12(sid, positions.get(sid, 512), now, time_constant_s) for sid in ids}
        super().__init__(
            servos, baud, faults, duplicate_ids, timing, usb_latency_s, process, on_goal_write
        )
        self.checksum_errors = 0

    # ------------------------------------------------------------------ inspection
    def servo(self, servo_id: int) -> AX12:
        return self.servos[servo_id]

    def register(self, servo_id: int, address: int, size: int = 1) -> int:
        """A control-table value (present-state registers refreshed)."""
        s = self.servos[servo_id]
        s.refresh(time.monotonic())
        return s.word(address) if size == 2 else s.table[address]

    # ------------------------------------------------------------------ packets
    def _take_packet(self, buf: bytearray) -> bytes | None:
        return take_packet(buf)

    def _sync_header(self, params: bytes) -> tuple[int, int, bytes] | None:
        return None if len(params) < 2 else (params[0], params[1], params[2:])

    def _status_packet(self, sid: int, error: int, params: bytes) -> bytes:
        return status_packet(sid, error, params)

    def _dispatch(self, pkt: bytes, now: float) -> None:
        reply_to, reply = self.handle(pkt, now)
        if self.timing:
            baud = self.baud
            start = max(now, self._bus_free)
            end_in = start + len(pkt) * 10.0 / baud
            if reply:
                rdt = 2e-6 * self.servos[reply_to].table[ADDR_RETURN_DELAY]
                ready = end_in + rdt + AX12_RESPONSE_S + len(reply) * 10.0 / baud
                self._bus_free = ready
                sleep_until(ready + self.usb_latency_s)
            else:
                self._bus_free = end_in
        self._send(reply)

    def handle(self, pkt: bytes, now: float | None = None) -> tuple[int | None, bytes]:
        """Process one instruction packet; returns (replying ID, bytes put on the line)."""
        now = time.monotonic() if now is None else now
        self.packets += 1
        sid, inst = pkt[2], pkt[4]
        params = pkt[5:-1]
        if sid != BROADCAST_ID:
            self._to[sid] = self._to.get(sid, 0) + 1
        ok = checksum(pkt[2:-1]) == pkt[-1]
        if not ok:
            self.checksum_errors += 1
            if sid != BROADCAST_ID and self._present(sid):
                return self._reply(sid, ERR_CHECKSUM, b"", now)
            return None, b""
        if inst == INST_SYNC_WRITE:
            self._sync_write(params, now)
            return None, b""
        targets = list(self.servos) if sid == BROADCAST_ID else [sid]
        if sid != BROADCAST_ID and not self._present(sid):
            return None, b""
        for target in targets:
            if not self._present(target):
                continue
            err = self._execute(target, inst, params, now)
            if sid == BROADCAST_ID:
                continue
            servo = self.servos[target]
            srl = servo.table[ADDR_STATUS_RETURN_LEVEL]  # 0: PING only, 1: + READ, 2: all
            if isinstance(err, bytes):  # READ data
                return self._reply(target, servo.error, err, now) if srl >= 1 else (None, b"")
            if inst == INST_PING or srl >= 2:
                return self._reply(target, servo.error | err, b"", now)
            return None, b""
        return None, b""

    def _execute(self, sid: int, inst: int, params: bytes, now: float) -> int | bytes:
        servo = self.servos[sid]
        self._apply_error_faults(sid, now)
        if inst == INST_PING:
            return 0
        if inst == INST_READ:
            if len(params) != 2:
                return ERR_INSTRUCTION
            data = servo.read(params[0], params[1], now)
            if data is None:
                return ERR_RANGE
            return data
        if inst in (INST_WRITE, INST_REG_WRITE):
            if len(params) < 2:
                return ERR_INSTRUCTION
            return self._write(sid, params[0], params[1:], now, "write")
        if inst in (INST_ACTION, INST_RESET):  # REG_WRITE applies at once: ACTION is a no-op
            return 0
        return ERR_INSTRUCTION

    def _write(self, sid: int, address: int, data: bytes, now: float, via: str) -> int:
        servo = self.servos[sid]
        err, goal = servo.write(address, bytes(data), now)
        self.writes.append(WriteRecord(now, sid, address, bytes(data), via))
        if goal is not None:
            self.goals.append(GoalRecord(now, sid, goal, not err & ERR_ANGLE_LIMIT, via))
        return err


# ---------------------------------------------------------------------- SSC-32
_GROUP = re.compile(rb"#(\d+)\s*(?:P(\d+)|(L)|(H))(?:S(\d+))?")
_TIME = re.compile(rb"T(\d+)\s*$")


@dataclass(frozen=True)
class PulseRecord:
    """A pulse command the SSC-32 received: time, channel, pulse (µs; 0 = output off)."""

    time: float
    channel: int
    pulse: int
    move_ms: int | None


class Ssc32Emulator(PtyRunner):
    """A Lynxmotion SSC-32 on a pty: records ``#<ch>P<pw>...T<ms>\\r`` and answers VER / Q.

    ``silent_after``: stop answering queries after this many move commands (a dead board).
    """

    VERSION = b"SSC32-V2.50USB\r"

    _state = ("pulses", "lines", "moves")

    def __init__(
        self, baud: int = 115200, silent_after: int | None = None, process: bool = False
    ) -> None:
        super().__init__(process)
        self.baud = baud
        self.silent_after = silent_after
        self.pulses: list[PulseRecord] = []
        self.lines: list[bytes] = []
        self.moves = 0
        self._buf = bytearray()
        self._expected_speed = getattr(termios, f"B{baud}", None)

    def _on_bytes(self, chunk: bytes, now: float) -> None:
        if self._expected_speed is not None and self._host_speed() != self._expected_speed:
            return
        self._buf += chunk
        while b"\r" in self._buf:
            line, _, rest = bytes(self._buf).partition(b"\r")
            self._buf = bytearray(rest)
            self._line(line.strip(), now)

    def _line(self, line: bytes, now: float) -> None:
        self.lines.append(line)
        silent = self.silent_after is not None and self.moves >= self.silent_after
        if line == b"VER":
            if not silent:
                self._send(self.VERSION)
            return
        if line == b"Q":
            if not silent:
                self._send(b".")
            return
        if line.startswith(b"#"):
            m = _TIME.search(line)
            move_ms = int(m.group(1)) if m else None
            any_pulse = False
            for g in _GROUP.finditer(line):
                ch = int(g.group(1))
                pulse = int(g.group(2)) if g.group(2) else 0
                any_pulse |= g.group(2) is not None
                self.pulses.append(PulseRecord(now, ch, pulse, move_ms))
            if any_pulse:
                self.moves += 1
