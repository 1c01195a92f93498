"""The servos as actuators: their control laws computed every physics step.

Three servo models, chosen by the robot's data (:func:`nominal_servo`): the Dynamixel AX-12A
(:class:`ServoParams`, :class:`ServoArray`: the Bioloid; the default of a robot with a
Protocol 1.0 ``servos.toml``), the Dynamixel XM430 (:mod:`wbc.sim.xm430`: the OP3; the
default with ``[bus] protocol = 2.0``) and a hobby PWM servo behind a Lynxmotion SSC-32 board
(:class:`HobbyServoParams`, :class:`HobbyServoArray`: Kokone; ``robot.toml`` ``[servo] law =
"hobby_pwm"``). The hobby model is described in :class:`HobbyServoArray`.

The AX-12A:

Parameters and sources (robots/bioloid/README.md, "Simulation"; ../shared/reference/physics.md
§1–2, bioloid-facts.md §4):

* stall torque ``τ_s = 1.5 N·m`` (12 V), no-load speed ``ω_0 = 59 rpm = 6.18 rad/s``;
* encoder quantisation: 1023 ticks over 300° (0.293°/tick); the servo compares the goal with
  its own quantised position;
* compliance margin ``m`` (registers 26/27, ticks): dead band, no drive inside it;
* compliance slope ``s`` (28/29, ticks): the drive ramps from the punch to full over ``s``
  ticks, so the stiffness is ``k ≈ τ_s / (s · 0.00512 rad)`` (9.2 N·m/rad at 32);
* punch ``p`` (48, of 1023): the minimum drive outside the margin;
* torque limit ``L`` (34, of 1023): ``|τ| ≤ τ_s · L / 1023``;
* moving speed (32): the goal the servo tracks moves toward the written goal at most at this
  speed (0 = the no-load speed);
* back-EMF: ``τ = τ_s · u − b · ω`` with ``b = τ_s / ω_0 ≈ 0.24 N·m·s/rad`` (a joint damping in
  MuJoCo, integrated implicitly), reflected rotor inertia (armature) and gear friction
  (frictionloss) are joint properties of the MuJoCo model (:mod:`wbc.sim.model`).

The law, per joint, in the servo's own tick direction (``e`` = tracked goal − quantised
position, ticks)::

    u = 0                                        if |e| <= m
    u = sign(e) · min(1, p/1023 + (|e| − m)/s)   otherwise
    τ = clip(τ_s · u, −τ_s · L/1023, τ_s · L/1023)

Overload: a servo whose torque sits at its limit for ``overload_time`` seconds raises the
overload error bit (0x20); if its alarm-shutdown mask holds that bit, its torque is cut (the
AX-12A sets its torque limit to 0), as a real servo does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numba
import numpy as np

from ..exceptions import ConfigurationError, ModelError, ServoError
from ..servo_map import RAD_PER_TICK, ServoMap, ServoSettings
from ..xseries import XSettings
from .servo_ticks import TickServos

if TYPE_CHECKING:
    from collections.abc import Mapping

    from ..model import Robot
    from ..servos.bus import Codec
    from ..servos.ssc32 import Ssc32Map
    from .xm430 import XServoParams

STALL_TORQUE = 1.5  # N·m at 12 V (EMAN-AX)
NO_LOAD_SPEED = 59.0 * 2.0 * math.pi / 60.0  # rad/s at 12 V (EMAN-AX)
BACK_EMF_DAMPING = STALL_TORQUE / NO_LOAD_SPEED  # N·m·s/rad (physics.md §1, derived)
ARMATURE = 0.005  # kg·m², reflected rotor inertia: physics.md §1 gives 0.002–0.01
FRICTION_LOSS = 0.05  # N·m, gear friction: published small-servo models 0.03–0.1 (§2)
OVERLOAD_TIME = 1.0  # s at the torque limit before the overload bit (assumption, unpublished)
ERR_OVERLOAD = 0x20


@dataclass(frozen=True)
class ServoParams:
    """Per-joint actuator parameters (model joint order), from the shared servo settings.

    ``stiffness_scale`` multiplies the ramp (randomised models); ``backlash`` (rad) is a play
    between the motor side and the link: the servo's position sensor follows the link only
    once the play is taken up (0 = none).
    """

    margin: np.ndarray  # ticks
    slope: np.ndarray  # ticks
    punch: np.ndarray  # fraction 0..1
    torque_cap: np.ndarray  # N·m
    stall_torque: float = STALL_TORQUE
    damping: float = BACK_EMF_DAMPING
    armature: float = ARMATURE
    friction_loss: float = FRICTION_LOSS
    overload_time: float = OVERLOAD_TIME
    alarm_shutdown: int = 36
    backlash: float = 0.0

    @classmethod
    def from_settings(cls, settings: ServoSettings, **kwargs) -> ServoParams:
        """Parameters of the registers in ``settings`` (e.g. ``robot.servo_map.settings``)."""
        if isinstance(settings, XSettings):
            raise ConfigurationError(
                "the AX-12A servo model (compliance margin/slope, punch) does not apply to "
                "X-series servos (servos.toml protocol 2.0): see wbc.sim.xm430"
            )
        stall = kwargs.pop("stall_torque", STALL_TORQUE)
        return cls(
            margin=settings.compliance_margin.astype(float),
            slope=settings.compliance_slope.astype(float),
            punch=settings.punch.astype(float) / 1023.0,
            torque_cap=stall * settings.torque_limit.astype(float) / 1023.0,
            stall_torque=stall,
            alarm_shutdown=settings.alarm_shutdown,
            **kwargs,
        )

    @property
    def stiffness(self) -> np.ndarray:
        """Small-error stiffness (N·m/rad): ``τ_s / (slope · rad per tick)``."""
        return self.stall_torque / (self.slope * RAD_PER_TICK)

    def scaled(self, stiffness: float = 1.0, torque: float = 1.0) -> ServoParams:
        """A copy with the ramp ``stiffness`` times steeper and the torque cap scaled."""
        return replace(self, slope=self.slope / stiffness, torque_cap=self.torque_cap * torque)


class ServoArray(TickServos):
    """The state and law of all servos of a robot (vectorised over joints).

    Positions and goals are in the servo map's ticks; torques are returned in the joint's
    (URDF) direction.
    """

    rad_per_tick = RAD_PER_TICK

    def __init__(self, servo_map: ServoMap, params: ServoParams) -> None:
        self.params = params
        self.signs = servo_map.signs.copy()
        self.zero = servo_map.zero_ticks.copy()
        n = len(servo_map)
        self.n = n
        self.goal = np.zeros(n)  # written goal (ticks)
        self.tracked = np.zeros(n)  # goal moving toward `goal` at the speed cap (ticks)
        self.speed = np.full(n, NO_LOAD_SPEED / RAD_PER_TICK)  # ticks/s
        self.enabled = np.zeros(n, dtype=bool)
        self.shutdown = np.zeros(n, dtype=bool)  # torque cut by an alarm
        self.error = np.zeros(n, dtype=int)  # status error bits
        self.at_limit_time = np.zeros(n)
        self.motor = np.zeros(n)  # motor-side position with backlash (ticks)
        self.torque = np.zeros(n)  # last output torque (N·m, joint direction)
        self._scale = 1.0 / RAD_PER_TICK

    def reset(self, q: np.ndarray) -> None:
        """Servos at rest at joint angles ``q``: goals there, torque off, no errors."""
        t = self.ticks(q)
        self.goal[:] = np.rint(t)
        self.tracked[:] = self.goal
        self.motor[:] = t
        self.enabled[:] = False
        self.shutdown[:] = False
        self.error[:] = 0
        self.at_limit_time[:] = 0.0
        self.torque[:] = 0.0

    def sensed(self, q: np.ndarray) -> np.ndarray:
        """The position the servo senses (ticks, before quantisation), backlash included."""
        t = self.ticks(q)
        half = 0.5 * self.params.backlash * self._scale
        if half > 0:
            self.motor = np.clip(self.motor, t - half, t + half)
            return self.motor.copy()
        return t

    def present(self, q: np.ndarray) -> np.ndarray:
        """Present Position (36): the quantised sensed position (ticks)."""
        return np.rint(self.sensed(q))

    def law(self, q: np.ndarray, dt: float) -> np.ndarray:
        """Advance the tracked goals by ``dt`` and return the joint torques (N·m) at ``q``
        (the compiled :func:`servo_law`; :meth:`law_numpy` is the same law in numpy)."""
        p = self.params
        servo_law(
            np.ascontiguousarray(q, dtype=np.float64), dt, self.goal, self.tracked, self.speed,
            self.zero, self.signs, p.margin, p.slope, p.punch, p.stall_torque, p.torque_cap,
            self.enabled, self.shutdown, self.error, self.at_limit_time, p.overload_time,
            p.alarm_shutdown, self.motor, 0.5 * p.backlash * self._scale, self._scale,
            self.torque,
        )  # fmt: skip
        return self.torque

    def law_numpy(self, q: np.ndarray, dt: float) -> np.ndarray:
        """The servo law in numpy (the reference of :func:`servo_law`)."""
        p = self.params
        step = self.speed * dt
        self.tracked += np.clip(self.goal - self.tracked, -step, step)
        e = self.tracked - np.rint(self.sensed(q))
        ae = np.abs(e)
        u = np.where(ae <= p.margin, 0.0, np.minimum(1.0, p.punch + (ae - p.margin) / p.slope))
        drive = p.stall_torque * u
        at_limit = drive >= p.torque_cap - 1e-12
        tau = np.sign(e) * np.minimum(drive, p.torque_cap)
        active = self.enabled & ~self.shutdown
        self.at_limit_time = np.where(active & at_limit, self.at_limit_time + dt, 0.0)
        over = self.at_limit_time >= p.overload_time
        if np.any(over):
            self.error[over] |= ERR_OVERLOAD
            if p.alarm_shutdown & ERR_OVERLOAD:
                self.shutdown |= over
                active = active & ~over
        self.torque = np.where(active, self.signs * tau, 0.0)
        return self.torque


@numba.njit(cache=True)
def servo_law(
    q, dt, goal, tracked, speed, zero, signs, margin, slope, punch, stall, cap, enabled,
    shutdown, error, at_limit_time, overload_time, alarm, motor, half_backlash, ticks_per_rad,
    torque,
):  # fmt: skip
    """The servo law of the module docstring, in place over all joints (one physics step)."""
    for i in range(q.size):
        step = speed[i] * dt
        d = goal[i] - tracked[i]
        tracked[i] += min(max(d, -step), step)
        sensed = zero[i] + signs[i] * q[i] * ticks_per_rad
        if half_backlash > 0.0:
            motor[i] = min(max(motor[i], sensed - half_backlash), sensed + half_backlash)
            sensed = motor[i]
        e = tracked[i] - np.rint(sensed)
        ae = abs(e)
        u = 0.0
        if ae > margin[i]:
            u = min(1.0, punch[i] + (ae - margin[i]) / slope[i])
        drive = stall * u
        at_limit = drive >= cap[i] - 1e-12
        tau = np.sign(e) * min(drive, cap[i])
        active = enabled[i] and not shutdown[i]
        if active and at_limit:
            at_limit_time[i] += dt
        else:
            at_limit_time[i] = 0.0
        if at_limit_time[i] >= overload_time:
            error[i] |= ERR_OVERLOAD
            if alarm & ERR_OVERLOAD:
                shutdown[i] = True
                active = False
        torque[i] = signs[i] * tau if active else 0.0


# ---------------------------------------------------------------------- hobby PWM servos
#: the servo laws a robot's ``[servo] law`` may name
SERVO_LAWS = ("ax12a", "hobby_pwm", "xm430")
HOBBY_KEYS = (
    "law", "name", "stall_torque", "no_load_speed", "dead_band_us", "proportional_band_us",
    "frame_period", "loop_period", "armature", "friction_loss",
)  # fmt: skip


@dataclass(frozen=True)
class HobbyServoParams:
    """A hobby (RC) position servo driven by PWM pulses; every joint has the same servo.

    ``stall_torque`` (N·m) and ``no_load_speed`` (rad/s) are the datasheet's; the back-EMF
    damping ``b = τ_s / ω_0`` makes the motor line ``τ = τ_s · u − b · ω`` (a joint damping in
    MuJoCo while the servo receives pulses). ``dead_band_us`` / ``proportional_band_us``: no
    drive within the dead band of the commanded pulse, full drive ``proportional_band_us``
    beyond it (µs of pulse width, the servo's own unit). ``frame_period``: the board repeats
    the pulses every frame (the servo's goal changes only then); ``loop_period``: how often
    the servo recomputes its drive from the error (None = once per received pulse, an analog
    servo; a digital one runs faster). ``armature`` (kg·m²): reflected rotor inertia;
    ``friction_loss`` (N·m): gear friction. Kokone's values and their sources:
    ``robots/kokone/robot.toml`` ``[servo]``.
    """

    stall_torque: float
    no_load_speed: float
    dead_band_us: float = 4.0
    proportional_band_us: float = 100.0
    frame_period: float = 0.02
    loop_period: float | None = None
    armature: float = 0.002
    friction_loss: float = 0.01
    name: str = "hobby PWM servo"

    @property
    def damping(self) -> float:
        """Back-EMF damping ``τ_s / ω_0`` (N·m·s/rad)."""
        return self.stall_torque / self.no_load_speed

    @property
    def period(self) -> float:
        """The drive update period (s): ``loop_period``, else the frame."""
        return self.frame_period if self.loop_period is None else self.loop_period

    def stiffness(self, us_per_rad: float | np.ndarray) -> float | np.ndarray:
        """Small-error stiffness (N·m/rad) past the dead band: ``τ_s / proportional band``."""
        return self.stall_torque * np.abs(us_per_rad) / self.proportional_band_us

    def scaled(self, stiffness: float = 1.0, torque: float = 1.0) -> HobbyServoParams:
        """A copy with the proportional band ``stiffness`` times narrower and ``torque`` times
        the stall torque (the no-load speed kept)."""
        return replace(
            self,
            proportional_band_us=self.proportional_band_us / stiffness,
            stall_torque=self.stall_torque * torque,
        )

    @classmethod
    def from_table(cls, table: Mapping, where: str = "[servo]") -> HobbyServoParams:
        """Parameters from a robot's ``[servo]`` table (one clear line per bad key)."""
        extra = sorted(set(table) - set(HOBBY_KEYS))
        if extra:
            raise ModelError(f"{where}: unknown keys {extra}; allowed: {', '.join(HOBBY_KEYS)}")
        values = {}
        for key in HOBBY_KEYS[2:]:
            if key not in table:
                if key in ("stall_torque", "no_load_speed"):
                    raise ModelError(f"{where}: {key} is required (the servo's datasheet value)")
                continue
            v = table[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ModelError(f"{where}: {key} = {v!r} must be a finite number")
            low = 0.0 if key in ("dead_band_us", "friction_loss", "armature") else None
            if (low is None and v <= 0) or (low is not None and v < low):
                raise ModelError(f"{where}: {key} = {v!r} must be {'>= 0' if low == 0 else '> 0'}")
            values[key] = float(v)
        if values.get("frame_period", 0.02) > 0.1:
            raise ModelError(f"{where}: frame_period = {values['frame_period']} s: at most 0.1 s")
        if values.get("loop_period", 0.0) > values.get("frame_period", 0.02):
            raise ModelError(f"{where}: loop_period must be <= frame_period")
        name = table.get("name", "hobby PWM servo")
        return cls(**values, name=str(name))


def servo_kind(robot: Robot) -> str:
    """The servo law of ``robot``'s joints: its ``robot.toml`` ``[servo] law``, else
    ``ax12a`` when it has a Dynamixel servo map; one clear line otherwise."""
    table = robot.robot_data.servo
    law = table.get("law")
    if law is None:
        if robot.servo_map is not None:
            return "xm430" if robot.servo_map.protocol == 2.0 else "ax12a"
        raise ModelError(
            f"robot {robot.name} has no servo model to simulate: give robot.toml a [servo] "
            f"table (law = {' or '.join(repr(x) for x in SERVO_LAWS)}) or a servos.toml"
        )
    if law not in SERVO_LAWS:
        raise ModelError(
            f"{robot.robot_data.source}/robot.toml: [servo] law = {law!r}; allowed: {SERVO_LAWS}"
        )
    if law in ("ax12a", "xm430") and robot.servo_map is None:
        raise ModelError(f"robot {robot.name}: [servo] law = {law!r} needs a servos.toml")
    if law in ("ax12a", "xm430") and (law == "xm430") != (robot.servo_map.protocol == 2.0):
        raise ModelError(
            f"robot {robot.name}: [servo] law = {law!r} does not match its servos.toml "
            f"protocol {robot.servo_map.protocol} (ax12a: 1.0, xm430: 2.0)"
        )
    return law


def nominal_servo(
    robot: Robot, settings: ServoSettings | XSettings | None = None, **kwargs: float | None
) -> ServoParams | HobbyServoParams | XServoParams:
    """The nominal servo model of ``robot``'s joints (:func:`servo_kind`): AX-12A or XM430
    parameters from the servo settings (``kwargs``: damping, armature, friction_loss), or the
    hobby servo of ``robot.toml`` ``[servo]``."""
    kind = servo_kind(robot)
    if kind == "xm430":
        from .xm430 import XServoParams

        return XServoParams.from_settings(settings or robot.servo_map.settings, **kwargs)
    if kind == "ax12a":
        kw = {k: v for k, v in kwargs.items() if v is not None}
        return ServoParams.from_settings(settings or robot.servo_map.settings, **kw)
    where = f"{robot.robot_data.source}/robot.toml [servo]"
    return HobbyServoParams.from_table(robot.robot_data.servo, where)


def pwm_map(robot: Robot) -> Ssc32Map:
    """The robot's SSC-32 map (``ssc32.toml`` beside its URDF), else the default map (channel
    = joint index, 1500 µs at q = 0, 13.33 µs/°)."""
    from ..servos.ssc32 import Ssc32Map

    own = robot.urdf_path.parent / "ssc32.toml"
    if own.is_file():
        return Ssc32Map.from_file(own, robot.joint_names)
    return Ssc32Map.default(robot.joint_names)


class HobbyServoArray:
    """An SSC-32 board's outputs and the hobby servos on them (model joint order).

    **The board** (the thesis's Lynxmotion SSC-32, kokone-thesis.md §1.3–1.4) repeats a pulse
    on every powered channel once per frame (``frame_period``, 20 ms). A group move
    (:meth:`write`: pulses, optional time ``T``) makes each channel's pulse go linearly from
    where it is to the target in ``T`` (all channels arriving together), updated at every
    frame and rounded to 1 µs; without ``T``, or on a channel's first command, it jumps.
    :meth:`off` (``#<ch>L``) stops a channel's pulses.

    **The servo** (analog, no feedback wire) compares the last pulse it received with its
    potentiometer, in µs (``e = pulse − (center + sign · µs_per_rad · q)``), every
    ``period`` (analog: once per pulse) and holds its drive until the next update::

        u = 0                                        if |e| <= dead band
        u = sign(e) · min(1, (|e| − dead band) / proportional band)   otherwise
        τ = sign · τ_s · u                           (joint direction; |τ| <= τ_s)

    plus the motor's back-EMF ``−b · ω`` (``b = τ_s / ω_0``: MuJoCo joint damping while
    pulses arrive, so that the unloaded joint tops out at ``ω_0``). Without pulses (before
    the first move, after ``#L``, or a cut signal wire: ``silent``) the servo is limp.
    Nothing is quantised but the 1 µs pulse; the work is a few numpy operations per frame.
    """

    def __init__(self, codec: Codec, params: HobbyServoParams, dt: float) -> None:
        self.params = params
        self.offset = np.asarray(codec.offset, dtype=float).copy()
        self.scale = np.asarray(codec.scale, dtype=float).copy()  # µs per rad, signed
        self.signs = np.sign(self.scale)
        self.cmd_min, self.cmd_max = float(codec.cmd_min), float(codec.cmd_max)
        n = self.offset.size
        self.n = n
        self.dt = float(dt)
        self.frame_steps = _steps(params.frame_period, dt, "frame_period")
        self.loop_steps = _steps(params.period, dt, "loop_period")
        self.start = np.full(n, np.nan)  # board: pulse where the current move began (µs)
        self.target = np.full(n, np.nan)  # board: the move's target (µs); NaN = output off
        self.t0 = np.zeros(n)
        self.move_time = np.zeros(n)
        self.out = np.full(n, np.nan)  # board: the pulse of the last frame (µs)
        self.held = np.full(n, np.nan)  # servo: the last pulse it received (NaN: none)
        self.drive = np.zeros(n)  # servo: held drive u in -1..1
        self.silent = np.zeros(n, dtype=bool)  # signal wire cut: no pulses reach the servo
        self.torque = np.zeros(n)
        self.error = np.zeros(n, dtype=int)  # hobby servos report nothing: always 0
        self.steps = 0
        self.powered_changed = False

    @property
    def time(self) -> float:
        """The board's clock (s since :meth:`reset`)."""
        return self.steps * self.dt

    @property
    def enabled(self) -> np.ndarray:
        """Servos receiving pulses (driven; the back-EMF brake acts)."""
        return ~np.isnan(self.held)

    def reset(self, q: np.ndarray) -> None:
        """Board just powered, no pulses yet (servos limp at ``q``)."""
        self.start[:] = self.target[:] = self.out[:] = self.held[:] = np.nan
        self.drive[:] = 0.0
        self.torque[:] = 0.0
        self.silent[:] = False
        self.steps = 0
        self.powered_changed = True

    def pulses(self, q: np.ndarray) -> np.ndarray:
        """The pulse widths (µs, unrounded) that command joint angles ``q``."""
        return self.offset + self.scale * np.asarray(q, dtype=float)

    def angles(self, pulses: np.ndarray) -> np.ndarray:
        """Joint angles (rad) of pulse widths."""
        return (np.asarray(pulses, dtype=float) - self.offset) / self.scale

    def goal_angles(self) -> np.ndarray:
        """The board's move targets as joint angles (NaN where the output is off)."""
        return self.angles(self.target)

    def _now_pulse(self, t: float) -> np.ndarray:
        """The board's interpolated pulse at time ``t`` (µs, unrounded; NaN where off)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            f = np.where(self.move_time > 0, (t - self.t0) / self.move_time, 1.0)
        return self.start + (self.target - self.start) * np.clip(f, 0.0, 1.0)

    def write(
        self, pulses: np.ndarray, move_ms: float | None = None, mask: np.ndarray | None = None
    ) -> None:
        """A group move: the channels of ``mask`` (default all) go to ``pulses`` (µs) in
        ``move_ms`` (None/0: at the next frame); a channel's first command jumps."""
        pulses = np.asarray(pulses, dtype=float)
        mask = np.ones(self.n, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        if np.any(mask & ((pulses < self.cmd_min) | (pulses > self.cmd_max))):
            raise ServoError(f"SSC-32: pulse outside {self.cmd_min:g}..{self.cmd_max:g} µs")
        now = self.time
        cur = self._now_pulse(now)
        first = np.isnan(cur)
        self.start = np.where(mask, np.where(first, pulses, cur), self.start)
        self.target = np.where(mask, pulses, self.target)
        self.t0 = np.where(mask, now, self.t0)
        T = 0.0 if not move_ms else float(move_ms) * 1e-3
        self.move_time = np.where(mask, T, self.move_time)

    def off(self, mask: np.ndarray | None = None) -> None:
        """``#<ch>L``: no more pulses on the channels of ``mask`` (default all)."""
        mask = np.ones(self.n, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        self.start[mask] = self.target[mask] = np.nan

    def law(self, q: np.ndarray, dt: float) -> np.ndarray:
        """Advance one physics step of ``dt`` (the construction's) and return the joint
        torques (N·m) at ``q``: a frame every ``frame_steps``, a drive update every
        ``loop_steps`` (see the class docstring)."""
        k = self.steps
        self.steps += 1
        if k % self.frame_steps == 0:
            self.out = np.rint(self._now_pulse(k * self.dt))
            held = np.where(self.silent, np.nan, self.out)
            if not np.array_equal(np.isnan(held), np.isnan(self.held)):
                self.powered_changed = True
            self.held = held
        if k % self.loop_steps == 0:
            p = self.params
            e = self.held - self.pulses(q)
            mag = np.clip((np.abs(e) - p.dead_band_us) / p.proportional_band_us, 0.0, 1.0)
            self.drive = np.where(np.isnan(e), 0.0, np.sign(e) * mag)
            self.torque = self.signs * p.stall_torque * self.drive
        return self.torque


def _steps(period: float, dt: float, what: str) -> int:
    n = round(period / dt)
    if n < 1 or abs(n * dt - period) > 1e-9:
        raise ConfigurationError(
            f"{what} = {period} s is not a whole number of {dt} s physics steps"
        )
    return n
