"""The CoM target moved vertically on plants identified soft (``Gains.lift``, off).

A soft servo plant (issue 30: servos softer than ``servos.toml``, no feed-forward) loses
the walk's end with a stance knee near its stall torque. ``lift`` (m) moves the walk's CoM
target vertically (+: up; −: down, the way measured better: −8 mm kept every soft plant of
seeds 0 and 1, but traded one on a held-out seed; benchmarks/physics.md) once the
stiffness identified at the start-up rest (:func:`wbc.balance.live.closed_loop`'s rest,
:func:`~wbc.balance.compliance.identify_stiffness`) is below ``lift_stiff`` × servos.toml's,
ramped in over the walk's first :data:`LIFT_RAMP` s. Not identified, nothing moves.
:class:`LiftedStabilizer` is the :class:`~wbc.balance.stabilizer.Stabilizer` with the
move applied to its adjusted targets (the closed loop builds it only when ``lift`` is set:
off, the stabilizer is main's).
"""

from __future__ import annotations

import numpy as np

from .stabilizer import Stabilizer

#: s: the lift ramped in from the walk's first tick (the rest's pose, then the lifted one)
LIFT_RAMP = 0.5


def lift_height(lift: float, stiff: float, scale: float | None, t: float) -> float:
    """m the CoM target moves up at walk time ``t`` (s) with ``lift`` and ``lift_stiff``
    ``stiff`` for a plant identified at ``scale`` × servos.toml's (None: not identified)."""
    if lift == 0.0 or scale is None or not scale < stiff:
        return 0.0
    return lift * min(max(t / LIFT_RAMP, 0.0), 1.0)


class LiftedStabilizer(Stabilizer):
    """A :class:`~wbc.balance.stabilizer.Stabilizer` whose adjusted CoM target moves up by
    :func:`lift_height` (``Gains.lift``, ``Gains.lift_stiff``)."""

    t0: float | None = None  # the reference time of the walk's first tick

    def adjust(self, targets, com_vel_ref: np.ndarray, q_cmd: np.ndarray, dt: float):
        """:meth:`Stabilizer.adjust`, then the CoM target lifted (not during the rest)."""
        out = super().adjust(targets, com_vel_ref, q_cmd, dt)
        if not self.enabled or self.calibrating:
            return out
        if self.t0 is None:
            self.t0 = float(targets.t)
        g = self.gains
        dz = lift_height(g.lift, g.lift_stiff, self.stiffness_scale, float(targets.t) - self.t0)
        if dz == 0.0:
            return out
        com = np.array(out.com, dtype=float)  # (a copy: the reference's row is shared)
        com[2] += dz
        return out.retarget(com, out.torso_rotation)
