"""AX-12A servos over Dynamixel Protocol 1.0, on ROBOTIS dynamixel-sdk.

Addresses are the AX-12A control table (bioloid-facts §4.2), *not* the X-series addresses of
the SDK's Protocol-1.0 examples; they, the packets and their framing are in
:mod:`wbc.servos.protocol1`. All goals go out in one SYNC_WRITE to address 30 (no status
reply). The AX series has no sync or bulk read: feedback is one READ per servo, which
dominates the bus budget.

Request/reply exchanges do not use the SDK's ``txRxPacket``, which matches a status packet
by ID only (a reply that came after its timeout is read as the answer to the next request
to that servo): :meth:`DynamixelBus.exchange` flushes stale input, checks ID, length and
checksum against the request, and rotates the form of consecutive READs of a servo so a
late reply cannot match (:func:`~wbc.servos.protocol1.read_variant`). The SDK's
``PortHandler`` (open, baud, read, write) and ``GroupSyncWrite`` are used as they are; a
subclass replaces the port's hard-coded 16 ms USB latency by a parameter, and the safe stop
clears ``port.is_using`` (left set by a Ctrl-C inside an SDK call) before sending torque-off.
"""

from __future__ import annotations

import math
import os
import select
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import ServoError
from ..servo_map import SETTING_REGISTERS, ServoMap
from .bus import (
    COMM_CORRUPT,
    COMM_OK,
    COMM_TIMEOUT,
    COMM_TX_FAIL,
    BusBudget,
    ServoBus,
    ServoStatus,
    stiffness_factors,
    stiffness_registers,
)
from .protocol1 import (
    ADDR_CW_COMPLIANCE_MARGIN,
    ADDR_CW_COMPLIANCE_SLOPE,
    ADDR_GOAL_POSITION,
    ADDR_MOVING_SPEED,
    ADDR_PRESENT_POSITION,
    ADDR_PUNCH,
    ADDR_RETURN_DELAY,
    ADDR_SHUTDOWN,
    ADDR_STATUS_RETURN_LEVEL,
    ADDR_TORQUE_ENABLE,
    ADDR_TORQUE_LIMIT,
    AX12_MAX_SPEED,
    AX12_MODEL_NUMBER,
    BROADCAST_ID,
    INST_PING,
    INST_READ,
    INST_WRITE,
    ax_budget,
    ax_codec,
    check_baud,
    checksum,
    fault_names,
    instruction_packet,
    read_variant,
    speed_register,
    take_packet,
    word,
)

# Adaptive reply deadline (DynamixelBus.reply_timeout_s): 3 x the median of the last 32 round
# trips, within [the SDK's rule, 12 ms] (at 50 Hz with --read a silent servo leaves room)
ADAPTIVE_FACTOR, ADAPTIVE_WINDOW, ADAPTIVE_MAX_S = 3.0, 32, 12e-3


def ftdi_latency_timer(port: str) -> int | None:
    """The latency timer (ms) of a USB-serial adapter, if the kernel exposes it."""
    name = Path(os.path.realpath(port)).name
    path = Path("/sys/bus/usb-serial/devices") / name / "latency_timer"
    try:
        return int(path.read_text().strip())
    except (OSError, ValueError):
        return None


def _sdk():
    try:
        import dynamixel_sdk
    except ModuleNotFoundError as exc:  # pragma: no cover - installed in the project venv
        raise ServoError("dynamixel-sdk is not installed (pip install 'wbc[servos]')") from exc
    return dynamixel_sdk


def _port_handler_class():
    sdk = _sdk()

    class PortHandler(sdk.PortHandler):
        """SDK port with a configurable USB latency (not 16 ms) in its packet timeout, and a
        receive that waits in ``select`` (up to 1 ms) instead of spinning: the SDK polls
        ``readPort`` in a tight loop, which burns a core and starves other processes (the
        servos' emulator, the controller) while a reply is awaited."""

        latency_timer_ms: float = 1.0
        poll_wait_s: float = 1e-3

        def readPort(self, length):
            if self.poll_wait_s > 0 and not self.ser.in_waiting:
                select.select([self.ser.fileno()], [], [], self.poll_wait_s)
            return self.ser.read(length)

        def setPacketTimeout(self, packet_length):
            self.packet_start_time = self.getCurrentTime()
            self.packet_timeout = (
                self.tx_time_per_byte * packet_length + 2.0 * self.latency_timer_ms + 2.0
            )

    return PortHandler


@dataclass
class ExchangeLog:
    """Every request/reply exchange of a bus: round-trip times of matched replies, and per
    servo ID the timeouts, corrupt or unmatched replies and late replies (a status packet that
    came after its deadline: flushed before a later request, or met while awaiting another)."""

    rtt: list[float] = field(default_factory=list)  # s, matched replies, in order
    timeouts: dict[int, int] = field(default_factory=dict)
    corrupt: dict[int, int] = field(default_factory=dict)
    late: dict[int, int] = field(default_factory=dict)
    stale_bytes: int = 0
    junk_bytes: int = 0  # bytes of no packet received within exchanges (garbage)

    def count(self, what: dict[int, int], servo_id: int) -> None:
        what[servo_id] = what.get(servo_id, 0) + 1

    def lines(self) -> list[str]:
        """A short summary for the deployment report."""
        if not self.rtt:
            return ["bus exchanges: no reply received"]
        ms = np.array(self.rtt) * 1e3
        out = [
            f"bus round trips: {ms.size} replies, p50 {np.percentile(ms, 50):.3f} ms, "
            f"p99 {np.percentile(ms, 99):.3f} ms, max {ms.max():.3f} ms"
        ]
        for name, d in (("timeouts", self.timeouts), ("corrupt/unmatched", self.corrupt)):
            if d:
                out.append(f"{name}: " + ", ".join(f"id {k} x{v}" for k, v in sorted(d.items())))
        if self.junk_bytes:
            out.append(f"garbage on the line: {self.junk_bytes} bytes outside any packet")
        if self.late:
            out.append(
                "late replies (discarded): "
                + ", ".join(f"id {k} x{v}" for k, v in sorted(self.late.items()))
            )
        return out


class DynamixelBus(ServoBus):
    """The robot's AX-12A servos on one Protocol 1.0 bus, in model joint order.

    Every exchange with a reply is matched (:meth:`exchange`): stale input is flushed first,
    the status packet must carry the servo's ID, a valid checksum and the length of what was
    asked, within the reply deadline, and come on a clean line (garbage bytes in the exchange
    make it ``corrupt``: persistent garbage trips the watchdog like silence); anything else is
    a failed exchange the watchdog counts.
    Start-up exchanges are retried up to ``attempts`` times; the motion loop's are not (the
    watchdog's streak decides). Settings (compliance, punch, torque limit, alarm shutdown)
    come from ``servo_map.settings`` (the config the simulator's servo model reads too).
    """

    name = "dynamixel"
    can_read = True
    servo_speed = AX12_MAX_SPEED
    # the protocol's parts (wbc.servos.protocol2.Dynamixel2Bus overrides them): the torque
    # enable and status return level registers, the accepted model numbers (address 0,
    # 2 bytes) and packet hooks below
    torque_address = ADDR_TORQUE_ENABLE
    status_return_level_address = ADDR_STATUS_RETURN_LEVEL
    models: Mapping[int, str] = {AX12_MODEL_NUMBER: "AX-12A"}
    can_set_stiffness = True
    #: the stiffness register (:meth:`set_stiffness`): CW/CCW Compliance Slope (28/29)
    stiffness_address = ADDR_CW_COMPLIANCE_SLOPE

    bus_budget = staticmethod(ax_budget)  # the protocol's wire-time budget

    def packet(self, servo_id: int, instruction: int, params: Sequence[int] = ()) -> bytes:
        """An instruction packet of the bus's protocol."""
        return instruction_packet(servo_id, instruction, params)

    def take(self, buf: bytearray) -> bytes | None:
        """The first complete packet off ``buf`` (:func:`take_packet`), None while incomplete."""
        return take_packet(buf)

    def status(self, pkt: bytes) -> tuple[int, int, bytes] | None:
        """``(id, error byte, parameters)`` of a status packet, None if its checksum fails."""
        if checksum(pkt[2:-1]) != pkt[-1]:
            return None
        return pkt[2], pkt[4], pkt[5:-1]

    status_overhead = 6  # bytes of a status packet besides its parameters
    ping_reply = 0  # parameters of a PING's status packet

    def address_params(self, address: int, values: Sequence[int]) -> list[int]:
        """READ/WRITE parameters: the address (1 byte) then ``values``."""
        return [address, *values]

    def read_params(self, address: int, length: int) -> list[int]:
        """READ parameters: address and length, one byte each."""
        return [address, length]

    def error_names(self, error: int) -> tuple[str, ...]:
        """Names of the bits of a status packet's error byte."""
        return fault_names(error)

    def __init__(
        self,
        port: str,
        servo_map: ServoMap,
        baud: int = 1_000_000,
        latency_timer_ms: float = 1.0,
        torque_limit: int | None = None,
        poll_wait_s: float = 1e-3,
        reply_timeout_ms: float | None = None,
        attempts: int = 3,
    ) -> None:
        if torque_limit is not None and not 0 <= torque_limit <= 1023:
            raise ServoError(f"torque limit must be 0..1023, got {torque_limit}")
        self._init_bus(
            port,
            servo_map,
            check_baud,
            baud,
            latency_timer_ms,
            poll_wait_s,
            reply_timeout_ms,
            attempts,
        )
        self.torque_limit = (
            np.asarray(self.settings.torque_limit, dtype=int)
            if torque_limit is None
            else np.full(len(self.ids), torque_limit, dtype=int)
        )

    def _init_bus(
        self,
        port: str,
        servo_map: ServoMap,
        baud_check: Callable[[int], None],
        baud: int,
        latency_timer_ms: float,
        poll_wait_s: float,
        reply_timeout_ms: float | None,
        attempts: int,
    ) -> None:
        """The arguments checked (``baud_check``: the protocol's baud rates) and the state
        both protocols' buses share."""
        labels = [
            f"id {int(i)} ({j})" for i, j in zip(servo_map.ids, servo_map.joint_names, strict=True)
        ]
        ServoBus.__init__(self, ax_codec(servo_map), labels)
        baud_check(baud)
        if reply_timeout_ms is not None and not (
            math.isfinite(reply_timeout_ms) and reply_timeout_ms > 0
        ):
            raise ServoError(f"reply timeout must be positive (ms), got {reply_timeout_ms}")
        if attempts < 1:
            raise ServoError(f"attempts must be >= 1, got {attempts}")
        self.port_name = port
        self.servo_map = servo_map
        self.settings = servo_map.settings
        self.baud = baud
        self.ids = [int(i) for i in servo_map.ids]
        self.latency_timer_ms = latency_timer_ms
        self.turnaround_s = latency_timer_ms * 1e-3
        self.reply_timeout_ms = reply_timeout_ms
        self.attempts = attempts
        self.poll_wait_s = poll_wait_s  # 0: busy-wait receive (like the SDK)
        self.warnings: list[str] = []
        self.notes: list[str] = []
        self.log = ExchangeLog()
        self.port = None
        self._sync_goal = None
        self._sync_speed = None
        self._sync_stiffness = None
        self._buf = bytearray()
        self._reads = np.zeros(len(self.ids), int)  # per servo: READ count, picks the form

    # ------------------------------------------------------------------ life cycle
    def open(self) -> None:
        if not os.path.exists(self.port_name):
            raise ServoError(f"unknown port {self.port_name!r}: no such device")
        sdk = _sdk()
        port = _port_handler_class()(self.port_name)
        port.latency_timer_ms = self.latency_timer_ms
        port.poll_wait_s = self.poll_wait_s
        latency = ftdi_latency_timer(self.port_name)
        if latency is not None and latency > self.latency_timer_ms:
            port.latency_timer_ms = float(latency)  # else every reply would look late
            self.latency_timer_ms = float(latency)
            self.turnaround_s = latency * 1e-3
            self.warnings.append(
                f"{self.port_name}: USB latency timer is {latency} ms (each READ takes about "
                f"{latency} ms); set it to 1 with 'echo 1 > /sys/bus/usb-serial/devices/"
                f"{Path(os.path.realpath(self.port_name)).name}/latency_timer'"
            )

        def opener():
            try:
                ok = port.setBaudRate(self.baud)  # opens the port (pyserial)
            except Exception as exc:  # serial.SerialException, OSError
                raise ServoError(f"cannot open port {self.port_name!r}: {exc}") from exc
            if not ok:
                raise ServoError(f"port {self.port_name!r} refused baud rate {self.baud}")
            return port

        # one owner per bus: refused before a byte is sent
        self.port = self.open_port(
            self.port_name, opener, lambda p: p.ser.fileno(), lambda p: p.closePort()
        )
        ph = sdk.Protocol1PacketHandler()
        self._sync_goal = sdk.GroupSyncWrite(port, ph, ADDR_GOAL_POSITION, 2)
        self._sync_speed = sdk.GroupSyncWrite(port, ph, ADDR_MOVING_SPEED, 2)
        self._sync_stiffness = sdk.GroupSyncWrite(port, ph, self.stiffness_address, 2)

    def close(self) -> None:
        self.unlock_port()
        if self.port is not None and self.port.is_open:
            self.port.closePort()

    def reset(self) -> None:
        """Recover the SDK port after an interrupted call (``is_using`` stuck at True)."""
        if self.port is not None:
            self.port.is_using = False
            self._flush()

    # ------------------------------------------------------------------ matched exchanges
    def reply_timeout_s(self, n_out: int, n_in: int) -> float:
        """Reply deadline after the request is written: ``--reply-timeout-ms`` if given, else
        adaptive: the SDK's rule (wire time of both packets + 2 · USB latency + 2 ms), raised
        to :data:`ADAPTIVE_FACTOR` × the median of the last :data:`ADAPTIVE_WINDOW` measured
        round trips (a loaded host or a slow adapter), at most :data:`ADAPTIVE_MAX_S`: a busy
        CPU is no false alarm, a servo that stays silent or answers later still fails."""
        if self.reply_timeout_ms is not None:
            return self.reply_timeout_ms * 1e-3
        wire = (n_out + n_in) * 10.0 / self.baud
        rule = wire + 2e-3 * self.latency_timer_ms + 2e-3
        recent = self.log.rtt[-ADAPTIVE_WINDOW:]
        if len(recent) < 3:
            return rule
        measured = ADAPTIVE_FACTOR * float(np.median(recent))
        return min(max(rule, measured), max(rule, ADAPTIVE_MAX_S))

    def _flush(self) -> None:
        """Drop what is pending on the line; status packets in it are late replies."""
        ser = self.port.ser
        n = ser.in_waiting
        if n:
            self._buf += ser.read(n)
        self.log.stale_bytes += len(self._buf)
        while (pkt := self.take(self._buf)) is not None:
            if (st := self.status(pkt)) is not None:
                self.log.count(self.log.late, st[0])
        self._buf.clear()

    def _transmit(self, pkt: bytes) -> float | None:
        """Write ``pkt`` to the port: the time it went out, or None if not all was written."""
        t0 = self.reply_clock()
        try:
            written = self.port.writePort(pkt)
        except Exception:
            written = -1
        return t0 if written == len(pkt) else None

    def _receive(self) -> None:
        """Append the bytes waiting on the port to the receive buffer."""
        ser = self.port.ser
        n = ser.in_waiting
        if n:
            self._buf += ser.read(n)

    def _take_counted(self) -> tuple[bytes | None, int]:
        """The next whole packet off the buffer (or None), and the bytes of no packet
        discarded on the way (noise, a babbling device)."""
        before = len(self._buf)
        reply = self.take(self._buf)
        return reply, before - len(self._buf) - (len(reply) if reply is not None else 0)

    def _wait_bytes(self, deadline: float, now: float) -> None:
        """Wait for bytes up to ``poll_wait_s`` (not past the deadline); 0: busy-wait, like
        the SDK."""
        if self.poll_wait_s > 0:
            ser = self.port.ser
            select.select([ser.fileno()], [], [], max(min(deadline - now, self.poll_wait_s), 0.0))

    def _sync_write_all(self, sync, data: list[int], what: str) -> None:
        """The same ``data`` to every servo in one SYNC_WRITE; raises naming ``what``."""
        sync.clearParam()
        for sid in self.ids:
            sync.addParam(sid, data)
        if self._comm(sync.txPacket()) != COMM_OK:
            raise ServoError(f"{self.port_name}: SYNC_WRITE of the {what} failed")

    def exchange(
        self,
        servo_id: int,
        instruction: int,
        params: Sequence[int] = (),
        n_reply: int = 0,
        patience: float = 1.0,
    ) -> tuple[str, int, bytes]:
        """One matched request/reply: ``(comm, error byte, reply parameters)``.

        The status packet must have ``servo_id``, ``n_reply`` parameters and a valid
        checksum, and arrive before :meth:`reply_timeout_s`; a valid packet of another ID is a
        late reply (logged, skipped); a wrong length or checksum is ``corrupt``. ``patience``
        multiplies the deadline (start-up retries wait longer each time)."""
        self._require_open()
        self._flush()
        pkt = self.packet(servo_id, instruction, params)
        t0 = self._transmit(pkt)
        if t0 is None:
            return COMM_TX_FAIL, 0, b""
        if servo_id == BROADCAST_ID:
            return COMM_OK, 0, b""
        deadline = t0 + patience * self.reply_timeout_s(len(pkt), n_reply + self.status_overhead)
        junk = 0  # bytes on the line that belong to no packet (noise, a babbling device)
        while True:
            now = self.reply_clock()
            self._receive()
            while True:
                reply, skipped = self._take_counted()
                junk += skipped
                if reply is None:
                    break
                st = self.status(reply)
                if st is None:
                    self.log.count(self.log.corrupt, servo_id)
                    return COMM_CORRUPT, 0, b""
                if st[0] != servo_id:
                    self.log.count(self.log.late, st[0])
                    continue
                if len(st[2]) != n_reply:  # e.g. the late answer to an earlier READ
                    self.log.count(self.log.late, servo_id)
                    continue
                if junk:  # a valid reply in garbage: the line is not clean, count a failure
                    self.log.junk_bytes += junk
                    self.log.count(self.log.corrupt, servo_id)
                    return COMM_CORRUPT, 0, b""
                self.log.rtt.append(self.reply_clock() - t0)
                return COMM_OK, st[1], st[2]
            if now >= deadline:  # the last look came after the deadline
                self.log.count(self.log.timeouts, servo_id)
                return COMM_TIMEOUT, 0, b""
            self._wait_bytes(deadline, now)

    def read(
        self, i: int, address: int, length: int, patience: float = 1.0
    ) -> tuple[str, int, bytes]:
        """A matched READ of servo ``i`` (model index), in the servo's next form
        (:func:`read_variant`), returning the ``length`` bytes at ``address``."""
        a, n = read_variant(address, length, int(self._reads[i]))
        self._reads[i] += 1
        comm, error, data = self.exchange(
            self.ids[i], INST_READ, self.read_params(a, n), n, patience
        )
        if comm != COMM_OK:
            return comm, 0, b""
        return comm, error, data[address - a :]

    def write(
        self, i: int, address: int, data: Sequence[int], patience: float = 1.0
    ) -> tuple[str, int]:
        """A matched WRITE (status packet expected: Status Return Level 2)."""
        params = self.address_params(address, data)
        comm, error, _ = self.exchange(self.ids[i], INST_WRITE, params, 0, patience)
        return comm, error

    def _retry(self, i: int, what: str, call) -> tuple:
        """A start-up exchange ``call(patience)``, retried up to ``attempts`` times on timeouts
        and corrupt replies with a deadline doubled each time (a stalled host or adapter gets
        longer to answer); raises naming the servo unless it succeeds without error bits."""
        for k in range(self.attempts):
            out = call(2.0**k)
            if out[0] == COMM_OK:
                break
        comm, error = out[0], out[1]
        if comm != COMM_OK:
            raise ServoError(f"{self.labels[i]}: {what}: {comm} after {self.attempts} attempts")
        if error:
            raise ServoError(
                f"{self.labels[i]}: {what}: status error 0x{error:02X} "
                f"{list(self.error_names(error))}"
            )
        return out

    def _require_open(self) -> None:
        if self.port is None:
            raise ServoError(f"{self.name}: port {self.port_name!r} is not open")

    # ------------------------------------------------------------------ start-up
    def identify(self) -> None:
        """PING every servo (up to ``attempts`` times) and check it is an AX-12A (model number
        read back); name the missing/garbled/wrong ones. Reports the measured round trip."""
        self._require_open()
        results: dict[int, str] = {}
        for i, sid in enumerate(self.ids):
            for k in range(self.attempts):
                results[i] = self.exchange(sid, INST_PING, (), self.ping_reply, 2.0**k)[0]
                if results[i] == COMM_OK:
                    break
            if i == 0 and results[0] == COMM_TIMEOUT:
                pings = (self.exchange(s, INST_PING, (), self.ping_reply) for s in self.ids[1:])
                if all(p[0] == COMM_TIMEOUT for p in pings):
                    raise ServoError(
                        f"no servo answered on {self.port_name} at {self.baud} baud (the servo "
                        f"map says {self.servo_map.baudrate}): wrong baud rate, no power, or "
                        "wrong port"
                    )
        ping_rtt = list(self.log.rtt)
        missing = [self.labels[i] for i, c in results.items() if c == COMM_TIMEOUT]
        garbled = [self.labels[i] for i, c in results.items() if c not in (COMM_OK, COMM_TIMEOUT)]
        wrong = []
        for i, c in results.items():
            if c != COMM_OK:
                continue
            data = self._retry(i, "read model number", lambda p, i=i: self.read(i, 0, 2, p))[2]
            model = data[0] | (data[1] << 8)
            if model not in self.models:
                wrong.append(f"{self.labels[i]} reports model {model}")
        problems = []
        if missing:
            problems.append("no reply to PING from " + ", ".join(missing))
        if garbled:
            problems.append(
                "garbled reply to PING from "
                + ", ".join(garbled)
                + " (two servos sharing an ID, or line noise)"
            )
        if wrong:
            known = ", ".join(f"{v} (model {k})" for k, v in self.models.items())
            problems.append(f"not {known}: " + ", ".join(wrong))
        if problems:
            raise ServoError(f"{self.port_name}: " + "; ".join(problems))
        if ping_rtt:
            ms = np.array(ping_rtt) * 1e3
            self.adapter_latency_s = float(np.median(ping_rtt))
            self.notes.append(
                f"adapter round trip (PING, {ms.size} replies): p50 {np.median(ms):.3f} ms, "
                f"max {ms.max():.3f} ms; reply deadline "
                f"{self.reply_timeout_s(14, 14) * 1e3:.1f} ms"
            )

    adapter_latency_s: float | None = None

    def configure(self) -> None:
        """Torque off; Status Return Level 2, Return Delay 0, angle limits (6/8) from the joint
        limits, Alarm Shutdown (18), compliance margins/slopes (26-29), torque limit (34) and
        punch (48) from the servo settings: each written only if it differs, then read back."""
        self._require_open()
        if self.cmd_lo is None or self.cmd_hi is None:
            raise ServoError(f"{self.name}: configure() needs the command limits first")
        unconfirmed = self.torque_off()
        if unconfirmed:
            raise ServoError("torque-off not confirmed by " + ", ".join(unconfirmed))
        st = self.settings
        for i in range(self.n):
            self._status_return_level_2(i)
            lo, hi = int(self.cmd_lo[i]), int(self.cmd_hi[i])
            m, s = int(st.compliance_margin[i]), int(st.compliance_slope[i])
            blocks = [
                ("return delay / angle limits", ADDR_RETURN_DELAY, [0, *word(lo), *word(hi)]),
                ("alarm shutdown", ADDR_SHUTDOWN, [int(st.alarm_shutdown)]),
                ("compliance margins / slopes", ADDR_CW_COMPLIANCE_MARGIN, [m, m, s, s]),
                ("torque limit", ADDR_TORQUE_LIMIT, word(int(self.torque_limit[i]))),
                ("punch", ADDR_PUNCH, word(int(st.punch[i]))),
            ]
            for what, address, wanted in blocks:
                self._set_block(i, what, address, wanted)
        self.stiffness = np.ones(self.n)

    def _status_return_level_2(self, i: int) -> None:
        """Status Return Level 2 on servo ``i`` if it is not: without it, WRITEs get no status
        and would look like timeouts."""
        a = self.status_return_level_address
        srl = self._retry(i, "read status return level", lambda p: self.read(i, a, 1, p))[2]
        if srl[0] != 2:
            self.exchange(self.ids[i], INST_WRITE, self.address_params(a, [2]))
            self._flush()

    def _set_block(self, i: int, what: str, address: int, wanted: list[int]) -> None:
        n = len(wanted)
        data = self._retry(i, f"read {what}", lambda p: self.read(i, address, n, p))[2]
        if list(data) == wanted:
            return
        self._retry(i, f"write {what}", lambda p: self.write(i, address, wanted, p))
        data = self._retry(i, f"read back {what}", lambda p: self.read(i, address, n, p))[2]
        if list(data) != wanted:
            raise ServoError(
                f"{self.labels[i]}: {what} did not stick: wrote {wanted}, read {list(data)} "
                "(EEPROM locked?)"
            )

    # ------------------------------------------------------------------ motion
    def set_torque(self, enabled: bool) -> None:
        """On: per servo, acknowledged (retried). Off: :meth:`torque_off` (acknowledged and
        read back); raises naming the servos that did not confirm."""
        self._require_open()
        if not enabled:
            unconfirmed = self.torque_off()
            if unconfirmed:
                raise ServoError("torque-off not confirmed by " + ", ".join(unconfirmed))
            return
        for i in range(self.n):
            self._retry(
                i, "torque enable", lambda p, i=i: self.write(i, self.torque_address, [1], p)
            )

    def torque_off(self) -> list[str]:
        """Torque off on every servo: a broadcast WRITE (reaches a servo that cannot answer),
        then per servo a WRITE with acknowledgement and a READ of register 24, each retried;
        returns the labels of servos whose torque is not confirmed off."""
        self._require_open()
        self.reset()
        self.exchange(BROADCAST_ID, INST_WRITE, self.address_params(self.torque_address, [0]))
        unconfirmed = []
        for i in range(self.n):
            ok = False
            for k in range(self.attempts):
                comm, _ = self.write(i, self.torque_address, [0], 2.0**k)
                if comm != COMM_OK:
                    continue
                comm, _, data = self.read(i, self.torque_address, 1, 2.0**k)
                if comm == COMM_OK and data[0] == 0:
                    ok = True
                    break
            if not ok:
                unconfirmed.append(self.labels[i])
        return unconfirmed

    def set_torque_limit(self, share: float) -> None:
        """Torque Limit (34, RAM) of every servo: ``share`` (0..1) of the maximum, one
        broadcast WRITE (the protective fall:
        :meth:`wbc.servos.playback.Deployment.safe_fall`)."""
        self._require_open()
        if not 0.0 <= share <= 1.0:
            raise ServoError(f"torque limit share must be in [0, 1], got {share}")
        self.exchange(BROADCAST_ID, INST_WRITE, (ADDR_TORQUE_LIMIT, *word(round(1023 * share))))

    def stiffness_registers(self, factors: float | Sequence[float] | np.ndarray) -> np.ndarray:
        """The Compliance Slope (28/29) of each servo for stiffness ``factors`` (the servo's
        stiffness ``τ_s / (slope · rad per tick)`` falls with the slope): the configured
        slope / factor, rounded, 1..254, else :class:`ServoError` naming the servos."""
        f = stiffness_factors(factors, self.n)
        return stiffness_registers(
            self.settings.compliance_slope, f, self.labels, "compliance slope",
            SETTING_REGISTERS["compliance_slope"][2], True,
        )  # fmt: skip

    def stiffness_bytes(self, register: int) -> list[int]:
        """The bytes written at :attr:`stiffness_address` for one servo: CW and CCW slope."""
        return [register, register]

    def set_stiffness(self, factors: float | Sequence[float] | np.ndarray) -> None:
        """Each servo's stiffness ``factors`` × the configured one (:meth:`ServoBus.
        set_stiffness`): its registers (:meth:`stiffness_registers`) in one SYNC_WRITE (no
        reply, as the goals; RAM registers, so :meth:`configure` restores the
        configuration at the next start)."""
        self._require_open()
        f = stiffness_factors(factors, self.n)
        regs = self.stiffness_registers(f)
        sync = self._sync_stiffness
        sync.clearParam()
        for sid, reg in zip(self.ids, regs, strict=True):
            sync.addParam(sid, self.stiffness_bytes(int(reg)))
        if self._comm(sync.txPacket()) != COMM_OK:
            raise ServoError(f"{self.port_name}: SYNC_WRITE of the stiffness failed")
        self.stiffness = f

    def set_speed(self, rad_per_s: float) -> None:
        """Moving Speed (32) of every servo in one SYNC_WRITE."""
        self._require_open()
        self._sync_write_all(self._sync_speed, word(speed_register(rad_per_s)), "moving speed")

    def _comm(self, result: int) -> str:
        return COMM_OK if result == _sdk().COMM_SUCCESS else COMM_TX_FAIL

    def write_goals(self, cmds: np.ndarray) -> str:
        """All goal positions in one SYNC_WRITE to address 30 (checked against the limits)."""
        self._require_open()
        cmds = self.check_goals(cmds)
        sync = self._sync_goal
        sync.clearParam()
        for i, (sid, tick) in enumerate(zip(self.ids, cmds, strict=True)):
            if i not in self.excluded:  # a faulted servo gets no goal during the crouch
                sync.addParam(sid, word(int(tick)))
        return self._comm(sync.txPacket())

    # ------------------------------------------------------------------ feedback
    def read_positions(self, indices: Sequence[int] | None = None) -> list[ServoStatus]:
        """One matched 2-byte READ of Present Position (36) per servo."""
        self._require_open()
        out = []
        for i in range(self.n) if indices is None else indices:
            comm, error, data = self.read(i, ADDR_PRESENT_POSITION, 2)
            if comm != COMM_OK:
                out.append(ServoStatus(i, comm))
                continue
            pos = float(data[0] | (data[1] << 8))
            out.append(ServoStatus(i, comm, fault_names(error), error, pos))
        return out

    def poll(self, index: int) -> ServoStatus:
        """One matched 8-byte READ at 36: position, speed, load, voltage, temperature and
        the error bits."""
        self._require_open()
        comm, error, data = self.read(index, ADDR_PRESENT_POSITION, 8)
        if comm != COMM_OK:
            return ServoStatus(index, comm)
        load = (data[4] | (data[5] << 8)) & 0x7FF
        load_frac = (load & 0x3FF) / 1023.0 * (-1.0 if load & 0x400 else 1.0)
        return ServoStatus(
            index,
            COMM_OK,
            fault_names(error),
            error,
            position=float(data[0] | (data[1] << 8)),
            voltage=data[6] / 10.0,
            temperature=float(data[7]),
            load=load_frac,
        )

    def budget(self, read_positions: bool) -> BusBudget:
        return self.bus_budget(self.n, self.baud, read_positions)

    def tick_budget(self, read_positions: bool, polls_per_tick: int) -> BusBudget:
        return self.bus_budget(self.n, self.baud, read_positions, polls_per_tick)

    def exchange_lines(self) -> list[str]:
        return self.log.lines()
