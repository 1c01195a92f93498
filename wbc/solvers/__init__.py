"""Stack solvers: weighted QP (VAT) and lexicographic QP (CJ) over task stacks."""

from .backends import BACKENDS, QPBackend, make_backend
from .base import StackSolver
from .hierarchical import HierarchicalQP
from .pose import PoseResult, solve_pose
from .stack import Level, TaskStack
from .weighted import WeightedQP

__all__ = [
    "BACKENDS",
    "HierarchicalQP",
    "Level",
    "PoseResult",
    "QPBackend",
    "StackSolver",
    "TaskStack",
    "WeightedQP",
    "make_backend",
    "solve_pose",
]
