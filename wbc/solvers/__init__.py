"""Stack solvers: weighted QP (VAT) and lexicographic QP (CJ) over task stacks."""

from .backends import BACKENDS, QPBackend, make_backend
from .base import PoseResult, StackSolver
from .hierarchical import HierarchicalQP
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
]
