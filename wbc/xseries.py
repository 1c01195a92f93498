"""Dynamixel X-series (Protocol 2.0) control table and servo settings: one definition shared
by the servo layer (:mod:`wbc.servos.protocol2`, which writes the settings at start-up) and the
simulator's XM430 law (:mod:`wbc.sim.xm430`, which derives its gains and limits from them).

Sources: ROBOTIS e-Manual, XM430-W350 control table (also ROBOTIS-Framework's
``XM-430.device``): positions are 0..4095 ticks over 360° (2048 = the centre) in position
control mode; gains, profile and current registers in the units below.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .exceptions import ServoMapError

TICKS_PER_REV = 4096
X_TICK_MIN = 0
X_TICK_MAX = 4095
X_CENTER_TICK = 2048
X_RAD_PER_TICK = 2.0 * math.pi / TICKS_PER_REV

# ---------------------------------------------------------------- control table (EEPROM)
ADDR_MODEL_NUMBER = 0  # 2 bytes; XM430-W350: 1020
ADDR_RETURN_DELAY = 9  # 1 byte, 2 µs units
ADDR_OPERATING_MODE = 11  # 1 byte: 3 = position control (0..4095)
ADDR_TEMPERATURE_LIMIT = 31
ADDR_CURRENT_LIMIT = 38  # 2 bytes, 2.69 mA units, 0..1193
ADDR_MAX_POSITION_LIMIT = 48  # 4 bytes
ADDR_MIN_POSITION_LIMIT = 52  # 4 bytes
ADDR_SHUTDOWN = 63  # 1 byte: the hardware errors that cut torque
# ---------------------------------------------------------------- control table (RAM)
ADDR_TORQUE_ENABLE = 64
ADDR_STATUS_RETURN_LEVEL = 68
ADDR_HARDWARE_ERROR = 70  # 1 byte
ADDR_POSITION_D_GAIN = 80  # 2 bytes each: D 80, I 82, P 84
ADDR_POSITION_I_GAIN = 82
ADDR_POSITION_P_GAIN = 84
ADDR_BUS_WATCHDOG = 98  # 1 byte, 20 ms units; 0 = off. Torque off when no packet comes in time
ADDR_PROFILE_ACCELERATION = 108  # 4 bytes, 214.577 rev/min² units; 0 = infinite
ADDR_PROFILE_VELOCITY = 112  # 4 bytes, 0.229 rev/min units; 0 = infinite
ADDR_GOAL_POSITION = 116  # 4 bytes
ADDR_PRESENT_CURRENT = 126  # 2 bytes signed, 2.69 mA units
ADDR_PRESENT_VELOCITY = 128  # 4 bytes signed, 0.229 rev/min
ADDR_PRESENT_POSITION = 132  # 4 bytes signed
ADDR_PRESENT_VOLTAGE = 144  # 2 bytes, 0.1 V
ADDR_PRESENT_TEMPERATURE = 146  # 1 byte, °C
CONTROL_TABLE_SIZE = 147

XM430_W350_MODEL = 1020
OPERATING_MODE_POSITION = 3
BUS_WATCHDOG_UNIT_S = 0.020
RPM_PER_VELOCITY_UNIT = 0.229
ACCEL_UNIT_RPM2 = 214.577
CURRENT_UNIT_A = 2.69e-3

# Hardware Error Status (70) bits
HW_INPUT_VOLTAGE = 0x01
HW_OVERHEATING = 0x04
HW_ENCODER = 0x08
HW_ELECTRICAL_SHOCK = 0x10
HW_OVERLOAD = 0x20
HW_ERROR_NAMES: dict[int, str] = {
    HW_INPUT_VOLTAGE: "input_voltage",
    HW_OVERHEATING: "overheating",
    HW_ENCODER: "encoder",
    HW_ELECTRICAL_SHOCK: "electrical_shock",
    HW_OVERLOAD: "overload",
}
#: factory Shutdown (63): overheating + electrical shock + overload
SHUTDOWN_DEFAULT = HW_OVERHEATING | HW_ELECTRICAL_SHOCK | HW_OVERLOAD

#: registers written from :class:`XSettings`: name -> (address, size, allowed range, default).
#: Defaults are the XM430-W350's factory values (e-Manual).
X_SETTING_REGISTERS: dict[str, tuple[int, int, tuple[int, int], int]] = {
    "position_p_gain": (ADDR_POSITION_P_GAIN, 2, (0, 16383), 800),
    "position_i_gain": (ADDR_POSITION_I_GAIN, 2, (0, 16383), 0),
    "position_d_gain": (ADDR_POSITION_D_GAIN, 2, (0, 16383), 0),
    "current_limit": (ADDR_CURRENT_LIMIT, 2, (0, 1193), 1193),
    "profile_acceleration": (ADDR_PROFILE_ACCELERATION, 4, (0, 32767), 0),
}


def hw_fault_names(error: int) -> tuple[str, ...]:
    """Names of the bits set in a Hardware Error Status value."""
    return tuple(name for bit, name in HW_ERROR_NAMES.items() if error & bit)


def profile_velocity_register(rad_per_s: float) -> int:
    """Profile Velocity (112) for a joint speed: 0.229 rev/min per unit, at least 1."""
    if not math.isfinite(rad_per_s) or rad_per_s <= 0:
        raise ServoMapError(f"profile velocity must be a positive finite rad/s, got {rad_per_s}")
    rpm = rad_per_s * 60.0 / (2.0 * math.pi)
    return int(min(32767, max(1, round(rpm / RPM_PER_VELOCITY_UNIT))))


def profile_velocity_rad_s(register: int) -> float:
    """Joint speed (rad/s) of a Profile Velocity value (0: unlimited)."""
    if register <= 0:
        return math.inf
    return register * RPM_PER_VELOCITY_UNIT * 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class XSettings:
    """Per-joint X-series settings (model joint order), register units: position P/I/D gains
    (``K_P = P/128``, ``K_I = I/65536``, ``K_D = D/16`` in PWM per tick, e-Manual), current
    limit (2.69 mA units), profile acceleration (214.577 rev/min²; 0 = none) and the Shutdown
    bit mask. The profile velocity is the deployment's speed cap (``set_speed``)."""

    position_p_gain: np.ndarray
    position_i_gain: np.ndarray
    position_d_gain: np.ndarray
    current_limit: np.ndarray
    profile_acceleration: np.ndarray
    shutdown: int = SHUTDOWN_DEFAULT

    @classmethod
    def defaults(cls, n: int) -> XSettings:
        """The XM430-W350 factory values for ``n`` joints."""
        return cls(*(np.full(n, v[3], dtype=int) for v in X_SETTING_REGISTERS.values()))

    @classmethod
    def from_table(
        cls, table: Mapping, joint_names: Sequence[str], source: str = "<memory>"
    ) -> XSettings:
        """Parse a ``[settings]`` table: global values plus ``[settings.joints]`` overrides;
        an unknown key is an error naming it."""
        values, shutdown = settings_table(
            table, joint_names, X_SETTING_REGISTERS, ("shutdown", SHUTDOWN_DEFAULT, 255), source
        )
        return cls(**values, shutdown=shutdown)


def checked_register(value, lo: int, hi: int, label: str) -> int:
    """``value`` if an integer in ``lo..hi``, else :class:`ServoMapError` naming ``label``."""
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ServoMapError(f"{label} = {value!r}: must be an integer in {lo}..{hi}")
    return value


def settings_table(
    table: Mapping,
    joint_names: Sequence[str],
    registers: Mapping[str, tuple],
    byte: tuple[str, int, int],
    source: str,
) -> tuple[dict[str, np.ndarray], int]:
    """A servo map's ``[settings]`` table: the per-joint ``registers``
    (:func:`per_joint_registers`) and one global byte ``(key, default, max)`` (the shutdown
    bits); an unknown key is an error naming it."""
    where = f"servo map {source}: [settings]"
    key, default, hi = byte
    known = set(registers) | {key, "joints"}
    extra = sorted(set(table) - known)
    if extra:
        raise ServoMapError(f"{where} has unknown keys {extra}; allowed: {sorted(known)}")
    values = per_joint_registers(table, joint_names, registers, where)
    return values, checked_register(table.get(key, default), 0, hi, f"{where} {key}")


def per_joint_registers(
    table: Mapping,
    joint_names: Sequence[str],
    registers: Mapping[str, tuple],
    where: str,
) -> dict[str, np.ndarray]:
    """Register values per joint from a ``[settings]`` table: each key of ``registers``
    (``(address, size, (lo, hi), default)``) at its global value or default, then the
    ``[settings.joints]`` overrides; a bad value, joint or key is an error naming it
    (an override as ``<where>.joints.<joint>.<key>``)."""
    n = len(joint_names)
    values = {}
    for key, (_, _, (lo, hi), default) in registers.items():
        values[key] = np.full(
            n, checked_register(table.get(key, default), lo, hi, f"{where} {key}")
        )
    index = {j: i for i, j in enumerate(joint_names)}
    overrides = table.get("joints", {})
    if not isinstance(overrides, Mapping):
        raise ServoMapError(f"{where}.joints must be a table of joint = {{ key = value }}")
    for joint, entry in overrides.items():
        if joint not in index:
            raise ServoMapError(f"{where}.joints: unknown joint {joint!r}")
        if not isinstance(entry, Mapping):
            raise ServoMapError(f"{where}.joints.{joint} must be a table")
        for key, v in entry.items():
            if key not in registers:
                raise ServoMapError(
                    f"{where}.joints.{joint}: unknown key {key!r}; allowed: {sorted(registers)}"
                )
            lo, hi = registers[key][2]
            values[key][index[joint]] = checked_register(v, lo, hi, f"{where}.joints.{joint}.{key}")
    return values
