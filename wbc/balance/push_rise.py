"""The push's rise: the CoM target raised after a push away from the swing foot (issue 30).

A push out past the stance sole's outer edge leaves the CoP on that edge ``e`` and the CoM
``x`` inside it: the LIPM with a varying height, ``ẍ = (x − e)(g + z̈)/z``, pulls the CoM
back the harder the more the body accelerates upward while ``x − e < 0``; the rise's end
(``z̈ < 0``) gives some back, later, with the CoM nearer the edge, so the net is a catch
(``Δẋ ≈ −a τ² ẋ / z`` for an up-and-stop of ``a`` over ``τ`` each, ``ẋ`` the push's CoM
speed). Lowering instead loses it (benchmarks/pushes.md, twenty-second session).

:class:`PushRise` (``Gains.push_rise`` m; 0: off): from the tick the hip strategy's push
trigger fires (``hip_jump``) the CoM target's height is raised to ``push_rise`` within
``rise_time`` s, held while the trigger is latched or the push's kick lasts (until the hip
strategy's roll is back to 0), then lowered back at ``push_rise / rise_back`` m/s.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .gains import Gains


class PushRise:
    """The rise's state for one walk (:meth:`raised`, called by
    :meth:`Stabilizer.adjust <wbc.balance.stabilizer.Stabilizer.adjust>`)."""

    __slots__ = ("dz", "since")

    def __init__(self) -> None:
        self.dz = 0.0  # m: the CoM target's height offset now
        self.since = 0.0  # s since the push trigger fired (0: not pushed)

    def update(self, pushed: bool, dt: float, rise: float, rise_time: float, back: float) -> float:
        """The height offset (m) for this tick: ``rise × min(t / rise_time, 1)`` ``t`` s after
        the trigger while ``pushed`` (never lower than it already is), else back toward 0 at
        ``rise / back`` m/s."""
        if pushed:
            self.since += dt
            self.dz = max(self.dz, rise * min(self.since / rise_time, 1.0))
        else:
            self.since = 0.0
            self.dz = max(self.dz - rise * dt / back, 0.0)
        return self.dz

    def raised(self, com: np.ndarray, pushed: bool, dt: float, g: Gains) -> np.ndarray:
        """``com`` (the CoM target, world) raised by this tick's offset (``g``: the
        :class:`~wbc.balance.gains.Gains`; ``com`` itself when the offset is 0)."""
        dz = self.update(pushed, dt, g.push_rise, g.rise_time, g.rise_back)
        if dz == 0.0:
            return com
        out = np.array(com, dtype=float)
        out[2] += dz
        return out
