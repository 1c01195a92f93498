"""The self-collision rows left out in the tick's box: only rows that no Δq of the box can
violate (max over the box of G_i Δq <= h_i), the box the compiled tick's own, and the walk's
answers bit for bit those of every row."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

import wbc.solvers.plan as plan_module
from wbc.bench.trajectories import build
from wbc.limits import SelfCollisionConstraint
from wbc.stacks import load_stack
from wbc.walking.loop import Session, StackController

TICKS = 150  # (walk10's first touch-down at 104: rows active around it)


def _cut(stack):
    """``stack`` with its self-collision limit's ``cut_in_box`` on (before any plan)."""
    _limit(stack).rows_in_box = True
    return stack


def _limit(stack) -> SelfCollisionConstraint:
    """The stack's self-collision limit."""
    constraints = stack.solver.stack.constraints()
    return next(c for c in constraints if isinstance(c, SelfCollisionConstraint))


def _walk(robot, boxed: bool, ticks: int = TICKS, check=None):
    """walk_strict along walk10 with ``cut_in_box`` (its default, off: every row; and on,
    with ``joint_box_arrays`` made to say None: every row too); each tick's Δq (``check(plan,
    limit)`` after each tick) and the limit."""
    keep = plan_module.joint_box_arrays
    if not boxed:
        plan_module.joint_box_arrays = lambda limits: None
    try:
        stack = _cut(load_stack("walk_strict", robot))
        controller = StackController(stack)
        solver = controller.solver
        session = Session(controller, robot, build("walk10", robot))
        limit = _limit(stack)
        out = []
        for i in range(ticks):
            session.tick(i)
            out.append(solver.fast.dq.copy())
            if check is not None:
                check(solver.fast, limit)
        assert solver.handed_back_ticks == 0
        return out, limit
    finally:
        plan_module.joint_box_arrays = keep


def _most(G: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """max over the box [lower, upper] of each row of G."""
    with np.errstate(invalid="ignore"):
        return np.where(G > 0, G * upper, np.where(G < 0, G * lower, 0.0)).sum(axis=1)


def test_rows_left_out_cannot_bind_and_the_walk_is_the_same(robot):
    """Along walk10 (150 ticks): the box the kernel made its cut in is the tick's bounds bit for
    bit; the rows kept are, in order, those of every row (the limit's own call at the same
    configuration, without the box) that can bind in it, and the rows left out could not (max
    over the box below h); most rows are left out; and each tick's Δq is the one with every
    row, bit for bit (the solvers never let such a row join)."""
    counted = [0, 0]  # (rows kept, every row)

    def check(plan, lim) -> None:
        G, h, r0 = lim._where
        if G is lim._G:  # (no rows written in the plan this tick)
            return
        r = lim._n_rows
        np.testing.assert_array_equal(lim._box_work[0], plan.lower)
        np.testing.assert_array_equal(lim._box_work[1], plan.upper)
        rows_G, rows_h = G[r0 : r0 + r].copy(), h[r0 : r0 + r].copy()
        full = lim.compute(lim._call[0])  # (every row again: its own call, no box)
        most = _most(full.G, plan.lower, plan.upper)
        binds = most > full.h - 1e-8 * (1 + np.abs(full.G).sum(axis=1))
        np.testing.assert_array_equal(rows_G, full.G[binds])
        np.testing.assert_array_equal(rows_h, full.h[binds])
        assert (most[~binds] <= full.h[~binds]).all()
        counted[0] += r
        counted[1] += full.h.shape[0]

    cut, limit = _walk(robot, True, check=check)
    every, other = _walk(robot, False)
    assert other.rows_left_out == 0 < limit.rows_left_out
    assert counted[0] < 0.3 * counted[1], counted  # (most rows cannot bind)
    assert all(np.array_equal(a, b) for a, b in zip(cut, every, strict=True))


def test_the_rows_of_a_call_without_the_box_are_every_row(robot):
    """A call at the configuration of a tick whose rows were cut in its box gives every row
    (made again), and the tick's rows again after it (the box's rows made again too)."""
    stack = _cut(load_stack("walk_strict", robot))
    controller = StackController(stack)
    session = Session(controller, robot, build("walk10", robot))
    limit = _limit(stack)
    for i in range(110):
        session.tick(i)
    plan = controller.solver.fast
    _, h, r0 = limit._where
    r = limit._n_rows
    cut = h[r0 : r0 + r].copy()
    kin = limit._call[0]
    full = limit.compute(kin)
    assert full.h.shape[0] > r > 0
    box = plan.constraints.box
    again = limit.rows_into(kin, plan.inequalities.G, plan.inequalities.h, r0, box)
    assert again == r
    np.testing.assert_array_equal(plan.inequalities.h[r0 : r0 + r], cut)


def test_the_option_is_off_by_default_and_read_from_the_stack_file(robot):
    """``cut_in_box``: off unless the stack file says so; anything but a boolean is one
    error line."""
    from wbc.exceptions import TaskError
    from wbc.stacks import build_stack

    assert _limit(load_stack("walk_strict", robot)).rows_in_box is False
    spec = {"solver": "hierarchical", "levels": [{"tasks": [{"type": "com"}], "constraints": [
        {"type": "self_collision", "cut_in_box": True}]}]}  # fmt: skip
    assert _limit(build_stack(spec, robot)).rows_in_box is True
    spec["levels"][0]["constraints"][0]["cut_in_box"] = 1
    with pytest.raises(TaskError, match="cut_in_box"):
        build_stack(spec, robot)
