"""Shared part of the tasks attached to one frame of the robot."""

from __future__ import annotations

from collections.abc import Sequence

from ..model import Robot
from .task import Task


class FrameTask(Task):
    """A task on frame ``frame`` of ``robot``; the frame can be re-bound (e.g. swing foot)."""

    def __init__(
        self,
        robot: Robot,
        frame: str,
        name: str | None,
        gain: float,
        weight: float | Sequence[float],
        mask: Sequence[bool] | None,
    ) -> None:
        self.robot = robot
        self.set_frame(frame)
        super().__init__(
            name or f"{type(self).__name__.removesuffix('Task').lower()}_{frame}",
            gain,
            weight,
            mask,
        )

    def set_frame(self, frame: str) -> None:
        """Attach the task to another frame (raises ModelError for unknown names)."""
        frame_id = self.robot.frame_id(frame)
        changed = frame_id != getattr(self, "frame_id", None)
        self.frame_id = frame_id
        self.frame = frame
        if changed:
            self._restructured()  # compiled plans hold the frame's placement views
