"""The AX-12A as an actuator: the servo's control law computed every physics step.

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

import numba
import numpy as np

from ..servo_map import RAD_PER_TICK, ServoMap, ServoSettings

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


class ServoArray:
    """The state and law of all servos of a robot (vectorised over joints).

    Positions and goals are in the servo map's ticks; torques are returned in the joint's
    (URDF) direction.
    """

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

    def ticks(self, q: np.ndarray) -> np.ndarray:
        """Unquantised ticks of joint angles."""
        return self.zero + self.signs * q * self._scale

    def angles(self, ticks: np.ndarray) -> np.ndarray:
        """Joint angles of ticks."""
        return self.signs * (ticks - self.zero) * RAD_PER_TICK

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
