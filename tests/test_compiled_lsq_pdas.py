"""PDAS going on past a step that does not lower its infeasibilities (the level solver's
``ties`` argument, the hierarchy's ``lsq.PDAS_TIES``; ``lsq.PDAS_RISE``) on a damped level: the
same answer as the dual method taking over at once.

The active set loop is run as Python (``_solve.py_func``, the subproblems compiled) with the
budget on and off, and compiled (``solve_level_iterations``'s ``ties``), on damped levels
warm-started from the active set of a nearby level (another right-hand side, a joined row), as
the hierarchy's last level from its last tick's set. The compiled ticks pass the hierarchy's
budget on the hierarchy's levels and 0 on the weighted QP's (tests below, the kernels as Python
around the level solver).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_compiled_lsq import N, assert_kkt, random_level, solve

from wbc.compiled import lsq
from wbc.compiled.lsq import OK, level_space

#: the budget on, as measured (benchmarks/self_collision.md, sixteenth pass)
ON = (2, 1)
#: the compiled kernels' setting (the hierarchy's budget; PDAS_RISE is read at compile time)
DEFAULT = (lsq.PDAS_TIES, lsq.PDAS_RISE)


def run_python(A, a, B, r, ridge, lower, upper, state, ties: int, rise: int):
    """``_solve`` as Python with the budget ``ties``, PDAS_RISE = ``rise``: (status, x, state,
    subproblems)."""
    keep = lsq.PDAS_RISE
    lsq.PDAS_RISE = rise
    try:
        state = state.copy()
        x = np.zeros(N)
        space = level_space(A.shape[0], N, B.shape[0])
        status, count = lsq._solve.py_func(
            A, a, B, r, float(ridge), lower, upper, state, x, 1e-9, 100, space,
            np.bool_(False), np.bool_(False), ties, np.bool_(False),
        )  # fmt: skip
    finally:
        lsq.PDAS_RISE = keep
    return int(status), x, state, int(count)


def nearby(seed: int, m: int, p: int, joined: bool):
    """A damped level and the active set of a nearby one (its right-hand side moved, or one
    row fewer) as the warm start."""
    A, a, B, r, ridge, lower, upper = random_level(seed, m, p, 1e-6)
    rng = np.random.default_rng(seed + 1)
    if joined:
        row = rng.standard_normal(N)
        x0 = np.linalg.lstsq(A, a, rcond=None)[0].clip(0.5 * lower, 0.5 * upper)
        A2, a2, r2 = np.vstack([A, row]), np.r_[a, row @ x0], r
    else:
        A2, a2, r2 = A, a, r + 2.0 * rng.standard_normal(p)
    status, _, state, _ = solve(A, a, B, r, ridge, lower, upper, max_iter=100)
    return (A2, a2, B, r2, ridge, lower, upper), state if status == OK else np.zeros(N, np.int8)


# (seeds whose warm start takes PDAS through steps that do not lower its count)
@example(seed=3, m=6, p=9, joined=False)
@example(seed=11, m=12, p=9, joined=True)
@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 2),
    m=st.sampled_from([0, 6, 12]),
    p=st.sampled_from([9, 21, 30]),
    joined=st.booleans(),
)
def test_pdas_past_a_stall_answers_as_the_dual_method_at_once(seed, m, p, joined):
    problem, warm = nearby(seed, m, p, joined and m > 0)
    before = run_python(*problem, warm, 0, 0)
    after = run_python(*problem, warm, *ON)
    compiled = solve(*problem, state=warm, max_iter=100)
    compiled_on = solve(*problem, state=warm, max_iter=100, ties=DEFAULT[0])
    assert before[0] == after[0] == compiled[0] == compiled_on[0]
    if before[0] != OK:
        return
    assert_kkt(after[1], after[2], *problem)
    assert_kkt(compiled_on[1], compiled_on[2], *problem)
    np.testing.assert_allclose(after[1], before[1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(compiled[1], before[1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(compiled_on[1], compiled[1], rtol=0, atol=1e-10)
    np.testing.assert_array_equal(after[2], before[2])
    np.testing.assert_array_equal(compiled_on[2], compiled[2])


def test_the_switch_takes_the_path_and_saves_subproblems():
    """Over fixed seeds: the compiled solver takes its ``ties`` argument (its subproblem
    counts are the Python run's with it: the hierarchy's budget, and 0), some seeds take fewer
    subproblems with the budget on than off, and the answers agree (the test above); so the
    path is exercised."""
    assert DEFAULT == ON  # (the hierarchy's default, as measured)
    fewer = more = 0
    total = {0: 0, 2: 0}
    for seed in range(120):
        problem, warm = nearby(seed, 6 if seed % 2 else 12, 9 if seed % 3 else 21, seed % 4 == 0)
        off = run_python(*problem, warm, 0, 0)
        on = run_python(*problem, warm, *ON)
        compiled_off = solve(*problem, state=warm, max_iter=100)
        compiled_on = solve(*problem, state=warm, max_iter=100, ties=lsq.PDAS_TIES)
        assert compiled_off[3] == off[3] and compiled_on[3] == on[3], seed
        if off[0] == OK:
            np.testing.assert_allclose(on[1], off[1], rtol=0, atol=1e-10)
            np.testing.assert_allclose(compiled_on[1], compiled_off[1], rtol=0, atol=1e-10)
        fewer += on[3] < off[3]
        more += on[3] > off[3]
        total[0] += off[3]
        total[2] += on[3]
    assert fewer > 0, "no seed took the path"
    assert total[2] <= total[0], total


def test_ties_are_bounded():
    """A PDAS that would cycle still hands over to the dual method: the same answer within the
    subproblem budget however many ties are allowed."""
    problem, warm = nearby(5, 6, 9, False)
    base = run_python(*problem, warm, 0, 0)
    for ties, rise in ((1, 0), (2, 1), (4, 3)):
        status, x, _, count = run_python(*problem, warm, ties, rise)
        assert status == base[0] == OK
        assert count <= 100
        np.testing.assert_allclose(x, base[1], rtol=0, atol=1e-10)


@pytest.mark.parametrize("ridge", [0.0])
def test_an_exact_level_keeps_the_old_path(ridge):
    """Without a ridge (optima need not be unique) the switch changes nothing: the same
    subproblems, bit for bit."""
    A, a, B, r, _, lower, upper = random_level(7, 6, 30, ridge)
    warm = np.zeros(N, np.int8)
    off = run_python(A, a, B, r, ridge, lower, upper, warm, 0, 0)
    on = run_python(A, a, B, r, ridge, lower, upper, warm, *ON)
    assert off[0] == on[0] and off[3] == on[3]
    np.testing.assert_array_equal(off[1], on[1])


def _recording(monkeypatch, seen: list):
    """The tick kernels around the level solver as Python, each level solve's (ridge, ties)
    into ``seen`` (the level solver itself compiled)."""
    from wbc.compiled import ticks

    level_in, proximal = ticks.solve_level_in, ticks.proximal_level

    def level_in_seen(*args):
        seen.append((float(args[4]), int(args[13])))
        return level_in(*args)

    def proximal_seen(*args):
        seen.append((-1.0, int(args[9])))
        return proximal(*args)

    monkeypatch.setattr(ticks, "solve_level_in", level_in_seen)
    monkeypatch.setattr(ticks, "proximal_level", proximal_seen)
    monkeypatch.setattr(ticks, "_level", ticks._level.py_func)
    monkeypatch.setattr(ticks, "solve_with_inequalities", ticks.solve_with_inequalities.py_func)
    return ticks


def test_the_weighted_qp_keeps_the_dual_method_at_the_first_tie(monkeypatch):
    """The weighted QP's level solves (alone and with its inequality rows) get a budget of 0,
    whatever the hierarchy's: its answer is the one before the budget, bit for bit (the
    thesis's qp-* controllers' runs)."""
    seen: list = []
    A, a, B, r, ridge, lower, upper = random_level(3, 6, 9, 1e-6)
    rng = np.random.default_rng(0)
    G = rng.standard_normal((3, N))
    free = solve(A, a, B, r, ridge, lower, upper)[1]
    h = G @ free - 0.05  # (violated by the solution without them: the rows' path)
    q = np.zeros(N + 1)
    q[6] = 1.0
    q_min, q_max = np.full(N - 6, -10.0), np.full(N - 6, 10.0)
    params = np.array([0.0, ridge, 1e-9, 1e-9])

    def run(kernel):
        dq, q_next = np.zeros(N), np.zeros(N + 1)
        status = kernel(
            B, r, A, a, G, h, np.array([0, 3], dtype=np.int64), q, q_min, q_max, params,
            lower.copy(), upper.copy(), np.zeros(N, np.int8), np.zeros(3, np.bool_), dq, q_next,
        )  # fmt: skip
        return int(status), dq

    from wbc.compiled import ticks

    compiled = run(ticks.weighted_solve)
    with monkeypatch.context() as patch:
        as_python = run(_recording(patch, seen).weighted_solve.py_func)
    assert compiled[0] == as_python[0] == OK
    np.testing.assert_array_equal(as_python[1], compiled[1])
    assert len(seen) >= 2 and all(ties == 0 for _, ties in seen), seen  # (alone, with rows)


def test_the_hierarchys_levels_get_the_stacks_budget(robot, monkeypatch):
    """``walk_strict`` along walk10 (its file sets ``pdas_ties``): every level solve of the
    compiled cascade, run with the kernels around the level solver as Python, gets the budget
    (``lsq.PDAS_TIES``), damped last levels included, and answers the compiled tick bit for
    bit (the same code); with its rows dropped too (the stack's option, not the tick's rows).
    With the option off (``params[4]`` 0: the thesis's stacks, whose ill-posed runs rounding
    moves) every solve gets 0, as the weighted QP's."""
    from test_compiled_solvers import _saved, _walk_strict_ticks

    seen: list = []
    checked = 0
    for i, plan, start, _, _ in _walk_strict_ticks(robot, 40, defer_with_rows=True):
        g = plan.inequalities
        dq = np.zeros(robot.nv)
        with monkeypatch.context() as patch:
            status = _recording(patch, seen)._cascade.py_func(
                plan.rows.J, plan.rows.b, plan.level_rows, plan.level_hard, g.G, g.h,
                g.g_rows, plan.params, plan.lower, plan.upper, start, np.zeros_like(g.working),
                np.zeros_like(g.h_eff), np.zeros_like(plan.achieved), dq, np.bool_(True),
                *plan.space, _saved(plan),
            )  # fmt: skip
        assert status == OK, i
        assert np.array_equal(dq, plan.dq), i
        checked += 1
    assert checked >= 20
    assert any(ridge > 0.0 for ridge, _ in seen)
    assert all(ties == lsq.PDAS_TIES for _, ties in seen), set(seen)
    for budget in (lsq.PDAS_TIES, 0):
        seen.clear()
        for _, plan, start, _, _ in _walk_strict_ticks(robot, 12, defer_with_rows=True):
            g = plan.inequalities
            params = plan.params.copy()
            params[4] = budget
            with monkeypatch.context() as patch:
                _recording(patch, seen)._cascade.py_func(
                    plan.rows.J, plan.rows.b, plan.level_rows, plan.level_hard, g.G, g.h,
                    np.zeros_like(g.g_rows), params, plan.lower, plan.upper, start,
                    np.zeros_like(g.working), np.zeros_like(g.h_eff),
                    np.zeros_like(plan.achieved), np.zeros(robot.nv), np.bool_(True),
                    *plan.space, _saved(plan),
                )  # fmt: skip
        assert any(ridge > 0.0 for ridge, _ in seen)
        assert all(ties == budget for _, ties in seen), (budget, set(seen))


def test_the_stacks_set_the_budget(robot):
    """The stacks with self-collision rows set ``pdas_ties`` in their files, the thesis's do
    not (nor a hierarchy built without it), and the plan passes it to the tick."""
    from wbc.solvers import HierarchicalQP
    from wbc.stacks import load_stack

    for name, on in (("walk", True), ("walk_strict", True), ("cj_com", False)):
        solver = load_stack(name, robot).solver
        assert getattr(solver, "pdas_ties", False) is on, name
    weighted = load_stack("walk_strict", robot, solver="weighted").solver
    assert not hasattr(weighted, "pdas_ties")
    assert not HierarchicalQP(load_stack("walk", robot).solver.stack).pdas_ties
