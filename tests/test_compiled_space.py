"""The compiled cascade's work space (:mod:`wbc.compiled.space`): a solver's, reused by every
tick at the same addresses, re-sized with the rows, and the answers as without it."""

from __future__ import annotations

import numpy as np
from test_compiled_solvers import _walk_strict_ticks

from wbc.compiled import ticks
from wbc.compiled.space import cascade_space_size


def _solve(plan, start, space):
    """The plan's tick solved again from its inputs (``start``: its level states) in
    ``space``: (status, Δq)."""
    g = plan.inequalities
    dq, q_next = np.zeros_like(plan.dq), np.zeros_like(plan.q_next)
    status = ticks.cascade_solve(
        plan.rows.J, plan.rows.b, plan.level_rows, plan.level_hard, g.G, g.h, g.g_rows,
        plan.q, plan.q_min, plan.q_max, plan.params, plan.lower, plan.upper, start.copy(),
        np.zeros_like(g.working), np.zeros_like(g.h_eff), np.zeros_like(plan.achieved), dq,
        q_next, *space,
    )  # fmt: skip
    return int(status), dq


def test_the_answers_do_not_depend_on_the_space(robot):
    """``walk_strict`` along walk10 (the rows joining the deferred solve: the sets its fallback
    keeps at the space's end): each tick solved again in the plan's space, in the same
    space filled with NaN first (what an earlier tick left there is never read before it is
    written), and in buffers too small (allocated in the call, as before the space) gives the
    tick's Δq bit for bit; the solve writes in the space it is given."""
    checked = rows = 0
    walk = _walk_strict_ticks(robot, 60, defer_with_rows=True, defer_rows_join=True)
    for i, plan, start, _, _ in walk:
        fw, iw = plan.space
        assert fw.size and iw.size
        for space in (plan.space, None, (np.zeros(0), np.zeros(0, np.int64))):
            if space is None:  # (stale values: NaN, and integers far out of range)
                fw.fill(np.nan)
                iw.fill(-(1 << 40))
                space = plan.space
            status, dq = _solve(plan, start, space)
            assert status == ticks.OK, i
            assert np.array_equal(dq, plan.dq), (i, np.abs(dq - plan.dq).max())
            if space is plan.space:
                assert not np.isnan(fw).all() and (iw != -(1 << 40)).any()
        checked += 1
        rows += plan.inequalities.g_rows[-1] > 0
    assert checked >= 40 and rows >= 40  # (ticks with self-collision rows: the rows' path)


def test_the_space_is_the_solvers_and_follows_the_rows(robot):
    """The tick is bound to the space (its address among the tick's buffers); the solver's
    plans (one per support layout) share one block, so a phase's first tick works where the
    tick before did; it is sized for the inequality rows' capacity, and re-sized (and the
    tick re-bound) when that grows."""
    plans = {}
    for _, plan, _, _, _ in _walk_strict_ticks(robot, 120, defer_with_rows=True):
        plans[id(plan)] = plan
        fw, iw = plan.space
        assert fw.ctypes.data in plan.packed[0] and iw.ctypes.data in plan.packed[0]
        f, i = cascade_space_size(plan.level_rows, plan.dq.shape[0], plan.inequalities.h.size)
        assert (fw.size, iw.size) == (f, i)
    assert len(plans) >= 2  # (walk10's first 120 ticks switch support)
    # (one block: the same start, or a larger one for more rows)
    addresses = {p.space[0].ctypes.data for p in plans.values()}
    assert len(addresses) < len(plans), addresses
    plan = list(plans.values())[-1]
    before = plan.space[0].size
    assert plan.inequalities.total > 0
    plan.reserve_rows(2 * plan.inequalities.h.size)
    fw, iw = plan.space
    f, i = cascade_space_size(plan.level_rows, plan.dq.shape[0], plan.inequalities.h.size)
    assert fw.size == f > before and iw.size == i
    assert fw.ctypes.data in plan.packed[0] and iw.ctypes.data in plan.packed[0]
    plan.work_space = False  # (off: none given, the solve allocates its arrays per call)
    plan._bind_args()
    assert plan.space[0].size == plan.space[1].size == 0
