"""The hierarchy's damped last level carries its working inequality rows from one compiled
tick to the next, found again by value (wbc/solvers/carry.py): the same answers, from a start
that is the tick's own final set."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from wbc.bench.trajectories import build
from wbc.compiled.carried import carry_rows, keep_rows
from wbc.solvers.carry import CARRY_TOL, CarriedRows
from wbc.stacks import build_stack, load_stack
from wbc.walking.loop import Session, StackController


def test_rows_kept_are_found_again_by_value_at_other_indices():
    """Rows kept at a tick's end are marked at the next tick where their (slightly moved)
    copies now stand; a row moved beyond the tolerance, or none near, is not marked; more
    rows than the buffer holds are not kept."""
    rng = np.random.default_rng(3)
    nv, p = 8, 12
    G, h = rng.normal(size=(p, nv)), rng.normal(size=p)
    working = np.zeros(p, np.bool_)
    working[[2, 9]] = True
    Gc, hc = np.zeros((nv, nv)), np.zeros(nv)
    assert keep_rows(G, h, p, working, Gc, hc) == 2
    assert np.array_equal(Gc[:2], G[[2, 9]]) and np.array_equal(hc[:2], h[[2, 9]])
    order = rng.permutation(p)  # (the next tick: rows at other indices, moved by 1 %)
    G2, h2 = G[order] * 1.01, h[order] + 0.001
    marked = np.zeros(p, np.bool_)
    assert carry_rows(Gc, hc, 2, G2, h2, p, marked, CARRY_TOL) == 2
    assert sorted(np.flatnonzero(marked)) == sorted(np.flatnonzero(np.isin(order, [2, 9])))
    far = np.zeros(p, np.bool_)  # (row 9 gone: nothing within the tolerance of it)
    keep = order != 9
    G3, h3 = G2[keep], h2[keep]
    assert carry_rows(Gc, hc, 2, G3, h3, p - 1, far, CARRY_TOL) == 1
    assert np.flatnonzero(far).tolist() == [int(np.flatnonzero(order[keep] == 2)[0])]
    assert keep_rows(G, h, p, np.ones(p, np.bool_), Gc, hc) == 0  # (12 rows, room for 8)


def _watched_walk(robot, stack, method: str, ticks: int, seen: list | None = None):
    """walk10 on ``stack``, ``CarriedRows.<method>`` watched: each tick's Δq; into ``seen``
    for each tick whose ``method`` marked rows, (its tick, the rows marked, its final set).
    Watching ``switch``, no ordinary tick may carry rows."""
    controller = StackController(stack)
    solver = controller.solver
    session = Session(controller, robot, build("walk10", robot))
    marked: list = []
    original = getattr(CarriedRows, method)

    def watch(self, *args):
        original(self, *args)
        p, working = args[-2], args[-1]
        marked.append(working[:p].copy())

    setattr(CarriedRows, method, watch)
    out = []
    try:
        for i in range(ticks):
            marked.clear()
            session.tick(i)
            plan = solver.fast
            out.append(plan.dq.copy())
            if method == "switch":
                assert plan.carried.count == 0  # (nothing carried to an ordinary tick)
            if seen is not None and marked and marked[0].any():
                k = plan.damped_level
                seen.append((i, marked[0], plan.inequalities.working[k, : marked[0].size].copy()))
    finally:
        setattr(CarriedRows, method, original)
    return out


def _walk(robot, carry: bool, ticks: int, seen: list | None = None):
    """walk10 on ``walk_strict``, ``carry_rows`` as given (see ``_watched_walk``)."""
    stack = load_stack("walk_strict", robot)
    stack.solver.carry_rows = carry
    return _watched_walk(robot, stack, "carry", ticks, seen)


#: the two walks' tests in one worker: their reference walk (:func:`plain_walk`) made once
same_walk = pytest.mark.xdist_group("carried_rows_walk")


@pytest.fixture(scope="module")
def plain_walk(robot):
    """Each tick's Δq of walk_strict along walk10's first 200 ticks as loaded (``carry_rows``
    and ``carry_at_switch`` off, the defaults): the answers both carries must give."""
    return _walk(robot, False, 200)


@same_walk
@pytest.mark.long(15)
def test_carried_rows_give_the_same_answers_from_the_final_set(robot, plain_walk):
    """walk_strict along walk10 (self-collision rows held in every single support): with the
    last level's rows carried (``carry_rows``, off by default) each tick's Δq is the one
    without (each tick's inputs the same: its minimiser is unique) to rounding; the ticks that
    start from carried rows are many, and most rows carried are in their tick's final set (59
    of 74 on these 200 ticks; rows carried by their index, 22 of 74: a self-collision row's
    index names another corner or pair as the legs' pairs come and go)."""
    assert not load_stack("walk_strict", robot).solver.carry_rows  # (the default)
    seen: list = []
    warm = _walk(robot, True, 200, seen)
    assert max(np.abs(a - b).max() for a, b in zip(warm, plain_walk, strict=True)) <= 1e-12
    assert len(seen) >= 20, len(seen)
    carried = sum(int(start.sum()) for _, start, _ in seen)
    final = sum(int((start & end).sum()) for _, start, end in seen)
    assert final >= 0.7 * carried, (final, carried)
    assert sum(np.array_equal(start, end) for _, start, end in seen) >= len(seen) // 2


def _switch_walk(robot, on: bool, ticks: int, seen: list | None = None):
    """walk10 on ``walk_strict`` with ``carry_at_switch`` as given (see ``_watched_walk``)."""
    stack = load_stack("walk_strict", robot, carry_at_switch=on)
    return _watched_walk(robot, stack, "switch", ticks, seen)


@same_walk
@pytest.mark.long(11)
def test_a_support_switch_starts_from_the_last_phases_rows(robot, plain_walk):
    """``walk_strict`` with ``carry_at_switch`` (off by default; a stack file's key) along
    walk10's first 160 ticks: the touch-downs (ticks 104, 144: self-collision rows held as single
    support ends) start the last level from the rows the last phase ended with, found in the
    new layout's rows by value, and most are in the tick's final set; no other tick is
    started so; each tick's Δq is the one without to rounding (its minimiser is unique)."""
    assert not load_stack("walk_strict", robot).solver.carry_at_switch  # (the default)
    assert build_stack({"solver": "hierarchical", "carry_at_switch": True, "levels": [
        {"tasks": [{"type": "com"}]}]}, robot).solver.carry_at_switch  # fmt: skip
    seen: list = []
    on = _switch_walk(robot, True, 160, seen)
    assert max(np.abs(a - b).max() for a, b in zip(on, plain_walk[:160], strict=True)) <= 1e-12
    ref = build("walk10", robot)
    firsts = set((np.flatnonzero(np.diff(ref.support[:160]) != 0) + 1).tolist())
    assert {104, 144} <= {i for i, *_ in seen} <= firsts, [i for i, *_ in seen]
    carried = sum(int(start.sum()) for _, start, _ in seen)
    final = sum(int((start & end).sum()) for _, start, end in seen)
    assert final >= 0.7 * carried > 0, (final, carried)
