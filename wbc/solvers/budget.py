"""What a solver's work may cost: the budget of a running pose iteration
(:func:`wbc.solvers.pose.solve_pose`) and the Gauss–Newton steps of a tick's recovery, shared
by the solver, its projection onto the hard levels and its recovery."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from ..exceptions import SolverError


@dataclass
class PoseBudget:
    """What a :func:`~wbc.solvers.pose.solve_pose` of solver ``who`` may spend: Gauss–Newton
    steps onto the hard levels and wall time (s; None: no limit), and what it has spent so
    far."""

    who: str
    max_steps: int
    seconds: float | None
    start: float = field(default_factory=time.perf_counter)
    steps: int = 0
    iteration: int = 0

    def spend(self, steps: int = 0, iteration: int | None = None) -> None:
        """Count ``steps`` Gauss–Newton steps and raise SolverError if the budget is spent,
        or its time budget is; ``iteration``: the iteration the pose has reached (for the
        message)."""
        if iteration is not None:
            self.iteration = iteration
        self.steps += steps
        spent = ""
        if self.steps > self.max_steps:
            spent = (
                f"its {self.max_steps} Gauss–Newton steps onto the hard levels "
                "(max_projection_steps)"
            )
        elif self.seconds is not None and time.perf_counter() - self.start > self.seconds:
            spent = f"its time budget of {self.seconds:g} s (time_budget)"
        if spent:
            raise SolverError(
                f"{self.who}: solve_pose spent {spent} at iteration {self.iteration} "
                f"({self.steps} Gauss–Newton steps, {time.perf_counter() - self.start:.3g} s)"
            )


class Work:
    """A solver's count of work: the budget of the running pose iteration (None outside
    one) and the Gauss–Newton steps the last solve spent bringing an infeasible start back
    onto the hard levels (:data:`wbc.solvers.recovery.TICK_RECOVERY_STEPS` at most outside a
    pose)."""

    def __init__(self) -> None:
        self.pose: PoseBudget | None = None
        self.recovery_steps = 0

    def spend(self, steps: int = 0, iteration: int | None = None) -> None:
        """Count ``steps`` against the running pose's budget (nothing outside one): see
        :meth:`PoseBudget.spend`."""
        if self.pose is not None:
            self.pose.spend(steps, iteration)
