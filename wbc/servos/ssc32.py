"""Lynxmotion SSC-32 backend: hobby PWM servos driven by ASCII commands (Kokone thesis).

One line moves a group of channels together (kokone-thesis.md §1.4)::

    #<ch>P<pw>#<ch>P<pw>...T<time>\\r      ch 0..31, pw 500..2500 µs, time in ms (<= 65535)

at 115200 baud (8N1). ``#<ch>L`` drives a channel's output low (no pulses: the servo goes
limp), which is our torque-off. The joint <-> channel map is a TOML table::

    [joints]
    <joint name> = { channel = 0, sign = 1, center_us = 1500, us_per_deg = 13.333 }

``center_us`` is the pulse at q = 0 (default 1500); the scale is ``us_per_deg`` or
``us_per_rad`` (default Kokone's 13.33 µs/deg = 0.075 deg/µs); ``[bus] baudrate`` (default
115200) and ``[bus] xonxoff`` (default true: the port is opened with XON/XOFF software flow
control, Kokone thesis Table 3.2). ``robots/kokone/ssc32.toml`` is the robot's own map.
The board gives no position feedback (``can_read = False``): soft start cannot begin at the
servos' real positions; the SSC-32 also moves a channel's first command at full speed.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import ServoError, ServoMapError
from ..paths import read_toml
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

PULSE_MIN = 500
PULSE_MAX = 2500
PULSE_CENTER = 1500
SSC32_BAUDS = (2400, 9600, 38400, 115200)
KOKONE_US_PER_DEG = 1.0 / 0.075  # 13.33 µs per degree (kokone-thesis.md §4.2)
BMS380_SPEED = math.radians(60.0) / 0.16  # 0.16 s/60 deg at 4.8 V (kokone-thesis.md Table 3.1)
MAX_CHANNEL = 31


@dataclass(frozen=True)
class Ssc32Channel:
    """One joint on the board: channel, sign, pulse at q = 0, µs per degree."""

    joint: str
    channel: int
    sign: int = 1
    center_us: float = PULSE_CENTER
    us_per_deg: float = KOKONE_US_PER_DEG


class Ssc32Map:
    """Joint <-> SSC-32 channel map in model joint order."""

    def __init__(self, channels: Sequence[Ssc32Channel], source: str = "<memory>") -> None:
        self.channels = tuple(channels)
        self.source = source
        self.baudrate = 115200
        #: software flow control (XON/XOFF), as Kokone's port is set up (thesis Table 3.2); the
        #: ASCII commands never contain 0x11/0x13, so it costs nothing when the board sends none
        self.xonxoff = True
        seen: dict[int, str] = {}
        for c in self.channels:
            where = f"{source}: joint {c.joint!r}"
            if isinstance(c.channel, bool) or not isinstance(c.channel, int):
                raise ServoMapError(f"{where}: channel must be an integer, got {c.channel!r}")
            if not 0 <= c.channel <= MAX_CHANNEL:
                raise ServoMapError(f"{where}: channel {c.channel} outside 0..{MAX_CHANNEL}")
            if c.channel in seen:
                raise ServoMapError(
                    f"{where}: duplicate channel {c.channel} (also {seen[c.channel]!r})"
                )
            seen[c.channel] = c.joint
            if c.sign not in (1, -1):
                raise ServoMapError(f"{where}: sign must be 1 or -1, got {c.sign!r}")
            if not PULSE_MIN <= c.center_us <= PULSE_MAX:
                raise ServoMapError(
                    f"{where}: center_us {c.center_us} outside {PULSE_MIN}..{PULSE_MAX}"
                )
            if not (math.isfinite(c.us_per_deg) and c.us_per_deg > 0):
                raise ServoMapError(f"{where}: us_per_deg must be positive, got {c.us_per_deg}")

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(c.joint for c in self.channels)

    @property
    def channel_numbers(self) -> list[int]:
        return [c.channel for c in self.channels]

    @classmethod
    def default(cls, joint_names: Sequence[str], signs: Sequence[int] | None = None) -> Ssc32Map:
        """Channel = model joint index, centre 1500 µs, Kokone's 13.33 µs/deg."""
        signs = [1] * len(joint_names) if signs is None else [int(s) for s in signs]
        return cls(
            [
                Ssc32Channel(j, i, s)
                for i, (j, s) in enumerate(zip(joint_names, signs, strict=True))
            ],
            source="default SSC-32 map",
        )

    @classmethod
    def from_file(cls, path: str | Path, joint_names: Sequence[str]) -> Ssc32Map:
        """Load a TOML map; every joint of the model must appear, no other."""
        path = Path(path)
        raw = read_toml(path, "SSC-32 map", ServoMapError)
        joints = raw.get("joints", {})
        missing = [j for j in joint_names if j not in joints]
        extra = [j for j in joints if j not in set(joint_names)]
        if missing or extra:
            raise ServoMapError(
                f"SSC-32 map {path} does not match the robot: missing {missing}, unknown {extra}"
            )
        channels = []
        for j in joint_names:
            e = joints[j]
            unknown = set(e) - {"channel", "sign", "center_us", "us_per_deg", "us_per_rad"}
            if unknown or "channel" not in e:
                raise ServoMapError(
                    f"SSC-32 map {path}: joint {j!r} needs 'channel'; unknown {unknown}"
                )
            if "us_per_deg" in e and "us_per_rad" in e:
                raise ServoMapError(
                    f"SSC-32 map {path}: joint {j!r}: give us_per_deg or us_per_rad, not both"
                )
            scale = e.get("us_per_deg", KOKONE_US_PER_DEG)
            if "us_per_rad" in e:
                scale = _number(e["us_per_rad"], f"SSC-32 map {path}: joint {j!r} us_per_rad")
                scale *= math.pi / 180.0
            channels.append(
                Ssc32Channel(
                    j,
                    e["channel"],
                    e.get("sign", 1),
                    _number(e.get("center_us", PULSE_CENTER), f"SSC-32 map {path}: {j} center_us"),
                    _number(scale, f"SSC-32 map {path}: joint {j!r} us_per_deg"),
                )
            )
        baud = raw.get("bus", {}).get("baudrate", 115200)
        if baud not in SSC32_BAUDS:
            raise ServoMapError(f"SSC-32 map {path}: [bus] baudrate {baud!r} not in {SSC32_BAUDS}")
        xonxoff = raw.get("bus", {}).get("xonxoff", True)
        if not isinstance(xonxoff, bool):
            raise ServoMapError(f"SSC-32 map {path}: [bus] xonxoff must be true or false")
        out = cls(channels, source=str(path))
        out.baudrate = baud
        out.xonxoff = xonxoff
        return out

    def range_warnings(self, q_min: np.ndarray, q_max: np.ndarray) -> list[str]:
        """One line per joint whose limits (rad, model order) map partly outside the board's
        500..2500 µs (a centre or scale to recalibrate; the goals are clamped to it)."""
        codec = self.codec()
        a, b = codec.encode_float(np.asarray(q_min)), codec.encode_float(np.asarray(q_max))
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        return [
            f"SSC-32 map {self.source}: {c.joint} (channel {c.channel}) limits map to "
            f"{lo[i]:.0f}..{hi[i]:.0f} µs, beyond {PULSE_MIN}..{PULSE_MAX}: that part of its "
            "range is unreachable"
            for i, c in enumerate(self.channels)
            if lo[i] < PULSE_MIN - 0.5 or hi[i] > PULSE_MAX + 0.5
        ]

    def codec(self) -> Codec:
        """``pulse = center_us + sign · us_per_deg · degrees(q)``, 500..2500 µs."""
        return Codec(
            offset=np.array([c.center_us for c in self.channels], dtype=float),
            scale=np.array([c.sign * c.us_per_deg * 180.0 / math.pi for c in self.channels]),
            cmd_min=PULSE_MIN,
            cmd_max=PULSE_MAX,
            unit="us",
        )


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ServoMapError(f"{where} = {value!r}: must be a number")
    return float(value)


def move_command(
    channels: Sequence[int], pulses: Sequence[int], time_ms: int | None = None
) -> bytes:
    """``#<ch>P<pw>...[T<time>]\\r``; refuses pulses outside 500..2500 µs."""
    if len(channels) != len(pulses) or not channels:
        raise ServoError(f"move command: {len(channels)} channels but {len(pulses)} pulses")
    parts = []
    for ch, pw in zip(channels, pulses, strict=True):
        if not 0 <= int(ch) <= MAX_CHANNEL:
            raise ServoError(f"move command: channel {ch} outside 0..{MAX_CHANNEL}")
        if int(pw) != pw or not PULSE_MIN <= int(pw) <= PULSE_MAX:
            raise ServoError(
                f"move command: channel {ch} pulse {pw} outside {PULSE_MIN}..{PULSE_MAX} µs"
            )
        parts.append(f"#{int(ch)}P{int(pw)}")
    if time_ms is not None:
        if not 0 <= int(time_ms) <= 65535:
            raise ServoError(f"move command: time {time_ms} ms outside 0..65535")
        parts.append(f"T{int(time_ms)}")
    return ("".join(parts) + "\r").encode("ascii")


def off_command(channels: Sequence[int]) -> bytes:
    """``#<ch>L...\\r``: outputs low, no pulses, servos limp."""
    return ("".join(f"#{int(ch)}L" for ch in channels) + "\r").encode("ascii")


class Ssc32Bus(ServoBus):
    """Joints on a Lynxmotion SSC-32 board (write-only; the board answers VER and Q)."""

    name = "ssc32"
    can_read = False
    health_per_servo = False  # Q asks the board
    servo_speed = BMS380_SPEED
    #: what the safety layer cannot check on hobby PWM servos (no feedback wire)
    unchecked = (
        "the servos' positions: no tracking error, no stall or blocked-joint detection",
        "that a servo is connected or powered: only the board answers (VER, Q)",
        "load, temperature or supply voltage: no overload or overheating cut-off",
        "the speed the servos actually reach: the board's T interpolation is open loop",
    )

    def __init__(
        self,
        port: str,
        ssc_map: Ssc32Map,
        baud: int = 115200,
        move_time_ms: int | None = None,
        reply_timeout_s: float = 0.05,
    ) -> None:
        labels = [f"ch {c.channel} ({c.joint})" for c in ssc_map.channels]
        super().__init__(ssc_map.codec(), labels)
        if baud not in SSC32_BAUDS:
            raise ServoError(f"baud rate {baud} is not an SSC-32 rate {SSC32_BAUDS}")
        self.port_name = port
        self.map = ssc_map
        self.baud = baud
        self.move_time_ms = move_time_ms
        self.reply_timeout_s = reply_timeout_s
        self.version = ""
        self.ser = None

    def open(self) -> None:
        if not os.path.exists(self.port_name):
            raise ServoError(f"unknown port {self.port_name!r}: no such device")
        try:
            import serial
        except ModuleNotFoundError as exc:  # pragma: no cover
            raise ServoError("pyserial is not installed (pip install 'wbc[servos]')") from exc

        def opener():
            try:
                return serial.Serial(self.port_name, self.baud, timeout=0, xonxoff=self.map.xonxoff)
            except Exception as exc:
                raise ServoError(f"cannot open port {self.port_name!r}: {exc}") from exc

        # one owner per bus: refused before a byte is sent
        self.ser = self.open_port(self.port_name, opener, lambda s: s.fileno(), lambda s: s.close())

    def close(self) -> None:
        self.unlock_port()
        if self.ser is not None and self.ser.is_open:
            self.ser.close()

    def _query(self, text: bytes, until: bytes | None = None) -> bytes | None:
        self.ser.reset_input_buffer()
        self.ser.write(text)
        deadline = self.reply_clock() + self.reply_timeout_s
        data = b""
        while True:  # the last look comes after the deadline (a stalled host misses no reply)
            now = self.reply_clock()
            data += self.ser.read(64)
            if data and (until is None or until in data):
                return data
            if now >= deadline:
                return None
            time.sleep(0.0002)

    def identify(self) -> None:
        if self.ser is None:
            raise ServoError(f"{self.name}: port {self.port_name!r} is not open")
        reply = self._query(b"VER\r", until=b"\r")
        if reply is None:
            raise ServoError(
                f"no SSC-32 answered VER on {self.port_name} at {self.baud} baud: wrong baud "
                "rate (the board's jumpers), no power, or wrong port"
            )
        self.version = reply.decode("ascii", "replace").strip()

    def configure(self) -> None:
        """Nothing to write: the SSC-32 has no angle limits (software limits only)."""

    def set_torque(self, enabled: bool) -> None:
        """On: nothing (pulses start with the first move). Off: all outputs low."""
        if not enabled and self.ser is not None:
            self.ser.write(off_command(self.map.channel_numbers))
            self._drain(0.2)

    def _drain(self, timeout_s: float) -> None:
        """Wait (bounded) until the output is sent: ``flush()`` (tcdrain) would wait for ever
        on a line held by XOFF, and the safe stop must never hang."""
        deadline = time.monotonic() + timeout_s
        while self.ser.out_waiting and time.monotonic() < deadline:
            time.sleep(0.001)

    def set_speed(self, rad_per_s: float) -> None:
        """The board interpolates each move over ``T`` = one tick; speed is limited in software."""

    def write_goals(self, cmds: np.ndarray) -> str:
        cmds = self.check_goals(cmds)
        line = move_command(self.map.channel_numbers, [int(c) for c in cmds], self.move_time_ms)
        try:
            n = self.ser.write(line)
        except Exception:
            return COMM_TX_FAIL
        return COMM_OK if n == len(line) else COMM_TX_FAIL

    def poll(self, index: int) -> ServoStatus:
        """``Q``: the board answers ``.`` (done) or ``+`` (moving); no per-servo status."""
        reply = self._query(b"Q\r")
        if not reply:
            return ServoStatus(None, COMM_TIMEOUT)
        # anything but '.' or '+' is garbage on the line: a failed exchange (3 in a row trip)
        ok = reply.strip() in (b".", b"+")
        return ServoStatus(None, COMM_OK if ok else COMM_CORRUPT)

    def budget(self, read_positions: bool) -> BusBudget:
        if read_positions:
            raise ServoError("the SSC-32 cannot read servo positions")
        line = move_command(self.map.channel_numbers, [PULSE_CENTER] * self.n, self.move_time_ms)
        items = (
            BudgetItem("move command (ASCII)", 1, len(line), 0, 0),
            BudgetItem("Q liveness query", 1, 2, 1, 1),
        )
        return BusBudget("write-only", self.baud, items)
