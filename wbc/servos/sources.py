"""Target sources for ``wbc deploy``: what the servos should do, one target per tick.

A :class:`TargetSource` gives joint targets (rad, the robot's model order) by playback time;
:class:`RecordingSource` resamples a recording (checked up front), :class:`CallableSource`
wraps a function such as a live controller.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from ..exceptions import TrajectoryError
from ..model import Robot
from ..recording import Recording
from .safety import check_trajectory


class TargetSource(Protocol):
    """Joint targets per tick (rad, in ``joint_names`` order = the robot's model order).

    ``first()`` is where the soft start goes; ``__call__(tick, t)`` gives the target of tick
    ``tick`` at playback time ``t = tick / rate`` (s), or None when the motion is over. Ticks
    follow the wall clock: a tick the loop missed is skipped (``tick`` jumps). A live
    controller implements the same two methods.
    """

    joint_names: tuple[str, ...]

    def first(self) -> np.ndarray: ...

    def __call__(self, tick: int, t: float) -> np.ndarray | None: ...


class RecordingSource:
    """A recording resampled (linear interpolation) at the playback rate, checked up front."""

    def __init__(self, recording: Recording, robot: Robot, tol: float = 1e-3) -> None:
        names = robot.joint_names
        rec_names = tuple(recording.joint_names)
        if set(rec_names) != set(names):
            missing = sorted(set(names) - set(rec_names))
            unknown = sorted(set(rec_names) - set(names))
            raise TrajectoryError(
                f"recording joints do not match {robot.name}: missing {missing}, unknown {unknown}"
            )
        order = [rec_names.index(n) for n in names]
        self.joint_names = names
        self.t = recording.t - recording.t[0]
        self.joints = recording.joints[:, order]
        check_trajectory(
            self.joints, robot.q_min, robot.q_max, names, tol, recording.t, "recording"
        )
        self.duration = float(self.t[-1])

    def first(self) -> np.ndarray:
        return self.joints[0].copy()

    def __call__(self, tick: int, t: float) -> np.ndarray | None:
        if t > self.duration + 1e-9:
            return None
        if self.t.size == 1:
            return self.joints[0].copy()
        i = int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, self.t.size - 2))
        w = (t - self.t[i]) / (self.t[i + 1] - self.t[i])
        w = min(max(w, 0.0), 1.0)
        return (1.0 - w) * self.joints[i] + w * self.joints[i + 1]


class CallableSource:
    """A source from a function ``f(tick, t) -> targets | None`` (e.g. a live controller)."""

    def __init__(
        self,
        f: Callable[[int, float], np.ndarray | None],
        first: np.ndarray,
        joint_names: Sequence[str],
    ) -> None:
        self.f = f
        self._first = np.asarray(first, dtype=float)
        self.joint_names = tuple(joint_names)

    def first(self) -> np.ndarray:
        return self._first.copy()

    def __call__(self, tick: int, t: float) -> np.ndarray | None:
        return self.f(tick, t)
