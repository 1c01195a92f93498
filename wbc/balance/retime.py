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
:class:`PhaseHold` is passed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..exceptions import WbcError
from ..recording import SUPPORT_DOUBLE
from ..walking.reference import WalkingReference


@dataclass(frozen=True)
class HoldParams:
    """When a lift-off waits (module docstring)."""

    band: float = 0.04  # m: DCM error toward the sole about to lift that is left alone
    max_hold: float = 1.0  # s: longest wait of one lift-off

    def check(self) -> HoldParams:
        for name in ("band", "max_hold"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise WbcError(f"hold: {name} must be a finite number >= 0, got {v}")
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

    def error(self, ref: WalkingReference, i: int, dcm: np.ndarray) -> float:
        """``e = (ξ − ξ_ref)·v`` at tick ``i`` (a single support): the DCM's error toward the
        sole that lifts there."""
        stance = ref.stance_side(i)
        if stance is None:
            raise WbcError(f"tick {i} is not a single support")
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
        if e <= self.params.band or self._waited + dt > self.params.max_hold + 1e-9:
            self._waited = 0.0
            return False
        if self._waited == 0.0:
            self.holds += 1
        self._waited += dt
        self.held += dt
        return True


#: s: the longest single support whose sway is narrowed (measured: narrowing the 0.4 s single
#: supports of ``fast_wb`` costs travelled distance, 0.90 → 0.89 of its plan at 3 mm)
SWAY_LONGEST = 0.3


def narrowed_sway(
    ref: WalkingReference, shift: float, longest: float = SWAY_LONGEST
) -> WalkingReference:
    """``ref`` with its CoM moved ``shift`` m toward the swing sole in every single support,
    smoothly: ``δ(t) = shift · sin(π s) · v`` (``s`` the phase's elapsed share, ``v`` the
    stance sole's lateral axis, toward the other sole), its velocity and
    acceleration added to the CoM's. At mid single support the DCM moves by ``shift`` too
    (``δ̇ = 0`` there), so a push away from the swing foot starts ``shift`` further from the
    stance sole's outer edge; the ZMP moves by ``shift (1 + (π/(ω T))²) sin(π s)`` inward
    (``T`` the phase's duration). Only single supports of at most ``longest`` s are changed;
    ``shift = 0`` or a static gait (its CoM stays over the stance sole): ``ref`` itself."""
    if not (math.isfinite(shift) and shift >= 0):
        raise WbcError(f"sway shift must be a finite number >= 0, got {shift}")
    if shift == 0 or ref.gait != "dynamic":
        return ref
    com, vel, acc = ref.com.copy(), ref.com_vel.copy(), ref.com_acc.copy()
    t = ref.t
    for a, b, _ in ref.phases():
        stance = ref.stance_side(a)
        if stance is None or b - a < 2 or (b - a) * ref.dt > longest + 1e-9:
            continue
        lift = "right" if stance == "left" else "left"
        k = np.arange(a, b)
        pos, yaw = ref.sole(stance)
        v = np.array([-math.sin(yaw[a]), math.cos(yaw[a])])  # the stance sole's lateral axis,
        if (ref.sole(lift)[0][a, :2] - pos[a, :2]) @ v < 0:  # toward the other sole
            v = -v
        T = (b - a) * ref.dt  # the phase runs until the next one's first tick
        w = math.pi / T
        s = (t[k] - t[a]) * w
        com[k, :2] += shift * np.sin(s)[:, None] * v
        vel[k, :2] += shift * w * np.cos(s)[:, None] * v
        acc[k, :2] -= shift * w * w * np.sin(s)[:, None] * v
    return replace(ref, com=com, com_vel=vel, com_acc=acc)
