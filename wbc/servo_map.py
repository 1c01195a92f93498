"""Servo map: joint angle (rad, our URDF frames) <-> Dynamixel ticks.

``servos.toml`` ``[bus] protocol`` names the servos' protocol and so their tick geometry:
1.0 (the default) is the AX-12A, 0..1023 ticks over 300 degrees (one tick 300/1023 degrees);
2.0 is the X series (e.g. the XM430), 0..4095 ticks over 360 degrees. For each joint the map
holds its Dynamixel ID, a sign and the tick at which our joint angle is zero::

    q = sign * (ticks - zero_tick) * rad_per_tick
    ticks = round(zero_tick + sign * q / rad_per_tick)

Every key of the file is read or refused (one line naming it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .exceptions import ServoMapError
from .paths import read_toml
from .xseries import (
    X_CENTER_TICK,
    X_RAD_PER_TICK,
    X_TICK_MAX,
    X_TICK_MIN,
    XSettings,
    settings_table,
)

TICK_MIN = 0
TICK_MAX = 1023
CENTER_TICK = 512
DEG_PER_TICK = 300.0 / 1023.0
RAD_PER_TICK = math.radians(DEG_PER_TICK)


@dataclass(frozen=True)
class TickGeometry:
    """A protocol's position ticks: range, centre, degrees of the range and radians per tick."""

    protocol: float
    tick_min: int
    tick_max: int
    center_tick: int
    range_deg: float
    ticks_over_range: int
    rad_per_tick: float


#: ``[bus] protocol`` -> its tick geometry (AX-12A: EMAN-AX; X series: the XM430 e-Manual)
GEOMETRIES: dict[float, TickGeometry] = {
    1.0: TickGeometry(1.0, TICK_MIN, TICK_MAX, CENTER_TICK, 300.0, 1023, RAD_PER_TICK),
    2.0: TickGeometry(2.0, X_TICK_MIN, X_TICK_MAX, X_CENTER_TICK, 360.0, 4096, X_RAD_PER_TICK),
}
#: keys of ``[bus]``: the protocol and baud rate are used; the others restate the geometry
#: and must equal the protocol's
BUS_KEYS = ("protocol", "baudrate", "ticks_over_range", "range_deg", "center_tick")
TOP_KEYS = ("bus", "joints", "poses", "settings")


def bus_geometry(bus: Mapping, source: str) -> TickGeometry:
    """The tick geometry of a ``[bus]`` table, checking every key (one line per problem)."""
    where = f"servo map {source}: [bus]"
    if not isinstance(bus, Mapping):
        raise ServoMapError(f"{where} must be a table")
    extra = sorted(set(bus) - set(BUS_KEYS))
    if extra:
        raise ServoMapError(f"{where} has unknown keys {extra}; allowed: {list(BUS_KEYS)}")
    protocol = bus.get("protocol", 1.0)
    if isinstance(protocol, bool) or protocol not in GEOMETRIES:
        raise ServoMapError(
            f"{where} protocol = {protocol!r}: allowed 1.0 (AX-12A) or 2.0 (X series)"
        )
    geo = GEOMETRIES[float(protocol)]
    for key in ("ticks_over_range", "range_deg", "center_tick"):
        if key in bus and bus[key] != getattr(geo, key):
            raise ServoMapError(
                f"{where} {key} = {bus[key]!r}, but protocol {geo.protocol} servos have "
                f"{getattr(geo, key)!r} (the key is optional)"
            )
    baud = bus.get("baudrate", 1_000_000)
    if isinstance(baud, bool) or not isinstance(baud, int) or baud <= 0:
        raise ServoMapError(f"{where} baudrate = {baud!r}: must be a positive integer")
    return geo


#: registers written from :class:`ServoSettings`: name -> (address, size, allowed range, default)
SETTING_REGISTERS: dict[str, tuple[int, int, tuple[int, int], int]] = {
    "compliance_margin": (26, 1, (0, 254), 1),  # and 27 (CCW), same value
    "compliance_slope": (28, 1, (1, 254), 32),  # and 29 (CCW), same value
    "punch": (48, 2, (32, 1023), 32),
    "torque_limit": (34, 2, (0, 1023), 1023),
}
#: error bits that cut torque (register 18); 36 = overload (0x20) + overheating (0x04)
ALARM_SHUTDOWN_DEFAULT = 36


@dataclass(frozen=True)
class ServoSettings:
    """Per-joint servo settings (model joint order): the one config read by the real servo
    layer, which writes them to the control table at start-up, and by the simulator's actuator
    model, which derives stiffness, dead band, punch and torque cap from them.

    All values are register units: ticks for the compliance margin/slope, 0..1023 for punch and
    torque limit (fraction of the maximum × 1023); ``alarm_shutdown`` is a bit mask.
    """

    compliance_margin: np.ndarray
    compliance_slope: np.ndarray
    punch: np.ndarray
    torque_limit: np.ndarray
    alarm_shutdown: int = ALARM_SHUTDOWN_DEFAULT

    @classmethod
    def defaults(cls, n: int) -> ServoSettings:
        """The AX-12A factory values for ``n`` joints."""
        return cls(
            *(np.full(n, SETTING_REGISTERS[k][3], dtype=int) for k in SETTING_REGISTERS),
        )

    @classmethod
    def from_table(
        cls, table: Mapping, joint_names: Sequence[str], source: str = "<memory>"
    ) -> ServoSettings:
        """Parse a ``[settings]`` table: global values plus ``[settings.joints]`` overrides."""
        byte = ("alarm_shutdown", ALARM_SHUTDOWN_DEFAULT, 127)
        values, alarm = settings_table(table, joint_names, SETTING_REGISTERS, byte, source)
        return cls(**values, alarm_shutdown=alarm)


@dataclass(frozen=True)
class ServoSpec:
    """One joint's servo: Dynamixel ID, direction sign and the tick where q = 0."""

    joint: str
    id: int
    sign: int
    zero_tick: float


class ServoMap:
    """Joint <-> servo mapping for a whole robot, in the robot model's joint order."""

    def __init__(
        self,
        specs: Sequence[ServoSpec],
        poses: Mapping[str, Mapping[int, int]] | None = None,
        baudrate: int = 1_000_000,
        source: str = "<memory>",
        settings: ServoSettings | XSettings | None = None,
        protocol: float = 1.0,
    ) -> None:
        self.source = source
        self.specs = tuple(specs)
        self.baudrate = baudrate
        if protocol not in GEOMETRIES:
            raise ServoMapError(f"{source}: protocol {protocol!r}; allowed: 1.0 or 2.0")
        #: the protocol's ticks (range, centre, radians per tick)
        self.geometry = GEOMETRIES[float(protocol)]
        self.protocol = self.geometry.protocol
        self.tick_min, self.tick_max = self.geometry.tick_min, self.geometry.tick_max
        self.rad_per_tick = self.geometry.rad_per_tick
        self._validate()
        self.joint_names = tuple(s.joint for s in self.specs)
        self.ids = np.array([s.id for s in self.specs], dtype=int)
        self.signs = np.array([s.sign for s in self.specs], dtype=float)
        self.zero_ticks = np.array([s.zero_tick for s in self.specs], dtype=float)
        self._by_id = {s.id: i for i, s in enumerate(self.specs)}
        self._by_joint = {s.joint: i for i, s in enumerate(self.specs)}
        #: the registers written at start-up, per joint (model order): compliance, punch,
        #: torque limit, alarm shutdown (AX-12A); position gains, current limit, profile
        #: acceleration, shutdown (X series: :class:`wbc.xseries.XSettings`)
        self.settings: ServoSettings | XSettings = settings or (
            XSettings.defaults(len(self.specs))
            if self.protocol == 2.0
            else ServoSettings.defaults(len(self.specs))
        )
        self.poses = {name: dict(p) for name, p in (poses or {}).items()}
        for name, pose in self.poses.items():
            unknown = sorted(set(pose) - set(self._by_id))
            if unknown:
                raise ServoMapError(f"{source}: pose {name!r} names unknown servo IDs {unknown}")
            missing = sorted(set(self._by_id) - set(pose))
            if missing:
                raise ServoMapError(f"{source}: pose {name!r} lacks servo IDs {missing}")

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_file(cls, path: str | Path, joint_names: Sequence[str] | None = None) -> ServoMap:
        """Load a servo map TOML; with ``joint_names``, reorder to (and check against) them."""
        path = Path(path)
        raw = read_toml(path, "servo map", ServoMapError)
        extra = sorted(set(raw) - set(TOP_KEYS))
        if extra:
            raise ServoMapError(
                f"servo map {path} has unknown tables/keys {extra}; allowed: {list(TOP_KEYS)}"
            )
        geometry = bus_geometry(raw.get("bus", {}), str(path))
        joints = raw.get("joints")
        if not isinstance(joints, dict) or not joints:
            raise ServoMapError(f"servo map {path} has no [joints] table")
        specs = []
        for joint, entry in joints.items():
            if not isinstance(entry, dict):
                raise ServoMapError(f"servo map {path}: joint {joint!r} must be a table")
            for key in ("id", "sign", "zero_tick"):
                if key not in entry:
                    raise ServoMapError(f"servo map {path}: joint {joint!r} lacks {key!r}")
            extra = set(entry) - {"id", "sign", "zero_tick"}
            if extra:
                raise ServoMapError(
                    f"servo map {path}: joint {joint!r} has unknown keys {sorted(extra)}"
                )
            specs.append(ServoSpec(joint, entry["id"], entry["sign"], entry["zero_tick"]))
        if joint_names is not None:
            by_name = {s.joint: s for s in specs}
            missing = [j for j in joint_names if j not in by_name]
            extra = [j for j in by_name if j not in set(joint_names)]
            if missing or extra:
                raise ServoMapError(
                    f"servo map {path} does not match the robot model: "
                    f"missing joints {missing}, joints not in the model {extra}"
                )
            specs = [by_name[j] for j in joint_names]
        poses = {}
        if not isinstance(raw.get("poses", {}), dict):
            raise ServoMapError(f"servo map {path}: [poses.<name>] entries must be tables")
        for name, pose in raw.get("poses", {}).items():
            try:
                poses[name] = {int(k): int(v) for k, v in pose.items()}
            except (TypeError, ValueError) as exc:
                raise ServoMapError(f"servo map {path}: pose {name!r}: {exc}") from exc
        baud = raw.get("bus", {}).get("baudrate", 1_000_000)
        kind = XSettings if geometry.protocol == 2.0 else ServoSettings
        settings = kind.from_table(raw.get("settings", {}), [s.joint for s in specs], str(path))
        return cls(specs, poses, baud, str(path), settings=settings, protocol=geometry.protocol)

    def _validate(self) -> None:
        seen: dict[int, str] = {}
        names: set[str] = set()
        for s in self.specs:
            where = f"{self.source}: joint {s.joint!r}"
            if s.joint in names:
                raise ServoMapError(f"{where} appears twice")
            names.add(s.joint)
            if isinstance(s.id, bool) or not isinstance(s.id, int) or not 0 <= s.id <= 253:
                raise ServoMapError(f"{where}: id {s.id!r} is not an integer in 0..253")
            if s.id in seen:
                raise ServoMapError(f"{where}: duplicate servo id {s.id} (also {seen[s.id]!r})")
            seen[s.id] = s.joint
            if s.sign not in (1, -1) or isinstance(s.sign, bool):
                raise ServoMapError(f"{where}: sign must be 1 or -1, got {s.sign!r}")
            if not isinstance(s.zero_tick, (int, float)) or isinstance(s.zero_tick, bool):
                raise ServoMapError(f"{where}: zero_tick must be a number, got {s.zero_tick!r}")
            if not self.tick_min <= s.zero_tick <= self.tick_max:
                raise ServoMapError(
                    f"{where}: zero_tick {s.zero_tick} outside {self.tick_min}..{self.tick_max} "
                    f"(protocol {self.protocol})"
                )

    # ------------------------------------------------------------------ lookups
    def __len__(self) -> int:
        return len(self.specs)

    def spec(self, joint: str) -> ServoSpec:
        """The servo of a joint, by joint name."""
        try:
            return self.specs[self._by_joint[joint]]
        except KeyError:
            raise ServoMapError(
                f"unknown joint {joint!r}; known joints: {', '.join(self.joint_names)}"
            ) from None

    def index_of_id(self, servo_id: int) -> int:
        """Position (model joint order) of a servo ID."""
        try:
            return self._by_id[servo_id]
        except KeyError:
            raise ServoMapError(f"unknown servo id {servo_id}") from None

    # ------------------------------------------------------------------ conversions
    def ticks_to_angles(self, ticks: Sequence[float] | np.ndarray) -> np.ndarray:
        """Joint angles (rad, model order) from ticks (model order)."""
        t = self._as_vector(ticks, "ticks")
        bad = np.flatnonzero((t < self.tick_min) | (t > self.tick_max))
        if bad.size:
            raise ServoMapError(self._range_message(t, bad, "ticks"))
        return self.signs * (t - self.zero_ticks) * self.rad_per_tick

    def angles_to_ticks_float(self, q: Sequence[float] | np.ndarray) -> np.ndarray:
        """Unrounded ticks for joint angles (rad, model order); no range check."""
        q = self._as_vector(q, "angles")
        return self.zero_ticks + self.signs * q / self.rad_per_tick

    def angles_to_ticks(self, q: Sequence[float] | np.ndarray) -> np.ndarray:
        """Integer goal ticks for joint angles (rad, model order).

        Raises :class:`ServoMapError` naming the joint if a tick falls outside the servo's range.
        """
        t = np.rint(self.angles_to_ticks_float(q))
        bad = np.flatnonzero((t < self.tick_min) | (t > self.tick_max))
        if bad.size:
            raise ServoMapError(self._range_message(t, bad, "angles"))
        return t.astype(int)

    def pose_ticks(self, name: str) -> np.ndarray:
        """A named pose of the map (e.g. ``walk_ready``) as ticks in model order."""
        try:
            pose = self.poses[name]
        except KeyError:
            raise ServoMapError(
                f"unknown pose {name!r}; poses in {self.source}: {sorted(self.poses)}"
            ) from None
        return np.array([pose[s.id] for s in self.specs], dtype=int)

    def ticks_by_id(self, ticks: Sequence[int] | np.ndarray) -> dict[int, int]:
        """Model-order ticks as ``{servo_id: tick}``."""
        return {int(i): int(t) for i, t in zip(self.ids, ticks, strict=True)}

    def _as_vector(self, values, what: str) -> np.ndarray:
        v = np.asarray(values, dtype=float)
        if v.shape != (len(self.specs),):
            raise ServoMapError(
                f"{what}: expected {len(self.specs)} values (one per joint), got shape {v.shape}"
            )
        if not np.all(np.isfinite(v)):
            bad = [self.specs[i].joint for i in np.flatnonzero(~np.isfinite(v))]
            raise ServoMapError(f"{what}: non-finite values for joints {bad}")
        return v

    def _range_message(self, ticks: np.ndarray, bad: np.ndarray, what: str) -> str:
        parts = [f"{self.specs[i].joint} (id {self.specs[i].id}) -> tick {ticks[i]:g}" for i in bad]
        span = f"{self.tick_min}..{self.tick_max}"
        return f"{what} outside the servo range {span}: " + "; ".join(parts)
