"""The hierarchy's compiled cascade with ``defer_rows_join`` (off by default): the levels above
the last stay deferred on ticks with inequality rows active, the rows joining the last level's
solve — the same answers to rounding, by another path."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from test_carried_rows import _watched_walk

from wbc.stacks import build_stack, load_stack


def _joined_walk(robot, on: bool, ticks: int):
    stack = load_stack("walk_strict", robot, defer_rows_join=on)
    assert stack.solver.defer_rows_join is on
    return _watched_walk(robot, stack, "carry", ticks)


def test_rows_join_the_deferred_solve_to_rounding(robot):
    """walk_strict along walk10's first 160 ticks (self-collision rows active around the
    touch-downs 104 and 144): each tick's Δq with the rows joining the deferred solve is the
    one without to 1e-12 (a strictly convex last level over the same set where the levels
    above are met exactly), and from the first tick that took the other path (84, rows
    active) the walk differs in its last bits: the option does something."""
    assert not load_stack("walk_strict", robot).solver.defer_rows_join  # (the default)
    assert build_stack({"solver": "hierarchical", "defer_rows_join": True, "levels": [
        {"tasks": [{"type": "com"}]}]}, robot).solver.defer_rows_join  # fmt: skip
    on = _joined_walk(robot, True, 160)
    off = _joined_walk(robot, False, 160)
    diffs = np.array([np.abs(a - b).max() for a, b in zip(on, off, strict=True)])
    assert diffs.max() <= 1e-12, diffs.max()
    moved = np.flatnonzero(diffs > 0)
    assert moved.size >= 3, moved  # (ticks whose path changed)
