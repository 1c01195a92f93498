"""X-series servos (XM430) over Dynamixel Protocol 2.0, on ROBOTIS dynamixel-sdk.

Packets (ROBOTIS e-Manual, "Protocol 2.0")::

    instruction  FF FF FD 00 ID LEN_L LEN_H INST    P1..Pn CRC_L CRC_H     LEN = n + 3
    status       FF FF FD 00 ID LEN_L LEN_H 55 ERR  P1..Pn CRC_L CRC_H     LEN = n + 4

``CRC`` is the CRC-16 (polynomial 0x8005) of every byte before it; *byte stuffing* inserts an
``FD`` after each ``FF FF FD`` inside the instruction and parameters (counted in ``LEN``), so
a header can never appear inside a packet. The status ``ERR`` byte carries an error number
(bits 0-6: result fail, instruction, CRC, data range, data length, data limit, access) and
the *alert* bit 7, set while the servo's Hardware Error Status (70) is not 0.

One tick: all goals in one SYNC_WRITE (116, 4 bytes, no reply) and, with ``--read``, one
SYNC_READ of a 10-byte block per servo (hardware error status, present current, position,
input voltage, temperature; :data:`HEALTH_BLOCK`), gathered by the Indirect Address registers
(168...) into Indirect Data (224...) at start-up: every servo's position and fault bits come
back in one transaction. Without ``--read``, the health polls are READs of the same block.

What comes from the SDK and what is the project's own (and why):

* ``PortHandler`` (open, baud, raw read/write) through :class:`DynamixelBus`, and
  ``GroupSyncWrite`` with ``Protocol2PacketHandler`` for goal positions and profile
  velocities: their data cannot contain ``FF FF FD`` (IDs <= 252; values < 2**15 in four
  little-endian bytes), so they never need stuffing.
* The CRC is the SDK's ``Protocol2PacketHandler.updateCRC``.
* Packets with a reply are built here (:func:`instruction_packet2`): the SDK's ``txPacket``
  ignores the list ``addStuffing`` returns when stuffing lengthens a packet and sends it
  unstuffed (dynamixel-sdk 3.7, ``protocol2_packet_handler.py``).
* Replies are matched here, as on Protocol 1.0 (:meth:`DynamixelBus.exchange`): the SDK's
  ``rxPacket`` / ``GroupSyncRead`` take any status packet with the right ID, so a reply that
  came after its deadline is read as the answer to the next request. Consecutive reads rotate
  their length (:func:`wbc.servos.dynamixel.read_variant`) so a late reply cannot match.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence

import numpy as np

from .. import xseries as x
from ..exceptions import ServoError
from ..servo_map import ServoMap
from .bus import (
    COMM_CORRUPT,
    COMM_OK,
    COMM_TIMEOUT,
    COMM_TX_FAIL,
    BudgetItem,
    BusBudget,
    ServoStatus,
    stiffness_factors,
    stiffness_registers,
)
from .dynamixel import DynamixelBus, _sdk
from .protocol1 import BROADCAST_ID, INST_PING, INST_WRITE, SDK_BAUDS, read_variant, word

INST_STATUS = 0x55
INST_REBOOT = 0x08
INST_SYNC_READ = 0x82
INST_SYNC_WRITE = 0x83
HEADER = b"\xff\xff\xfd"
MAX_LENGTH = 1024  # LEN of the longest packet the bus expects (SYNC_WRITE of 253 x 4 bytes)

STATUS_ERRORS = {
    1: "result_fail",
    2: "instruction",
    3: "crc",
    4: "data_range",
    5: "data_length",
    6: "data_limit",
    7: "access",
}
ERR_ALERT = 0x80

#: registers gathered by the Indirect Addresses into Indirect Data 224.. (one READ/SYNC_READ):
#: hardware error status, present current (2), present position (4), input voltage (2),
#: temperature
HEALTH_BLOCK = (
    x.ADDR_HARDWARE_ERROR,
    *range(x.ADDR_PRESENT_CURRENT, x.ADDR_PRESENT_CURRENT + 2),
    *range(x.ADDR_PRESENT_POSITION, x.ADDR_PRESENT_POSITION + 4),
    *range(x.ADDR_PRESENT_VOLTAGE, x.ADDR_PRESENT_VOLTAGE + 2),
    x.ADDR_PRESENT_TEMPERATURE,
)
ADDR_INDIRECT_ADDRESS = 168  # Indirect Address 1 (2 bytes each, 28 of them)
ADDR_INDIRECT_DATA = 224  # Indirect Data 1

#: Baud Rate (8) register values of the X series (e-Manual)
X_BAUDS = {9600: 0, 57600: 1, 115200: 2, 1_000_000: 3, 2_000_000: 4, 3_000_000: 5, 4_000_000: 6}
#: the servo's processing time before its status packet at Return Delay 0 (ESTIMATE, as the
#: AX-12A's 22 µs: ROBOTIS does not publish it)
X_RESPONSE_S = 22e-6
XM430_NO_LOAD_SPEED = 46.0 * 2.0 * math.pi / 60.0  # rad/s at 12 V (e-Manual XM430-W350)
XM430_STALL_CURRENT_A = 2.3  # A at 12 V (e-Manual XM430-W350): present current / this = load


@functools.cache
def _crc_handler():
    return _sdk().Protocol2PacketHandler()


def crc16(data: bytes | Sequence[int]) -> int:
    """CRC-16 of Protocol 2.0 (the SDK's ``updateCRC``, polynomial 0x8005, initial 0)."""
    data = list(data)
    return _crc_handler().updateCRC(0, data, len(data))


def stuff(body: bytes) -> bytes:
    """Insert ``FD`` after every ``FF FF FD`` of an instruction/status body."""
    out = bytearray()
    for b in body:
        out.append(b)
        if b == 0xFD and out[-3:-1] == b"\xff\xff" and len(out) >= 3:
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    """Remove the ``FD`` that follows every ``FF FF FD`` (the inverse of :func:`stuff`)."""
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        stuffed = i + 1 < len(body) and body[i + 1] == 0xFD
        if body[i] == 0xFD and out[-3:-1] == b"\xff\xff" and stuffed:
            i += 1  # skip the stuffed FD
        i += 1
    return bytes(out)


def _frame(servo_id: int, body: bytes) -> bytes:
    body = stuff(body)
    n = len(body) + 2
    head = HEADER + bytes([0x00, servo_id, n & 0xFF, n >> 8])
    crc = crc16(head + body)
    return head + body + bytes([crc & 0xFF, crc >> 8])


def instruction_packet2(servo_id: int, instruction: int, params: Sequence[int] = ()) -> bytes:
    """``FF FF FD 00 ID LEN_L LEN_H INST P.. CRC_L CRC_H`` (stuffed)."""
    return _frame(servo_id, bytes([instruction, *params]))


def status_packet2(servo_id: int, error: int, params: Sequence[int] = ()) -> bytes:
    """``FF FF FD 00 ID LEN_L LEN_H 55 ERR P.. CRC_L CRC_H`` (stuffed)."""
    return _frame(servo_id, bytes([INST_STATUS, error, *params]))


def take_packet2(buf: bytearray) -> bytes | None:
    """Take the first complete Protocol 2.0 packet (still stuffed) off ``buf``; bytes before a
    header are dropped; None while incomplete. The CRC is not checked here."""
    while True:
        i = buf.find(HEADER)
        if i < 0:
            del buf[: max(0, len(buf) - 2)]
            return None
        del buf[:i]
        if len(buf) < 7:
            return None
        if buf[3] != 0x00:  # FF FF FD FD is stuffing, not a header; 00 is reserved
            del buf[:1]
            continue
        length = buf[5] | (buf[6] << 8)
        if not 3 <= length <= MAX_LENGTH:
            del buf[:1]
            continue
        if len(buf) < 7 + length:
            return None
        pkt = bytes(buf[: 7 + length])
        del buf[: 7 + length]
        return pkt


def parse_packet2(pkt: bytes) -> tuple[int, bytes] | None:
    """``(id, unstuffed body)`` of a packet (body = instruction or 55 ERR, then parameters),
    or None if its CRC is wrong."""
    if len(pkt) < 10 or crc16(pkt[:-2]) != (pkt[-2] | (pkt[-1] << 8)):
        return None
    return pkt[4], unstuff(pkt[7:-2])


def status_error_names(error: int) -> tuple[str, ...]:
    """Names in a status packet's ERR byte: the error number, and ``hardware_alert``."""
    names = []
    if error & 0x7F:
        names.append(STATUS_ERRORS.get(error & 0x7F, f"error_{error & 0x7F}"))
    if error & ERR_ALERT:
        names.append("hardware_alert")
    return tuple(names)


def dword(value: int) -> list[int]:
    """Little-endian four bytes (two's complement)."""
    return list((int(value) & 0xFFFFFFFF).to_bytes(4, "little"))


def check_baud2(baud: int) -> None:
    """Raise :class:`ServoError` unless the X series and the SDK's port support ``baud``."""
    if baud not in X_BAUDS or baud not in SDK_BAUDS:
        raise ServoError(
            f"baud rate {baud} is not an X-series rate the SDK supports; use one of "
            f"{', '.join(str(b) for b in X_BAUDS if b in SDK_BAUDS)}"
        )


def sync_write2_length(n_servos: int, data_length: int) -> int:
    """Bytes of a SYNC_WRITE: header 7 + INST + address 2 + length 2 + n·(1 + L) + CRC 2."""
    return 14 + n_servos * (1 + data_length)


def x_budget(
    n_servos: int,
    baud: int,
    read_positions: bool,
    polls_per_tick: int = 1,
    return_delay_s: float = X_RESPONSE_S,
) -> BusBudget:
    """Bus budget of one tick: a SYNC_WRITE of all goals (4 bytes each) plus either one
    SYNC_READ of the 10-byte health block of every servo (``read_positions``: one request,
    ``n`` status packets of 21-23 bytes, one host turnaround) or ``polls_per_tick`` READs of
    it. The servos' response time is counted once per transaction (they answer back to back;
    :data:`X_RESPONSE_S` is an estimate). Reads are counted in their longest form."""
    block = len(HEALTH_BLOCK) + 2  # + up to 2 bytes of the rotated form
    items = [BudgetItem("SYNC_WRITE goal position", 1, sync_write2_length(n_servos, 4), 0, 0)]
    if read_positions:
        items.append(
            BudgetItem(
                f"SYNC_READ health block ({len(HEALTH_BLOCK)}-{block} B x {n_servos})",
                1,
                14 + n_servos,
                n_servos * (11 + block),
                1,
            )
        )
    elif polls_per_tick:
        items.append(BudgetItem("READ health block", polls_per_tick, 14, 11 + block, 1))
    name = "write + read" if read_positions else "write-only"
    return BusBudget(name, baud, tuple(items), return_delay_s=return_delay_s)


class Dynamixel2Bus(DynamixelBus):
    """The robot's X-series servos (XM430-W350) on one Protocol 2.0 bus, in model joint order.

    Shares the Protocol 1.0 bus's matched exchanges, retries, identification and verified
    torque-off (:class:`DynamixelBus`, through its packet hooks). Start-up writes, each only if
    it differs and read back: Return Delay 0, operating mode 3 (position), current limit,
    position limits (48/52) from the joint limits, Shutdown, position P/I/D gains, profile
    acceleration (``servo_map.settings``: :class:`wbc.xseries.XSettings`, the settings the
    simulator's XM430 law reads) and the indirect addresses of :data:`HEALTH_BLOCK`. Torque on
    arms the Bus Watchdog (98, ``watchdog_ms``): if the host stops sending (a killed process),
    each servo stops taking goals and holds; torque-off disarms it first.
    """

    name = "dynamixel2"
    servo_speed = XM430_NO_LOAD_SPEED
    torque_address = x.ADDR_TORQUE_ENABLE
    status_return_level_address = x.ADDR_STATUS_RETURN_LEVEL
    models: Mapping[int, str] = {x.XM430_W350_MODEL: "XM430-W350", 1030: "XM430-W210"}
    status_overhead = 11
    ping_reply = 3  # model number (2 bytes), firmware version
    #: the stiffness register (:meth:`set_stiffness`): Position P Gain (84, 2 bytes)
    stiffness_address = x.ADDR_POSITION_P_GAIN

    def __init__(
        self,
        port: str,
        servo_map: ServoMap,
        baud: int = 2_000_000,
        latency_timer_ms: float = 1.0,
        poll_wait_s: float = 1e-3,
        reply_timeout_ms: float | None = None,
        attempts: int = 3,
        watchdog_ms: float = 100.0,
    ) -> None:
        if servo_map.protocol != 2.0:
            raise ServoError(f"servo map {servo_map.source} is protocol {servo_map.protocol}")
        self._init_bus(
            port,
            servo_map,
            check_baud2,
            baud,
            latency_timer_ms,
            poll_wait_s,
            reply_timeout_ms,
            attempts,
        )
        units = math.ceil(watchdog_ms * 1e-3 / x.BUS_WATCHDOG_UNIT_S - 1e-9)
        if not 1 <= units <= 127:
            raise ServoError(f"bus watchdog {watchdog_ms} ms: allowed 20..2540 ms")
        self.watchdog_units = units
        self._sync_reads = 0

    # ------------------------------------------------------------------ protocol hooks
    bus_budget = staticmethod(x_budget)

    def packet(self, servo_id: int, instruction: int, params: Sequence[int] = ()) -> bytes:
        return instruction_packet2(servo_id, instruction, params)

    def take(self, buf: bytearray) -> bytes | None:
        return take_packet2(buf)

    def status(self, pkt: bytes) -> tuple[int, int, bytes] | None:
        parsed = parse_packet2(pkt)
        if parsed is None or len(parsed[1]) < 2 or parsed[1][0] != INST_STATUS:
            return None
        sid, body = parsed
        return sid, body[1], body[2:]

    def address_params(self, address: int, values: Sequence[int]) -> list[int]:
        return [address & 0xFF, address >> 8, *values]

    def read_params(self, address: int, length: int) -> list[int]:
        return [address & 0xFF, address >> 8, length & 0xFF, length >> 8]

    def error_names(self, error: int) -> tuple[str, ...]:
        return status_error_names(error)

    # ------------------------------------------------------------------ life cycle
    def open(self) -> None:
        """The Protocol 1.0 bus's port opening, then Protocol 2.0 group writes."""
        super().open()
        sdk = _sdk()
        ph = sdk.Protocol2PacketHandler()
        self._sync_goal = sdk.GroupSyncWrite(self.port, ph, x.ADDR_GOAL_POSITION, 4)
        self._sync_speed = sdk.GroupSyncWrite(self.port, ph, x.ADDR_PROFILE_VELOCITY, 4)
        self._sync_stiffness = sdk.GroupSyncWrite(self.port, ph, self.stiffness_address, 2)

    def configure(self) -> None:
        """Torque off (verified), then each setting written only if it differs and read back
        (see the class docstring); the Bus Watchdog off until torque is enabled."""
        self._require_open()
        if self.cmd_lo is None or self.cmd_hi is None:
            raise ServoError(f"{self.name}: configure() needs the command limits first")
        unconfirmed = self.torque_off()
        if unconfirmed:
            raise ServoError("torque-off not confirmed by " + ", ".join(unconfirmed))
        st = self.settings
        if not isinstance(st, x.XSettings):
            raise ServoError(f"{self.name}: the servo map's settings are not X-series settings")
        indirect = [b for a in HEALTH_BLOCK for b in (a & 0xFF, a >> 8)]
        for i in range(self.n):
            self._status_return_level_2(i)
            gains = [
                *word(int(st.position_d_gain[i])),
                *word(int(st.position_i_gain[i])),
                *word(int(st.position_p_gain[i])),
            ]
            blocks = [
                ("return delay", x.ADDR_RETURN_DELAY, [0]),
                ("operating mode", x.ADDR_OPERATING_MODE, [x.OPERATING_MODE_POSITION]),
                ("current limit", x.ADDR_CURRENT_LIMIT, word(int(st.current_limit[i]))),
                (
                    "position limits",
                    x.ADDR_MAX_POSITION_LIMIT,
                    dword(self.cmd_hi[i]) + dword(self.cmd_lo[i]),
                ),
                ("shutdown", x.ADDR_SHUTDOWN, [int(st.shutdown)]),
                ("position gains", x.ADDR_POSITION_D_GAIN, gains),
                ("bus watchdog", x.ADDR_BUS_WATCHDOG, [0]),
                ("profile acceleration", x.ADDR_PROFILE_ACCELERATION,
                 dword(st.profile_acceleration[i])),
                ("indirect addresses", ADDR_INDIRECT_ADDRESS, indirect),
            ]  # fmt: skip
            for what, address, wanted in blocks:
                self._set_block(i, what, address, wanted)
        self.stiffness = np.ones(self.n)

    # ------------------------------------------------------------------ motion
    def set_torque(self, enabled: bool) -> None:
        """On: torque enable per servo (acknowledged), then the Bus Watchdog armed per servo
        (``watchdog_ms``; the deployment re-arms it for its own period through
        :meth:`arm_watchdog`). Off: :meth:`torque_off`."""
        super().set_torque(enabled)
        if enabled:
            self._write_watchdog(self.watchdog_units)

    def _write_watchdog(self, units: int) -> None:
        for i in range(self.n):
            self._retry(
                i, "bus watchdog", lambda p, i=i: self.write(i, x.ADDR_BUS_WATCHDOG, [units], p)
            )

    def arm_watchdog(self, timeout_s: float) -> bool:
        """The Bus Watchdog (98) at ``timeout_s`` (20 ms units, 1..127): a servo that receives
        no valid instruction for that long stops taking goals and holds (a killed process)."""
        units = math.ceil(timeout_s / x.BUS_WATCHDOG_UNIT_S - 1e-9)
        if not (math.isfinite(timeout_s) and 1 <= units <= 127):
            raise ServoError(f"bus watchdog {timeout_s * 1e3:.0f} ms: allowed 20..2540 ms")
        self.watchdog_units = units
        self._write_watchdog(units)
        return True

    def torque_off(self) -> list[str]:
        """Disarm the Bus Watchdog (a broadcast WRITE of 0, which also clears a watchdog
        error), then the verified torque-off of :class:`DynamixelBus`."""
        self._require_open()
        self.reset()
        self.exchange(BROADCAST_ID, INST_WRITE, self.address_params(x.ADDR_BUS_WATCHDOG, [0]))
        return super().torque_off()

    def stiffness_registers(self, factors: float | Sequence[float] | np.ndarray) -> np.ndarray:
        """The Position P Gain (84) of each servo for stiffness ``factors`` (the P term's
        stiffness grows with it): the configured gain × factor, rounded, 0..16383, else
        :class:`ServoError` naming the servos. The I and D gains are left as configured."""
        st = self.settings
        if not isinstance(st, x.XSettings):
            raise ServoError(f"{self.name}: the servo map's settings are not X-series settings")
        f = stiffness_factors(factors, self.n)
        lo, hi = x.X_SETTING_REGISTERS["position_p_gain"][2]
        return stiffness_registers(st.position_p_gain, f, self.labels, "position P gain",
                                   (lo, hi), False)  # fmt: skip

    def stiffness_bytes(self, register: int) -> list[int]:
        return word(register)

    def set_speed(self, rad_per_s: float) -> None:
        """Profile Velocity (112) of every servo in one SYNC_WRITE: the servos' own speed cap."""
        self._require_open()
        try:
            reg = x.profile_velocity_register(rad_per_s)
        except Exception as exc:
            raise ServoError(str(exc)) from exc
        self._sync_write_all(self._sync_speed, dword(reg), "profile velocity")

    def write_goals(self, cmds: np.ndarray) -> str:
        """All goal positions in one SYNC_WRITE to address 116 (checked against the limits)."""
        self._require_open()
        cmds = self.check_goals(cmds)
        sync = self._sync_goal
        sync.clearParam()
        for sid, tick in zip(self.ids, cmds, strict=True):
            sync.addParam(sid, dword(int(tick)))
        return self._comm(sync.txPacket())

    # ------------------------------------------------------------------ feedback
    def _health(self, i: int, error: int, data: bytes) -> ServoStatus:
        """A status from the health block's bytes."""
        hw = data[0]
        current = int.from_bytes(data[1:3], "little", signed=True)
        position = int.from_bytes(data[3:7], "little", signed=True)
        return ServoStatus(
            i,
            COMM_OK,
            x.hw_fault_names(hw),
            hw,
            position=float(position),
            voltage=int.from_bytes(data[7:9], "little") / 10.0,
            temperature=float(data[9]),
            load=current * x.CURRENT_UNIT_A / XM430_STALL_CURRENT_A,
        )

    def poll(self, index: int) -> ServoStatus:
        """One matched READ of the health block (rotated form)."""
        self._require_open()
        comm, error, data = self.read(index, ADDR_INDIRECT_DATA, len(HEALTH_BLOCK))
        if comm != COMM_OK:
            return ServoStatus(index, comm)
        return self._health(index, error, data)

    def read_positions(self, indices: Sequence[int] | None = None) -> list[ServoStatus]:
        """One SYNC_READ of the health block of the given servos (default all): every status
        packet matched by ID and length (the form rotates per SYNC_READ), before a deadline
        of the wire time of all replies + 2 · USB latency + 2 ms. A corrupt packet fails the
        servo whose turn it was; a valid reply after bytes of no packet (garbage on the
        line) fails its servo."""
        self._require_open()
        idx = list(range(self.n)) if indices is None else list(indices)
        a, n = read_variant(ADDR_INDIRECT_DATA, len(HEALTH_BLOCK), self._sync_reads)
        self._sync_reads += 1
        ids = [self.ids[i] for i in idx]
        self._flush()
        pkt = self.packet(BROADCAST_ID, INST_SYNC_READ, [*self.read_params(a, n), *ids])
        t0 = self._transmit(pkt)
        if t0 is None:
            return [ServoStatus(i, COMM_TX_FAIL) for i in idx]
        deadline = t0 + self.reply_timeout_s(len(pkt), len(ids) * (n + self.status_overhead))
        out: dict[int, ServoStatus] = {}
        by_id = dict(zip(ids, idx, strict=True))
        junk = 0  # bytes that belong to no packet (noise, a babbling device)
        while len(out) < len(ids):
            now = self.reply_clock()
            self._receive()
            while True:
                reply, skipped = self._take_counted()
                junk += skipped
                if reply is None:
                    break
                st = self.status(reply)
                pending = [s for s in ids if by_id[s] not in out]
                # a corrupt packet fails the servo whose turn it was; a valid reply after
                # garbage (the line is not clean) fails the servo it names
                if st is None or (junk and st[0] in pending):
                    junk = 0
                    who = st[0] if st is not None else (pending[0] if pending else None)
                    if who is not None:
                        self.log.count(self.log.corrupt, who)
                        out[by_id[who]] = ServoStatus(by_id[who], COMM_CORRUPT)
                    continue
                sid, error, data = st
                if sid not in pending or len(data) != n:
                    self.log.count(self.log.late, sid)
                    continue
                self.log.rtt.append(self.reply_clock() - t0)
                out[by_id[sid]] = self._health(by_id[sid], error, data[ADDR_INDIRECT_DATA - a :])
            if len(out) == len(ids) or now >= deadline:
                break
            self._wait_bytes(deadline, now)
        for s in ids:
            if by_id[s] not in out:
                self.log.count(self.log.timeouts, s)
                out[by_id[s]] = ServoStatus(by_id[s], COMM_TIMEOUT)
        return [out[i] for i in idx]

    def reboot(self, index: int) -> str:
        """REBOOT one servo (clears a hardware error; torque comes back off)."""
        return self.exchange(self.ids[index], INST_REBOOT)[0]

    def ping(self, index: int) -> str:
        """PING one servo (its reply carries the model number and firmware version)."""
        return self.exchange(self.ids[index], INST_PING, (), 3)[0]
