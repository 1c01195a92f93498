"""PDAS's exchange with ``lsq.REFIX_GUARD`` (off by default): a variable the step before
released is not fixed again on the same side while other variables change in the step (1: at
every step; 2: at the steps that did not lower PDAS's count). Run as Python
(``_solve.py_func``, the subproblems compiled) on damped levels warm-started from a nearby
level's set (``test_compiled_lsq_pdas.nearby``, the hierarchy's PDAS budget): the same
statuses, active sets and answers (1e-10) as without it, and the guard changes the path on
some of them (a test that can fail)."""

from __future__ import annotations

import numpy as np
import pytest
from test_compiled_lsq import N, assert_kkt, solve
from test_compiled_lsq_pdas import nearby

from wbc.compiled import lsq
from wbc.compiled.lsq import OK, level_space


def run_python(problem, warm, guard: int, monkeypatch):
    """``_solve`` as Python with REFIX_GUARD = ``guard``: (status, x, state, subproblems)."""
    monkeypatch.setattr(lsq, "REFIX_GUARD", guard)
    A, a, B, r, ridge, lower, upper = problem
    state, x = warm.copy(), np.zeros(N)
    space = level_space(A.shape[0], N, B.shape[0])
    status, count = lsq._solve.py_func(
        A, a, B, r, float(ridge), lower, upper, state, x, 1e-9, 100, space,
        np.bool_(False), np.bool_(False), lsq.PDAS_TIES,
    )  # fmt: skip
    return int(status), x, state, int(count)


def test_the_guard_is_off_by_default():
    assert lsq.REFIX_GUARD == 0


@pytest.mark.parametrize("guard", [1, 2])
def test_the_guarded_exchange_answers_as_the_plain_one(guard, monkeypatch):
    changed = 0
    for seed in range(80):
        problem, warm = nearby(seed, 6 if seed % 2 else 12, 9 if seed % 3 else 21, seed % 4 == 0)
        off = run_python(problem, warm, 0, monkeypatch)
        on = run_python(problem, warm, guard, monkeypatch)
        compiled = solve(*problem, state=warm, max_iter=100, ties=lsq.PDAS_TIES)
        assert off[3] == compiled[3], seed  # (the Python run is the compiled default's path)
        assert on[0] == off[0] == compiled[0], seed
        changed += on[3] != off[3]
        if off[0] != OK:
            continue
        assert_kkt(on[1], on[2], *problem)
        np.testing.assert_array_equal(on[2], off[2])
        np.testing.assert_allclose(on[1], off[1], rtol=0, atol=1e-10)
    assert changed > 0, "the guard never acted"
