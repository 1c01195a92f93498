"""The tick's q ⊕ Δq written into an array bound in the loop's idle part
(wbc.solvers.buffers, StackSolver.prepare_output): ``step`` returns it without a copy, the same
numbers as the copy, and never writes into an array it returned."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.bench.trajectories import build
from wbc.solvers.buffers import bind
from wbc.stacks import load_stack
from wbc.walking.loop import Session, StackController


def _walk(robot, stack: str, ticks: int, prepare: bool) -> tuple[list, list, int]:
    """walk10's first ``ticks`` ticks: the returned arrays, their values at return, and how
    many were the plan's bound array itself (not a copy)."""
    ref = build("walk10", robot)
    controller = StackController(load_stack(stack, robot))
    controller.solver.output_ahead = prepare  # (off by default: the copy)
    session = Session(controller, robot, ref)
    returned, values, bound = [], [], 0
    for i in range(ticks):
        q = session.tick(i)
        returned.append(q)
        values.append(q.copy())
        bound += q is controller.solver.fast.q_next
        if prepare:
            session.prepare_next()
    assert controller.solver.compiled_ticks == ticks
    return returned, values, bound


@pytest.mark.parametrize("stack", ["walk_strict", "walk"])
def test_the_bound_output_is_the_copy_and_is_never_written_again(robot, stack):
    """With the idle part (the loop's prepare_next: an array bound before each tick) the
    ticks return the same numbers, bit for bit, as with a copy each tick; no returned array
    is changed by a later tick, and the ticks after the first return the bound array itself."""
    returned, values, bound = _walk(robot, stack, 80, True)
    _, copies, none = _walk(robot, stack, 80, False)
    for q, v, c in zip(returned, values, copies, strict=True):
        assert np.array_equal(v, c)
        assert np.array_equal(q, v)  # (not written since it was returned)
    assert len({id(q) for q in returned}) == len(returned)
    assert bound == 80 and none == 0  # (the session binds one before its first tick too)


def test_a_step_without_the_idle_part_copies_and_spares_the_lent_array(robot):
    """A step after a returned bound array, with no new one bound: the plan writes into its own
    array again (the lent one is left as returned), and the step returns a copy."""
    controller = StackController(load_stack("walk_strict", robot))
    solver = controller.solver
    solver.output_ahead = True
    q0 = robot.configuration("walk_ready").copy()
    solver.prepare(q0, 0.01)
    q1 = solver.step(q0, 0.01)  # (the first compiled tick: a copy)
    assert q1 is not solver.fast.q_next
    solver.prepare_output()
    q2 = solver.step(q1, 0.01)
    assert q2 is solver.fast.q_next and solver.fast.lent
    kept = q2.copy()
    q3 = solver.step(q2, 0.01)  # (no idle part: the plan back on its own array)
    assert np.array_equal(q2, kept)
    assert q3 is not q2 and q3 is not solver.fast.q_next and not solver.fast.lent
    assert solver.fast.q_next is solver.fast.own_q_next
    solver.prepare_output()
    solver.prepare_output()  # (twice: the same array, still not returned)
    bound = solver.fast.q_next
    assert bound is not solver.fast.own_q_next
    assert solver.step(q3, 0.01) is bound


def test_off_by_default_the_step_copies(robot):
    _, _, bound = _walk(robot, "walk_strict", 20, False)
    controller = StackController(load_stack("walk_strict", robot))
    assert controller.solver.output_ahead is False and bound == 0
    controller.solver.prepare(robot.configuration("walk_ready").copy(), 0.01)
    controller.solver.prepare_output()
    assert controller.solver.fast.q_next is controller.solver.fast.own_q_next


def test_bind_checks_the_array(robot):
    controller = StackController(load_stack("walk_strict", robot))
    solver = controller.solver
    solver.prepare(robot.configuration("walk_ready").copy(), 0.01)
    plan = solver.fast
    for wrong in (
        np.empty(robot.nq, np.float32),
        np.empty(robot.nq + 1),
        np.empty(2 * robot.nq)[::2],
    ):
        with pytest.raises(TypeError):
            bind(plan, wrong)
