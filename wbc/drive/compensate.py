"""The servo compliance feed-forward's defaults for driven walks (:class:`wbc.drive.walker.
Walker`'s ``compensate`` and ``correct``) and its load split over a walking double support
(:class:`LoadRamp`)."""

from __future__ import annotations

from types import MappingProxyType

from ..exceptions import ConfigurationError, WbcError
from ..model import Robot
from ..roles import SOLE_FRAMES
from ..types import SUPPORT_DOUBLE
from ..walking.spline import min_jerk

#: the AX-12A compliance feed-forward's gain for driven walks: with the encoders' correction
#: (``Walker(correct=True)``) 0.75, without it issue 30's 0.5 (benchmarks/drive.md: on the
#: randomised Bioloids the corrected ×0.75 falls least; the corrected ×0.5 threw the nominal
#: Bioloid at the sideways limit, ×1 the stiff, lightly damped models at the start)
DRIVE_COMPENSATE = MappingProxyType({True: 0.75, False: 0.5})


#: the encoders' correction's fit for driven walks (:class:`~wbc.balance.compliance.
#: EncoderCorrection`): a 1 s forgetting window and scales moving up to 3 /s, so that a stiff
#: servo's scale has dropped before the first steps (the defaults, 3 s and 1 /s, let the
#: stiffest randomised Bioloids fall sideways 2.3 s in: random sequences 4 falls of 100
#: against 2, benchmarks/drive.md)
DRIVE_CORRECTION = MappingProxyType({"window": 1.0, "rate": 3.0})


def default_compensate(robot: Robot | None = None, correct: bool = True) -> float:
    """The feed-forward gain a driven walk uses: on AX-12A servos (or ``robot`` None)
    :data:`DRIVE_COMPENSATE` (measured on driven walks); on other servo laws the commands'
    measured best (:func:`wbc.balance.best_compensate`: driven walks not measured there)."""
    if robot is not None:
        from ..balance import best_compensate
        from ..sim.actuator import servo_kind

        try:
            kind = servo_kind(robot)
        except WbcError:  # no servo model at all: nothing to feed forward
            return 0.0
        if kind != "ax12a":
            return best_compensate(robot)
    return DRIVE_COMPENSATE[bool(correct)]


class LoadRamp:
    """The compliance feed-forward's load split in a walking double support
    (:attr:`CompensatedSource.share <wbc.balance.compliance.CompensatedSource.share>`,
    ``Walker(load_ramp=True)``): from the sole that carried the single support before it to
    the sole that carries the one after it, min-jerk over ``ticks`` (the gait's double
    support), instead of by the CoM's place between the soles — which at a landing moves
    the feed-forward's share of the body onto the landed leg in one tick, and the rest of it
    at the lift-off. The left sole's share, or None (the CoM's split) in a double support
    that is no walk's: the start, the end, standing."""

    def __init__(self, ticks: int) -> None:
        if not (isinstance(ticks, int) and ticks >= 1):
            raise ConfigurationError(f"load ramp: ticks must be an integer >= 1, got {ticks}")
        self.ticks = ticks
        self._before: str | None = None  # the support sole of the last single support
        self._ramp: tuple[float, float, int] | None = None  # left share from, to; ticks done

    def update(self, support: int, support_frame: str) -> float | None:
        """One walk tick: its support and support sole (:class:`~wbc.walking.engine.
        EngineTick`'s, in double support the next single support's); the left share."""
        if support != SUPPORT_DOUBLE:
            self._before, self._ramp = support_frame, None
            return None
        if self._ramp is None:
            if self._before is None or self._before == support_frame:  # (no walk's transfer)
                return None
            left = float(self._before == SOLE_FRAMES["left"])
            self._ramp = (left, 1.0 - left, 0)
            self._before = None
        start, end, done = self._ramp
        done = min(done + 1, self.ticks)
        self._ramp = (start, end, done)
        f = float(min_jerk(done / self.ticks)[0])
        return start + f * (end - start)
