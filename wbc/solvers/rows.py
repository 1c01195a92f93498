"""Constraint rows as the solvers' recovery and projections use them: the rows to hold apart
from the requests of the constraints violated at the start, and small row helpers."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..limits import Constraint
from ..model import Kinematics
from .cascade import LevelProblem

#: no values (a level without a right-hand side)
EMPTY = np.zeros(0)


class SplitRows(NamedTuple):
    """Constraint rows G Δq <= h split into the rows to hold (with each constraint's slice,
    for diagnostics) and the requests of the constraints violated at the start (h < 0: the
    way back; :meth:`~wbc.limits.Constraint.split`: self-collision pairs inside their margin,
    sole corners below the ground)."""

    G: np.ndarray
    h: np.ndarray
    slices: list[tuple[str, slice]]
    G_inside: np.ndarray
    h_inside: np.ndarray


def split_rows(
    constraints: list[Constraint], kin: Kinematics, nv: int, recovering: bool = False
) -> SplitRows:
    """The constraints' rows at ``kin``, the requests of those violated at ``kin`` apart (see
    :class:`SplitRows`; ``recovering``: :meth:`~wbc.limits.Constraint.split`)."""
    G, h, sl, Gi, hi = [], [], [], [], []
    r = 0
    for c in constraints:
        (Gc, hc), (G_ask, h_ask) = c.split(kin, recovering)
        if h_ask.size:
            Gi.append(G_ask)
            hi.append(h_ask)
        G.append(Gc)
        h.append(hc)
        sl.append((c.name, slice(r, r + hc.size)))
        r += hc.size

    def stacked(Gs: list, hs: list) -> tuple[np.ndarray, np.ndarray]:
        return (np.vstack(Gs), np.concatenate(hs)) if Gs else no_rows(nv)

    return SplitRows(*stacked(G, h), sl, *stacked(Gi, hi))


def no_rows(nv: int) -> tuple[np.ndarray, np.ndarray]:
    """No inequality rows (G, h) over nv variables."""
    return np.zeros((0, nv)), np.zeros(0)


def no_jacobian(nv: int) -> np.ndarray:
    """No task rows over nv variables."""
    return np.zeros((0, nv))


def loosened(problem: LevelProblem, slack: float) -> LevelProblem:
    """``problem`` with its inequality rows loosened by ``slack``."""
    if not problem.h.size:
        return problem
    return LevelProblem(
        problem.priority, problem.J, problem.b, problem.G, problem.h + slack, problem.hard,
        problem.task_rows, problem.constraint_rows,
    )  # fmt: skip
