"""Limits (bounds on Δq) and constraints (inequality rows on Δq)."""

from .ground_clearance import GroundClearanceConstraint, LinearInequality
from .joint_limits import JointPositionLimit, JointVelocityLimit
from .limit import Bounds, BoxLimit, Constraint, Inequality, box_bounds
from .self_collision import SelfCollisionConstraint
from .support_polygon import ComPolygonConstraint, SupportPolygon

__all__ = [
    "Bounds",
    "BoxLimit",
    "ComPolygonConstraint",
    "Constraint",
    "GroundClearanceConstraint",
    "Inequality",
    "JointPositionLimit",
    "JointVelocityLimit",
    "LinearInequality",
    "SelfCollisionConstraint",
    "SupportPolygon",
    "box_bounds",
]
