"""The damped last level's weakly held bounds marked in the carried set and released at the
next solve's start (:mod:`wbc.compiled.lsq_release`, ``HierarchicalQP.release_small``)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.test_compiled_lsq import random_level
from wbc.compiled.lsq import OK, level_space, solve_level_in
from wbc.compiled.lsq_release import WEAK, mark_weak, release_marked
from wbc.exceptions import ConfigurationError


def _solve(A, a, B, r, ridge, lower, upper, state, space):
    x = np.zeros(A.shape[1])
    status, count = solve_level_in(
        A, a, B, r, ridge, lower, upper, state, x, 1e-9, np.int64(100), space, np.bool_(False),
        np.int64(2),
    )  # fmt: skip
    return status, count, x


@pytest.mark.parametrize("seed", range(10))
def test_the_marks_are_the_bounds_held_with_a_small_gradient(seed):
    """Without equalities a held bound's multiplier is its gradient entry, Bᵀ(Bx − r) + ridge·x
    (computed here in numpy, not read from the solver): the marked bounds are exactly those
    below the ratio × the largest held one, each on its side; a pinned variable is never
    marked; :func:`release_marked` frees exactly the marked ones."""
    A, a, B, r, ridge, lower, upper = random_level(seed, 0, 30, 1e-3)
    lower[-1] = upper[-1] = 0.1  # (a pinned variable)
    n = A.shape[1]
    space = level_space(0, n, B.shape[0])
    state = np.zeros(n, np.int8)
    status, _, x = _solve(A, a, B, r, ridge, lower, upper, state, space)
    assert status == OK
    grad = B.T @ (B @ x - r) + ridge * x
    held = (state != 0) & (lower < upper)
    assert held.sum() >= 2
    ratio = 0.5
    expect = held & (np.abs(grad) < ratio * np.abs(grad[held]).max())
    assert 0 < expect.sum() < held.sum()
    plain = state.copy()
    marked = mark_weak(state, space[0][3], lower, upper, ratio)
    assert marked == expect.sum()
    np.testing.assert_array_equal(np.abs(state) == WEAK, expect)
    np.testing.assert_array_equal(np.sign(state), np.sign(plain))  # (the side kept)
    assert abs(state[-1]) == 1
    assert release_marked(state) == marked
    np.testing.assert_array_equal(state, np.where(expect, 0, plain))


@pytest.mark.parametrize("m", [0, 4])
def test_a_start_with_the_weak_bounds_released_reaches_the_same_minimiser(m):
    """The next tick's level (the same A, B; moved right-hand sides) solved from the last set
    and from it with the weak bounds released: the same set and x within 1e-12 (a damped level
    has one minimiser), on 10 random levels; and the released start is another start on most
    of them (else the option would do nothing)."""
    other = 0
    for seed in range(10):
        A, a, B, r, ridge, lower, upper = random_level(seed, m, 30, 1e-3)
        n, p = A.shape[1], B.shape[0]
        space = level_space(m, n, p)
        state = np.zeros(n, np.int8)
        status, _, _ = _solve(A, a, B, r, ridge, lower, upper, state, space)
        assert status == OK
        marks = state.copy()
        mark_weak(marks, space[0][3], lower, upper, 0.3)
        rng = np.random.default_rng(100 + seed)
        r2 = r + 0.5 * rng.standard_normal(p)
        kept, released = state.copy(), marks.copy()
        other += release_marked(released) > 0
        s1, _, x1 = _solve(A, a, B, r2, ridge, lower, upper, kept, level_space(m, n, p))
        s2, _, x2 = _solve(A, a, B, r2, ridge, lower, upper, released, level_space(m, n, p))
        assert s1 == s2 == OK
        np.testing.assert_array_equal(kept, released)
        assert np.abs(x1 - x2).max() <= 1e-12
    assert other >= 5


def test_the_option_is_checked():
    from wbc import load_robot
    from wbc.solvers import HierarchicalQP, TaskStack

    stack = TaskStack(load_robot("bioloid"))
    assert HierarchicalQP(stack).release_small == 0.0  # (off by default: main's path)
    assert HierarchicalQP(stack, release_small=0.03).release_small == 0.03
    with pytest.raises(ConfigurationError, match=r"release_small must be a number in \[0, 1\]"):
        HierarchicalQP(stack, release_small=1.5)
