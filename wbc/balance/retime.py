"""Re-timing the walk after a push: hold the double support until the DCM allows a lift-off.

A walking reference keeps its own clock; a pushed robot does not. After a sideways push the
robot may still be catching itself on its old stance sole (its DCM far outward of it, the
other sole in the air or only just down) when the plan's next single support begins — and that
support lifts the very sole the robot stands on. :class:`PhaseHold` delays the plan instead:
inside the closed loop (:class:`~wbc.walking.loop.Session`'s ``hold``), at the first tick of a
single support on sole ``S`` (the other sole ``F`` about to lift), with ``v`` the horizontal
unit vector from ``S`` toward ``F`` and ``ξ``, ``ξ_ref`` the estimated and planned DCM,

    e = (ξ − ξ_ref) · v

the lift-off waits (the session replays the last double-support tick: both soles down, the
CoM asked where the plan wants it at the lift-off) while ``e > band``, at most ``max_hold``
seconds per lift-off; then the walk resumes where it stopped, later by the time held (the
rest of the plan is not re-timed: its CoM, soles and phases just start later). Unpushed walks
never hold: their ``e`` stays below the band (benchmarks/pushes.md). Off unless a
:class:`PhaseHold` is passed. With ``contact`` (off) the lift-off also waits while the sole
``S`` is not down (the estimator's contact detection, ``Gains.contact_band``: the soles'
lowest points from the IMU and the encoders): a landing the push made late.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..exceptions import ConfigurationError, TrajectoryError
from ..recording import SUPPORT_DOUBLE
from ..walking.reference import WalkingReference


@dataclass(frozen=True)
class HoldParams:
    """When a lift-off waits (module docstring)."""

    band: float = 0.04  # m: DCM error toward the sole about to lift that is left alone
    max_hold: float = 1.0  # s: longest wait of one lift-off
    #: the lift-off also waits while the sole it stands the robot on is not down (the
    #: estimator's contact detection, ``Gains.contact_band``: a late landing; off)
    contact: bool = False

    def check(self) -> HoldParams:
        for name in ("band", "max_hold"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigurationError(f"hold: {name} must be a finite number >= 0, got {v}")
        return self


class PhaseHold:
    """Decides, tick by tick, whether the walk's next lift-off waits (module docstring).

    ``holds`` counts the lift-offs that waited, ``held`` the total time waited (s) and
    ``worst`` the largest ``e`` (m) seen at a lift-off (the margin of the unpushed walks)."""

    def __init__(self, params: HoldParams | None = None) -> None:
        self.params = (params or HoldParams()).check()
        self.holds = 0
        self.held = 0.0
        self.worst = -math.inf
        self._waited = 0.0  # s waited at the current lift-off
        #: the state estimator whose contact detection ``contact`` reads (set by
        #: wbc.balance.live.closed_loop; None: the DCM alone)
        self.contact: Any = None

    def error(self, ref: WalkingReference, i: int, dcm: np.ndarray) -> float:
        """``e = (ξ − ξ_ref)·v`` at tick ``i`` (a single support): the DCM's error toward the
        sole that lifts there."""
        stance = ref.stance_side(i)
        if stance is None:
            raise TrajectoryError(f"tick {i} is not a single support")
        lift = "right" if stance == "left" else "left"
        v = ref.sole(lift)[0][i, :2] - ref.sole(stance)[0][i, :2]
        v = v / max(math.hypot(v[0], v[1]), 1e-9)
        return float((np.asarray(dcm[:2], float) - ref.dcm_at(i)) @ v)

    def wait(self, ref: WalkingReference, last: int, i: int, dcm: np.ndarray, dt: float) -> bool:
        """True if the walk, at tick ``last`` (double support) and due at tick ``i`` (single
        support), should stay at ``last`` for ``dt`` more seconds."""
        if ref.support[last] != SUPPORT_DOUBLE or ref.support[i] == SUPPORT_DOUBLE:
            self._waited = 0.0
            return False
        e = self.error(ref, i, dcm)
        if self._waited == 0.0:
            self.worst = max(self.worst, e)
        late = False  # the sole the lift-off stands on not down yet (``contact``)
        if self.params.contact and self.contact is not None:
            late = not self.contact.down[0 if ref.stance_side(i) == "left" else 1]
        ready = e <= self.params.band and not late
        if ready or self._waited + dt > self.params.max_hold + 1e-9:
            self._waited = 0.0
            return False
        if self._waited == 0.0:
            self.holds += 1
        self._waited += dt
        self.held += dt
        return True
