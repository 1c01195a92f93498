"""Dynamixel Protocol 1.0 and the AX-12A, without a port: the control table's addresses
(bioloid-facts §4.2), instructions and error bits, packets (bioloid-facts §4.3)::

    instruction  FF FF ID LEN INST P1..Pn CHK     LEN = n + 2
    status       FF FF ID LEN ERR  P1..Pn CHK     CHK = ~(ID + LEN + INST|ERR + P1..Pn) & 0xFF

their framing (:func:`take_packet`) and the rotating form of a READ (:func:`read_variant`),
speeds, baud rates, the angle <-> tick codec and the bus budget of a tick. The bus on
dynamixel-sdk is :class:`wbc.servos.dynamixel.DynamixelBus`; the pty emulator speaks the same
protocol (:mod:`wbc.servos.emulator`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from ..exceptions import ServoError
from ..servo_map import RAD_PER_TICK, ServoMap
from .bus import BudgetItem, BusBudget, Codec

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
ADDR_CW_COMPLIANCE_MARGIN = 26
ADDR_CCW_COMPLIANCE_MARGIN = 27
ADDR_CW_COMPLIANCE_SLOPE = 28
ADDR_CCW_COMPLIANCE_SLOPE = 29
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
    """Angle <-> tick codec of a servo map (either protocol): ``tick = zero_tick + sign · q /
    rad_per_tick`` within the map's tick range."""
    return Codec(
        offset=servo_map.zero_ticks.copy(),
        scale=servo_map.signs / servo_map.rad_per_tick,
        cmd_min=servo_map.tick_min,
        cmd_max=servo_map.tick_max,
        unit="tick",
    )


def ax_budget(
    n_servos: int,
    baud: int,
    read_positions: bool,
    polls_per_tick: int = 1,
    return_delay_s: float = AX12_RESPONSE_S,
) -> BusBudget:
    """Bus budget of one tick: a SYNC_WRITE of all goals plus either one READ of present
    position per servo (``read_positions``) or ``polls_per_tick`` health READs (position,
    speed, load, voltage, temperature: addresses 36..43). READs are counted in their longest
    form (:func:`read_variant`: up to 2 more bytes)."""
    items = [BudgetItem("SYNC_WRITE goal position", 1, sync_write_length(n_servos, 2), 0, 0)]
    if read_positions:
        items.append(BudgetItem("READ present position (2-4 B)", n_servos, 8, 6 + 4, 1))
    elif polls_per_tick:
        items.append(BudgetItem("READ health poll (8-10 B)", polls_per_tick, 8, 6 + 10, 1))
    name = "write + read" if read_positions else "write-only"
    return BusBudget(name, baud, tuple(items), return_delay_s=return_delay_s)


def take_packet(buf: bytearray) -> bytes | None:
    """Take the first complete Protocol 1.0 packet (status or instruction: the framing is the
    same) off ``buf``; bytes before a header are dropped; None while incomplete. The checksum
    is not checked here."""
    while True:
        i = buf.find(b"\xff\xff")
        if i < 0:
            del buf[: max(0, len(buf) - 1)]
            return None
        del buf[:i]
        if len(buf) < 4:
            return None
        if buf[2] == 0xFF:  # a third 0xFF: slide by one
            del buf[:1]
            continue
        length = buf[3]
        if length < 2:
            del buf[:2]
            continue
        if len(buf) < length + 4:
            return None
        pkt = bytes(buf[: length + 4])
        del buf[: length + 4]
        return pkt


def read_variant(address: int, length: int, k: int) -> tuple[int, int]:
    """The ``k``-th (mod 3) form of a READ of ``length`` bytes at ``address``: the same bytes
    preceded by 0, 1 or 2 lower registers. Consecutive reads of one servo use consecutive
    forms, so a late reply to the previous (or the one before) has the wrong length and can
    never be taken as the answer to the current request (Protocol 1.0 has no sequence number)."""
    extra = min(k % 3, address)
    return address - extra, length + extra
