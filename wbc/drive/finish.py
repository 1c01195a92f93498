"""Finish steps: after a stop, the closing step's landing measured and, if it is off the
commanded pose, one more closing step aimed from the measured frame (a real walker's
"finish step"). The closing step is the one landing no later step measures: every other
landing is measured at the end of the double support that follows it and the next step is
aimed from there (:attr:`WalkEngine.on_landing <wbc.walking.engine.WalkEngine.on_landing>`);
the closing step is followed by the end phase and standing.

:class:`FinishSteps` decides, when a walk has ended (the closing step landed, the end phase
over), from the outer loop's odometry (:class:`~wbc.drive.odometry.PoseOdometry`): the
soles' midpoint measured, the heading the torso's by the gyro since the walk's start (what
the command turns: on the random sequences of benchmarks/drive.md the soles' measured mean
heading was a mean 1.7° off the torso's at the walks' ends, the standing posture's twist).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..geometry import wrap_angle

#: a finishing stop (``Walker.stop(finish=True)``) closes as soon as the planned walking
#: frame, with the odometry's offset, is this close to the commanded pose (m, rad); a finish
#: step is taken when the measured frame after the closing step is further than this from it
DRIVE_FINISH_TOLERANCE = (0.005, math.radians(1.0))

#: finish steps after a stop (``Walker(finish_steps=N)``; 0: none), at most. Random
#: sequences 0–9 × randomised Bioloids 0–9 beside main (benchmarks/drive.md, 2026-12-06;
#: a finish step in 30 of the 100 runs): heading within 15 % 72 -> 75 of 80 (sequence 3,
#: −21°: 4 -> 7 of 10), displacement 67 -> 69 of 100, no fall either way; the median heading
#: error 1.85 -> 1.49°, the mean displacement error 21.5 -> 22.3 mm (each extra step adds
#: its slip) and one run of model 0 (the most backlash) turned 14° in the step's end phase
DRIVE_FINISH_STEPS_AFTER = 1

#: ... none if the measured frame is further than this from the commanded pose (m, rad): not
#: a closing step's residual but a robot turned or slid on its soles (the randomised
#: Bioloid 0, the most backlash, measured 9° off at the end of a random sequence, and a
#: finish step aimed at it ended 18° off: benchmarks/drive.md, 2026-12-06)
DRIVE_FINISH_BELIEVED = (0.02, math.radians(5.0))


class FinishSteps:
    """At most ``steps`` finish steps per stop (:meth:`stop` arms them); ``xy``: correct the
    measured position too (False: the heading alone, the soles' midpoint aimed where it is
    planned: the step turns a sole in place). :attr:`errors`: at each walk's end, the
    commanded pose less the measured frame (x, y, heading; world)."""

    def __init__(self, steps: int, xy: bool = False) -> None:
        self.steps = int(steps)
        self.xy = bool(xy)
        self.left = 0  # finish steps this stop may still take
        self.errors: list[np.ndarray] = []

    def stop(self) -> None:
        """A stop: its finish steps armed."""
        self.left = self.steps

    def after_walk(self, engine: Any, odometry: Any, q: np.ndarray) -> None:
        """The walk of ``engine`` (a :class:`~wbc.walking.engine.WalkEngine`) has ended:
        ``odometry`` measures the closing step's landing (``q``: the present joints'
        configuration) and, if the measured frame is further than
        :data:`DRIVE_FINISH_TOLERANCE` from the commanded pose (within
        :data:`DRIVE_FINISH_BELIEVED`) and a finish step is left, the engine takes one more
        closing step aimed from the measured frame (:meth:`WalkEngine.finish_step
        <wbc.walking.engine.WalkEngine.finish_step>`: the sole whose step ends nearer)."""
        measured = odometry.landed(engine.planned[-1].side, q)
        planned = engine.mid_frame()
        want = engine.commanded_frame()
        off = want - measured
        turned = wrap_angle(engine.pose_cmd[2] - engine.start_pose[2])
        off[2] = wrap_angle(turned - (odometry.heading - odometry.start_heading))
        self.errors.append(off)
        xy, yaw = float(np.hypot(*off[:2])), abs(float(off[2]))
        tol_xy, tol_yaw = DRIVE_FINISH_TOLERANCE
        most_xy, most_yaw = DRIVE_FINISH_BELIEVED
        if not self.xy:
            xy, most_xy = 0.0, math.inf
        if self.left <= 0 or (xy <= tol_xy and yaw <= tol_yaw) or xy > most_xy or yaw > most_yaw:
            return
        error = measured - planned  # (the frame's error as the engine aims from it)
        error[2] = wrap_angle(want[2] - planned[2] - off[2])
        if not self.xy:
            error[:2] = want[:2] - planned[:2]
        self.left -= 1
        engine.finish_step(error)
