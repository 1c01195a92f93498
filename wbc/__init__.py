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

__version__ = "0.1.0"

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
