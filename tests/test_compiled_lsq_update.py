"""The compiled level solver's updated subproblem (:mod:`wbc.compiled.lsq_update`): bounds added
to a solved set give the subproblem solved afresh (x and the bounds' multipliers), and the
update declines where it does not apply (a bound that depends on the equalities, more bounds
than the null space holds, a released variable whose column leaves the range of the
equalities, a base bound moved to its other side). Base bounds released since are updated too
(the bordered system), alone or with bounds added; and with ``FLIPS`` (an option, off: the
update run as Python with it set, its kernels compiled) base bounds moved to their other
side (a released bound whose w is known), alone, with the others, with rows joined."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.compiled import lsq_update
from wbc.compiled.lsq_linalg import _I_FIXED, _N_IVEC, _N_VEC, _V_MU, _V_MU_TOL
from wbc.compiled.lsq_subproblem import _SUB_OK, _subproblem
from wbc.compiled.lsq_update import _DECLINED, _ROW_DEPENDS, _U_Q, _U_ROWS, _UPDATED, _updated


def _update(A, a, B, ridge, lower, upper, x, work, ind, U, S, K, base, k, m, first, flips=False):
    """:func:`_updated` on the base's work arrays (rank ``k``, ``m`` rows; ``first``: the base's
    solution still in x), the integer and flag arguments typed as the tick passes them;
    ``flips``: its Python body with ``lsq_update.FLIPS`` set (the kernels it calls compiled)."""
    update = _updated.py_func if flips else _updated
    return update(A, a, B, ridge, lower, upper, x, *work, ind, U, S, K, base, np.int64(k),
                  np.bool_(first), np.int64(m))  # fmt: skip


def _work(m: int, n: int, p: int) -> tuple:
    pp = (p + 3) & ~3
    work = np.zeros((4, max(m, n, _N_VEC), max(m, n, pp)))
    ind = np.zeros((_N_IVEC, max(m, n)), dtype=np.int64)
    U = np.zeros((_U_Q + _U_ROWS * n, max(n, pp)))
    S = np.zeros((n, n + 1))
    K = np.zeros((n, 2 * n + 3))
    return work, ind, U, S, K


def _problem(seed: int, m: int, n: int = 24, p: int = 21) -> tuple:
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, n))
    a = rng.standard_normal(m)
    B = rng.standard_normal((p, n))
    r = 3.0 * rng.standard_normal(p)
    lower = -rng.uniform(0.1, 1.0, n)
    upper = rng.uniform(0.1, 1.0, n)
    return A, a, B, r, lower, upper


def _base(A, a, B, r, ridge, lower, upper, fixed, work, ind):
    """The base subproblem solved afresh for the fixed set ``fixed``: its x, its rank."""
    n = A.shape[1]
    x = np.zeros(n)
    ind[_I_FIXED, :n] = fixed
    status, k = _subproblem(
        A,
        a,
        B,
        r,
        ridge,
        lower,
        upper,
        x,
        1e-9,
        work[0],
        work[1],
        work[2],
        work[3],
        ind,
        np.int64(0),
    )
    assert status == _SUB_OK
    return x, k


def _updated_and_afresh(A, a, B, r, lower, upper, m, released, added, moved=()) -> tuple:
    """The base (A's first ``m`` rows, x_1, x_5, x_9, x_13 held at their bounds) updated to
    every row of A with the bounds ``released`` freed, ``added`` held and ``moved`` held at
    their other bound (the update must apply), and the same set solved afresh: (x, μ,
    x afresh, μ afresh, the base's rank, the fresh rank, the held mask)."""
    n = A.shape[1]
    ridge = 1e-4
    base = np.zeros(n, dtype=np.int64)
    base[[1, 5, 9, 13]] = [-1, 1, -1, 1]
    work, ind, U, S, K = _work(A.shape[0], n, B.shape[0])
    x, k = _base(A[:m], a[:m], B, r, ridge, lower, upper, base, work, ind)
    fixed = base.copy()
    fixed[released] = 0
    for j, v in enumerate(added):
        fixed[v] = 1 if j % 2 else -1
    for v in moved:
        fixed[v] = -base[v]
    ind[_I_FIXED, :n] = fixed
    flips = len(moved) > 0
    assert _update(
        A, a, B, ridge, lower, upper, x, work, ind, U, S, K, base, k, m, True, flips
    ) == (_UPDATED)
    mu = work[3][_V_MU, :n].copy()
    work2, ind2, _, _, _ = _work(A.shape[0], n, B.shape[0])
    x2, k2 = _base(A, a, B, r, ridge, lower, upper, fixed, work2, ind2)
    return x, mu, x2, work2[3][_V_MU, :n], k, k2, fixed != 0


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [6, 15])
@pytest.mark.parametrize("added", [1, 2, 3])
def test_added_bounds_answer_as_the_subproblem_solved_afresh(seed, m, added):
    A, a, B, r, lower, upper = _problem(seed, m)
    n = A.shape[1]
    ridge = 1e-4
    base = np.zeros(n, dtype=np.int64)
    base[[1, 5, 9]] = [-1, 1, -1]
    work, ind, U, S, K = _work(m, n, B.shape[0])
    x, k = _base(A, a, B, r, ridge, lower, upper, base, work, ind)
    fixed = base.copy()
    for j, v in enumerate([3, 11, 17][:added]):
        fixed[v] = 1 if j % 2 else -1
    ind[_I_FIXED, :n] = fixed
    assert _update(A, a, B, ridge, lower, upper, x, work, ind, U, S, K, base, k, m, True)
    mu = work[3][_V_MU, :n].copy()
    mu_tol = work[3][_V_MU_TOL, :n].copy()
    # the same set solved afresh
    work2, ind2, _, _, _ = _work(m, n, B.shape[0])
    x2, _ = _base(A, a, B, r, ridge, lower, upper, fixed, work2, ind2)
    held = fixed != 0
    assert np.max(np.abs(x - x2)) < 1e-10 * (1.0 + np.max(np.abs(x2)))
    assert np.allclose(mu[held], work2[3][_V_MU, :n][held], rtol=1e-8, atol=1e-10)
    assert np.allclose(mu_tol[held], work2[3][_V_MU_TOL, :n][held], rtol=1e-6, atol=1e-15)
    # and a second update from the same base (its solution kept in U) answers the same
    ind[_I_FIXED, :n] = fixed
    x3 = np.full(n, np.nan)
    assert _update(A, a, B, ridge, lower, upper, x3, work, ind, U, S, K, base, k, m, False)
    assert np.max(np.abs(x3 - x2)) < 1e-10 * (1.0 + np.max(np.abs(x2)))


def test_the_update_declines_where_it_does_not_apply(monkeypatch):
    m = 6
    A, a, B, r, lower, upper = _problem(0, m)
    n = A.shape[1]
    A[0] = 0.0
    A[0, 7] = 1.0  # x_7 = a_0: holding x_7 at a bound drops the rank of A_F
    ridge = 1e-4
    base = np.zeros(n, dtype=np.int64)
    base[[1, 5]] = [-1, 1]
    work, ind, U, S, K = _work(m, n, B.shape[0])
    x, k = _base(A, a, B, r, ridge, lower, upper, base, work, ind)
    args = (np.int64(k), np.bool_(True), np.int64(m))

    def update(fixed, flips=False):
        ind[_I_FIXED, :n] = fixed
        solve = _updated.py_func if flips else _updated
        return solve(A, a, B, ridge, lower, upper, x.copy(), *work, ind, U, S, K, base, *args)

    moved = base.copy()  # a base bound moved to its other side: declined, unless FLIPS
    moved[5] = -1
    assert update(moved) == _DECLINED
    monkeypatch.setattr(lsq_update, "FLIPS", True)
    assert update(moved, True) == _UPDATED
    dependent = base.copy()
    dependent[7] = 1
    assert not update(dependent)
    d = n - 2 - k  # more bounds than the null space's dimension
    too_many = base.copy()
    too_many[[v for v in range(n) if base[v] == 0 and v != 7][: d + 1]] = -1
    assert update(too_many) == _DECLINED
    too_many[5] = -1  # (... with a bound moved too)
    assert update(too_many, True) == _DECLINED
    one = base.copy()
    one[3] = 1
    assert update(one)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [6, 15])
@pytest.mark.parametrize(
    "released, added", [([5], []), ([1, 9], []), ([5], [3]), ([1, 5], [11, 17])]
)
def test_released_bounds_answer_as_the_subproblem_solved_afresh(seed, m, released, added):
    A, a, B, r, lower, upper = _problem(seed, m)
    x, mu, x2, mu2, _, _, held = _updated_and_afresh(A, a, B, r, lower, upper, m, released, added)
    assert np.max(np.abs(x - x2)) < 1e-10 * (1.0 + np.max(np.abs(x2)))
    assert np.allclose(mu[held], mu2[held], rtol=1e-8, atol=1e-10)
    # the released variables are free and not at their base bounds any more
    assert np.all(np.abs(x[released] - x2[released]) < 1e-10)


def test_a_release_that_changes_the_rank_declines():
    m = 6
    A, a, B, r, lower, upper = _problem(0, m)
    n = A.shape[1]
    # row 0 holds only x_5 and x_7; with both fixed the others' columns leave row 0 out of
    # the range of A_F: releasing x_5 raises the rank
    A[0] = 0.0
    A[0, 5] = 1.0
    A[0, 7] = 1.0
    a[0] = upper[5] + lower[7]  # (met by the base's bounds)
    ridge = 1e-4
    base = np.zeros(n, dtype=np.int64)
    base[[1, 5, 7]] = [-1, 1, -1]
    work, ind, U, S, K = _work(m, n, B.shape[0])
    x, k = _base(A, a, B, r, ridge, lower, upper, base, work, ind)
    fixed = base.copy()
    fixed[5] = 0
    ind[_I_FIXED, :n] = fixed
    assert not _update(A, a, B, ridge, lower, upper, x, work, ind, U, S, K, base, k, m, True)
    fixed = base.copy()
    fixed[1] = 0  # x_1's column is in the range: updated
    ind[_I_FIXED, :n] = fixed
    assert _update(A, a, B, ridge, lower, upper, x, work, ind, U, S, K, base, k, m, True)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [6, 15])
@pytest.mark.parametrize(
    "joined, released, added", [(1, [], []), (2, [], []), (1, [], [3]), (2, [5], [11]),
                                (1, [1, 9], [])],
)  # fmt: skip
def test_joined_rows_answer_as_the_subproblem_solved_afresh(seed, m, joined, released, added):
    """Equality rows joined since the base (A's rows from the base's m on, as a row of
    self-collision joins the hierarchy's last level), with bounds added or released: the
    subproblem of the whole set solved afresh (x, the held bounds' multipliers)."""
    A, a, B, r, lower, upper = _problem(seed, m + joined)
    x, mu, x2, mu2, k, k2, held = _updated_and_afresh(A, a, B, r, lower, upper, m, released, added)
    assert k2 == k + joined
    assert np.max(np.abs(x - x2)) < 1e-10 * (1.0 + np.max(np.abs(x2)))
    assert np.allclose(mu[held], mu2[held], rtol=1e-8, atol=1e-10)
    assert np.max(np.abs(A @ x - a)) < 1e-10


def test_a_joined_row_that_depends_on_the_others_declines():
    m = 6
    A, a, B, r, lower, upper = _problem(0, m + 1)
    n = A.shape[1]
    ridge = 1e-4
    base = np.zeros(n, dtype=np.int64)
    base[[1, 5]] = [-1, 1]
    work, ind, U, S, K = _work(m + 1, n, B.shape[0])
    x, k = _base(A[:m], a[:m], B, r, ridge, lower, upper, base, work, ind)

    def update():
        ind[_I_FIXED, :n] = base
        return _update(A, a, B, ridge, lower, upper, x.copy(), work, ind, U, S, K, base, k, m, True)

    A[m] = A[0] - 2.0 * A[3]  # a combination of the base's rows
    a[m] = a[0] - 2.0 * a[3]
    assert update() == _ROW_DEPENDS
    A[m] = 0.0
    A[m, [1, 5]] = [1.0, 2.0]  # on the held variables only
    assert update() == _ROW_DEPENDS
    A[m, 7] = 1.0  # and a free one: an update
    assert update() == _UPDATED


def _on_released(seed: int, m: int, extra: float) -> tuple:
    """A problem whose joined row A[m] is, on the base's free variables, a combination of the
    base's rows (no part in its null space: ``c_g = 0``) and reaches the held x_1 by
    ``extra`` more than that combination does."""
    A, a, B, r, lower, upper = _problem(seed, m + 1)
    A[m] = A[0] - 2.0 * A[3]
    A[m, 1] += extra
    return A, a, B, r, lower, upper


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [6, 15])
@pytest.mark.parametrize("released, added", [([1], []), ([1, 9], []), ([1], [3]), ([1, 5], [11])])
def test_a_joined_row_on_released_variables_answers_as_solved_afresh(seed, m, released, added):
    """A joined row with no part in the base's null space that reaches a released variable
    (``WFIRST``: w eliminated before ν, as on walk_strict's double-support ticks after a row's
    bounds are released): the subproblem solved afresh, x and the held bounds' multipliers."""
    A, a, B, r, lower, upper = _on_released(seed, m, 0.7)
    x, mu, x2, mu2, k, k2, held = _updated_and_afresh(A, a, B, r, lower, upper, m, released, added)
    assert k2 == k + 1
    assert np.max(np.abs(x - x2)) < 1e-10 * (1.0 + np.max(np.abs(x2)))
    assert np.allclose(mu[held], mu2[held], rtol=1e-8, atol=1e-10)
    assert np.max(np.abs(A @ x - a)) < 1e-10


@pytest.mark.parametrize("seed", range(3))
def test_a_joined_row_still_dependent_after_the_release_declines(seed):
    """The same row without the extra reach (a combination of the base's rows on every
    variable, released ones included): dependent whatever is released, so no update."""
    m = 6
    A, a, B, r, lower, upper = _on_released(seed, m, 0.0)
    n = A.shape[1]
    ridge = 1e-4
    base = np.zeros(n, dtype=np.int64)
    base[[1, 5, 9, 13]] = [-1, 1, -1, 1]
    work, ind, U, S, K = _work(m + 1, n, B.shape[0])
    x, k = _base(A[:m], a[:m], B, r, ridge, lower, upper, base, work, ind)
    fixed = base.copy()
    fixed[1] = 0
    ind[_I_FIXED, :n] = fixed
    assert _update(A, a, B, ridge, lower, upper, x, work, ind, U, S, K, base, k, m, True) == (
        _ROW_DEPENDS
    )


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("m", [6, 15])
@pytest.mark.parametrize(
    "joined, released, added, moved",
    [(0, [], [], [5]), (0, [], [], [1, 13]), (0, [9], [], [5]), (0, [], [3], [5]),
     (0, [1], [11, 17], [9, 13]), (1, [], [], [5]), (2, [9], [3], [1, 5])],
)  # fmt: skip
def test_moved_bounds_answer_as_the_subproblem_solved_afresh(
    seed, m, joined, released, added, moved, monkeypatch
):
    """Base bounds moved to their other side (a joint from one speed bound to the other, as on
    walk_strict's mid-swing ticks), alone, with bounds released or added, with rows joined:
    the subproblem of the whole set solved afresh (x, the held bounds' multipliers); the
    moved variables exactly on their new bounds (``FLIPS`` set)."""
    monkeypatch.setattr(lsq_update, "FLIPS", True)
    A, a, B, r, lower, upper = _problem(seed, m + joined)
    x, mu, x2, mu2, k, k2, held = _updated_and_afresh(
        A, a, B, r, lower, upper, m, released, added, moved
    )
    assert k2 == k + joined
    assert np.max(np.abs(x - x2)) < 1e-10 * (1.0 + np.max(np.abs(x2)))
    assert np.allclose(mu[held], mu2[held], rtol=1e-8, atol=1e-10)
    assert np.array_equal(x[moved], x2[moved])
    assert np.max(np.abs(A @ x - a)) < 1e-10


@pytest.mark.parametrize("seed", range(6))
def test_a_moved_bound_with_a_joined_row_on_released_variables_answers_as_solved_afresh(
    seed, monkeypatch
):
    """A joined row with no part in the base's null space, met on a released variable (w
    first: ``_w_first``), with a base bound moved to its other side (its known w in the
    bordered system's right-hand side; ``FLIPS`` set)."""
    monkeypatch.setattr(lsq_update, "FLIPS", True)
    m = 6
    A, a, B, r, lower, upper = _on_released(seed, m, 0.7)
    x, mu, x2, mu2, k, k2, held = _updated_and_afresh(A, a, B, r, lower, upper, m, [1], [], [9])
    assert k2 == k + 1
    assert np.max(np.abs(x - x2)) < 1e-10 * (1.0 + np.max(np.abs(x2)))
    assert np.allclose(mu[held], mu2[held], rtol=1e-8, atol=1e-10)
    assert np.max(np.abs(A @ x - a)) < 1e-10
