"""Standing still after a walk: when a driven robot stands, no torso feedback.

The torso feedback (:class:`~wbc.balance.stabilizer.Gains` ``k_p``, ``k_i``, ``k_d``: the
torso target tilted against the estimated tilt error and the gyro's rate) closes a loop
through the servos' latency and play. On the stiff, lightly damped randomised Bioloid with
12 ms of latency (model 0 of benchmarks/drive.md) it rings in double support: the torso
rolls at ~12 Hz, ±150°/s, the solved hip yaws follow the leaning torso's commanded roll
(±2°), and the soles, both loaded, stick and slip and turn the standing robot by 2–25°/s
either way (a trace: benchmarks/drive.md, thirteenth session). ``k_d`` off alone keeps it
ringing (``k_p`` with the latency suffices). Standing on both flat soles the robot needs no
torso feedback — the rest before the walk already stands without it
(:data:`~wbc.drive.walker.DRIVE_YAW_REST_S`) — so :class:`QuietStand` says when the walker
stands still: ``"standing"``, the engine standing (the walk's end phase over, or not yet
started); ``"end"``, from the landing of a closing step on (the walk's end phase, the
double support in which the CoM settles between the soles, too), a finish step's double
supports as well (its 0.8 s start phase rang and turned model 0 by 23°).
"""

from __future__ import annotations

from ..exceptions import ConfigurationError
from ..recording import SUPPORT_DOUBLE
from ..walking.engine import EngineTick

#: when a driven robot (with the outer loop) stands without torso feedback: ``"end"`` from
#: its closing step's landing (and a finish step's double supports), ``"standing"`` once the
#: engine stands, ``""`` never (the behaviour before 2026-12-06). Random sequences 3 and 1 ×
#: randomised Bioloids 0–9, 4 s after the stop (benchmarks/drive.md, thirteenth session):
#: model 0's heading error 31.3 / 10.3° -> 2.2 / 3.5°, no fall, no failed solve
DRIVE_QUIET_STAND = "end"

QUIET_STAND_MODES = ("", "standing", "end")


class QuietStand:
    """Whether the walker stands still this tick (``mode``: :data:`DRIVE_QUIET_STAND`'s;
    ``on`` False: never, the mode checked all the same)."""

    def __init__(self, mode: str = DRIVE_QUIET_STAND, on: bool = True) -> None:
        if mode not in QUIET_STAND_MODES:
            raise ConfigurationError(
                f"quiet_stand must be one of {', '.join(map(repr, QUIET_STAND_MODES))}, "
                f"got {mode!r}"
            )
        self.mode = mode if on else ""
        self._stopped = False  # a walk's end phase seen since the last start

    def __call__(self, e: EngineTick, starting: bool, ending: bool) -> bool:
        """True when the walker stands still at engine tick ``e`` (``starting``: a start asked
        for; ``ending``: the walk's end phase, :attr:`WalkEngine.ending
        <wbc.walking.engine.WalkEngine.ending>`). With ``"end"``, after a walk's end phase a
        finish step's double supports (its start and end phases) stand still too, until the
        next :meth:`start`."""
        if e.state == "standing":  # (a start asked after a walk's end: a finish step)
            return bool(self.mode) and (not starting or (self.mode == "end" and self._stopped))
        if self.mode != "end":
            return False
        self._stopped = self._stopped or ending
        return ending or (self._stopped and e.support == SUPPORT_DOUBLE)

    def start(self) -> None:
        """A walk starts (not a finish step): the torso feedback on from its start phase."""
        self._stopped = False
