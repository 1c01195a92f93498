"""Limits (bounds on Δq) and constraints (inequality rows on Δq)."""

from .ground_clearance import GroundClearanceConstraint, LinearInequality
from .joint_limits import JointPositionLimit, JointVelocityLimit, intersect_bounds
from .limit import Bounds, BoxLimit, Constraint, Inequality
from .support_polygon import (
    FOOT_LENGTH,
    FOOT_WIDTH,
    ComPolygonConstraint,
    SupportPolygon,
    convex_hull,
    foot_corners,
    halfspaces,
    signed_distance,
)

__all__ = [
    "FOOT_LENGTH",
    "FOOT_WIDTH",
    "Bounds",
    "BoxLimit",
    "ComPolygonConstraint",
    "Constraint",
    "GroundClearanceConstraint",
    "Inequality",
    "JointPositionLimit",
    "JointVelocityLimit",
    "LinearInequality",
    "SupportPolygon",
    "convex_hull",
    "foot_corners",
    "halfspaces",
    "intersect_bounds",
    "signed_distance",
]
