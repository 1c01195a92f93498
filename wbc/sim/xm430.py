"""The Dynamixel XM430-W350 as an actuator: its position PID computed every physics step.

The third servo law of the simulator (:func:`wbc.sim.actuator.nominal_servo`), for robots whose
``servos.toml`` says ``[bus] protocol = 2.0`` (the ROBOTIS OP3); its gains, current limit and
Shutdown come from the same :class:`wbc.xseries.XSettings` the deployment writes to the servos.

Figures and sources (ROBOTIS e-Manual, XM430-W350 page: specifications and control table;
../shared/reference/physics.md §2 for the MuJoCo joint properties):

* stall torque ``τ_s = 4.1 N·m`` and no-load speed ``ω_0 = 46 rev/min = 4.82 rad/s`` at
  12.0 V; stall current 2.3 A;
* encoder: 4096 ticks per revolution; the servo compares its goal with its own quantised
  position (``e`` in ticks);
* position mode's PID (e-Manual "Position P/I/D Gain"): ``K_P = P / 128``,
  ``K_I = I / 65536``, ``K_D = D / 16``, the output a PWM in 0..885 (the PWM limit, 100 %)::

      pwm = K_P · e + K_I · Σ e + K_D · Δe        (per control cycle, ``LOOP_S``)
      u   = clip(pwm / 885, −1, 1)
      τ   = clip(τ_s · u, −cap, cap) − b · ω      (b · ω: the joint damping in MuJoCo)

  The sum and difference are per control cycle; the cycle is not published: ``LOOP_S`` =
  1 ms is an ESTIMATE (the integral and derivative are scaled by ``dt / LOOP_S``);
  at the factory P = 800 the small-error stiffness is ``τ_s · K_P / 885 / rad_per_tick``
  = 18.9 N·m/rad (the OP3's MuJoCo model in mujoco_menagerie uses kp = 21.1, physics.md §2);
* ``cap = τ_s · min(1, I_lim / I_stall)`` with the Current Limit (38, 2.69 mA units): with
  the factory 1193 (3.2 A) it does not bind. (On the real servo in position mode (3) the
  current is not regulated; the register limits it in the current-based modes.)
* Profile Velocity (112): the goal the PID tracks moves toward the written goal at most at
  this speed (``set_speed``; 0 = the no-load speed). Profile acceleration is not modelled
  (the settings must leave it 0);
* back-EMF ``b = τ_s / ω_0 = 0.85 N·m·s/rad`` (joint damping while torque is on), reflected
  rotor inertia (armature) 0.045 kg·m² and gear friction 0.03 N·m (mujoco_menagerie
  ``robotis_op3``, physics.md §2);
* overload: an output saturated for ``overload_time`` (1 s, as the AX-12A model: an
  assumption) raises Hardware Error bit 0x20; with it in Shutdown (63), torque goes off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..exceptions import ConfigurationError
from ..servo_map import ServoMap
from ..xseries import CURRENT_UNIT_A, HW_OVERLOAD, X_RAD_PER_TICK, XSettings
from .servo_ticks import TickServos

STALL_TORQUE = 4.1  # N·m at 12 V (e-Manual XM430-W350)
NO_LOAD_SPEED = 46.0 * 2.0 * math.pi / 60.0  # rad/s at 12 V (e-Manual)
STALL_CURRENT = 2.3  # A at 12 V (e-Manual)
PWM_MAX = 885.0  # PWM Limit (36) maximum = 100 % (e-Manual)
LOOP_S = 1e-3  # ESTIMATE: the firmware's control cycle (not published)
ARMATURE = 0.045  # kg·m², mujoco_menagerie robotis_op3 (physics.md §2)
FRICTION_LOSS = 0.03  # N·m, same source
OVERLOAD_TIME = 1.0  # s, as the AX-12A model (assumption)


@dataclass(frozen=True)
class XServoParams:
    """Per-joint XM430 parameters (model joint order) from the X-series settings."""

    kp: np.ndarray  # PWM units per tick
    ki: np.ndarray  # PWM units per tick·cycle
    kd: np.ndarray  # PWM units per tick/cycle
    torque_cap: np.ndarray  # N·m
    stall_torque: float = STALL_TORQUE
    no_load_speed: float = NO_LOAD_SPEED
    armature: float = ARMATURE
    friction_loss: float = FRICTION_LOSS
    damping: float = STALL_TORQUE / NO_LOAD_SPEED
    overload_time: float = OVERLOAD_TIME
    shutdown: int = 0x34
    name: str = "XM430-W350"

    @classmethod
    def from_settings(cls, settings: XSettings, **kwargs) -> XServoParams:
        """Parameters of the registers in ``settings`` (``robot.servo_map.settings``)."""
        if np.any(settings.profile_acceleration != 0):
            raise ConfigurationError(
                "the XM430 simulation does not model a profile acceleration: leave "
                "[settings] profile_acceleration at 0 to simulate this robot"
            )
        stall = kwargs.pop("stall_torque", STALL_TORQUE)
        current = settings.current_limit.astype(float) * CURRENT_UNIT_A
        return cls(
            kp=settings.position_p_gain.astype(float) / 128.0,
            ki=settings.position_i_gain.astype(float) / 65536.0,
            kd=settings.position_d_gain.astype(float) / 16.0,
            torque_cap=stall * np.minimum(1.0, current / STALL_CURRENT),
            stall_torque=stall,
            shutdown=settings.shutdown,
            **{k: v for k, v in kwargs.items() if v is not None},
        )

    @property
    def stiffness(self) -> np.ndarray:
        """Small-error stiffness (N·m/rad) of the P term: ``τ_s · K_P / 885 / rad_per_tick``."""
        return self.stall_torque * self.kp / PWM_MAX / X_RAD_PER_TICK

    def deflection(self, tau: np.ndarray) -> np.ndarray:
        """Position error δ (rad, joint direction) at which the P term alone holds ``tau``
        (N·m): the static inverse of the law without its integral,
        ``δ = sign(τ) · min(|τ|, cap) / k`` (``k``: :attr:`stiffness`; a joint with P = 0:
        no deflection). The integral removes this error over ``K_P / K_I`` cycles (the OP3's
        knees: about 1 s), longer than a step: what the servo shows while walking."""
        tau = np.asarray(tau, dtype=float)
        k = self.stiffness
        mag = np.minimum(np.abs(tau), np.minimum(self.torque_cap, self.stall_torque))
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(k > 0, np.sign(tau) * mag / k, 0.0)

    @property
    def integral_time(self) -> np.ndarray:
        """The PI's integral time ``T_i = K_P / K_I · LOOP_S`` (s; inf without an I gain):
        a load held longer than that is taken over by the integral, the error decaying as
        ``exp(−t / T_i)`` (quasi-static: ``k e + (k / T_i) ∫ e dt = τ``)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.ki > 0, self.kp / self.ki * LOOP_S, np.inf)

    def scaled(self, stiffness: float = 1.0, torque: float = 1.0) -> XServoParams:
        """A copy with the gains ``stiffness`` times higher and the torque cap scaled."""
        return replace(
            self,
            kp=self.kp * stiffness,
            ki=self.ki * stiffness,
            kd=self.kd * stiffness,
            torque_cap=self.torque_cap * torque,
        )


class XServoArray(TickServos):
    """The state and law of all XM430 servos of a robot (vectorised over joints); the same
    interface as :class:`wbc.sim.actuator.ServoArray` (ticks in, joint torques out)."""

    rad_per_tick = X_RAD_PER_TICK

    def __init__(self, servo_map: ServoMap, params: XServoParams) -> None:
        self.params = params
        self.signs = servo_map.signs.copy()
        self.zero = servo_map.zero_ticks.copy()
        n = len(servo_map)
        self.n = n
        self.goal = np.zeros(n)
        self.tracked = np.zeros(n)
        self.speed = np.full(n, NO_LOAD_SPEED / X_RAD_PER_TICK)  # ticks/s
        self.enabled = np.zeros(n, dtype=bool)
        self.shutdown = np.zeros(n, dtype=bool)
        self.error = np.zeros(n, dtype=int)  # Hardware Error Status bits
        self.at_limit_time = np.zeros(n)
        self.integral = np.zeros(n)  # Σ e (tick·cycles)
        self.last_error = np.zeros(n)
        self.torque = np.zeros(n)
        self._scale = 1.0 / X_RAD_PER_TICK

    def reset(self, q: np.ndarray) -> None:
        """Servos at rest at ``q``: goals there, torque off, no errors, PID state cleared."""
        self.goal[:] = np.rint(self.ticks(q))
        self.tracked[:] = self.goal
        self.enabled[:] = False
        self.shutdown[:] = False
        self.error[:] = 0
        self.at_limit_time[:] = 0.0
        self.integral[:] = 0.0
        self.last_error[:] = 0.0
        self.torque[:] = 0.0

    def present(self, q: np.ndarray) -> np.ndarray:
        """Present Position (132): the quantised position (ticks)."""
        return np.rint(self.ticks(q))

    def law(self, q: np.ndarray, dt: float) -> np.ndarray:
        """Advance the profile by ``dt`` and return the joint torques (N·m) at ``q``."""
        p = self.params
        step = self.speed * dt
        self.tracked += np.clip(self.goal - self.tracked, -step, step)
        e = self.tracked - self.present(q)
        active = self.enabled & ~self.shutdown
        cycles = dt / LOOP_S
        with np.errstate(divide="ignore", invalid="ignore"):
            wind = np.where(p.ki > 0, PWM_MAX / p.ki, 0.0)  # anti-windup: |K_I Σe| <= 885
        self.integral = np.where(active, np.clip(self.integral + e * cycles, -wind, wind), 0.0)
        de = (e - self.last_error) / cycles
        self.last_error = e
        pwm = p.kp * e + p.ki * self.integral + p.kd * de
        u = np.clip(pwm / PWM_MAX, -1.0, 1.0)
        drive = p.stall_torque * u
        tau = np.clip(drive, -p.torque_cap, p.torque_cap)
        at_limit = np.abs(drive) >= p.torque_cap - 1e-12
        self.at_limit_time = np.where(active & at_limit, self.at_limit_time + dt, 0.0)
        over = self.at_limit_time >= p.overload_time
        if np.any(over):
            self.error[over] |= HW_OVERLOAD
            if p.shutdown & HW_OVERLOAD:
                self.shutdown |= over
                active = active & ~over
        self.torque = np.where(active, self.signs * tau, 0.0)
        return self.torque
