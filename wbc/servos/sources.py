"""Target sources for ``wbc deploy``: what the servos should do, one target per tick.

A :class:`TargetSource` gives joint targets (rad, the robot's model order) by playback time;
:class:`RecordingSource` resamples a recording (checked up front), :class:`CallableSource`
wraps a function such as a live controller.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from typing import Protocol

import numpy as np

from ..exceptions import TrajectoryError
from ..model import Robot
from ..recording import Recording, RecordingReader
from .safety import check_trajectory


class TargetSource(Protocol):
    """Joint targets per tick (rad, in ``joint_names`` order = the robot's model order).

    ``first()`` is where the soft start goes; ``__call__(tick, t)`` gives the target of tick
    ``tick`` at playback time ``t = tick / rate`` (s), or None when the motion is over. Ticks
    follow the wall clock: a tick the loop missed is skipped (``tick`` jumps). A live
    controller implements the same two methods. A source may also carry ``stiffness``
    (factors of the servos' configured stiffness, per joint or one for all; None: as
    configured): the deployment writes it when it changes
    (:meth:`wbc.servos.bus.ServoBus.set_stiffness`) and restores the configuration at the
    end and in every safe stop. And ``idle()``: called once a tick's goals are sent (in the
    period's slack, not in the tick's work): a live controller's preparation for the next
    tick (:meth:`wbc.walking.loop.Session.prepare_next`). And ``warm()``: called just before
    each tick's deadline on the wall clock (:meth:`wbc.servos.playback.Ticker.wait`):
    the tick's code and arrays brought back into the caches (:meth:`wbc.walking.loop.Session.
    warm_next`).
    """

    joint_names: tuple[str, ...]

    def first(self) -> np.ndarray: ...

    def __call__(self, tick: int, t: float) -> np.ndarray | None: ...


class RecordingSource:
    """A recording resampled (linear interpolation) at the playback rate, checked up front."""

    def __init__(self, recording: Recording, robot: Robot, tol: float = 1e-3) -> None:
        names = robot.joint_names
        order = _joint_order(recording.joint_names, robot)
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
        return _interpolate(self.t, self.joints, t)


def _interpolate(ts: np.ndarray, joints: np.ndarray, t: float) -> np.ndarray:
    """Joint values at time ``t`` by linear interpolation between rows (held at the ends)."""
    if ts.size == 1:
        return joints[0].copy()
    i = int(np.clip(np.searchsorted(ts, t, side="right") - 1, 0, ts.size - 2))
    w = (t - ts[i]) / (ts[i + 1] - ts[i])
    w = min(max(w, 0.0), 1.0)
    return (1.0 - w) * joints[i] + w * joints[i + 1]


def _joint_order(rec_names: Sequence[str], robot: Robot) -> list[int]:
    names = robot.joint_names
    if set(rec_names) != set(names):
        missing = sorted(set(names) - set(rec_names))
        unknown = sorted(set(rec_names) - set(names))
        raise TrajectoryError(
            f"recording joints do not match {robot.name}: missing {missing}, unknown {unknown}"
        )
    return [list(rec_names).index(n) for n in names]


class StreamedRecordingSource:
    """A recording played from its file a chunk at a time (:class:`RecordingReader`): checked
    whole in a first pass, then read again as the playback advances, holding one chunk, so
    the memory does not grow with the recording's length (a 10-hour walk plays in a few MB).
    Targets are those of :class:`RecordingSource` (linear interpolation)."""

    def __init__(self, reader: RecordingReader, robot: Robot, tol: float = 1e-3) -> None:
        self.reader = reader
        self.joint_names = robot.joint_names
        self._order = np.array(_joint_order(reader.joint_names, robot)) + 7
        t0 = t_last = None
        k = 0
        for t, q in reader.chunks():  # pass 1: the whole recording is checked before playing
            if (
                not np.all(np.isfinite(t))
                or np.any(np.diff(t) <= 0)
                or (t_last is not None and t[0] <= t_last)
            ):
                raise TrajectoryError("recording: t must be finite and strictly increasing")
            joints = q[:, self._order]
            check_trajectory(joints, robot.q_min, robot.q_max, self.joint_names, tol, t,
                             "recording", first_tick=k)  # fmt: skip
            if t0 is None:
                t0, self._first = float(t[0]), joints[0].copy()
            t_last, k = float(t[-1]), k + t.size
        assert t0 is not None and t_last is not None  # a reader has at least one row
        self._t0 = t0
        self.duration = t_last - t0
        self._chunks: Iterator[tuple[np.ndarray, np.ndarray]] | None = None
        self._t = np.zeros(0)
        self._joints = np.zeros((0, len(self.joint_names)))

    def first(self) -> np.ndarray:
        return self._first.copy()

    def __call__(self, tick: int, t: float) -> np.ndarray | None:
        if t > self.duration + 1e-9:
            return None
        if self._chunks is None:
            self._chunks = self.reader.chunks()
        while self._t.size == 0 or self._t[-1] < t:  # times only go forward: read on
            nxt = next(self._chunks, None)
            if nxt is None:
                break
            tc, qc = nxt  # keep the last row read: the interval across the chunk boundary
            self._t = np.concatenate([self._t[-1:], tc - self._t0])
            self._joints = np.concatenate([self._joints[-1:], qc[:, self._order]])
        return _interpolate(self._t, self._joints, t)


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
        #: the servos' stiffness the function asks for (TargetSource; None: as configured)
        self.stiffness: float | np.ndarray | None = None

    def first(self) -> np.ndarray:
        return self._first.copy()

    def __call__(self, tick: int, t: float) -> np.ndarray | None:
        return self.f(tick, t)
