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
    :func:`twist_factor` (module docstring): its compiled tick is given a copy of the packed
    gains with ``k_twist`` × :attr:`twist` (the gains themselves never changed)."""

    _twisted: tuple = (None, 1.0, None)  # (the gains' consts, a factor, them with it: _consts)

    @property
    def twist(self) -> float:
        """This tick's factor on ``k_twist`` (1: untouched; not during the rest)."""
        g = self.gains
        if not self.enabled or g.stiff_twist == 1.0 or self.calibrating:
            return 1.0
        return twist_factor(g.stiff_twist, g.lift_stiff, self.stiffness_scale)

    def _consts(self) -> np.ndarray:
        """:meth:`Stabilizer._consts` with ``k_twist`` × :attr:`twist` (a copy when it is not
        1)."""
        k, f = super()._consts(), self.twist
        if f == 1.0:
            return k
        base, held, twisted = self._twisted
        if base is not k or held != f:
            twisted = k.copy()
            twisted[_K_TWIST] = self.gains.k_twist * f
            self._twisted = (k, f, twisted)
        return twisted


@cache
def stiff_class(base: type[Stabilizer]) -> type[Stabilizer]:
    """``base`` (a :class:`~wbc.balance.stabilizer.Stabilizer` class) with ``stiff_twist``
    applied to the gains its compiled tick is given (one class per base:
    :class:`StiffStabilizer` for the stabilizer itself)."""
    if base is Stabilizer:
        return StiffStabilizer
    return type(f"Stiff{base.__name__}", (base, StiffStabilizer), {})
