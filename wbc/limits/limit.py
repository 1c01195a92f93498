"""Limits and constraints: they only provide bounds or inequality rows on Δq.

Two kinds, mirroring pink: a :class:`BoxLimit` bounds each coordinate of Δq
(``lower <= Δq <= upper``, intersected over all box limits); a :class:`Constraint` gives
inequality rows ``G Δq <= h``. Solvers stack them, independently of the QP backend.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import NamedTuple

import numpy as np

from ..model import Kinematics


def way_back(violation: np.ndarray, fraction: float, most: float) -> np.ndarray:
    """h of the rows of a constraint violated by ``violation`` > 0 at the current
    configuration (a sole corner below the ground, two links inside their margin): the
    row −g'(q) Δq <= h asks a fraction ``fraction`` of the way back per step, at most
    ``most`` (m): h = −min(ξ · violation, most).

    Like a joint outside its range (moved back at the servo's speed, never further out), a
    start that violates a constraint is never asked to jump back in one step (which the
    velocity limits and the hard contacts may not allow), and the row is met from any
    start by a bounded motion."""
    return -np.minimum(fraction * np.asarray(violation, dtype=float), most)


class Bounds(NamedTuple):
    """lower <= Δq <= upper (nv each; ±inf where unbounded)."""

    lower: np.ndarray
    upper: np.ndarray


class Inequality(NamedTuple):
    """G Δq <= h."""

    G: np.ndarray
    h: np.ndarray


class BoxLimit(ABC):
    """A limit that bounds every coordinate of Δq."""

    name: str = "box"

    @abstractmethod
    def bounds(self, kin: Kinematics, dt: float | None) -> Bounds:
        """Bounds on Δq at the configuration of ``kin`` for a step of ``dt`` seconds
        (``dt=None``: iterating to convergence, no time step)."""


class Constraint(ABC):
    """Linear inequality rows on Δq, usable at any priority level."""

    #: True if :meth:`split` holds only rows that Δq = 0 meets (h >= 0): every row violated
    #: at ``kin`` is a request, so the rows held never show a violation there (a converged
    #: pose's hard-level error then skips computing them:
    #: :meth:`wbc.solvers.base.StackSolver.solve_pose`)
    held_rows_met = False

    def __init__(self, name: str) -> None:
        self.name = name
        self._active = True

    @property
    def active(self) -> bool:
        """Inactive constraints are skipped by every solver (e.g. the swing sole's clearance
        in double support); switching re-plans the solvers' layouts."""
        return self._active

    @active.setter
    def active(self, value: bool) -> None:
        if bool(value) != self._active:
            self._active = bool(value)
            for stack in getattr(self, "_stacks", ()):
                stack.revision += 1

    @abstractmethod
    def compute(self, kin: Kinematics) -> Inequality:
        """(G, h) at the configuration of ``kin``."""

    def split(self, kin: Kinematics, recovering: bool = False) -> tuple[Inequality, Inequality]:
        """The rows at ``kin`` as (rows to hold, requests): a request is a row that Δq = 0
        does not meet because the constraint is violated at ``kin`` itself (a start below the
        ground, links inside their margin) and that asks for the way back
        (:func:`way_back`). A solver that cannot meet the requests with its hard tasks ranks
        them below those, as the best achievable way back
        (:meth:`wbc.solvers.base.StackSolver.solve`). ``recovering``: the rows of the re-solve
        of an infeasible tick, where a constraint may hold its bare bound instead of a rate
        that only smooths its activation (the self-collision damper). Default: every row
        held, the same rows either way."""
        rows = self.compute(kin)
        return rows, Inequality(rows.G[:0], rows.h[:0])

    def solved(self) -> None:
        """Called by the solvers after each control tick (a solve with a time step) with this
        constraint at a hard level (its rows computed at that tick's configuration): a
        constraint violated at the start and
        not brought back (a request the hard tasks keep unmet) raises
        :class:`~wbc.exceptions.InfeasibleError` here, naming what (default: nothing)."""
        return None

    def violation(self, kin: Kinematics, dq: np.ndarray) -> np.ndarray:
        """max(0, G Δq − h) per row (for diagnostics and tests)."""
        G, h = self.compute(kin)
        return np.maximum(G @ dq - h, 0.0)
