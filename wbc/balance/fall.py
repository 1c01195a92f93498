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
  (:func:`wbc.balance.capture.capture_bounds`: 0.09–0.16 m of landing shift on the
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

import numba
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


#: :func:`fall_code`'s answers (0: no fall) and its limits' layout (``FallDetector.limits``)
TILT, TILT_RATE, DCM = 1, 2, 3
_L_TILT, _L_MOVING, _L_RATE, _L_REACH, _L_TICKS, _L_HALF, _L_SIZE = 0, 1, 2, 3, 4, 5, 7
#: :func:`fall_code`'s state (``FallDetector.state``): the DCM's consecutive ticks beyond
#: reach; the last tilt (rad), its rate away (rad/s) and the DCM's distance (m) computed; the
#: detector's clock (s) and whether it started (1/0: :meth:`FallDetector.tick`)
_F_BEYOND, _F_TILT, _F_AWAY, _F_OUT, _F_T, _F_STARTED, _F_SIZE = 0, 1, 2, 3, 4, 5, 6


@numba.njit(cache=True)
def fall_tick(state: np.ndarray, dt: float) -> None:
    """The detector's clock advanced by ``dt`` (0 at its first tick)."""
    if state[_F_STARTED] > 0.5:
        state[_F_T] += dt
    state[_F_STARTED] = 1.0


@numba.njit(cache=True, error_model="numpy")
def fall_code(
    e: np.ndarray,
    R: np.ndarray,
    omega: np.ndarray,
    dcm: np.ndarray,
    soles: np.ndarray,
    count: int,
    limits: np.ndarray,
    state: np.ndarray,
) -> int:
    """One tick of :meth:`FallDetector.update` (module docstring), compiled (the closed
    loop's tick calls it inside its kernel, :mod:`wbc.balance.stabilizer`): ``e`` the
    orientation error (world), ``R``, ``omega``, ``dcm`` the estimate's rotation, gyro rate
    (torso frame) and DCM, ``soles[:count]`` the stance soles' homogeneous placements,
    ``limits`` the thresholds (``_L_*``), ``state`` the counter and the values (``_F_*``,
    updated). Returns 0, :data:`TILT`, :data:`TILT_RATE` or :data:`DCM`."""
    tilt = math.hypot(e[0], e[1])
    state[_F_TILT] = tilt
    if tilt > limits[_L_TILT]:
        return TILT
    if tilt > limits[_L_MOVING]:
        w = np.dot(np.ascontiguousarray(R), np.ascontiguousarray(omega))  # (numpy's BLAS R @ ω)
        away = (w[0] * e[0] + w[1] * e[1]) / tilt
        state[_F_AWAY] = away
        if away > limits[_L_RATE]:
            return TILT_RATE
    best = math.inf  # the distance to the nearest sole rectangle (0 inside one)
    for k in range(count):
        A = soles[k]
        dx, dy = dcm[0] - A[0, 3], dcm[1] - A[1, 3]
        lx = abs(A[0, 0] * dx + A[1, 0] * dy) - limits[_L_HALF]  # in the sole's frame (yaw)
        ly = abs(A[0, 1] * dx + A[1, 1] * dy) - limits[_L_HALF + 1]
        best = min(best, math.hypot(max(lx, 0.0), max(ly, 0.0)))
    state[_F_OUT] = best
    state[_F_BEYOND] = state[_F_BEYOND] + 1.0 if best > limits[_L_REACH] else 0.0
    return DCM if state[_F_BEYOND] >= limits[_L_TICKS] else 0


class FallDetector:
    """Declares a fall from the state estimate (module docstring); :attr:`time` is the
    estimator clock (s since the first tick) at the detection."""

    def __init__(self, params: FallParams | None = None, foot: tuple[float, float] = (0.1, 0.06)):
        self.params = (params or FallParams()).check()
        self.half = 0.5 * np.asarray(foot, dtype=float)  # sole half length, half width (m)
        p = self.params
        self.limits = np.r_[p.tilt, p.tilt_moving, p.rate, p.reach, p.dcm_ticks, self.half]
        self.state = np.zeros(_F_SIZE)
        self.time: float | None = None
        self.reason: str | None = None

    @property
    def t(self) -> float:
        """The detector's clock (s; 0 at its first tick)."""
        return float(self.state[_F_T])

    @property
    def started(self) -> bool:
        return bool(self.state[_F_STARTED])

    @property
    def beyond(self) -> int:
        """Consecutive ticks the DCM has been beyond ``reach``."""
        return int(self.state[_F_BEYOND])

    def update(self, est, soles, dt: float, error: np.ndarray) -> str | None:
        """One tick: ``est`` the estimate, ``soles`` the stance sole placements (pin.SE3),
        ``error`` the torso's orientation error from its target (rotation vector, world).
        Returns the reason of a fall (and raises nothing), else None. The detector's clock
        (:attr:`t`, s) is 0 at its first update."""
        self.tick(dt)
        placements = np.array([s.homogeneous for s in soles])
        code = fall_code(np.asarray(error, dtype=float), np.asarray(est.rotation, dtype=float),
                         np.asarray(est.angular_velocity, dtype=float),
                         np.asarray(est.dcm, dtype=float), placements, len(placements),
                         self.limits, self.state)  # fmt: skip
        return self.declare(code)

    def tick(self, dt: float) -> None:
        """Advance the detector's clock by ``dt`` (0 at its first tick; the closed loop's
        tick does this inside its kernel, :func:`fall_tick`)."""
        fall_tick(self.state, dt)

    def declare(self, code: int) -> str | None:
        """The reason of :func:`fall_code`'s answer ``code`` (None: no fall), kept as the
        first fall's (:attr:`reason`, :attr:`time`)."""
        if code == 0:
            return None
        p, st = self.params, self.state
        tilt = math.degrees(st[_F_TILT])
        if code == TILT:
            reason = f"torso tilted {tilt:.0f}° (> {math.degrees(p.tilt):.0f}°)"
        elif code == TILT_RATE:
            reason = (
                f"torso tilted {tilt:.0f}° and falling at {st[_F_AWAY]:.1f} rad/s "
                f"(> {math.degrees(p.tilt_moving):.0f}° and {p.rate:g} rad/s)"
            )
        else:
            reason = (
                f"DCM {1e3 * st[_F_OUT]:.0f} mm beyond the support (> {1e3 * p.reach:.0f} mm: "
                "no step reaches it)"
            )
        if self.reason is None:
            self.time, self.reason = self.t, reason
        return reason

    def raise_if_falling(self, est, soles, dt: float, error: np.ndarray) -> None:
        """:meth:`update`, raising :class:`~wbc.exceptions.FallDetected` on a fall."""
        self.raise_for(self.update(est, soles, dt, error))

    def raise_for(self, reason: str | None) -> None:
        """Raise :class:`~wbc.exceptions.FallDetected` for ``reason`` (a fall's), if any."""
        if reason is not None:
            raise FallDetected(f"fall detected at {self.t:.2f} s: {reason}")
