"""A lift-off held while a sole is off the floor's plane (:class:`FlatLiftoff`,
``Walker(flat_liftoff=deg)``; off by default).

On the lightly damped randomised Bioloids a sole sometimes lands on its heel or toe edge
(pitched 8–13° against the other sole) and the other sole lifts off all the same: the
single support then stands on an edge, where the floor resists no turn, and the body spins
on it (up to 33° in one single support; benchmarks/drive.md, 2026-12-07 twenty-first
session). Both soles are on the floor at a walking double support's end, so the angle
between their normals by the encoders, ``acos(R_rel[2, 2])`` with ``R_rel`` the landed
sole's rotation in the stance sole's frame (forward kinematics of the present positions),
is a tilt the IMU is not needed for. While it exceeds the threshold the lift-off waits,
at most :data:`FLAT_LIFTOFF_TICKS` ticks.
"""

from __future__ import annotations

import math

import numpy as np

from ..exceptions import ConfigurationError
from ..model import Robot
from ..roles import SOLE_FRAMES

#: the longest a lift-off waits for the soles to lie flat on each other (ticks)
FLAT_LIFTOFF_TICKS = 10


def normal_angle(rotation: np.ndarray) -> float:
    """The angle (rad) between a frame's normal ``R[:, 2]`` and its reference's ``z``:
    ``acos(R[2, 2])``."""
    return math.acos(min(1.0, max(-1.0, float(rotation[2, 2]))))


def tilt_vector(rotation: np.ndarray) -> np.ndarray:
    """The tilt of a frame of rotation ``rotation`` against its reference: the rotation
    vector (rad, in the reference) about a horizontal axis that takes the reference's
    normal ``z`` to the frame's ``n = R[:, 2]``, ``(z × n)/|z × n| · acos(n_z)``; its norm is
    the angle between the normals."""
    n = rotation[:, 2]
    axis = np.array([-n[1], n[0], 0.0])
    s = float(np.linalg.norm(axis))
    return axis * (normal_angle(rotation) / s) if s > 1e-12 else np.zeros(3)


def soles_tilt(robot: Robot, q: np.ndarray) -> float:
    """The angle (rad) between the two soles' normals in configuration ``q`` (forward
    kinematics; the norm of :func:`tilt_vector` of their relative rotation): 0 when both lie
    in one plane (the floor's)."""
    (rel,) = robot.placements_in(q, SOLE_FRAMES["left"], [SOLE_FRAMES["right"]])
    return normal_angle(rel.rotation)


class FlatLiftoff:
    """Hold a walking double support's last tick while the soles' relative tilt
    (:func:`soles_tilt`) exceeds ``tilt_deg`` (°), at most ``ticks`` ticks a lift-off.
    :meth:`landed` arms it at a double support's last tick; :meth:`hold` answers each tick
    after whether the engine waits."""

    def __init__(self, robot: Robot, tilt_deg: float, ticks: int = FLAT_LIFTOFF_TICKS) -> None:
        if not (math.isfinite(tilt_deg) and tilt_deg >= 0):
            raise ConfigurationError(
                f"flat_liftoff must be a finite angle >= 0 (°; 0: off), got {tilt_deg}"
            )
        if not (isinstance(ticks, int) and ticks >= 1):
            raise ConfigurationError(f"flat lift-off: ticks must be an integer >= 1, got {ticks}")
        self.robot = robot
        self.tilt = math.radians(tilt_deg)
        self.ticks = ticks
        self._left = 0  # ticks this lift-off may still wait
        self.held = 0  #: ticks waited over the walk
        self.lift_offs_held = 0  #: lift-offs that waited at least a tick

    def landed(self, q: np.ndarray | None) -> None:
        """A walking double support's last tick (the landing's record): the next tick may
        wait if the soles in ``q`` (present positions; None: unread) are not flat."""
        self._left = self.ticks if q is not None and soles_tilt(self.robot, q) > self.tilt else 0

    @property
    def armed(self) -> bool:
        """A lift-off may still wait (:meth:`hold` reads the soles only then)."""
        return self._left > 0

    def hold(self, q: np.ndarray | None) -> bool:
        """Whether this tick waits (the engine not advanced): armed, some wait left and the
        soles in ``q`` still tilted (unread: no wait)."""
        if self._left <= 0:
            return False
        if q is None or soles_tilt(self.robot, q) <= self.tilt:
            self._left = 0
            return False
        if self._left == self.ticks:
            self.lift_offs_held += 1
        self._left -= 1
        self.held += 1
        return True

    def cancel(self) -> None:
        """No wait pending (a walk's end)."""
        self._left = 0
