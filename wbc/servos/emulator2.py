"""X-series servos (XM430-W350) on Dynamixel Protocol 2.0, emulated on a pseudo-terminal.

:class:`XEmulator` is the Protocol 2.0 twin of :class:`wbc.servos.emulator.AX12Emulator`
(both subclass :class:`~wbc.servos.emulator.ServoBusEmulator`: the pty runner, the
:class:`~wbc.servos.emulator.Fault` kinds, the goal and write records, SYNC_WRITE and the
reply faults; the servos' motion is :func:`~wbc.servos.emulator.lag_step`): a control
table per servo (e-Manual XM430-W350, :mod:`wbc.xseries`), status packets
with CRC-16 and byte stuffing, PING, READ, WRITE, SYNC_WRITE, SYNC_READ (the servos answer in
the order of the request), REBOOT, indirect addresses (168..) and data (224..), and a position
that follows the goal as a first-order lag saturated at the Profile Velocity::

    dp/dt = clip((goal - p) / tau, -v, +v),   v = Profile Velocity (0 = no-load 46 rpm)

Faults as on the AX-12A emulator: silence, late replies, bad CRCs, garbage, a missing servo,
duplicate IDs and hardware error bits (``error_bits``: the bits go to Hardware Error Status
(70), every status packet carries the alert bit, and a bit in Shutdown (63) cuts torque until
a REBOOT). EEPROM writes with torque on are refused (access error); a goal outside the
position limits is refused (data limit error). The Bus Watchdog (98): once set, a servo that
receives no packet for its time stops taking goals (the register reads 255) until 0 is
written to it. Timing (``timing=True``): wire time of each packet at the baud rate, Return
Delay, a 22 µs response and ``usb_latency_s`` per reply, as on the AX-12A emulator.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping

from .. import xseries as x
from .emulator import Fault, GoalRecord, ServoBusEmulator, WriteRecord, lag_step
from .protocol1 import BROADCAST_ID, INST_PING, INST_READ, INST_WRITE
from .protocol2 import (
    ADDR_INDIRECT_ADDRESS,
    ADDR_INDIRECT_DATA,
    ERR_ALERT,
    INST_REBOOT,
    INST_SYNC_READ,
    INST_SYNC_WRITE,
    X_RESPONSE_S,
    XM430_NO_LOAD_SPEED,
    parse_packet2,
    status_packet2,
    take_packet2,
)
from .pty_runner import sleep_until

TABLE_SIZE = 256  # through Indirect Data 28 (251)
N_INDIRECT = 28
ERR_RESULT_FAIL, ERR_INSTRUCTION, ERR_CRC, ERR_RANGE, ERR_LENGTH, ERR_LIMIT, ERR_ACCESS = range(
    1, 8
)
_FOUR_BYTE = {20, 24, 40, 44, 48, 52, 104, 108, 112, 116, 128, 132, 136, 140}
_READ_ONLY = set(range(0, 7)) | {70} | set(range(120, 148))
_EEPROM_END = 64  # addresses below: writable only with torque off


class XServo:
    """One emulated XM430-W350: control table plus the first-order position response."""

    def __init__(self, servo_id: int, position: float, now: float, tau: float) -> None:
        t = bytearray(TABLE_SIZE)
        t[0:2] = x.XM430_W350_MODEL.to_bytes(2, "little")
        t[6] = 45  # firmware
        t[7] = servo_id
        t[8] = 4  # 2 Mbps
        t[x.ADDR_RETURN_DELAY] = 250
        t[x.ADDR_OPERATING_MODE] = x.OPERATING_MODE_POSITION
        t[x.ADDR_TEMPERATURE_LIMIT] = 80
        t[x.ADDR_CURRENT_LIMIT : x.ADDR_CURRENT_LIMIT + 2] = (1193).to_bytes(2, "little")
        t[x.ADDR_MAX_POSITION_LIMIT : x.ADDR_MAX_POSITION_LIMIT + 4] = (4095).to_bytes(4, "little")
        t[x.ADDR_SHUTDOWN] = x.SHUTDOWN_DEFAULT
        t[x.ADDR_STATUS_RETURN_LEVEL] = 2
        t[x.ADDR_POSITION_P_GAIN : x.ADDR_POSITION_P_GAIN + 2] = (800).to_bytes(2, "little")
        t[x.ADDR_PRESENT_VOLTAGE : x.ADDR_PRESENT_VOLTAGE + 2] = (120).to_bytes(2, "little")
        t[x.ADDR_PRESENT_TEMPERATURE] = 35
        for k in range(N_INDIRECT):  # factory: indirect address k points at 224 + k
            a = ADDR_INDIRECT_ADDRESS + 2 * k
            t[a : a + 2] = (ADDR_INDIRECT_DATA + k).to_bytes(2, "little")
        self.table = t
        self.id = servo_id
        self.pos = float(position)
        self.speed = 0.0  # ticks/s
        self.tau = tau
        self.last = now
        self.last_packet = now
        self.set_value(x.ADDR_GOAL_POSITION, 4, round(position))

    def value(self, address: int, size: int, signed: bool = False) -> int:
        return int.from_bytes(self.table[address : address + size], "little", signed=signed)

    def set_value(self, address: int, size: int, value: int) -> None:
        self.table[address : address + size] = (int(value) & (2 ** (8 * size) - 1)).to_bytes(
            size, "little"
        )

    @property
    def hardware_error(self) -> int:
        return self.table[x.ADDR_HARDWARE_ERROR]

    injected = hardware_error  # the fault bits set (the base emulator's name)

    def inject(self, bits: int) -> None:
        """Set hardware error bits; a bit in Shutdown (63) cuts torque (until REBOOT)."""
        self.table[x.ADDR_HARDWARE_ERROR] |= bits
        if bits & self.table[x.ADDR_SHUTDOWN]:
            self.table[x.ADDR_TORQUE_ENABLE] = 0
        if bits & x.HW_OVERHEATING:
            self.table[x.ADDR_PRESENT_TEMPERATURE] = 85
        if bits & x.HW_INPUT_VOLTAGE:
            self.set_value(x.ADDR_PRESENT_VOLTAGE, 2, 90)

    def heard(self, now: float) -> None:
        """A packet reached the servo: check, then feed, the Bus Watchdog."""
        w = self.table[x.ADDR_BUS_WATCHDOG]
        if 0 < w < 128 and now - self.last_packet > w * x.BUS_WATCHDOG_UNIT_S:
            self.table[x.ADDR_BUS_WATCHDOG] = 255  # watchdog error: goals refused
        self.last_packet = now

    def advance(self, now: float) -> None:
        """Move toward the goal: linear at speed v while |e| > v·tau, then exponential."""
        dt = now - self.last
        self.last = now
        if dt <= 0:
            return
        if not self.table[x.ADDR_TORQUE_ENABLE]:
            self.speed = 0.0
            return
        goal = float(self.value(x.ADDR_GOAL_POSITION, 4, signed=True))
        reg = self.value(x.ADDR_PROFILE_VELOCITY, 4)
        v = min(x.profile_velocity_rad_s(reg), XM430_NO_LOAD_SPEED) / x.X_RAD_PER_TICK
        self.pos, self.speed = lag_step(self.pos, goal, v, self.tau, dt)

    def refresh(self, now: float) -> None:
        """Update the present-state registers and the indirect data."""
        self.advance(now)
        self.set_value(x.ADDR_PRESENT_POSITION, 4, round(self.pos))
        rpm = self.speed * x.X_RAD_PER_TICK * 60.0 / (2.0 * math.pi)
        self.set_value(x.ADDR_PRESENT_VELOCITY, 4, round(rpm / x.RPM_PER_VELOCITY_UNIT))
        self.set_value(x.ADDR_PRESENT_CURRENT, 2, 0)
        for k in range(N_INDIRECT):
            a = self.value(ADDR_INDIRECT_ADDRESS + 2 * k, 2)
            if a < ADDR_INDIRECT_DATA:
                self.table[ADDR_INDIRECT_DATA + k] = self.table[a]

    def read(self, address: int, length: int, now: float) -> bytes | None:
        if length < 1 or address + length > TABLE_SIZE:
            return None
        self.refresh(now)
        return bytes(self.table[address : address + length])

    def write(self, address: int, data: bytes, now: float) -> tuple[int, int | None]:
        """Apply a write; returns (error number, the goal tick written or None)."""
        end = address + len(data)
        if not data or end > TABLE_SIZE:
            return ERR_RANGE, None
        if any(a in _READ_ONLY for a in range(address, end)):
            return ERR_ACCESS, None
        if address < _EEPROM_END and self.table[x.ADDR_TORQUE_ENABLE]:
            return ERR_ACCESS, None
        self.advance(now)
        new = bytearray(self.table)
        new[address:end] = data
        if new[x.ADDR_TORQUE_ENABLE] > 1:
            return ERR_RANGE, None
        if new[x.ADDR_TORQUE_ENABLE] and not self.table[x.ADDR_TORQUE_ENABLE]:
            if self.hardware_error:
                return ERR_RESULT_FAIL, None  # torque stays off until a REBOOT
            self.last = now
        goal = None
        g = x.ADDR_GOAL_POSITION
        if address < g + 4 and g < end:
            if self.table[x.ADDR_BUS_WATCHDOG] == 255:
                return ERR_ACCESS, None
            goal = int.from_bytes(new[g : g + 4], "little", signed=True)
            lo = int.from_bytes(new[52:56], "little")
            hi = int.from_bytes(new[48:52], "little")
            if not lo <= goal <= hi:
                return ERR_LIMIT, None
        self.table[:] = new
        return 0, goal


class XEmulator(ServoBusEmulator):
    """20 (by default) XM430-W350 servos on a pseudo-terminal; see the module docstring."""

    _state = (*ServoBusEmulator._state, "sync_reads", "crc_errors")
    _goal_address = x.ADDR_GOAL_POSITION
    _bad_checksum_note = "bad crc"
    servos: dict[int, XServo]

    def __init__(
        self,
        ids: Iterable[int] = range(1, 21),
        positions: Mapping[int, float] | None = None,
        baud: int = 2_000_000,
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
        servos = {
            sid: XServo(sid, positions.get(sid, x.X_CENTER_TICK), now, time_constant_s)
            for sid in ids
        }
        super().__init__(
            servos, baud, faults, duplicate_ids, timing, usb_latency_s, process, on_goal_write
        )
        self.sync_reads = 0
        self.crc_errors = 0

    # ------------------------------------------------------------------ inspection
    def register(self, servo_id: int, address: int, size: int = 1) -> int:
        """A control-table value (present-state registers refreshed)."""
        s = self.servos[servo_id]
        s.refresh(time.monotonic())
        return s.value(address, size, signed=size == 4)

    # ------------------------------------------------------------------ packets
    def _take_packet(self, buf: bytearray) -> bytes | None:
        return take_packet2(buf)

    def _sync_header(self, params: bytes) -> tuple[int, int, bytes] | None:
        if len(params) < 4:
            return None
        return params[0] | params[1] << 8, params[2] | params[3] << 8, params[4:]

    def _status_packet(self, sid: int, error: int, params: bytes) -> bytes:
        if self.servos[sid].hardware_error:
            error |= ERR_ALERT
        return status_packet2(sid, error, params)

    def _dispatch(self, pkt: bytes, now: float) -> None:
        self._send_replies(pkt, self.handle(pkt, now), now)

    def _send_replies(self, pkt: bytes, replies: list[tuple[int, bytes]], now: float) -> None:
        if self.timing:
            start = max(now, self._bus_free)
            end = start + len(pkt) * 10.0 / self.baud
            for sid, reply in replies:
                rdt = 2e-6 * self.servos[sid].table[x.ADDR_RETURN_DELAY]
                end += rdt + X_RESPONSE_S + len(reply) * 10.0 / self.baud
            self._bus_free = end
            if any(r for _, r in replies):
                sleep_until(end + self.usb_latency_s)
        self._send(b"".join(r for _, r in replies))

    def handle(self, pkt: bytes, now: float | None = None) -> list[tuple[int, bytes]]:
        """Process one instruction packet; returns the (ID, bytes) replies in order."""
        now = time.monotonic() if now is None else now
        self.packets += 1
        sid = pkt[4]
        for s in self.servos.values():
            s.heard(now)
        if sid != BROADCAST_ID:
            self._to[sid] = self._to.get(sid, 0) + 1
        parsed = parse_packet2(pkt)
        if parsed is None:
            self.crc_errors += 1
            if sid != BROADCAST_ID and self._present(sid):
                return [self._reply(sid, ERR_CRC, b"", now)]
            return []
        body = parsed[1]
        inst, params = body[0], body[1:]
        if inst == INST_SYNC_WRITE:
            self._sync_write(params, now)
            return []
        if inst == INST_SYNC_READ:
            return self._sync_read(params, now)
        if sid != BROADCAST_ID and not self._present(sid):
            return []
        targets = list(self.servos) if sid == BROADCAST_ID else [sid]
        for target in targets:
            if not self._present(target):
                continue
            result = self._execute(target, inst, params, now)
            if sid == BROADCAST_ID:
                continue
            srl = self.servos[target].table[x.ADDR_STATUS_RETURN_LEVEL]
            if isinstance(result, bytes):
                return [self._reply(target, 0, result, now)] if srl >= 1 else []
            if inst == INST_PING or srl >= 2:
                return [self._reply(target, result, b"", now)]
        return []

    def _execute(self, sid: int, inst: int, params: bytes, now: float) -> int | bytes:
        servo = self.servos[sid]
        self._apply_error_faults(sid, now)
        if inst == INST_PING:
            return bytes(servo.table[0:2] + servo.table[6:7])
        if inst == INST_READ:
            if len(params) != 4:
                return ERR_LENGTH
            data = servo.read(params[0] | params[1] << 8, params[2] | params[3] << 8, now)
            return ERR_RANGE if data is None else data
        if inst == INST_WRITE:
            if len(params) < 3:
                return ERR_LENGTH
            return self._write(sid, params[0] | params[1] << 8, params[2:], now, "write")
        if inst == INST_REBOOT:
            servo.table[x.ADDR_HARDWARE_ERROR] = 0
            servo.table[x.ADDR_TORQUE_ENABLE] = 0
            servo.table[x.ADDR_BUS_WATCHDOG] = 0
            return 0
        return ERR_INSTRUCTION

    def _write(self, sid: int, address: int, data: bytes, now: float, via: str) -> int:
        err, goal = self.servos[sid].write(address, bytes(data), now)
        self.writes.append(WriteRecord(now, sid, address, bytes(data), via))
        g = x.ADDR_GOAL_POSITION
        if address <= g < address + len(data) and len(data) >= g - address + 4:
            tick = (
                goal
                if goal is not None
                else int.from_bytes(data[g - address : g - address + 4], "little", signed=True)
            )
            self.goals.append(GoalRecord(now, sid, tick, err == 0, via))
        return err

    def _sync_read(self, params: bytes, now: float) -> list[tuple[int, bytes]]:
        if len(params) < 5:
            return []
        self.sync_reads += 1
        address, size = params[0] | params[1] << 8, params[2] | params[3] << 8
        out = []
        for sid in params[4:]:
            self._to[sid] = self._to.get(sid, 0) + 1
            if not self._present(sid):
                continue  # the others still answer in turn (simplification)
            self._apply_error_faults(sid, now)
            data = self.servos[sid].read(address, size, now)
            out.append(self._reply(sid, ERR_RANGE if data is None else 0, data or b"", now))
        return out
