"""The simulated robot behind the hardware interfaces: :class:`SimServoBus`,
:class:`SimSsc32Bus` and :class:`SimImu`.

:class:`SimSsc32Bus` is the SSC-32 backend itself (:class:`~wbc.servos.ssc32.Ssc32Bus`,
unchanged) writing its ASCII lines to :class:`SimSsc32Serial`, a simulated board that parses
them and drives the simulated hobby servos (:class:`~wbc.sim.actuator.HobbyServoArray`).

:class:`SimServoBus` is a :class:`~wbc.servos.bus.ServoBus` (AX-12A ticks, the servo map's
codec and labels), so ``wbc deploy --sim`` runs the deployment code unchanged: start-up,
soft start, clamping, rate limit, watchdog, safe stop. Two timings:

* **lockstep** (default): the bus exposes a :attr:`SimServoBus.clock` whose ``sleep`` steps
  the physics; the deployment's tick scheduler then advances simulated time by exactly one
  control period per tick, as fast as the computer allows;
* **real time**: no clock; before every exchange the physics catches up with the wall clock
  since :meth:`~SimServoBus.open`.

Faults: :meth:`SimServoBus.inject` (now, or after the N-th goal write) makes a servo fall
silent or raises its overload bit; a servo whose torque sits at its limit raises the bit by
itself (:mod:`wbc.sim.actuator`). ``latency_ticks`` delays every goal by whole ticks.
"""

from __future__ import annotations

import re
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, ServoError
from ..imu import Imu, ImuReading
from ..servos.bus import (
    COMM_OK,
    COMM_TIMEOUT,
    BusBudget,
    ServoBus,
    ServoStatus,
    stiffness_factors,
    stiffness_registers,
)
from ..servos.protocol1 import (
    AX12_MAX_SPEED,
    ax_budget,
    ax_codec,
    fault_names,
    speed_register,
    speed_ticks_per_s,
)
from ..servos.ssc32 import Ssc32Bus
from ..xseries import hw_fault_names
from .simulator import FAULT_KINDS, Simulation


class SimClock:
    """Simulated time for the deployment's scheduler: ``sleep`` runs the physics."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim

    def now(self) -> float:
        return self.sim.time

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            self.sim.advance(seconds)


class SimServoBus(ServoBus):
    """The simulated robot's servos on a bus (model joint order, AX-12A ticks)."""

    name = "sim"
    can_read = True
    servo_speed = AX12_MAX_SPEED
    can_set_stiffness = True

    def __init__(
        self,
        sim: Simulation,
        realtime: bool = False,
        latency_ticks: int = 0,
        torque_limit: int | None = None,
        on_tick: Callable[[SimServoBus], None] | None = None,
        on_close: Callable[[], None] | None = None,
    ) -> None:
        if sim.hobby:
            raise ConfigurationError(
                f"robot {sim.robot.name} has hobby PWM servos: its simulated bus is SimSsc32Bus "
                "(wbc.sim.bus.sim_bus picks the robot's own)"
            )
        sm = sim.robot.servo_map
        labels = [f"id {int(i)} ({j})" for i, j in zip(sm.ids, sm.joint_names, strict=True)]
        super().__init__(ax_codec(sm), labels)
        #: X-series servos (XM430, Protocol 2.0): their speed, profile velocity, error names
        #: and bus budget; else the AX-12A's
        self.xseries = sm.protocol == 2.0
        if self.xseries:
            from ..servos.protocol2 import XM430_NO_LOAD_SPEED

            self.servo_speed = XM430_NO_LOAD_SPEED
            if torque_limit is not None:
                raise ServoError(
                    "--torque-limit is an AX-12A register: X-series servos take "
                    "[settings] current_limit in servos.toml"
                )
        if latency_ticks < 0:
            raise ServoError(f"latency_ticks must be >= 0, got {latency_ticks}")
        if torque_limit is not None and not 0 <= torque_limit <= 1023:
            raise ServoError(f"torque limit must be 0..1023, got {torque_limit}")
        self.sim = sim
        self.realtime = realtime
        self.clock = None if realtime else SimClock(sim)
        self.latency_ticks = latency_ticks
        self.torque_limit = torque_limit
        self.on_tick = on_tick
        self.on_close = on_close
        self.goals_written = 0
        self.is_open = False
        self._pending: deque[np.ndarray] = deque()
        self._scheduled: list[tuple[int, str, int]] = []
        self._wall0 = 0.0
        self._sim0 = 0.0
        #: the stiffness registers the simulated servos hold (configured at first)
        self._registers = self.stiffness_registers(1.0)

    # ------------------------------------------------------------------ time
    def _sync(self) -> None:
        """Real-time mode: run the physics up to the wall-clock time."""
        if self.realtime and self.is_open:
            self.sim.advance_to(self._sim0 + time.perf_counter() - self._wall0)

    # ------------------------------------------------------------------ faults
    def inject(self, kind: str, index: int, after_goals: int = 0) -> None:
        """A fault on servo ``index`` now, or once ``after_goals`` goal writes have been made
        (``kind``: ``silent`` or ``overload``, see :meth:`Simulation.inject`)."""
        if kind not in FAULT_KINDS:
            raise ServoError(f"unknown fault {kind!r}; choose from {FAULT_KINDS}")
        if not 0 <= index < self.n:
            raise ServoError(f"fault: servo index {index} outside 0..{self.n - 1}")
        if after_goals <= self.goals_written:
            self.sim.inject(kind, index)
        else:
            self._scheduled.append((after_goals, kind, index))

    # ------------------------------------------------------------------ life cycle
    def open(self) -> None:
        self.is_open = True
        self._wall0 = time.perf_counter()
        self._sim0 = self.sim.time

    def close(self) -> None:
        self.is_open = False
        if self.on_close is not None:
            self.on_close()

    def identify(self) -> None:
        self._require_open()
        silent = [self.labels[i] for i in np.flatnonzero(self.sim.silent)]
        if silent:
            raise ServoError(f"{self.name}: no reply to PING from " + ", ".join(silent))

    def configure(self) -> None:
        """Torque off and the torque-limit register (if given), as the real bus does."""
        self._require_open()
        self.set_torque(False)
        self._apply_registers(self.stiffness_registers(1.0))
        self.stiffness = np.ones(self.n)
        if self.torque_limit is not None:
            p = self.sim.servos.params
            cap = np.full(self.n, p.stall_torque * self.torque_limit / 1023.0)
            self.sim.servos.params = replace(p, torque_cap=cap)

    def _require_open(self) -> None:
        if not self.is_open:
            raise ServoError(f"{self.name}: the simulated bus is not open")

    def set_torque_limit(self, share: float) -> None:
        """Torque Limit (34) of every servo: ``share`` (0..1) of the stall torque."""
        self._require_open()
        if not 0.0 <= share <= 1.0:
            raise ServoError(f"torque limit share must be in [0, 1], got {share}")
        p = self.sim.servos.params
        cap = np.full(self.n, p.stall_torque * round(1023 * share) / 1023.0)
        self.sim.servos.params = replace(p, torque_cap=cap)

    # ------------------------------------------------------------------ stiffness
    def stiffness_registers(self, factors: float | Sequence[float] | np.ndarray) -> np.ndarray:
        """The registers the real bus would write for stiffness ``factors``
        (:meth:`wbc.servos.dynamixel.DynamixelBus.stiffness_registers`: AX-12A compliance
        slopes, X-series position P gains), refused alike when out of range."""
        from ..servo_map import SETTING_REGISTERS
        from ..xseries import X_SETTING_REGISTERS

        f = stiffness_factors(factors, self.n)
        st = self.sim.robot.servo_map.settings
        if self.xseries:
            allowed = X_SETTING_REGISTERS["position_p_gain"][2]
            return stiffness_registers(st.position_p_gain, f, self.labels, "position P gain",
                                       allowed, False)  # fmt: skip
        allowed = SETTING_REGISTERS["compliance_slope"][2]
        return stiffness_registers(st.compliance_slope, f, self.labels, "compliance slope",
                                   allowed, True)  # fmt: skip

    def _apply_registers(self, registers: np.ndarray) -> None:
        """The servo law's parameters follow the registers: the AX-12A's ramp (``slope``) and
        the XM430's P gain scale with them, so a randomised model keeps its own scale."""
        if np.array_equal(registers, self._registers):
            return
        ratio = registers / self._registers
        p = self.sim.servos.params
        if self.xseries:
            self.sim.servos.params = replace(p, kp=p.kp * ratio)  # type: ignore[call-arg]
        else:
            self.sim.servos.params = replace(p, slope=p.slope * ratio)  # type: ignore[call-arg]
        self._registers = np.asarray(registers).copy()

    def set_stiffness(self, factors: float | Sequence[float] | np.ndarray) -> None:
        """The simulated servos' stiffness ``factors`` × the configured one, through the
        registers the real bus writes (:meth:`stiffness_registers`)."""
        self._require_open()
        self._sync()
        f = stiffness_factors(factors, self.n)
        self._apply_registers(self.stiffness_registers(f))
        self.stiffness = f

    # ------------------------------------------------------------------ motion
    def set_torque(self, enabled: bool) -> None:
        self._require_open()
        self._sync()
        if enabled:  # torque on clears the alarm state of the answering servos
            ok = ~self.sim.silent
            self.sim.servos.shutdown[ok] = False
            self.sim.servos.error[ok] = 0
            self.sim.set_torque(np.where(ok, True, self.sim.servos.enabled))
        else:
            self.sim.set_torque(False)  # a broadcast reaches silent servos too

    def set_speed(self, rad_per_s: float) -> None:
        self._require_open()
        self._sync()
        if self.xseries:  # Profile Velocity (112), 0.229 rev/min units
            from ..xseries import X_RAD_PER_TICK, profile_velocity_rad_s, profile_velocity_register

            cap = profile_velocity_rad_s(profile_velocity_register(rad_per_s)) / X_RAD_PER_TICK
        else:
            cap = speed_ticks_per_s(speed_register(rad_per_s))
        self.sim.set_speed_ticks(np.where(self.sim.silent, self.sim.servos.speed, cap))

    def write_goals(self, cmds: np.ndarray) -> str:
        self._require_open()
        cmds = self.check_goals(cmds)
        self._sync()
        self.goals_written += 1
        for entry in [s for s in self._scheduled if s[0] <= self.goals_written]:
            self.sim.inject(entry[1], entry[2])
            self._scheduled.remove(entry)
        self._pending.append(np.asarray(cmds, dtype=float))
        while len(self._pending) > self.latency_ticks:
            self.sim.write_goals(self._pending.popleft())
        if self.on_tick is not None:
            self.on_tick(self)
        return COMM_OK

    # ------------------------------------------------------------------ feedback
    def _status(self, i: int, present: np.ndarray, load: bool = False) -> ServoStatus:
        if self.sim.silent[i]:
            return ServoStatus(i, COMM_TIMEOUT)
        err = int(self.sim.servos.error[i])
        names = hw_fault_names if self.xseries else fault_names
        status = ServoStatus(i, COMM_OK, names(err) if err else (), err, float(present[i]))
        if load:
            servos = self.sim.servos
            status.load = float(servos.torque[i] * servos.signs[i] / servos.params.stall_torque)
        return status

    def read_positions(self, indices: Sequence[int] | None = None) -> list[ServoStatus]:
        self._require_open()
        self._sync()
        present = self.sim.present_ticks()
        return [self._status(i, present) for i in (range(self.n) if indices is None else indices)]

    def poll(self, index: int) -> ServoStatus:
        self._require_open()
        self._sync()
        return self._status(index, self.sim.present_ticks(), load=True)

    def budget(self, read_positions: bool) -> BusBudget:
        """The budget of the real bus the simulated servos stand for: AX-12A at 1 Mbps, or
        X series (Protocol 2.0) at the servo map's baud rate."""
        return self.tick_budget(read_positions, 1)

    def tick_budget(self, read_positions: bool, polls_per_tick: int) -> BusBudget:
        """As :meth:`budget`, with the deployment's ``polls_per_tick`` health reads."""
        if self.xseries:
            from ..servos.protocol2 import x_budget

            baud = self.sim.robot.servo_map.baudrate
            return x_budget(self.n, baud, read_positions, polls_per_tick)
        return ax_budget(self.n, 1_000_000, read_positions, polls_per_tick)


_GROUP = re.compile(r"#(\d+)\s*(?:P(\d+)|(L))(?:S(\d+))?")
_TIME = re.compile(r"T(\d+)\s*$")


class SimSsc32Serial:
    """A simulated SSC-32 on the other end of the serial port: ``write`` parses the ASCII
    lines (``#<ch>P<pw>...T<ms>``, ``#<ch>L``, ``VER``, ``Q``) and acts on the simulation;
    ``read`` returns the board's answers. ``latency_moves`` delivers each move that many
    moves late; ``before`` runs before every line (real-time catch-up)."""

    VERSION = b"SSC32-SIM\r"

    def __init__(
        self,
        sim: Simulation,
        channels: Sequence[int],
        latency_moves: int = 0,
        before: Callable[[], None] | None = None,
    ) -> None:
        self.sim = sim
        self.index = {int(c): i for i, c in enumerate(channels)}
        self.latency_moves = latency_moves
        self.before = before
        self.is_open = True
        self.lines: list[str] = []
        self._reply = bytearray()
        self._buf = ""
        self._pending: deque[tuple[np.ndarray, np.ndarray, int | None]] = deque()

    def write(self, data: bytes) -> int:
        if self.before is not None:
            self.before()
        self._buf += data.decode("ascii")
        while "\r" in self._buf:
            line, _, self._buf = self._buf.partition("\r")
            self._line(line.strip())
        return len(data)

    def _line(self, line: str) -> None:
        self.lines.append(line)
        if line == "VER":
            self._reply += self.VERSION
            return
        if line == "Q":
            s = self.sim.servos
            moving = np.any(~np.isnan(s.target) & (s.out != np.rint(s.target)))
            self._reply += b"+" if moving else b"."
            return
        if not line.startswith("#"):
            return  # the real board ignores what it does not understand
        n = self.sim.robot.n_joints
        pulses, mask, off = np.zeros(n), np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        for g in _GROUP.finditer(line):
            i = self.index.get(int(g.group(1)))
            if i is None:
                continue  # a channel with no servo of the model on it
            if g.group(3):
                off[i] = True
            else:
                pulses[i], mask[i] = float(g.group(2)), True
        if np.any(off):
            self.sim.servos.off(off)
        if np.any(mask):
            m = _TIME.search(line)
            self._pending.append((pulses, mask, int(m.group(1)) if m else None))
            while len(self._pending) > self.latency_moves:
                p, k, ms = self._pending.popleft()
                self.sim.servos.write(p, ms, k)

    def read(self, size: int = 1) -> bytes:
        out = bytes(self._reply[:size])
        del self._reply[:size]
        return out

    def reset_input_buffer(self) -> None:
        self._reply.clear()

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self.is_open = False


class SimSsc32Bus(Ssc32Bus):
    """The SSC-32 backend on a simulated board and hobby servos (``wbc deploy --bus ssc32
    --sim``): the code that drives the real board, its bytes parsed by
    :class:`SimSsc32Serial`. Lockstep (the bus's clock runs the physics) or ``realtime``.
    Like the real board it reads nothing back; :meth:`inject` can still cut a servo's signal
    wire (``silent``), which the deployment cannot see."""

    name = "sim"

    def __init__(
        self,
        sim: Simulation,
        realtime: bool = False,
        latency_ticks: int = 0,
        move_time_ms: int | None = None,
        on_tick: Callable[[SimSsc32Bus], None] | None = None,
        on_close: Callable[[], None] | None = None,
    ) -> None:
        if not sim.hobby:
            raise ConfigurationError(
                f"robot {sim.robot.name} has AX-12A servos: the simulated SSC-32 drives hobby "
                "PWM servos (robot.toml [servo] law = 'hobby_pwm')"
            )
        if latency_ticks < 0:
            raise ServoError(f"latency_ticks must be >= 0, got {latency_ticks}")
        super().__init__("<sim>", sim.pwm_map, sim.pwm_map.baudrate, move_time_ms=move_time_ms)
        self.sim = sim
        self.realtime = realtime
        self.clock = None if realtime else SimClock(sim)
        self.latency_ticks = latency_ticks
        self.on_tick = on_tick
        self.on_close = on_close
        self._wall0 = 0.0
        self._sim0 = 0.0

    def close(self) -> None:
        super().close()
        if self.on_close is not None:
            self.on_close()

    def _sync(self) -> None:
        if self.realtime and self.ser is not None:
            self.sim.advance_to(self._sim0 + time.perf_counter() - self._wall0)

    def open(self) -> None:
        self._wall0, self._sim0 = time.perf_counter(), self.sim.time
        self.ser = SimSsc32Serial(
            self.sim, self.map.channel_numbers, self.latency_ticks, before=self._sync
        )

    def inject(self, kind: str, index: int, after_goals: int = 0) -> None:
        """Cut servo ``index``'s signal wire (``silent``; hobby servos have no error bits)."""
        if kind != "silent":
            raise ServoError(f"hobby servos report no errors: only 'silent', not {kind!r}")
        if not 0 <= index < self.n:
            raise ServoError(f"fault: servo index {index} outside 0..{self.n - 1}")
        self.sim.inject(kind, index)

    def write_goals(self, cmds: np.ndarray) -> str:
        status = super().write_goals(cmds)
        if self.on_tick is not None:
            self.on_tick(self)
        return status


def sim_bus(sim: Simulation, rate: float, **kwargs) -> SimServoBus | SimSsc32Bus:
    """The simulated bus of ``sim``'s servos: :class:`SimServoBus` (AX-12A) or
    :class:`SimSsc32Bus` (hobby servos; each move's ``T`` = one tick at ``rate`` Hz, as
    ``wbc deploy --bus ssc32``)."""
    if sim.hobby:
        if kwargs.pop("torque_limit", None) is not None:
            raise ServoError("--torque-limit is an AX-12A register: hobby servos have none")
        return SimSsc32Bus(sim, move_time_ms=max(1, round(1000.0 / rate)), **kwargs)
    return SimServoBus(sim, **kwargs)


class SimImu(Imu):
    """The simulated torso IMU: MuJoCo's frame-quaternion, gyro and accelerometer sensors
    at the ``imu`` site, with white noise (standard deviations) and a constant bias per
    axis drawn once from ``bias_std`` (seeded); ``integrate`` (off): the gyro the rotation
    since the last reading over the time since it, as a delta-angle IMU. Its :attr:`mount` is
    the robot folder's (``robot.toml`` ``[imu]``, :func:`wbc.sim.model.imu_mount`): what the
    controller is told, whatever the simulated model's ``imu_rotation``."""

    name = "sim-imu"

    def __init__(
        self,
        sim: Simulation,
        gyro_noise: float = 0.0,  # rad/s
        acc_noise: float = 0.0,  # m/s²
        orientation_noise: float = 0.0,  # rad
        gyro_bias_std: float = 0.0,  # rad/s
        acc_bias_std: float = 0.0,  # m/s²
        seed: int | None = 0,
        integrate: bool = False,
    ) -> None:
        for name, v in (
            ("gyro_noise", gyro_noise),
            ("acc_noise", acc_noise),
            ("orientation_noise", orientation_noise),
            ("gyro_bias_std", gyro_bias_std),
            ("acc_bias_std", acc_bias_std),
        ):
            if not (np.isfinite(v) and v >= 0):
                raise ServoError(f"SimImu: {name} must be >= 0, got {v}")
        from .model import imu_mount

        self.sim = sim
        self.mount = imu_mount(sim.robot)
        self.rng = np.random.default_rng(seed)
        self.gyro_noise, self.acc_noise, self.orientation_noise = (
            gyro_noise,
            acc_noise,
            orientation_noise,
        )
        self.gyro_bias = self.rng.normal(0.0, gyro_bias_std, 3) if gyro_bias_std else np.zeros(3)
        self.acc_bias = self.rng.normal(0.0, acc_bias_std, 3) if acc_bias_std else np.zeros(3)
        #: the gyro read as the site's rotation since the last reading over the time since it
        #: (a delta-angle IMU: the mean rate over the interval), not MuJoCo's rate at the read
        self.integrate = bool(integrate)
        self._last: tuple[float, np.ndarray] | None = None  # (time, rotation) at the last read
        m, mj = sim.model, sim.mj
        self._adr = {}
        for key in ("imu_quat", "imu_gyro", "imu_acc"):
            k = mj.mj_name2id(m, mj.mjtObj.mjOBJ_SENSOR, key)
            self._adr[key] = slice(m.sensor_adr[k], m.sensor_adr[k] + m.sensor_dim[k])

    def read(self) -> ImuReading:
        s = self.sim.data.sensordata
        w, x, y, z = s[self._adr["imu_quat"]]
        quat = np.array([x, y, z, w])
        if self.orientation_noise:
            axis = self.rng.normal(0.0, self.orientation_noise, 3)  # small rotation vector
            half = 0.5 * axis
            dq = np.array([*half, 1.0])
            dq /= np.linalg.norm(dq)
            quat = _quat_mul(quat, dq)
        gyro = s[self._adr["imu_gyro"]] + self.gyro_bias
        if self.integrate:
            R = pin.Quaternion(w, x, y, z).toRotationMatrix()
            last, self._last = self._last, (self.sim.time, R)
            if last is not None and self.sim.time > last[0]:
                gyro = pin.log3(last[1].T @ R) / (self.sim.time - last[0]) + self.gyro_bias
        acc = s[self._adr["imu_acc"]] + self.acc_bias
        if self.gyro_noise:
            gyro = gyro + self.rng.normal(0.0, self.gyro_noise, 3)
        if self.acc_noise:
            acc = acc + self.rng.normal(0.0, self.acc_noise, 3)
        return ImuReading(self.sim.time, quat, gyro, acc)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ])  # fmt: skip
