"""wbc: optimisation-based whole-body control for small servo-driven humanoids."""

from .exceptions import (
    ConfigurationError,
    IKError,
    InfeasibleError,
    ModelError,
    ServoError,
    ServoMapError,
    SolverError,
    TaskError,
    TrajectoryError,
    WbcError,
)
from .model import Kinematics, Robot, available_robots, load_robot
from .servo_map import ServoMap, ServoSpec
from .version import __version__ as __version__

#: sub-modules reachable as attributes after a plain ``import wbc`` (imported on first use)
_SUBMODULES = (
    "bench", "compiled", "geometry", "ik", "limits", "model", "paths", "pinv", "recording",
    "servo_map", "servos", "solvers", "stacks", "tasks", "viewer", "walking",
)  # fmt: skip


def __getattr__(name: str):
    """``wbc.stacks``, ``wbc.solvers``, ... without importing them all at ``import wbc``."""
    if name in _SUBMODULES:
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'wbc' has no attribute {name!r}")


__all__ = [
    "ConfigurationError",
    "IKError",
    "InfeasibleError",
    "Kinematics",
    "ModelError",
    "Robot",
    "ServoError",
    "ServoMap",
    "ServoMapError",
    "ServoSpec",
    "SolverError",
    "TaskError",
    "TrajectoryError",
    "WbcError",
    "available_robots",
    "load_robot",
]
