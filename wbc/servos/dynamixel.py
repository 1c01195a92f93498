"""AX-12A servos over Dynamixel Protocol 1.0, on ROBOTIS dynamixel-sdk.

Addresses are the AX-12A control table (bioloid-facts §4.2), *not* the X-series addresses of
the SDK's Protocol-1.0 examples. Packets (bioloid-facts §4.3)::

    instruction  FF FF ID LEN INST P1..Pn CHK     LEN = n + 2
    status       FF FF ID LEN ERR  P1..Pn CHK     CHK = ~(ID + LEN + INST|ERR + P1..Pn) & 0xFF

All goals go out in one SYNC_WRITE to address 30 (no status reply). The AX series has no
sync or bulk read: feedback is one READ per servo, which dominates the bus budget.

SDK traps handled here: ``PortHandler`` hard-codes a 16 ms USB latency (packet timeout
``tx + 2·16 + 2`` ms), so :class:`DynamixelBus` uses a subclass whose latency is a parameter
(set the FTDI adapter's latency timer to 1 ms to match); a Ctrl-C inside an SDK call leaves
``port.is_using`` set, which makes every later call fail with COMM_PORT_BUSY, so the safe
stop resets it before sending torque-off.
"""

from __future__ import annotations

import math
import os
import select
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..exceptions import ServoError
from ..servo_map import RAD_PER_TICK, TICK_MAX, TICK_MIN, ServoMap
from .bus import (
    COMM_CORRUPT,
    COMM_OK,
    COMM_TIMEOUT,
    COMM_TX_FAIL,
    BudgetItem,
    BusBudget,
    Codec,
    ServoBus,
    ServoStatus,
)

# ---------------------------------------------------------------- AX-12A control table
ADDR_MODEL_NUMBER = 0
ADDR_FIRMWARE = 2
ADDR_ID = 3
ADDR_BAUD = 4
ADDR_RETURN_DELAY = 5
ADDR_CW_ANGLE_LIMIT = 6
ADDR_CCW_ANGLE_LIMIT = 8
ADDR_TEMPERATURE_LIMIT = 11
ADDR_MIN_VOLTAGE = 12
ADDR_MAX_VOLTAGE = 13
ADDR_MAX_TORQUE = 14
ADDR_STATUS_RETURN_LEVEL = 16
ADDR_ALARM_LED = 17
ADDR_SHUTDOWN = 18
ADDR_TORQUE_ENABLE = 24
ADDR_LED = 25
ADDR_GOAL_POSITION = 30
ADDR_MOVING_SPEED = 32
ADDR_TORQUE_LIMIT = 34
ADDR_PRESENT_POSITION = 36
ADDR_PRESENT_SPEED = 38
ADDR_PRESENT_LOAD = 40
ADDR_PRESENT_VOLTAGE = 42
ADDR_PRESENT_TEMPERATURE = 43
ADDR_REGISTERED = 44
ADDR_MOVING = 46
ADDR_LOCK = 47
ADDR_PUNCH = 48
CONTROL_TABLE_SIZE = 50

AX12_MODEL_NUMBER = 12
BROADCAST_ID = 0xFE

# ---------------------------------------------------------------- Protocol 1.0
INST_PING = 0x01
INST_READ = 0x02
INST_WRITE = 0x03
INST_REG_WRITE = 0x04
INST_ACTION = 0x05
INST_RESET = 0x06
INST_SYNC_WRITE = 0x83

ERR_INPUT_VOLTAGE = 0x01
ERR_ANGLE_LIMIT = 0x02
ERR_OVERHEATING = 0x04
ERR_RANGE = 0x08
ERR_CHECKSUM = 0x10
ERR_OVERLOAD = 0x20
ERR_INSTRUCTION = 0x40
ERROR_NAMES: dict[int, str] = {
    ERR_INPUT_VOLTAGE: "input_voltage",
    ERR_ANGLE_LIMIT: "angle_limit",
    ERR_OVERHEATING: "overheating",
    ERR_RANGE: "range",
    ERR_CHECKSUM: "checksum",
    ERR_OVERLOAD: "overload",
    ERR_INSTRUCTION: "instruction",
}

# ---------------------------------------------------------------- speeds
RPM_PER_SPEED_UNIT = 0.111  # Moving Speed (32) unit in joint mode
AX12_NO_LOAD_RPM = 59.0  # at 12 V
AX12_MAX_SPEED = AX12_NO_LOAD_RPM * 2.0 * math.pi / 60.0  # rad/s
# The servo's own processing delay before a status packet at Return Delay Time 0 (estimate
# from peers.md §7, USB2AX notes); used by the bus budget and by the emulator's timing model.
AX12_RESPONSE_S = 22e-6

# Baud rates the SDK's PortHandler accepts.
SDK_BAUDS = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600)
SDK_BAUDS += (1000000, 1152000, 2000000, 2500000, 3000000, 3500000, 4000000)


def checksum(body: Sequence[int] | bytes) -> int:
    """Protocol 1.0 checksum of ID, LENGTH, INSTRUCTION/ERROR and parameters."""
    return ~sum(body) & 0xFF


def instruction_packet(servo_id: int, instruction: int, params: Sequence[int] = ()) -> bytes:
    """``FF FF ID LEN INST P.. CHK``."""
    body = bytes([servo_id, len(params) + 2, instruction, *params])
    return b"\xff\xff" + body + bytes([checksum(body)])


def status_packet(servo_id: int, error: int, params: Sequence[int] = ()) -> bytes:
    """``FF FF ID LEN ERR P.. CHK``."""
    body = bytes([servo_id, len(params) + 2, error, *params])
    return b"\xff\xff" + body + bytes([checksum(body)])


def sync_write_packet(address: int, data_length: int, data: Mapping[int, Sequence[int]]) -> bytes:
    """SYNC_WRITE to broadcast: ``FF FF FE LEN 83 addr L [id d1..dL]*N CHK``."""
    params = [address, data_length]
    for servo_id, values in data.items():
        if len(values) != data_length:
            raise ServoError(
                f"sync write: id {servo_id} has {len(values)} bytes, not {data_length}"
            )
        params += [servo_id, *values]
    return instruction_packet(BROADCAST_ID, INST_SYNC_WRITE, params)


def sync_write_length(n_servos: int, data_length: int) -> int:
    """Bytes of a SYNC_WRITE of ``n_servos`` × ``data_length`` bytes: 8 + n·(1 + L)."""
    return 8 + n_servos * (1 + data_length)


def word(value: int) -> list[int]:
    """Little-endian two bytes."""
    return [value & 0xFF, (value >> 8) & 0xFF]


def fault_names(error: int) -> tuple[str, ...]:
    """Names of the error bits set in a status packet's error byte."""
    return tuple(name for bit, name in ERROR_NAMES.items() if error & bit)


def ax_baud_register(baud: int) -> int | None:
    """The Baud Rate register value n with 2e6/(n+1) within 3 % of ``baud``, else None."""
    if baud <= 0:
        return None
    n = round(2_000_000 / baud) - 1
    if n < 1 or n > 254:
        return None
    actual = 2_000_000 / (n + 1)
    return n if abs(actual - baud) / baud <= 0.03 else None


def check_baud(baud: int) -> None:
    """Raise :class:`ServoError` unless both the AX-12A and the SDK's port support ``baud``."""
    if ax_baud_register(baud) is None:
        raise ServoError(
            f"baud rate {baud} is not an AX-12A rate (2000000/(n+1), n = 1..254, e.g. 1000000, "
            "500000, 115200, 57600)"
        )
    if baud not in SDK_BAUDS:
        raise ServoError(
            f"baud rate {baud} is not supported by dynamixel-sdk's PortHandler; use one of "
            f"{', '.join(map(str, SDK_BAUDS))}"
        )


def speed_register(rad_per_s: float) -> int:
    """Moving Speed (32) value for a joint speed: 0.111 rpm per unit, 1..1023 (0 = no limit)."""
    if not math.isfinite(rad_per_s) or rad_per_s <= 0:
        raise ServoError(f"moving speed must be a positive finite rad/s, got {rad_per_s}")
    rpm = rad_per_s * 60.0 / (2.0 * math.pi)
    return int(min(1023, max(1, round(rpm / RPM_PER_SPEED_UNIT))))


def speed_ticks_per_s(register: int) -> float:
    """Ticks per second of a Moving Speed value (0 = the no-load speed)."""
    rpm = AX12_NO_LOAD_RPM if register == 0 else min(register * RPM_PER_SPEED_UNIT, 114.0)
    rpm = min(rpm, AX12_NO_LOAD_RPM)
    return rpm * 2.0 * math.pi / 60.0 / RAD_PER_TICK


def ax_codec(servo_map: ServoMap) -> Codec:
    """Angle <-> tick codec of a servo map: ``tick = zero_tick + sign · q / RAD_PER_TICK``."""
    return Codec(
        offset=servo_map.zero_ticks.copy(),
        scale=servo_map.signs / RAD_PER_TICK,
        cmd_min=TICK_MIN,
        cmd_max=TICK_MAX,
        unit="tick",
    )


def ax_budget(
    n_servos: int,
    baud: int,
    read_positions: bool,
    polls_per_tick: int = 1,
    return_delay_s: float = AX12_RESPONSE_S,
) -> BusBudget:
    """Bus budget of one tick: a SYNC_WRITE of all goals plus either one 2-byte READ of present
    position per servo (``read_positions``) or ``polls_per_tick`` 8-byte health READs
    (position, speed, load, voltage, temperature: addresses 36..43)."""
    items = [BudgetItem("SYNC_WRITE goal position", 1, sync_write_length(n_servos, 2), 0, 0)]
    if read_positions:
        items.append(BudgetItem("READ present position (2 B)", n_servos, 8, 6 + 2, 1))
    elif polls_per_tick:
        items.append(BudgetItem("READ health poll (8 B)", polls_per_tick, 8, 6 + 8, 1))
    name = "write + read" if read_positions else "write-only"
    return BusBudget(name, baud, tuple(items), return_delay_s=return_delay_s)


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


class DynamixelBus(ServoBus):
    """The robot's AX-12A servos on one Protocol 1.0 bus, in model joint order."""

    name = "dynamixel"
    can_read = True
    servo_speed = AX12_MAX_SPEED

    def __init__(
        self,
        port: str,
        servo_map: ServoMap,
        baud: int = 1_000_000,
        latency_timer_ms: float = 1.0,
        torque_limit: int = 1023,
        poll_wait_s: float = 1e-3,
    ) -> None:
        labels = [
            f"id {int(i)} ({j})" for i, j in zip(servo_map.ids, servo_map.joint_names, strict=True)
        ]
        super().__init__(ax_codec(servo_map), labels)
        check_baud(baud)
        if not 0 <= torque_limit <= 1023:
            raise ServoError(f"torque limit must be 0..1023, got {torque_limit}")
        self.port_name = port
        self.servo_map = servo_map
        self.baud = baud
        self.ids = [int(i) for i in servo_map.ids]
        self.latency_timer_ms = latency_timer_ms
        self.turnaround_s = latency_timer_ms * 1e-3
        self.torque_limit = torque_limit
        self.ping_attempts = 2
        self.poll_wait_s = poll_wait_s  # 0: the SDK's original busy-wait receive
        self.warnings: list[str] = []
        self.port = None
        self.ph = None
        self._sync_goal = None
        self._sync_speed = None

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
            self.turnaround_s = latency * 1e-3
            self.warnings.append(
                f"{self.port_name}: USB latency timer is {latency} ms (each READ takes about "
                f"{latency} ms); set it to 1 with 'echo 1 > /sys/bus/usb-serial/devices/"
                f"{Path(os.path.realpath(self.port_name)).name}/latency_timer'"
            )
        try:
            ok = port.setBaudRate(self.baud)  # opens the port (pyserial)
        except Exception as exc:  # serial.SerialException, OSError
            raise ServoError(f"cannot open port {self.port_name!r}: {exc}") from exc
        if not ok:
            raise ServoError(f"port {self.port_name!r} refused baud rate {self.baud}")
        self.port = port
        self.ph = sdk.Protocol1PacketHandler()
        self._sync_goal = sdk.GroupSyncWrite(port, self.ph, ADDR_GOAL_POSITION, 2)
        self._sync_speed = sdk.GroupSyncWrite(port, self.ph, ADDR_MOVING_SPEED, 2)

    def close(self) -> None:
        if self.port is not None and self.port.is_open:
            self.port.closePort()

    def reset(self) -> None:
        """Recover the SDK port after an interrupted call (``is_using`` stuck at True)."""
        if self.port is not None:
            self.port.is_using = False
            try:
                self.port.clearPort()
            except Exception:
                pass

    # ------------------------------------------------------------------ helpers
    def _comm(self, result: int) -> str:
        sdk = _sdk()
        if result == sdk.COMM_SUCCESS:
            return COMM_OK
        if result == sdk.COMM_RX_TIMEOUT:
            return COMM_TIMEOUT
        if result == sdk.COMM_RX_CORRUPT:
            return COMM_CORRUPT
        return COMM_TX_FAIL

    def _label(self, i: int) -> str:
        return self.labels[i]

    def _expect(self, i: int, result: int, error: int, what: str) -> None:
        """Raise naming the servo unless a start-up exchange succeeded without error bits."""
        comm = self._comm(result)
        if comm != COMM_OK:
            raise ServoError(f"{self._label(i)}: {what}: {comm} ({self.ph.getTxRxResult(result)})")
        if error:
            raise ServoError(
                f"{self._label(i)}: {what}: status error 0x{error:02X} {list(fault_names(error))}"
            )

    def _require_open(self) -> None:
        if self.port is None:
            raise ServoError(f"{self.name}: port {self.port_name!r} is not open")

    # ------------------------------------------------------------------ start-up
    def _ping(self, servo_id: int) -> tuple[str, int]:
        model, result, _ = self.ph.ping(self.port, servo_id)
        return self._comm(result), model

    def identify(self) -> None:
        """PING every servo and check it is an AX-12A; name the missing/garbled/wrong ones."""
        self._require_open()
        results = {i: self._ping(sid) for i, sid in enumerate(self.ids)}
        if all(comm == COMM_TIMEOUT for comm, _ in results.values()):
            raise ServoError(
                f"no servo answered on {self.port_name} at {self.baud} baud (the servo map says "
                f"{self.servo_map.baudrate}): wrong baud rate, no power, or wrong port"
            )
        for _attempt in range(1, self.ping_attempts):  # one lost reply is not a missing servo
            for i, (comm, _) in list(results.items()):
                if comm != COMM_OK:
                    results[i] = self._ping(self.ids[i])
        missing = [self._label(i) for i, (c, _) in results.items() if c == COMM_TIMEOUT]
        garbled = [
            self._label(i) for i, (c, _) in results.items() if c not in (COMM_OK, COMM_TIMEOUT)
        ]
        wrong = [
            f"{self._label(i)} reports model {model}"
            for i, (c, model) in results.items()
            if c == COMM_OK and model != AX12_MODEL_NUMBER
        ]
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
            problems.append(f"not AX-12A (model {AX12_MODEL_NUMBER}): " + ", ".join(wrong))
        if problems:
            raise ServoError(f"{self.port_name}: " + "; ".join(problems))

    def configure(self) -> None:
        """Torque off; Status Return Level 2, Return Delay 0, angle limits (6/8) from the joint
        limits and the torque limit, each written only if it differs and read back."""
        self._require_open()
        if self.cmd_lo is None or self.cmd_hi is None:
            raise ServoError(f"{self.name}: configure() needs the command limits first")
        self.set_torque(False)
        port, ph = self.port, self.ph
        for i, sid in enumerate(self.ids):
            srl, result, error = ph.read1ByteTxRx(port, sid, ADDR_STATUS_RETURN_LEVEL)
            self._expect(i, result, error, "read status return level")
            if srl != 2:  # without level 2, WRITEs get no status and would look like timeouts
                ph.write1ByteTxOnly(port, sid, ADDR_STATUS_RETURN_LEVEL, 2)
            lo, hi = int(self.cmd_lo[i]), int(self.cmd_hi[i])
            wanted = [0, *word(lo), *word(hi)]
            data, result, error = ph.readTxRx(port, sid, ADDR_RETURN_DELAY, 5)
            self._expect(i, result, error, "read return delay / angle limits")
            if list(data) != wanted:
                result, error = ph.writeTxRx(port, sid, ADDR_RETURN_DELAY, 5, wanted)
                self._expect(i, result, error, "write return delay / angle limits")
                data, result, error = ph.readTxRx(port, sid, ADDR_RETURN_DELAY, 5)
                self._expect(i, result, error, "read back return delay / angle limits")
                if list(data) != wanted:
                    raise ServoError(
                        f"{self._label(i)}: angle limits did not stick: wrote {wanted}, "
                        f"read {list(data)} (EEPROM locked?)"
                    )
            result, error = ph.write2ByteTxRx(port, sid, ADDR_TORQUE_LIMIT, self.torque_limit)
            self._expect(i, result, error, "write torque limit")

    # ------------------------------------------------------------------ motion
    def set_torque(self, enabled: bool) -> None:
        """On: per servo, confirmed. Off: one broadcast WRITE (reaches silent servos too)."""
        self._require_open()
        if not enabled:
            self.reset()
            self.ph.write1ByteTxOnly(self.port, BROADCAST_ID, ADDR_TORQUE_ENABLE, 0)
            return
        for i, sid in enumerate(self.ids):
            result, error = self.ph.write1ByteTxRx(self.port, sid, ADDR_TORQUE_ENABLE, 1)
            self._expect(i, result, error, "torque enable")

    def set_speed(self, rad_per_s: float) -> None:
        """Moving Speed (32) of every servo in one SYNC_WRITE."""
        self._require_open()
        reg = speed_register(rad_per_s)
        sync = self._sync_speed
        sync.clearParam()
        for sid in self.ids:
            sync.addParam(sid, word(reg))
        if self._comm(sync.txPacket()) != COMM_OK:
            raise ServoError(f"{self.port_name}: SYNC_WRITE of the moving speed failed")

    def write_goals(self, cmds: np.ndarray) -> str:
        """All goal positions in one SYNC_WRITE to address 30 (checked against the limits)."""
        self._require_open()
        cmds = self.check_goals(cmds)
        sync = self._sync_goal
        sync.clearParam()
        for sid, tick in zip(self.ids, cmds, strict=True):
            sync.addParam(sid, word(int(tick)))
        return self._comm(sync.txPacket())

    # ------------------------------------------------------------------ feedback
    def read_positions(self, indices: Sequence[int] | None = None) -> list[ServoStatus]:
        """One 2-byte READ of Present Position (36) per servo."""
        self._require_open()
        out = []
        for i in range(self.n) if indices is None else indices:
            value, result, error = self.ph.read2ByteTxRx(
                self.port, self.ids[i], ADDR_PRESENT_POSITION
            )
            comm = self._comm(result)
            out.append(
                ServoStatus(
                    i,
                    comm,
                    fault_names(error) if comm == COMM_OK else (),
                    error if comm == COMM_OK else 0,
                    float(value) if comm == COMM_OK else None,
                )
            )
        return out

    def poll(self, index: int) -> ServoStatus:
        """One 8-byte READ at 36: position, speed, load, voltage, temperature and error bits."""
        self._require_open()
        data, result, error = self.ph.readTxRx(self.port, self.ids[index], ADDR_PRESENT_POSITION, 8)
        comm = self._comm(result)
        if comm != COMM_OK or len(data) != 8:
            return ServoStatus(index, comm if comm != COMM_OK else COMM_CORRUPT)
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
        return ax_budget(self.n, self.baud, read_positions)
