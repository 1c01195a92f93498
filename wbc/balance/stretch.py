"""The pushed swing given the time its re-planned landing needs (``SteppingParams.stretch``).

A push at mid single support leaves the swing ~90 ms: its re-planned landing is clipped to the
room that time leaves at the foot speed (:meth:`~.stepping.StepAdjuster.place`: ``room = v /
ġ_max``, the bend's peak rate ``ġ_max`` in the reference's time). With the walk's clock run at
``r`` (< 1) the same bend takes ``1 / r`` as long, so the room at the same foot speed is
``room / r``: the clock is slowed just enough that the room covers the change the re-plan
wants, ``r = room / |Δ|``, but no slower than ``1 / (1 + stretch)`` (the swing's time left
at most ``1 + stretch`` times as long); the landing is placed with that room. Each re-plan
decides anew: one whose change the room covers at the reference's pace puts the clock back
to it (the earlier bend then asked faster than the foot speed, the servos' limiter lagging
it). Kept slowed to the landing instead (every later room at the slowed pace), the backward
screen kept 3 of 8 pushes against this form's 7 (both at 0.5) and main's 5. On by default
at 0.3: of 80 backward pushes at seven push times it keeps every push main keeps and 8 more
(43 against 35; 16 against 11 on the 27 at times no earlier screen used); the bisected mean
reads 0.734 against main's 0.742 N·s (the survival is not monotone near the bound)
(benchmarks/pushes.md, twenty-first session).
"""

from __future__ import annotations


class SwingStretch:
    """The clock rate a stretched swing runs at (:meth:`room` sets it, :meth:`rate` reads it):
    one per :class:`~.stepping.StepAdjuster`."""

    def __init__(self, stretch: float) -> None:
        self.stretch = stretch
        self.phase = -1  # the stretched swing's phase index (-1: none)
        self.clock = 1.0  # its clock's rate

    def room(self, phase: int, room: float, change: float) -> float:
        """The room (m) of the swing of phase ``phase`` for a landing change of ``change`` m,
        its time left stretched (the clock slowed) when ``room`` (at the reference's pace)
        cannot cover it."""
        rate = 1.0
        if self.stretch > 0 and change > room > 0:
            rate = max(room / change, 1.0 / (1.0 + self.stretch))
        self.phase, self.clock = (phase, rate) if rate < 1.0 else (-1, 1.0)
        return room / rate

    def rate(self, phase: int) -> float | None:
        """The clock's rate in the swing of phase ``phase`` when it is stretched, else
        None."""
        return self.clock if phase == self.phase else None
