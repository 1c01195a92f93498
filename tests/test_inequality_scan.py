"""The inequality rows' active set around a damped level (:func:`wbc.compiled.ticks.
solve_with_inequalities`): what its last scan reports and the lone row it keeps without its
multiplier computed."""

from __future__ import annotations

import numpy as np
import pytest
from test_compiled_lsq import N, random_level, solve

from wbc.compiled.lsq import OK, level_space
from wbc.compiled.lsq_multipliers import equality_multipliers
from wbc.compiled.ticks import DEGENERATE_ROW, _degenerate, solve_with_inequalities

TOL = 1e-9


def _rows(A, a, B, r, ridge, lower, upper, G, h):
    """The rows' solve from the level's minimiser without them (the damped last level's way,
    the most violated joining first): (status, near, x, state, working)."""
    status, x, state, _ = solve(A, a, B, r, ridge, lower, upper)
    assert status == OK
    working = np.zeros(G.shape[0], np.bool_)
    space = level_space(A.shape[0] + G.shape[0], N, B.shape[0])
    status, near = solve_with_inequalities(
        A, a, B, r, ridge, np.bool_(False), lower, upper, state, x, G, h, G.shape[0], TOL,
        working, x.copy(), np.bool_(False), space, np.bool_(False), np.int64(0), np.empty(0),
        np.empty(0, np.int64),
    )  # fmt: skip
    return int(status), bool(near), x, state, working


def _level_with_rows(seed: int, p: int, pushed: float):
    """A random damped level and p rows, the first violated by its minimiser without rows by
    ``pushed`` (the others slack by 0.05-0.5)."""
    A, a, B, r, ridge, lower, upper = random_level(seed, 4, 12, 1e-4)
    free = solve(A, a, B, r, ridge, lower, upper)[1]
    rng = np.random.default_rng(100 + seed)
    G = rng.standard_normal((p, N))
    h = G @ free + rng.uniform(0.05, 0.5, p)
    h[0] = G[0] @ free - pushed
    return A, a, B, r, ridge, lower, upper, G, h


def test_near_is_the_degenerate_check_at_the_answer():
    """``near`` (from the rows' values of the last scan) is :func:`_degenerate` at the answer:
    False with every other row slack; True once a row that stays outside the working set is
    put within DEGENERATE_ROW of its bound at that answer (on most of the levels: the row may
    join on the way there and leave)."""
    tight = 0
    for seed in range(12):
        A, a, B, r, ridge, lower, upper, G, h = _level_with_rows(seed, 5, 0.05)
        status, near, x, _, working = _rows(A, a, B, r, ridge, lower, upper, G, h)
        assert status == OK
        assert near == _degenerate(G, h, G.shape[0], working, x)
        assert not near  # (the other rows slack by 0.05 or more at the start)
        outside = int(np.flatnonzero(~working)[-1])
        h_tight = h.copy()
        h_tight[outside] = G[outside] @ x + 0.1 * DEGENERATE_ROW  # (met, not violated)
        status, near, x2, _, working = _rows(A, a, B, r, ridge, lower, upper, G, h_tight)
        assert status == OK
        assert near == _degenerate(G, h_tight, G.shape[0], working, x2)
        np.testing.assert_allclose(x2, x, rtol=0, atol=1e-8)
        tight += near
    assert tight >= 8, tight


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("pushed", [1e-8, 1e-3, 0.2])
def test_a_lone_row_kept_without_its_multiplier_has_one_of_the_right_sign(seed, pushed):
    """One row violated by the level's minimiser without rows joins alone and stays, its
    multiplier not computed: computed here it is ≥ 0 (the value of the level as that row's
    bound moves is convex, least beyond it), and the answer meets the row and the level's
    stationarity with it (``equality_multipliers`` finds a certificate)."""
    A, a, B, r, ridge, lower, upper, G, h = _level_with_rows(seed, 1, pushed)
    status, _, x, state, working = _rows(A, a, B, r, ridge, lower, upper, G, h)
    assert status == OK and working.tolist() == [True]
    assert abs(G[0] @ x - h[0]) <= 1e-9 * (1 + abs(h[0]))
    grad = B.T @ (B @ x - r) + ridge * x
    lam = np.zeros(A.shape[0] + 1)
    assert equality_multipliers(np.vstack([A, G[:1]]), state, grad, lam)
    assert lam[-1] >= -TOL * (1.0 + abs(lam[-1])), lam[-1]
