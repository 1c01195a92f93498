"""Tasks: each gives an error e(q) = x* − x(q) and its Jacobian J(q).

The same task objects serve the weighted and hierarchical QP solvers (:mod:`wbc.solvers`) and
the thesis's pseudo-inverse baselines (:mod:`wbc.pinv`).
"""

from .com import ComTask
from .contact import ContactTask
from .frame_local_pose import LocalFramePoseTask
from .frame_orientation import FrameOrientationTask
from .frame_pose import FramePoseTask
from .frame_position import FramePositionTask
from .frame_task import FrameTask
from .frame_tilt import FrameTiltTask
from .limit_damping import JointLimitDampingTask
from .momentum import YawMomentumTask
from .posture import DampingTask, PostureTask
from .relative_position import RelativeFramePositionTask
from .task import Objective, Task
from .thesis_orientation import SwingFootOrientationTask, TorsoOrientationTask

__all__ = [
    "ComTask",
    "ContactTask",
    "DampingTask",
    "FrameOrientationTask",
    "FramePoseTask",
    "FramePositionTask",
    "FrameTask",
    "FrameTiltTask",
    "JointLimitDampingTask",
    "LocalFramePoseTask",
    "Objective",
    "PostureTask",
    "RelativeFramePositionTask",
    "SwingFootOrientationTask",
    "Task",
    "TorsoOrientationTask",
    "YawMomentumTask",
]
