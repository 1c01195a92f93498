"""The gyro's bias trimmed while walking, from the encoders in double support
(:class:`StanceTrim`, ``Walker(gyro_trim=T0)``; off by default).

A zero-velocity update: in a walking double support both soles stand on the floor, so the
torso's angular velocity is the one its rotation over the soles by the encoders (forward
kinematics of the present links, the play out) shows, ``ω_enc = log(R_{k−1}ᵀ R_k) / dt``
(torso frame; the mean of the two soles' chains). What the calibrated gyro reads beyond
it, ``e = ω − ω_enc``, is the bias the odometry has not yet taken out, plus the torso's
motion inside the servos' play and the soles' own turn on the floor. The trim is the
residual's mean over all such ticks so far, weighted against a prior of no trim held for
``prior`` seconds, ``d = Σ e dt / (T0 + Σ dt)`` per axis (the vertical included), bounded by
:data:`TRIM_BOUND`; the outer loop's heading integrates ``ω − d``.

Measured against the simulator's true bias (``benchmarks/gyro_trim_probe.py --walk``,
benchmarks/drive.md 2026-12-07 twenty-third session): over the double supports of a 30 s
walk (soles within 5°) the residual about the vertical is 0.02–0.61°/s off the gyro's true
one on model 0 and model 3 — the rest's bias is 0.06–0.33°/s off: the soles turn on the
floor in double support (up to 1.8°/s on average over a walk) and the torso's motion inside
the play is sampled at one phase of the gait only (the torso's turn less the encoders' and
the sole's: up to ±1.1°/s), so neither averages out. The pitch axis' trim does converge
(13/0: −3.0 against the true −3.1°/s). Closed loop (``benchmarks/drive.py --gyro-trim 5``):
the held-out block 25/25 up, displacement within 15 % 24/25, heading 21/25, 21.3 mm /
5.09° against main's 25, 25, 13.1 mm / 1.02°. An option, off.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError
from ..model import Robot
from ..recording import SUPPORT_DOUBLE
from ..roles import SOLE_FRAMES
from .liftoff import normal_angle

#: the largest trim per axis (rad/s): 3°/s, the size of the start-up calibration's worst
#: error on the randomised Bioloids (benchmarks/drive.md)
TRIM_BOUND = math.radians(3.0)

#: the soles' relative tilt (°) above which a double support's tick is not taken (a sole on
#: its edge, rolling: the randomised Bioloids' edges 9–13°, flat double supports < 2–4°)
TRIM_FLAT_DEG = 5.0


class StanceTrim:
    """The gyro's remaining bias from the walking double supports (module docstring).
    ``prior`` (s, > 0): the weight of the prior (no trim) in seconds of double support;
    ``flat_deg``: the soles' relative tilt above which a tick is skipped."""

    def __init__(self, robot: Robot, prior: float, flat_deg: float = TRIM_FLAT_DEG) -> None:
        if not (math.isfinite(prior) and prior >= 0):
            raise ConfigurationError(
                f"gyro_trim must be a finite number >= 0 (s; 0: off), got {prior}"
            )
        if not (math.isfinite(flat_deg) and flat_deg > 0):
            raise ConfigurationError(
                f"gyro trim: flat_deg must be a finite angle > 0 (°), got {flat_deg}"
            )
        self.robot = robot
        self.prior = float(prior)
        self.flat = math.radians(flat_deg)
        self.bias = np.zeros(3)  #: the trim (rad/s, torso frame), taken out of the rate
        self.time = 0.0  #: s of double support taken
        self._sum = np.zeros(3)  # Σ e dt
        self._last: tuple[np.ndarray, np.ndarray] | None = None  # torso over (left, right)

    def sample(self, q: np.ndarray | None, double: bool, rate: np.ndarray, dt: float) -> np.ndarray:
        """One tick: ``q`` the present links' configuration (None: unread), ``double`` a
        walking double support, ``rate`` the gyro as the odometry takes it, its other bias
        terms out (:meth:`PoseOdometry.unbiased <wbc.drive.odometry.PoseOdometry.unbiased>`),
        the trim not; returns the trim (rad/s, torso frame) to take out of the rate."""
        rate = np.asarray(rate, dtype=float)
        last, self._last = self._last, None
        if q is None or not double:
            return self.bias
        soles = [SOLE_FRAMES["left"], SOLE_FRAMES["right"]]
        left, right = self.robot.placements_in(q, "torso", soles)
        if normal_angle(left.rotation.T @ right.rotation) > self.flat:
            return self.bias
        # torso over each sole: the inverse of the soles in the torso
        now = (left.rotation.T, right.rotation.T)
        self._last = now
        if last is not None:
            seen = 0.5 * (pin.log3(last[0].T @ now[0]) + pin.log3(last[1].T @ now[1]))
            self._sum += rate * dt - seen
            self.time += dt
            if self.prior + self.time > 0:
                mean = self._sum / (self.prior + self.time)
                self.bias = np.clip(mean, -TRIM_BOUND, TRIM_BOUND)
        return self.bias

    def walker_tick(self, walker: Any, e: Any, rotation: np.ndarray, rate: np.ndarray,
                    dt: float) -> np.ndarray:  # fmt: skip
        """:meth:`sample` from a :class:`~wbc.drive.walker.Walker`'s tick (its outer loop's
        odometry started): ``e`` the engine's tick, ``rotation`` and ``rate`` the heading's
        inputs; returns the trim."""
        double = e.support == SUPPORT_DOUBLE and walker.engine.walking
        q = walker._present_configuration() if double else None
        return self.sample(q, double, walker.odometry.unbiased(rotation, rate), dt)


def stance_trim(robot: Robot, prior: float, track: bool) -> StanceTrim | None:
    """The walker's trim: ``prior`` checked (:class:`StanceTrim`), None when off (0, or
    without the outer loop, ``track`` False)."""
    trim = StanceTrim(robot, prior)
    return trim if track and prior > 0 else None


def upward_crossings(x: np.ndarray) -> list[int]:
    """The samples where ``x`` turns from negative to non-negative."""
    return [int(k) + 1 for k in np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))]


class RestPeriods:
    """The rest's bias about the vertical over whole periods of the torso's rocking
    (``PoseOdometry(rest_periods=True)``, ``Walker(rest_periods=True)``; off): a torso
    rocking at rest twists inside the servos' play with it, and the rest's mean takes the
    incomplete period's share for bias. The window runs from the first to the last upward
    zero crossing of the de-meaned rate about the axis that rocks most (the torso's
    frame); with fewer than two crossings, the whole rest's mean stands.

    Measured against the simulator's bias (``benchmarks/gyro_trim_probe.py --rest``,
    benchmarks/drive.md 2026-12-07): model 0's error (pitch rocking ±14°/s) +0.165 →
    +0.008°/s and −0.184 → −0.039°/s, but on 20 rests of models 1–10 no better on average
    (0.071 against 0.073°/s); the held-out drive block's heading 1.54° against 1.02°
    (`condim` 3), 1.55° against 1.45° (`condim` 4): off."""

    def __init__(self) -> None:
        self._rates: list[np.ndarray] = []  # the gyro per rest tick (rad/s, torso frame)
        self._steps: list[float] = []  # the heading's change per rest tick (rad)
        self._dts: list[float] = []

    def add(self, rate: np.ndarray, step: float, dt: float, mean: float) -> float:
        """One rest tick (``step`` the heading's change over ``dt``); returns the bias over
        the whole periods so far, or ``mean`` (the whole rest's) without two crossings."""
        self._rates.append(np.asarray(rate, dtype=float))
        self._steps.append(float(step))
        self._dts.append(float(dt))
        rates = np.array(self._rates)
        rates -= rates.mean(axis=0)
        up = upward_crossings(rates[:, int(np.argmax(rates.std(axis=0)))])
        if len(up) < 2:
            return mean
        i, j = up[0], up[-1]
        return sum(self._steps[i:j]) / sum(self._dts[i:j])
