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
started); ``"end"``, from the landing of the closing step on (its end phase, the double
support in which the CoM settles between the soles, too).
"""

from __future__ import annotations

from ..exceptions import ConfigurationError
from ..recording import SUPPORT_DOUBLE
from ..walking.engine import EngineTick

#: when a driven robot (with the outer loop) stands without torso feedback: ``"end"`` from
#: its closing step's landing, ``"standing"`` once the engine stands, ``""`` never (the
#: behaviour before 2026-12-06 18:00 UTC). Measured: benchmarks/drive.md, thirteenth session
DRIVE_QUIET_STAND = ""

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
        self._swung = False  # the closing step's swing seen (state "stopping", single support)

    def __call__(self, e: EngineTick, starting: bool) -> bool:
        """True when the engine tick ``e`` stands still (``starting``: a start asked for)."""
        if not self.mode:
            return False
        if e.state == "standing":
            self._swung = False
            return not starting
        if e.state != "stopping" or self.mode != "end":
            self._swung = False
            return False
        if e.support != SUPPORT_DOUBLE:
            self._swung = True  # (the closing step in the air)
            return False
        return self._swung  # the closing step landed: its end phase
