"""Exception hierarchy: every error raised by wbc derives from :class:`WbcError`."""

from __future__ import annotations


class WbcError(Exception):
    """Base class of all wbc errors."""


class ModelError(WbcError, ValueError):
    """A robot description is missing, malformed, or a frame/joint name is unknown."""


class ConfigurationError(WbcError, ValueError):
    """A configuration vector has the wrong size or non-finite values."""


class ServoMapError(WbcError, ValueError):
    """A servo map is malformed, inconsistent with the URDF, or a value is out of range."""


class IKError(WbcError, ValueError):
    """Analytic inverse kinematics: the target is not reachable."""


class TaskError(WbcError, ValueError):
    """A task is misconfigured or received an invalid target."""


class InfeasibleError(WbcError):
    """A hard level of a task stack has no solution; the message names what conflicts."""


class SolverError(WbcError):
    """A QP backend failed for a reason other than infeasibility."""


class TrajectoryError(WbcError, ValueError):
    """A reference trajectory or footstep plan is invalid (checked before any motion)."""


class ServoError(WbcError):
    """A servo bus, servo or deployment safety error."""
