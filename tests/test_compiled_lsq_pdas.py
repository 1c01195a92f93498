"""PDAS going on past a step that does not lower its infeasibilities (``lsq.PDAS_TIES``,
``lsq.PDAS_RISE``) on a damped level: the same answer as the dual method taking over at once.

The active set loop is run as Python (``_solve.py_func``, the subproblems compiled) with the
switch on and off (it reads the module's constants at run time), and compiled (the default
switch), on damped levels warm-started from the active set of a nearby level (another
right-hand side, a joined row), as the hierarchy's last level from its last tick's set.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_compiled_lsq import N, assert_kkt, random_level, solve

from wbc.compiled import lsq
from wbc.compiled.lsq import OK, level_space

#: the switch on, as measured (benchmarks/self_collision.md, sixteenth pass)
ON = (2, 1)
#: the compiled kernels' setting
DEFAULT = (lsq.PDAS_TIES, lsq.PDAS_RISE)


def run_python(A, a, B, r, ridge, lower, upper, state, ties: int, rise: int):
    """``_solve`` as Python with PDAS_TIES = ``ties``, PDAS_RISE = ``rise``: (status, x, state,
    subproblems)."""
    keep = lsq.PDAS_TIES, lsq.PDAS_RISE
    lsq.PDAS_TIES, lsq.PDAS_RISE = ties, rise
    try:
        state = state.copy()
        x = np.zeros(N)
        space = level_space(A.shape[0], N, B.shape[0])
        status, count = lsq._solve.py_func(
            A, a, B, r, float(ridge), lower, upper, state, x, 1e-9, 100, space,
            np.bool_(False), np.bool_(False),
        )  # fmt: skip
    finally:
        lsq.PDAS_TIES, lsq.PDAS_RISE = keep
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
    assert before[0] == after[0] == compiled[0]
    if before[0] != OK:
        return
    assert_kkt(after[1], after[2], *problem)
    np.testing.assert_allclose(after[1], before[1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(compiled[1], before[1], rtol=0, atol=1e-10)
    np.testing.assert_array_equal(after[2], before[2])


def test_the_switch_takes_the_path_and_saves_subproblems():
    """Over fixed seeds: the compiled kernels take the module's setting (their subproblem
    counts are the Python run's with it), some seeds take fewer subproblems with the switch on
    than off, and the answers agree (the test above); so the path is exercised."""
    fewer = more = 0
    total = {0: 0, 2: 0}
    for seed in range(120):
        problem, warm = nearby(seed, 6 if seed % 2 else 12, 9 if seed % 3 else 21, seed % 4 == 0)
        off = run_python(*problem, warm, 0, 0)
        on = run_python(*problem, warm, *ON)
        compiled = solve(*problem, state=warm, max_iter=100)
        assert compiled[3] == (on if DEFAULT == ON else off)[3], seed
        if off[0] == OK:
            np.testing.assert_allclose(on[1], off[1], rtol=0, atol=1e-10)
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
