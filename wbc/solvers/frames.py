"""A compiled plan's frames: one slot per frame that its tasks and box limits use, and every
frame's placement as the views of Pinocchio's data that the tick reads."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..limits import BoxLimit
from ..model import Kinematics, Robot
from ..tasks import Task
from .buffers import Scratch

#: frame slots of a tick, padded to a multiple of this (see :class:`Frames`)
FRAME_SLOTS = 8


class Frames:
    """One slot per frame used by a task or a box limit: its frame id (the tick copies that
    frame's world rotation/position from ``R``/``p``, every frame's, into ``Rs``/``ps``, and
    its velocity into ``vs`` where a kernel reads them) and joint support; ``slots`` lists each
    task's and limit's slots."""

    def __init__(
        self,
        robot: Robot,
        kin: Kinematics,
        tasks: Sequence[Task | BoxLimit],
        scratch: Scratch,
    ) -> None:
        self.slot: dict[int, int] = {}
        for t in tasks:
            for fid in t.frame_ids():
                self.slot.setdefault(fid, len(self.slot))
        ids = list(self.slot)
        n = len(ids) + (-len(ids) % FRAME_SLOTS) if ids else FRAME_SLOTS
        self.support = np.zeros((n, robot.nv), dtype=np.bool_)
        for s, fid in enumerate(ids):
            self.support[s] = robot.frame_support(fid)
        self.ids = np.array(ids, dtype=np.int64)
        # every frame's placement: views of Pinocchio's that follow every Kinematics.update,
        # or (another layout) a copy in the same strided layout, refreshed before each tick
        views = kin.frame_placements()
        self.copies: list[tuple[int, np.ndarray, np.ndarray]] = []
        if views is None:
            records = np.zeros((robot.model.nframes, 12))  # R column-major, then p
            as_strided = np.lib.stride_tricks.as_strided
            views = (
                as_strided(records, shape=(len(records), 3, 3), strides=(96, 8, 24)),
                as_strided(records[:, 9:], shape=(len(records), 3), strides=(96, 8)),
            )
            self.copies = [(f, kin.rotation(f), kin.translation(f)) for f in ids]
        self.R, self.p = views
        self.Rs = scratch.get("Rs", (n, 3, 3))
        self.ps = scratch.get("ps", (n, 3))
        self.vs = np.zeros((n, 6))  # (the plan's own: zeros unless its kernels read them)
        self._slots: list[int] = []
        self.slots = np.zeros(0, dtype=np.int64)

    def refresh(self) -> None:
        """Copy the frames' placements (only when they are not views of Pinocchio's)."""
        for f, R, p in self.copies:
            self.R[f] = R
            self.p[f] = p

    def add(self, task: Task | BoxLimit) -> tuple[int, int]:
        """(offset, count) of the task's or limit's frame slots in :attr:`slots`."""
        offset = len(self._slots)
        self._slots.extend(self.slot[f] for f in task.frame_ids())
        self.slots = np.array(self._slots, dtype=np.int64)
        return offset, len(self._slots) - offset
