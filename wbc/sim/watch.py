"""Did the simulated robot stay up? The fall thresholds, and :class:`UprightWatch`.

A run *falls* when the torso deviates more than :data:`FALL_TILT_DEG` from its reference
orientation or drops below :data:`FALL_HEIGHT` of its reference height (the physics
benchmark, :func:`wbc.bench.sim_record.physics_record`, compares with the plan;
:class:`UprightWatch` with the start, for ``wbc deploy --sim``, which has no plan).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .simulator import Simulation

#: deg: a torso tilted further than this from its reference has fallen
FALL_TILT_DEG = 45.0
#: a torso below this share of its reference height has fallen
FALL_HEIGHT = 0.6


class UprightWatch:
    """What the physics did during ``wbc deploy --sim`` (no plan to compare with): the
    largest torso tilt from its start, and a fall (tilt > 45° or the torso below 60 % of its
    start height, as the physics benchmark's thresholds), checked every control tick."""

    def __init__(self, sim: Simulation) -> None:
        self.sim = sim
        self.limits = (FALL_TILT_DEG, FALL_HEIGHT)
        self.R0 = sim.base_rotation()
        self.z0 = float(sim.q()[2])
        self.xy0 = sim.q()[:2].copy()
        self.t0 = sim.time
        self.tilt_max = 0.0
        self.fell_at: float | None = None

    def __call__(self) -> None:
        R = self.sim.base_rotation()
        tilt = math.degrees(math.acos(np.clip((np.trace(self.R0.T @ R) - 1.0) / 2.0, -1, 1)))
        if self.fell_at is None:
            self.tilt_max = max(self.tilt_max, tilt)
            if tilt > self.limits[0] or self.sim.q()[2] < self.limits[1] * self.z0:
                self.fell_at = self.sim.time - self.t0

    def line(self) -> str:
        """One line: fell (when) or stayed up, the largest torso tilt, the base's travel."""
        moved = 1e3 * np.linalg.norm(self.sim.q()[:2] - self.xy0)
        if self.fell_at is not None:
            return f"sim: FELL at {self.fell_at:.2f} s (torso tilt {self.tilt_max:.1f}° then)"
        return (
            f"sim: stayed up; torso tilt at most {self.tilt_max:.1f}° from the start, "
            f"the base moved {moved:.0f} mm"
        )
