"""Joint angles ↔ servo ticks: the part every simulated servo array shares (the AX-12A's
:class:`~wbc.sim.actuator.ServoArray`, the XM430's :class:`~wbc.sim.xm430.XServoArray`)."""

from __future__ import annotations

import numpy as np


class TickServos:
    """Joint angles ↔ servo ticks of a servo array (``signs``, ``zero`` ticks, and
    ``_scale`` = 1 / :attr:`rad_per_tick`, set by the array)."""

    rad_per_tick: float
    signs: np.ndarray
    zero: np.ndarray
    goal: np.ndarray
    _scale: float

    def ticks(self, q: np.ndarray) -> np.ndarray:
        """Unquantised ticks of joint angles."""
        return self.zero + self.signs * q * self._scale

    def angles(self, ticks: np.ndarray) -> np.ndarray:
        """Joint angles of ticks."""
        return self.signs * (ticks - self.zero) * self.rad_per_tick

    def goal_angles(self) -> np.ndarray:
        """The written goals as joint angles (rad)."""
        return self.angles(self.goal)
