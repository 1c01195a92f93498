"""Exception hierarchy: every error raised by wbc derives from :class:`WbcError`.

Which error a mistake raises (one rule):

* a bad argument, option or input value — the caller's mistake, found before anything runs —
  raises the ``ValueError`` subclass of its subject: :class:`TaskError` (tasks, task stacks,
  constraints, stack files), :class:`ModelError` (robot files, frame and joint names),
  :class:`ServoMapError` (servo maps), :class:`TrajectoryError` (references, footstep plans),
  and :class:`ConfigurationError` for everything else (configurations, solver, backend and
  run options);
* a failure while computing raises :class:`InfeasibleError` (no solution: the message names
  what conflicts), :class:`SolverError` (a numerical method failed), :class:`IKError` or
  :class:`ServoError`;
* :class:`WbcError` itself is never raised: catch it to catch them all.
"""

from __future__ import annotations


class WbcError(Exception):
    """Base class of all wbc errors."""


class ModelError(WbcError, ValueError):
    """A robot description is missing, malformed, or a frame/joint name is unknown."""


class ConfigurationError(WbcError, ValueError):
    """A bad argument or option outside the other subjects: a configuration vector of the wrong
    size or with non-finite values, a solver/backend/run option out of its allowed set."""


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


class FallDetected(ServoError):
    """The closed loop found the robot beyond recovery (:mod:`wbc.balance.fall`); raised from
    a control tick, it makes the deployment's safe stop take the protective fall."""
