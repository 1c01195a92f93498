"""wbc.walking: walking references (the thesis's step, 3-D LIPM, multi-step ZMP gaits) and
the checks run on them before any motion.

Typical use::

    start = StandingState.from_robot(robot)          # Walk Ready: CoM and soles
    ref = thesis_step(start)                          # ch. 4: 100 poses, static gait
    ref = thesis_lipm_step(start)                     # ch. 4.1.2: the same with a 3-D LIPM CoM
    ref = forward_walk(start, n_steps=10, generator="mpc")   # preview | mpc | lipm
    window = BalanceWindow.from_robot(robot)          # whole body: torso lean, arms
    ref = static_walk(start, window)                  # CoM over the stance sole
    ref = forward_walk(start, 10, zmp_offset=(0, 0.018), margin=0.01, window=window)
    ref.com[i], ref.sole_placement(i, "left"), ref.support[i], ref.swing_side(i)

Every builder checks its reference before returning it (:func:`check_reference`: ZMP or
CoM in the support polygon, soles above the ground, feet apart, legs within reach and hip
roll) and raises :class:`~wbc.exceptions.TrajectoryError` otherwise.
:func:`kinematic_feasibility` tracks a reference with a bounded IK as an independent check.
"""

from .checks import CheckReport, check_reference
from .feasibility import FeasibilityReport, kinematic_feasibility
from .footsteps import Footstep, FootstepPlan, other_side, plan_footsteps
from .gait import GENERATORS, forward_walk, lateral_walk, turning_walk, walk, walk_steps
from .geometry import Foot, polygon_distance, signed_distance, support_polygon
from .legs import LegGeometry
from .lipm import Lipm3D, lipm_com_for_zmp, lipm_walk_com
from .mpc import LipmMpc, MpcParams
from .preview import PreviewController, PreviewParams
from .reference import StandingState, WalkingReference
from .schedule import GaitTiming, SwingParams
from .spline import CubicSpline, QuinticSegment, min_jerk
from .static_walk import StaticWalkParams, static_walk
from .thesis_step import ThesisStepParams, thesis_lipm_step, thesis_step
from .window import BalanceWindow

__all__ = [
    "GENERATORS",
    "BalanceWindow",
    "CheckReport",
    "CubicSpline",
    "FeasibilityReport",
    "Foot",
    "Footstep",
    "FootstepPlan",
    "GaitTiming",
    "LegGeometry",
    "Lipm3D",
    "LipmMpc",
    "MpcParams",
    "PreviewController",
    "PreviewParams",
    "QuinticSegment",
    "StandingState",
    "StaticWalkParams",
    "SwingParams",
    "ThesisStepParams",
    "WalkingReference",
    "check_reference",
    "forward_walk",
    "kinematic_feasibility",
    "lateral_walk",
    "lipm_com_for_zmp",
    "lipm_walk_com",
    "min_jerk",
    "other_side",
    "plan_footsteps",
    "polygon_distance",
    "signed_distance",
    "static_walk",
    "support_polygon",
    "thesis_lipm_step",
    "thesis_step",
    "turning_walk",
    "walk",
    "walk_steps",
]
