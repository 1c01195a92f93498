"""The servo compliance feed-forward's defaults for driven walks (:class:`wbc.drive.walker.
Walker`'s ``compensate`` and ``correct``)."""

from __future__ import annotations

from types import MappingProxyType

from ..exceptions import WbcError
from ..model import Robot

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
