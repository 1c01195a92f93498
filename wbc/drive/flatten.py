"""A landed sole flattened on the floor from the encoders' tilt (:class:`SoleFlatten`,
``Walker(flatten=rate)``; off by default).

On the lightly damped randomised Bioloids a landed sole sometimes rolls onto its heel or
toe edge as the load comes onto it (1–4° against the other sole at the touch-down, 5–13° at
the lift-off), the other sole lifts all the same and the single support stands on an edge,
where the floor resists no turn (benchmarks/drive.md, 2026-12-07 twenty-first and
twenty-second sessions). The controller's model has the
sole flat (its contact target); the plant's joints (compliance, play, latency) do not.

Both soles are on the floor in a walking double support, so the landed sole's tilt against
the stance sole by the encoders (:func:`~wbc.drive.liftoff.tilt_vector` of their relative
rotation, forward kinematics of the present positions: the rotation about a horizontal axis
taking the stance sole's normal to the landed one's, ``v``) is its tilt on the floor, with
no IMU. The landed sole's contact target is tilted against it, an integral loop: each tick
of that double support ``c ← c + min(1, k·dt)·v`` (``k``: ``rate``, 1/s), ``|c|`` at most
``max_deg``, and the target's rotation ``exp(−c)·Rz(ψ)``: what the plant adds, ``d``, the
target takes away (``v ≈ d − c`` → 0). At the other sole's lift-off ``c`` fades out of the
standing sole's target over ``fade`` ticks (with one sole down there is nothing to read it
against; held, it tilted the next double support and the loop ran away), and a sole that
lifts with a correction left has it faded out of the swing's rotation target likewise.
``band_deg``: a dead band, the tilt's size less it taken (0: all of it). Both soles'
contact targets and the swing's rotation only; positions as planned. Measured
(benchmarks/drive.md, 2026-12-07 twenty-second session): off.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError
from ..model import Robot
from ..roles import SOLE_FRAMES
from ..walking.loop import TickTargets
from .liftoff import tilt_vector

#: the largest tilt (°) the landed sole's target takes against the measured one
FLATTEN_MAX_DEG = 15.0
#: ticks over which a lifted sole's correction fades out of the swing's rotation target
FLATTEN_FADE_TICKS = 10

_FRAMES = {frame: side for side, frame in SOLE_FRAMES.items()}


class SoleFlatten:
    """The landed sole's contact target tilted against its measured tilt on the floor, by
    an integral loop over each walking double support (module docstring). :meth:`update`
    once a walk tick, after the contact targets are set."""

    def __init__(
        self,
        robot: Robot,
        rate: float,
        max_deg: float = FLATTEN_MAX_DEG,
        fade: int = FLATTEN_FADE_TICKS,
        band_deg: float = 0.0,
    ) -> None:
        if not (math.isfinite(rate) and rate >= 0):
            raise ConfigurationError(
                f"flatten must be a finite rate >= 0 (1/s; 0: off), got {rate}"
            )
        if not (math.isfinite(max_deg) and max_deg > 0):
            raise ConfigurationError(f"flatten: max_deg must be a finite angle > 0, got {max_deg}")
        if not (math.isfinite(band_deg) and band_deg >= 0):
            raise ConfigurationError(f"flatten_band must be a finite angle >= 0, got {band_deg}")
        if not (isinstance(fade, int) and fade >= 1):
            raise ConfigurationError(f"flatten: fade must be an integer >= 1, got {fade}")
        self.robot = robot
        self.rate = float(rate)
        self.max = math.radians(max_deg)
        self.fade = fade
        self.band = math.radians(band_deg)
        #: per sole in contact, its correction (world, horizontal rotation vector, rad)
        self.correction: dict[str, np.ndarray] = {}
        self._fading: tuple[str, np.ndarray, int] | None = None  # (swing frame, c, ticks left)
        self._stance: tuple[str, np.ndarray, int] | None = None  # (frame, c, ticks left)
        self._swing: str | None = None  # the swing frame of the last single support
        self._landed: str | None = None  # the sole that landed into this double support
        self.largest = 0.0  #: the largest correction taken over the walk (rad)

    def update(self, targets: TickTargets, q: np.ndarray | None, walking: bool, dt: float) -> None:
        """One tick: ``targets`` (their contact placements set, :func:`~wbc.drive.contacts.
        move_contacts`) get the held corrections; in a walking double support the landed
        sole's grows by the measured tilt in ``q`` (present positions; None: unread)."""
        if targets.phase == "single":
            swing = targets.swing
            if self._swing != swing:  # a lift-off: the lifted sole's correction fades out
                c = self.correction.pop(swing, None)
                self._fading = None if c is None else (swing, c, self.fade)
                if targets.support in self.correction:  # the standing sole's fades out
                    c = self.correction[targets.support]
                    self._stance = (targets.support, c, self.fade)
            self._swing, self._landed = swing, None
            self._fade(targets)
            if self._stance is not None:
                frame, c, left = self._stance
                if left > 0:
                    self.correction[frame] = c * (left - 1) / self.fade
                    self._stance = (frame, c, left - 1)
        else:
            self._fading = self._stance = None
            if self._swing is not None and self._landed is None:
                self._landed = self._swing  # it landed into this double support
            landed = self._landed
            if walking and landed is not None and q is not None and self.rate > 0:
                stance = SOLE_FRAMES["right" if _FRAMES[landed] == "left" else "left"]
                (rel,) = self.robot.placements_in(q, stance, [landed])
                flat = targets.sole(stance).rotation  # (the stance sole's target: flat)
                v = flat @ tilt_vector(rel.rotation)
                size = float(np.linalg.norm(v))
                v *= max(0.0, 1.0 - self.band / size) if size > 0 else 0.0  # the dead band
                c = self.correction.get(landed, np.zeros(3)) + min(1.0, self.rate * dt) * v
                c[2] = 0.0
                norm = float(np.linalg.norm(c))
                if norm > self.max:
                    c *= self.max / norm
                self.correction[landed] = c
                self.largest = max(self.largest, min(norm, self.max))
        for frame, c in self.correction.items():
            if frame == targets.support or targets.phase == "double":
                held = targets.sole(frame)
                placed = pin.SE3(pin.exp3(-c) @ held.rotation, held.translation)
                if frame == SOLE_FRAMES["left"]:
                    targets.l_sole = placed
                else:
                    targets.r_sole = placed

    def _fade(self, targets: TickTargets) -> None:
        """The lifted sole's correction, shrinking, on the swing's rotation target."""
        if self._fading is None:
            return
        frame, c, left = self._fading
        share = left / (self.fade + 1)
        targets.swing_rotation = pin.exp3(-share * c) @ targets.swing_rotation
        self._fading = (frame, c, left - 1) if left > 1 else None
