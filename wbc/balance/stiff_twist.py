"""The torso command's twist scaled on servos identified stiff (``Gains.stiff_twist``, off).

The torso command's part about the torso target's own vertical axis (its twist: the heading
feedback, and the part of a roll about the heading that a leaned torso turns into a twist)
is what the hip yaws carry (``Gains.k_twist``, :mod:`wbc.balance.stabilizer`). On a plant whose
servos are stiff and late (issue 30, the plant-randomised sweep's last three losses: 11–18 ms of
goal latency; traced, benchmarks/physics.md, nineteenth session) that loop rings: both hip yaws
driven to their stall torque, the stance sole spun on the floor (a heading slip of 7–14° in
one single support) and, its command at the shared clip, the tilt starved. ``stiff_twist``
scales ``k_twist`` on a plant whose stiffness identified at the start-up rest
(:func:`wbc.balance.live.closed_loop`, :func:`~wbc.balance.compliance.identify_stiffness`)
is at least ``lift_stiff`` × servos.toml's — the complement of the soft plants ``lift``, the
walk's end and ``soft_hip`` act on. Not identified, nothing moves. :func:`stiff_class` gives
the stabilizer class that applies it (the closed loop builds it only when ``stiff_twist`` is
set: off, the stabilizer is main's).

The servos' lag measured online (:func:`wbc.balance.servo_lag.servo_lag`) does not tell these
plants apart: it reads the servo's own following more than its delay (the nominal plant
35–38 ms, the stiff, late ones 17–31 ms; benchmarks/physics.md), so the stiffness identified
at rest is the gate.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from .stabilizer import _K_TWIST, Stabilizer
from .stance_lift import identified_soft


def twist_factor(stiff_twist: float, stiff: float, scale: float | None) -> float:
    """The factor on ``k_twist`` with ``stiff_twist`` and ``lift_stiff`` ``stiff`` for a plant
    identified at ``scale`` × servos.toml's (None: not identified): ``stiff_twist`` on an
    identified plant at least ``stiff``, else 1."""
    if scale is None or identified_soft(stiff, scale):
        return 1.0
    return stiff_twist


class StiffStabilizer(Stabilizer):
    """A :class:`~wbc.balance.stabilizer.Stabilizer` whose torso command's twist is scaled by
    :func:`twist_factor` (module docstring)."""

    twist = 1.0  # the factor of the last tick (1: untouched)

    def adjust(self, targets, com_vel_ref: np.ndarray, q_cmd: np.ndarray, dt: float):
        """The tick's ``k_twist`` scaled (:func:`twist_factor`), then the stabilizer's adjust."""
        g = self.gains
        if self.enabled and g.stiff_twist != 1.0 and not self.calibrating:
            f = twist_factor(g.stiff_twist, g.lift_stiff, self.stiffness_scale)
            k = self._consts()  # (the packed gains of the tick: set in place from g's)
            k[_K_TWIST] = g.k_twist * f
            self.twist = f
        return super().adjust(targets, com_vel_ref, q_cmd, dt)


@cache
def stiff_class(base: type[Stabilizer]) -> type[Stabilizer]:
    """``base`` (a :class:`~wbc.balance.stabilizer.Stabilizer` class) with ``stiff_twist``
    applied after its own :meth:`adjust` work and before the stabilizer's (one class per
    base: :class:`StiffStabilizer` for the stabilizer itself)."""
    if base is Stabilizer:
        return StiffStabilizer
    return type(f"Stiff{base.__name__}", (base, StiffStabilizer), {})
