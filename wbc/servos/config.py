"""A deployment's settings (:class:`DeployConfig`) and their bounds: the rate, the soft
speed, the safe-stop and end actions (:mod:`wbc.servos.playback` plays them;
:mod:`wbc.servos.plan` budgets the bus for them)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..exceptions import ConfigurationError

MAX_RATE_HZ = 100.0
#: a soft start (and crouch) faster than this is no longer soft, rad/s
MAX_SOFT_SPEED = 1.0
ON_FAULT_CHOICES = ("auto", "hold", "torque-off", "crouch")
AT_END_CHOICES = ("hold", "torque-off")


@dataclass
class DeployConfig:
    """Playback and safety settings (speeds in rad/s, tolerances in rad, times in s)."""

    rate: float = 50.0
    read: bool = False  # read all present positions each tick (tracking error)
    on_fault: str = "auto"  # see the module docstring
    at_end: str = "hold"  # or "torque-off"
    max_speed: float | None = None  # default: min(URDF velocity limit, servo speed)
    soft_speed: float = 0.5  # soft start and crouch
    max_failures: int = 3
    start_tol: float = 0.05  # present position may lie this far outside the limits
    log_path: str | None = None
    fault_bound_s: float = 0.1  # health schedule: fault -> last goal
    crouch_pose: str = "stand"  # a named pose of the robot (its standing pose by default)

    def validate(self) -> None:
        if not (math.isfinite(self.rate) and 0 < self.rate <= MAX_RATE_HZ):
            raise ConfigurationError(f"rate must be in (0, {MAX_RATE_HZ:g}] Hz, got {self.rate}")
        if self.on_fault not in ON_FAULT_CHOICES:
            raise ConfigurationError(
                f"on_fault must be one of {ON_FAULT_CHOICES}, got {self.on_fault!r}"
            )
        if self.at_end not in AT_END_CHOICES:
            raise ConfigurationError(f"at_end must be one of {AT_END_CHOICES}, got {self.at_end!r}")
        for name in ("soft_speed", "start_tol", "fault_bound_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigurationError(f"{name} must be positive, got {v}")
        if self.soft_speed > MAX_SOFT_SPEED:
            raise ConfigurationError(
                f"soft_speed must be at most {MAX_SOFT_SPEED:g} rad/s (a soft start), "
                f"got {self.soft_speed}"
            )
        if self.max_speed is not None and not (
            math.isfinite(self.max_speed) and self.max_speed > 0
        ):
            raise ConfigurationError(f"max_speed must be positive, got {self.max_speed}")
        if self.max_failures < 1:
            raise ConfigurationError(f"max_failures must be >= 1, got {self.max_failures}")
