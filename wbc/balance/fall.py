"""Fall detection and a safe fall.

:class:`FallDetector` looks at every tick's state estimate
(:class:`~wbc.balance.estimator.StateEstimate`) inside the closed loop and declares a state
beyond recovery when any of:

* **tilt**: the torso is more than ``tilt`` (rad, 40°) from its target orientation (the
  reference's, with the hip strategy's deliberate roll: :mod:`wbc.balance.stabilizer`),
  ``|e_xy|`` with ``e = log(R_est R_targetᵀ)``;
* **tilt and rate**: more than ``tilt_moving`` (20°) and still turning away from it faster
  than ``rate`` (rad/s, 2): ``ω_xy · ê_xy > rate`` (world-frame gyro rate along the
  error's horizontal axis);
* **DCM**: the estimated DCM further than ``reach`` (m) from every stance sole's rectangle
  (held for ``dcm_ticks`` ticks; the rectangles, not their hull: between the feet that is at
  most half their gap, far below ``reach``): no step lands there in time
  (:func:`wbc.balance.stepping.capture_bounds`: 0.09–0.16 m of landing shift on the
  Bioloid; beyond it the LIPM diverges whatever the feet do).

The closed loop then raises :class:`~wbc.exceptions.FallDetected` from the tick; the
deployment's safe stop (:mod:`wbc.servos.playback`, action ``fall`` under ``on_fault=auto``)
runs :meth:`~wbc.servos.playback.Deployment.safe_fall`: lower the torque limit (the servos
give way on impact instead of stalling), move at full speed to the robot's protective posture
(its ``crouch`` pose: CoM low, knees bent), wait ``settle_s`` for the impact, then torque off
— verified per servo — logging why (the trip's reason names the criterion and its values).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..exceptions import ConfigurationError, FallDetected
from ..servos.playback import FALL_SETTLE_S, FALL_TORQUE_LIMIT


@dataclass(frozen=True)
class FallParams:
    """Thresholds of :class:`FallDetector` and the safe fall (module docstring)."""

    tilt: float = math.radians(40.0)  # rad
    tilt_moving: float = math.radians(20.0)  # rad
    rate: float = 2.0  # rad/s away from the target
    reach: float = 0.15  # m of DCM beyond the support polygon (the legs reach ~0.1–0.16 m)
    dcm_ticks: int = 3  # consecutive ticks the DCM must be beyond reach
    torque_limit: float = FALL_TORQUE_LIMIT  # share of the servos' maximum torque in the fall
    settle_s: float = FALL_SETTLE_S  # s in the protective posture before torque off

    def check(self) -> FallParams:
        for name in ("tilt", "tilt_moving", "rate", "reach", "torque_limit", "settle_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigurationError(f"fall: {name} must be a finite number >= 0, got {v}")
        if self.torque_limit > 1:
            raise ConfigurationError(
                f"fall: torque_limit must be in [0, 1], got {self.torque_limit}"
            )
        if int(self.dcm_ticks) != self.dcm_ticks or self.dcm_ticks < 1:
            raise ConfigurationError(
                f"fall: dcm_ticks must be an integer >= 1, got {self.dcm_ticks}"
            )
        return self


class FallDetector:
    """Declares a fall from the state estimate (module docstring); :attr:`time` is the
    estimator clock (s since the first tick) at the detection."""

    def __init__(self, params: FallParams | None = None, foot: tuple[float, float] = (0.1, 0.06)):
        self.params = (params or FallParams()).check()
        self.half = 0.5 * np.asarray(foot, dtype=float)  # sole half length, half width (m)
        self.t = 0.0
        self.started = False
        self.beyond = 0
        self.time: float | None = None
        self.reason: str | None = None

    def _outside(self, soles, x: float, y: float) -> float:
        """Distance (m) from (x, y) to the nearest sole rectangle (0 inside one)."""
        hx, hy = float(self.half[0]), float(self.half[1])
        best = math.inf
        for placement in soles:
            R, p = placement.rotation, placement.translation
            dx, dy = x - float(p[0]), y - float(p[1])
            lx = abs(R[0, 0] * dx + R[1, 0] * dy) - hx  # in the sole's frame (yaw only)
            ly = abs(R[0, 1] * dx + R[1, 1] * dy) - hy
            best = min(best, math.hypot(max(lx, 0.0), max(ly, 0.0)))
        return best

    def update(self, est, soles, dt: float, error: np.ndarray) -> str | None:
        """One tick: ``est`` the estimate, ``soles`` the stance sole placements (pin.SE3),
        ``error`` the torso's orientation error from its target (rotation vector, world).
        Returns the reason of a fall (and raises nothing), else None. The detector's clock
        (:attr:`t`, s) is 0 at its first update."""
        if self.started:
            self.t += dt
        self.started = True
        p = self.params
        tilt = math.hypot(float(error[0]), float(error[1]))
        reason = None
        if tilt > p.tilt:
            reason = f"torso tilted {math.degrees(tilt):.0f}° (> {math.degrees(p.tilt):.0f}°)"
        elif tilt > p.tilt_moving:
            w = est.rotation @ est.angular_velocity
            away = float(w[0] * error[0] + w[1] * error[1]) / tilt
            if away > p.rate:
                reason = (
                    f"torso tilted {math.degrees(tilt):.0f}° and falling at {away:.1f} rad/s "
                    f"(> {math.degrees(p.tilt_moving):.0f}° and {p.rate:g} rad/s)"
                )
        if reason is None:
            dcm = est.dcm
            out = self._outside(soles, float(dcm[0]), float(dcm[1]))
            self.beyond = self.beyond + 1 if out > p.reach else 0
            if self.beyond >= p.dcm_ticks:
                reason = (
                    f"DCM {1e3 * out:.0f} mm beyond the support (> {1e3 * p.reach:.0f} mm: "
                    "no step reaches it)"
                )
        if reason is not None and self.reason is None:
            self.time, self.reason = self.t, reason
        return reason

    def raise_if_falling(self, est, soles, dt: float, error: np.ndarray) -> None:
        """:meth:`update`, raising :class:`~wbc.exceptions.FallDetected` on a fall."""
        reason = self.update(est, soles, dt, error)
        if reason is not None:
            raise FallDetected(f"fall detected at {self.t:.2f} s: {reason}")
