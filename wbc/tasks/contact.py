"""Contact task: a sole held where it is (6-D)."""

from __future__ import annotations

from collections.abc import Sequence

from ..model import Kinematics, Robot
from .frame_pose import FramePoseTask


class ContactTask(FramePoseTask):
    """Hold a frame (a sole) at the placement it had when the contact was made.

    Call :meth:`make_contact` when the sole touches down (or at start-up); the task then
    keeps ``e = [p_c − p; log(R_c Rᵀ)]`` at zero. Use it hard (an equality) or with a large
    weight; one per sole for single support, two for double support.
    """

    stack_type = "contact"  # its `type` in stack files (wbc.tasks.task.register)

    def __init__(
        self,
        robot: Robot,
        frame: str,
        name: str | None = None,
        gain: float = 1.0,
        weight: float | Sequence[float] = 1.0,
        mask: Sequence[bool] | None = None,
    ) -> None:
        super().__init__(robot, frame, None, name or f"contact_{frame}", gain, weight, mask)

    def make_contact(self, kin: Kinematics) -> None:
        """Anchor the contact at the frame's current placement."""
        self.set_target_from(kin)
