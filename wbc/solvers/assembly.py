"""Stacking task rows and constraint rows into preallocated matrices."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..limits import Constraint
from ..model import Kinematics
from ..tasks import Task


class TaskBlock:
    """Preallocated rows for a fixed list of tasks: raw errors ``E`` and J Δq ≈ b rows.

    Weights and gains are gathered once (at construction), so a tick is one ``fill`` per task
    plus two vector operations.
    """

    def __init__(self, tasks: Sequence[Task], nv: int) -> None:
        self.tasks = list(tasks)
        self.m = sum(t.rows for t in self.tasks)
        self.J = np.zeros((self.m, nv))
        self.E = np.zeros(self.m)
        self.b = np.zeros(self.m)
        self.slices: list[tuple[str, slice]] = []
        r = 0
        for t in self.tasks:
            self.slices.append((t.name, slice(r, r + t.rows)))
            r += t.rows
        self._parts = [
            (t, self.J[sl], self.E[sl]) for t, (_, sl) in zip(self.tasks, self.slices, strict=True)
        ]
        w = np.concatenate([t.weight for t in self.tasks]) if self.tasks else np.zeros(0)
        gains = np.concatenate([np.full(t.rows, t.gain) for t in self.tasks]) if self.tasks else w
        self.sqrt_w = np.sqrt(w)[:, None]
        self.gain_sqrt_w = gains * np.sqrt(w)
        self.gains = gains

    def fill_into(self, kin: Kinematics, J: np.ndarray, b: np.ndarray) -> None:
        """Unweighted rows J Δq = α e into the given arrays (hard tasks: equalities)."""
        E = self.E
        r = 0
        for task, _, e in self._parts:
            k = task.rows
            task.fill(kin, J[r : r + k], e)
            r += k
        np.multiply(E, self.gains, out=b)

    def fill_weighted(self, kin: Kinematics) -> None:
        """Rows scaled by √w: ‖J Δq − b‖² is the weighted cost Σ w ‖J_i Δq − α e_i‖²."""
        for task, J, e in self._parts:
            task.fill(kin, J, e)
        np.multiply(self.J, self.sqrt_w, out=self.J)
        np.multiply(self.E, self.gain_sqrt_w, out=self.b)


def stack_constraints(
    constraints: Sequence[Constraint], kin: Kinematics, nv: int
) -> tuple[np.ndarray, np.ndarray, list[tuple[str, slice]]]:
    """(G, h, row slices) of the constraints at ``kin`` (sizes may change between calls)."""
    if not constraints:
        return np.zeros((0, nv)), np.zeros(0), []
    if len(constraints) == 1:  # the common case: no stacking copies
        G, h = constraints[0].compute(kin)
        return G, h, [(constraints[0].name, slice(0, len(h)))]
    Gs, hs, slices = [], [], []
    r = 0
    for c in constraints:
        G, h = c.compute(kin)
        Gs.append(G)
        hs.append(h)
        slices.append((c.name, slice(r, r + len(h))))
        r += len(h)
    return np.vstack(Gs), np.concatenate(hs), slices
