"""The walk engine's gait (:class:`EngineParams`) and velocity limits
(:class:`VelocityLimits`, measured on a robot by :meth:`VelocityLimits.from_robot`);
:mod:`wbc.walking.engine` re-exports both."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..exceptions import ConfigurationError, TrajectoryError
from .geometry import Foot
from .legs import LegGeometry
from .preview import PreviewParams
from .reference import StandingState
from .schedule import GaitTiming, SwingParams
from .window import BalanceWindow


@dataclass(frozen=True)
class EngineParams:
    """Gait of the engine. Defaults: the whole-body walks' (``fast_wb``, ``turn_wb``,
    ``lateral_wb``): 0.5 s steps with 20 % double support, the torso leaning over the stance
    sole (``whole_body``: a :class:`~wbc.drive.walker.Walker` measures the balance window),
    the ZMP 18 mm in from each sole's centre, reached within 15 % of each double support; a
    10 mm swing apex (12 mm: the Bioloid's forward limit is 7.5 cm/s within 0.75 of the
    servo speed, 10 mm: 8.7 cm/s). The legs-only walks' gait (``walk10``: 0.4 s steps, the
    torso upright, the ZMP 28.5 mm in, ``whole_body=False``) asks the swing knee for more than
    that speed rule allows at any stride (its planning limits are 0; benchmarks/drive.md)."""

    timing: GaitTiming = field(
        default_factory=lambda: GaitTiming(step_time=0.5, double_support_ratio=0.2)
    )
    swing: SwingParams = field(default_factory=lambda: SwingParams(apex=0.010))
    zmp_offset: tuple[float, float] = (0.0, 0.018)
    transfer: float = 0.15
    #: lean the torso over the stance sole (the whole-body balance window)
    whole_body: bool = True
    preview: PreviewParams = field(default_factory=PreviewParams)
    horizon_steps: int = 4
    min_clearance: float = 0.005
    #: share of the start phase the ZMP stays put before it moves onto the first stance sole
    start_hold: float = 0.2
    #: points along each planned swing (ends included) where the feet's clearance is checked
    swing_samples: int = 7
    #: the largest make-up of the commanded pose's lag per step, as a share of the velocity
    #: limits (diamond norm) on top of the command: a start or a change is caught up gently
    #: (at the limits a randomised Bioloid falls sideways, benchmarks/drive.md)
    catch_up: float = 0.25
    #: a stop's closing step lands where the commanded pose at the stop puts the walking
    #: frame (:meth:`WalkEngine._closing`; False: beside the stance sole, as before)
    close_on_target: bool = True
    #: share of each swing at its end in which the sole only comes down: its horizontal
    #: move and turn end that much earlier (the same min-jerk profile, compressed), so a
    #: sole touching down early — a lagging, compliant leg — lands in place instead of
    #: dragging (0: off; 0.2 measured better on the random sets, benchmarks/drive.md)
    settle: float = 0.2

    def check(self) -> EngineParams:
        self.timing.validate()
        self.swing.validate()
        self.preview.validate()
        if self.timing.double_support_time < self.timing.dt:
            raise ConfigurationError("walk engine: the gait needs a double support of >= 1 tick")
        if not (0.0 < self.transfer <= 1.0):
            raise ConfigurationError(
                f"walk engine: transfer must be in (0, 1], got {self.transfer}"
            )
        if int(self.horizon_steps) != self.horizon_steps or self.horizon_steps < 1:
            raise ConfigurationError(
                f"walk engine: horizon_steps must be a positive integer, got {self.horizon_steps}"
            )
        if not (math.isfinite(self.catch_up) and self.catch_up >= 0):
            raise ConfigurationError(f"walk engine: catch_up must be >= 0, got {self.catch_up}")
        if not (0.0 <= self.settle < 1.0):  # (NaN too)
            raise ConfigurationError(f"walk engine: settle must be in [0, 1), got {self.settle}")
        if not all(math.isfinite(v) for v in self.zmp_offset):
            raise ConfigurationError(f"walk engine: zmp_offset must be finite, {self.zmp_offset}")
        return self


@dataclass(frozen=True)
class VelocityLimits:
    """The largest commands (m/s, rad/s): forward, backward, sideways, turning. A combined
    command is scaled into the diamond ``|vx|/vx_max + |vy|/vy_max + |ωz|/wz_max <= 1``."""

    vx_forward: float
    vx_backward: float
    vy: float
    wz: float

    def check(self) -> VelocityLimits:
        for name in ("vx_forward", "vx_backward", "vy", "wz"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v >= 0):  # (inf: no limit; NaN fails)
                raise ConfigurationError(f"velocity limit {name} must be a number >= 0, got {v}")
        return self

    def clip(self, vx: float, vy: float, wz: float) -> tuple[float, float, float]:
        """The command scaled (direction kept) into the limits."""
        vxm = self.vx_forward if vx >= 0 else self.vx_backward
        s = 0.0
        for v, m in ((vx, vxm), (vy, self.vy), (wz, self.wz)):
            if v != 0.0:
                s += math.inf if m <= 0 else abs(v) / m
        if s <= 1.0:
            return float(vx), float(vy), float(wz)
        if math.isinf(s):  # an axis with no range: drop it, scale the rest
            vx, vy, wz = (v if m > 0 else 0.0 for v, m in ((vx, vxm), (vy, self.vy), (wz, self.wz)))
            return self.clip(vx, vy, wz)
        return float(vx / s), float(vy / s), float(wz / s)

    def as_dict(self) -> dict[str, float]:
        return dict(self.__dict__)

    @classmethod
    def from_robot(
        cls,
        robot: Any,
        params: EngineParams | None = None,
        window: BalanceWindow | None = None,
        legs: LegGeometry | None = None,
        foot: Foot | None = None,
        fraction: float | None = None,
        iterations: int = 6,
    ) -> VelocityLimits:
        """Measured on the model: per axis, the largest per-step stride (bisection) whose
        three-step walk (:func:`wbc.walking.gait.walk_steps` with this gait) passes the
        walks' checks (reach, hip roll or the balance window, clearance, ZMP margin) and is
        tracked by the bounded IK (:func:`kinematic_feasibility`) with no joint faster than
        ``fraction`` (default :data:`PLANNING_SPEED_FRACTION`) of its servo's speed; divided
        by the step time. A pre-motion computation (a few seconds)."""
        from .feasibility import PLANNING_SPEED_FRACTION, kinematic_feasibility
        from .gait import walk_steps

        params = (params or EngineParams()).check()
        fraction = PLANNING_SPEED_FRACTION if fraction is None else fraction
        stand = robot.configuration("stand")
        start = StandingState.from_robot(robot, stand)
        legs = legs or LegGeometry.from_robot(robot, stand)
        foot = foot or Foot(*robot.foot_size)
        margin = 0.010 if window is not None else 0.001  # (the walks' ZMP margins)

        def ok(stride: tuple[float, float, float]) -> bool:
            try:
                ref = walk_steps(
                    start, 3, stride, timing=params.timing, swing=params.swing, foot=foot,
                    legs=legs, window=window, zmp_offset=params.zmp_offset, margin=margin,
                    min_clearance=params.min_clearance,
                )  # fmt: skip
            except TrajectoryError:
                return False
            rep = kinematic_feasibility(robot, ref, torques=False)
            if not rep.feasible:
                return False
            j = robot.joint_names.index(rep.speed_joint) if rep.speed_joint else 0
            return rep.max_joint_speed <= fraction * robot.v_max[j]

        def largest(axis: int, sign: float, hi: float) -> float:
            lo = 0.0
            for _ in range(iterations):
                mid = 0.5 * (lo + hi)
                stride = [0.0, 0.0, 0.0]
                stride[axis] = sign * mid
                if ok((stride[0], stride[1], stride[2])):
                    lo = mid
                else:
                    hi = mid
            return lo

        T = params.timing.step_time
        reach = legs.thigh + legs.shin
        return cls(
            largest(0, 1.0, 0.6 * reach) / T,
            largest(0, -1.0, 0.6 * reach) / T,
            largest(1, 1.0, 0.3 * reach) / T,
            largest(2, 1.0, 0.6) / T,
        ).check()


__all__ = ["EngineParams", "VelocityLimits"]
