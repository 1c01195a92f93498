"""A subproblem of the set whose factors are in the work space solves only its right-hand sides
(``lsq._FACTORED``): the same answer, bit for bit, as the subproblem factored afresh."""

from __future__ import annotations

import numpy as np
import pytest

from tests.test_compiled_lsq import random_level
from wbc.compiled import lsq, proximal
from wbc.compiled.lsq import OK, _solve, level_space


def _shifted(seed: int, A, a, B, r, lower, upper, x):
    """The same A and B with other right-hand sides: a proximal step's (a − A x, r − B x, the
    bounds less x) at a point x moved a little off the answer."""
    rng = np.random.default_rng(seed)
    x = x + 1e-3 * rng.standard_normal(x.shape[0])
    x = np.clip(x, lower, upper)
    return a - A @ x, r - B @ x, lower - x, upper - x


def _call(A, a, B, r, ridge, lower, upper, state, space, same):
    x = np.zeros(A.shape[1])
    status, count = _solve(
        A, a, B, r, ridge, lower, upper, state, x, 1e-9, 100, space, np.bool_(False),
        np.bool_(False), 0, np.bool_(same),
    )  # fmt: skip
    return status, count, x


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("m, p", [(6, 9), (4, 30)])  # (the row form, p < d; the normal form)
def test_a_factored_subproblem_is_the_fresh_one_bit_for_bit(seed, m, p):
    """A second call with ``same`` (only a, r and the bounds changed) warm from the first's set:
    its first subproblem takes the factors of the first call's last fresh one where that was of
    the same set (:func:`test_the_factors_are_used`), and x, the set and the count are those of
    the same call in a fresh space, bit for bit: a factored path that left out a right-hand
    side (a, r, the fixed bounds) or took a stale set's factors would not give the same bits."""
    A, a, B, r, ridge, lower, upper = random_level(seed, m, p, 1e-6)
    space = level_space(m, A.shape[1], p)
    state = np.zeros(A.shape[1], np.int8)
    status, _, x = _call(A, a, B, r, ridge, lower, upper, state, space, False)
    assert status == OK
    a2, r2, lo2, up2 = _shifted(seed, A, a, B, r, lower, upper, x)
    s_same, s_fresh = state.copy(), state.copy()
    st1, n1, x1 = _call(A, a2, B, r2, ridge, lo2, up2, s_same, space, True)
    fresh = level_space(m, A.shape[1], p)
    st2, n2, x2 = _call(A, a2, B, r2, ridge, lo2, up2, s_fresh, fresh, False)
    assert (st1, n1) == (st2, n2)
    assert np.array_equal(s_same, s_fresh)
    assert np.array_equal(x1, x2)


def test_the_factors_are_used(monkeypatch):
    """The second call's first subproblem (above) takes the factors (``factored`` > 0) on at
    least half of the random levels: the comparison above is of the factored path, not of two
    fresh solves (a mutant that never reuses them fails here)."""
    seen: list[int] = []
    sub = lsq._subproblem

    def counted(*args):
        seen.append(int(args[-1]))
        return sub(*args)

    monkeypatch.setattr(lsq, "_subproblem", counted)
    used = 0
    for seed in range(12):
        A, a, B, r, ridge, lower, upper = random_level(seed, 6, 9, 1e-6)
        space = level_space(6, A.shape[1], 9)
        state = np.zeros(A.shape[1], np.int8)
        x = np.zeros(A.shape[1])
        lsq._solve.py_func(
            A, a, B, r, ridge, lower, upper, state, x, 1e-9, 100, space, False, False, 0, False
        )
        a2, r2, lo2, up2 = _shifted(seed, A, a, B, r, lower, upper, x)
        seen.clear()
        y = np.zeros(A.shape[1])
        lsq._solve.py_func(
            A, a2, B, r2, ridge, lo2, up2, state, y, 1e-9, 100, space, False, False, 0, True
        )
        used += seen[0] > 0
    assert used >= 6, used


@pytest.mark.parametrize("seed", range(6))
def test_proximal_steps_in_the_level_space_are_those_in_a_fresh_one(seed):
    """The proximal steps in a work space left by another call (its factors, its carry) give the
    answer of the same steps in a fresh space, bit for bit (each step's ``same`` holds only
    for the steps before it)."""
    A, a, B, r, _, lower, upper = random_level(seed, 6, 9, 0.0)
    n = A.shape[1]
    used = level_space(6, n, 9)
    st0 = np.zeros(n, np.int8)
    # (another level's call in it first: its factors, of another B, in the space)
    B_other = B[::-1].copy()
    _call(A, a, B_other, r, 1e-3, lower, upper, st0.copy(), used, False)
    xs, states = [], []
    for space in (used, level_space(6, n, 9)):
        x = np.zeros(n)
        state = np.zeros(n, np.int8)
        status = lsq.solve_level(A, a, B, r, 1e-3, lower, upper, state, x)
        assert status == OK
        status = proximal.proximal_level(A, a, B, r, lower, upper, state, x, 100, 0, space)
        assert status == OK
        xs.append(x)
        states.append(state)
    assert np.array_equal(xs[0], xs[1])
    assert np.array_equal(states[0], states[1])
