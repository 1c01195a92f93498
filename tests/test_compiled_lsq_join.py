"""The compiled level solver continued across calls (:func:`wbc.compiled.lsq.solve_level_in`):
equality rows joining a solved level (the hierarchy's rows joining its last level, one call
each) update the last call's factors, and the answers are a fresh solve's from the same warm
start: on random levels, with rows that are independent, dependent on the level's rows
(consistent or not), on the variables the warm set holds, or a combination of the level's
rows that reaches held variables beyond it (no part in the null space until they are
released: ``lsq_update.WFIRST``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from test_compiled_lsq import N, random_level, solve

from wbc.compiled import lsq
from wbc.compiled.lsq import INCONSISTENT, OK, PDAS_TIES, level_space, solve_level_in

_KINDS = ["random", "dependent", "inconsistent", "held", "held_rounded", "sparse", "lifted"]


def _row(kind, rng, A, a, state, x):
    """A row to join (and its target) of the given kind."""
    if kind == "dependent":  # a combination of the level's rows: consistent
        c = rng.standard_normal(A.shape[0])
        return c @ A, c @ a
    if kind == "inconsistent":
        c = rng.standard_normal(A.shape[0])
        return c @ A, c @ a + 1.0
    if kind == "lifted" and np.any(state != 0):  # the level's rows, and a held variable more
        c = rng.standard_normal(A.shape[0])
        row = c @ A
        row[np.flatnonzero(state != 0)[0]] += 1.0 + rng.uniform()
        return row, row @ x - 0.05
    row = np.zeros(N)
    if kind in ("held", "held_rounded"):  # on variables the warm set holds at their bounds
        held = np.flatnonzero(state != 0)  # (a collision row on joints at their speed), met
        row[held[: max(1, len(held) // 2)]] = rng.standard_normal(max(1, len(held) // 2))
        target = row @ (0.5 * x)  # halfway in; ... with rounding on the free variables (the
        if kind == "held_rounded":  # walk's rows: ~1e-20 on joints outside the pair's chains)
            free = np.flatnonzero(state == 0)
            row[free] = 1e-18 * np.abs(row).max() * rng.standard_normal(free.size)
        return row, target
    elif kind == "sparse":
        row[rng.choice(N, 4, replace=False)] = rng.standard_normal(4)
    else:
        row = rng.standard_normal(N)
    return row, row @ x - 0.05  # (x moved a little: as a violated row held at its bound)


def _continued(A, a, B, r, ridge, lower, upper, state, space, cont):
    x = np.zeros(N)
    state = state.copy()
    status, count = solve_level_in(
        A, a, B, r, float(ridge), lower, upper, state, x, 1e-9, 100, space, np.bool_(cont), 0
    )
    return status, x, state, count


@example(seed=0, m=6, p=30, kinds=["random", "random", "random"])
@example(seed=1, m=12, p=9, kinds=["held", "random"])
@example(seed=2, m=6, p=30, kinds=["dependent", "sparse"])
@example(seed=3, m=6, p=9, kinds=["inconsistent"])
@example(seed=4, m=6, p=30, kinds=["lifted", "held", "lifted"])
@example(seed=5, m=12, p=9, kinds=["held", "held", "held"])
@example(seed=6, m=6, p=30, kinds=["held_rounded", "held_rounded"])
@given(
    seed=st.integers(0, 2**32 - 1), m=st.sampled_from([6, 12]), p=st.sampled_from([30, 9]),
    kinds=st.lists(st.sampled_from(_KINDS), min_size=1, max_size=3),
)  # fmt: skip
def test_rows_joining_a_level_answer_as_a_fresh_solve(seed, m, p, kinds):
    A, a, B, r, ridge, lower, upper = random_level(seed, m, p, 1e-6)
    rng = np.random.default_rng(seed)
    space = level_space(m + len(kinds), N, p)
    status, x, state, _ = _continued(A, a, B, r, ridge, lower, upper, np.zeros(N, np.int8),
                                     space, False)  # fmt: skip
    assert status == OK
    for kind in kinds:
        row, target = _row(kind, rng, A, a, state, x)
        A, a = np.vstack([A, row]), np.r_[a, target]
        status_c, x_c, state_c, _ = _continued(A, a, B, r, ridge, lower, upper, state, space,
                                               True)  # fmt: skip
        status_f, x_f, state_f, _ = solve(A, a, B, r, ridge, lower, upper, state=state,
                                          max_iter=100)  # fmt: skip
        assert status_c == status_f
        if status_f != OK:
            return
        np.testing.assert_array_equal(state_c, state_f)
        np.testing.assert_allclose(x_c, x_f, rtol=0, atol=1e-10)
        x, state = x_c, state_c


@pytest.mark.parametrize("seed", range(8))
def test_a_joined_row_updates_the_last_calls_factors(seed):
    """An independent row joining: the continued call's final subproblem is an update of the
    last call's base (its rows: the level's without the row), not solved afresh; and without
    ``cont`` it is solved afresh."""
    m, p = 6, 30
    A, a, B, r, ridge, lower, upper = random_level(seed, m, p, 1e-6)
    rng = np.random.default_rng(seed)
    space = level_space(m + 1, N, p)
    status, x, state, _ = _continued(A, a, B, r, ridge, lower, upper, np.zeros(N, np.int8),
                                     space, False)  # fmt: skip
    assert status == OK
    carry = space[7]
    assert carry[0] == 1 and carry[1] == m
    row, target = _row("random", rng, A, a, state, x)
    A2, a2 = np.vstack([A, row]), np.r_[a, target]
    status, x2, _, _ = _continued(A2, a2, B, r, ridge, lower, upper, state, space, True)
    assert status == OK
    assert carry[0] == 1 and carry[1] == m  # (the base kept: every subproblem an update)
    status, x3, _, _ = _continued(A2, a2, B, r, ridge, lower, upper, state, space, False)
    assert carry[0] == 1 and carry[1] == m + 1
    np.testing.assert_allclose(x2, x3, rtol=0, atol=1e-10)


def test_an_inconsistent_joined_row_is_reported_as_a_fresh_solve():
    A, a, B, r, ridge, lower, upper = random_level(5, 6, 30, 1e-6)
    space = level_space(7, N, 30)
    status, _, state, _ = _continued(A, a, B, r, ridge, lower, upper, np.zeros(N, np.int8),
                                     space, False)  # fmt: skip
    A2, a2 = np.vstack([A, A[0] + A[1]]), np.r_[a, a[0] + a[1] + 1.0]
    status, x, _, _ = _continued(A2, a2, B, r, ridge, lower, upper, state, space, True)
    assert status == INCONSISTENT and np.all(np.isnan(x))


@pytest.mark.parametrize("kind", ["held", "held_rounded"])
@pytest.mark.parametrize("seed", range(8))
def test_a_row_on_held_variables_releases_them_without_a_solve(seed, kind):
    """A row joining on variables the warm set holds (an inconsistent warm start): their
    bounds released at once, where a fresh solve finds the set inconsistent first (one
    subproblem more), and the row on the released variables an update of the last call's
    base (``lsq_update.WFIRST``: no subproblem solved afresh); the same answer. Also with
    rounding (1e-18 of the row) on the free variables, as the walk's rows have (these random
    levels decline the same way with ``lsq_update.ROW_FULL_SIZE`` off: the walk's own case,
    :func:`test_a_walks_row_on_a_held_joint_is_one_update`, is the one that tells)."""
    m, p = 6, 30
    A, a, B, r, ridge, lower, upper = random_level(seed, m, p, 1e-6)
    rng = np.random.default_rng(seed)
    space = level_space(m + 1, N, p)
    status, x, state, _ = _continued(A, a, B, r, ridge, lower, upper, np.zeros(N, np.int8),
                                     space, False)  # fmt: skip
    assert status == OK and np.any(state != 0)
    row, target = _row(kind, rng, A, a, state, x)
    A2, a2 = np.vstack([A, row]), np.r_[a, target]
    status_c, x_c, state_c, count_c = _continued(A2, a2, B, r, ridge, lower, upper, state,
                                                 space, True)  # fmt: skip
    status_f, x_f, state_f, count_f = solve(A2, a2, B, r, ridge, lower, upper, state=state,
                                            max_iter=100)  # fmt: skip
    assert status_c == status_f == OK
    assert count_c < count_f
    assert space[7][0] == 1 and space[7][1] == m  # (the base kept: every subproblem an update)
    np.testing.assert_array_equal(state_c, state_f)
    np.testing.assert_allclose(x_c, x_f, rtol=0, atol=1e-10)


def test_a_walks_row_on_a_held_joint_is_one_update():
    """walk_strict's walk10 tick 287 (benchmarks/cascade_replay.py), its last level: a
    self-collision row joining on one joint the warm set holds, ~1e-20 on the others (the
    rows' Jacobians' rounding). Measured against its whole size (``lsq_update.ROW_FULL_SIZE``)
    it depends on the held bound, which is released, and the row on the released joint is one
    update; measured on the free variables alone it passed as independent, its update moved x
    beyond 15 of the 24 bounds and the call took 3 subproblems (2 fresh). The answer is the
    fresh solve's from the same warm set."""
    d = np.load(Path(__file__).parent / "data" / "walk10_joined_row_on_a_held_joint.npz")
    keys = ("A", "a", "B", "r", "lower", "upper")
    A, a, B, r, lower, upper = (np.ascontiguousarray(d[k]) for k in keys)
    ridge, warm = float(d["ridge"]), d["state"]
    n = A.shape[1]
    space = level_space(A.shape[0], n, B.shape[0])
    state = warm.copy()
    x = np.zeros(n)
    status, _ = solve_level_in(A[:-1].copy(), a[:-1].copy(), B, r, ridge, lower, upper, state,
                               x, 1e-9, 100, space, np.bool_(False), 0)  # fmt: skip
    assert status == OK and np.array_equal(state, warm)
    status_c, x_c, state_c, count_c = _continued(A, a, B, r, ridge, lower, upper, state, space,
                                                 True)  # fmt: skip
    status_f, x_f, state_f, _ = solve(A, a, B, r, ridge, lower, upper, state=warm, max_iter=100)
    assert status_c == status_f == OK
    assert count_c == 1
    np.testing.assert_array_equal(state_c, state_f)
    np.testing.assert_allclose(x_c, x_f, rtol=0, atol=1e-10)


def test_a_touch_downs_row_releases_the_bounds_it_pushes_inwards(monkeypatch):
    """walk_strict's walk10 touch-down at tick 144 (solve 150 of a benchmarks/cascade_replay.py
    capture), its last level: a self-collision row joining on joints the warm set holds
    (``lsq_update._ROW_DEPENDS``). With ``lsq.INWARD_RELEASE`` (the default: compiled, and
    the solver run here as Python with it set, its kernels compiled) only the bounds the
    row's miss pushes inwards are released and the call takes one subproblem, an update (the
    stack's PDAS budget, ``lsq.PDAS_TIES``); releasing every bound in the row (off, as
    Python), PDAS fixes most of them again in 4. Both answer as the fresh solve from the same
    warm set."""
    d = np.load(Path(__file__).parent / "data" / "walk10_touch_down_row_on_held_joints.npz")
    keys = ("A", "a", "B", "r", "lower", "upper")
    A, a, B, r, lower, upper = (np.ascontiguousarray(d[k]) for k in keys)
    ridge = float(d["ridge"])
    n = A.shape[1]
    cold = np.zeros(n, np.int8)  # (the cold start: the same minimiser)
    status_f, x_f, _, _ = solve(A, a, B, r, ridge, lower, upper, state=cold, max_iter=100)

    def joined(inward: bool, compiled: bool):
        monkeypatch.setattr(lsq, "INWARD_RELEASE", inward)
        level = lsq.solve_level_in if compiled else _as_python
        space = level_space(A.shape[0], n, B.shape[0])
        state, x = d["state"].copy(), np.zeros(n)
        status, _ = level(A[:-1].copy(), a[:-1].copy(), B, r, ridge, lower, upper, state, x,
                          1e-9, 100, space, np.bool_(False), PDAS_TIES)  # fmt: skip
        assert status == OK and np.any(state != 0)
        assert A[-1] @ x > a[-1]  # (the row joins violated)
        warm = state.copy()
        status, count = level(A, a, B, r, ridge, lower, upper, state, x, 1e-9, 100, space,
                              np.bool_(True), PDAS_TIES)  # fmt: skip
        status_w, x_w, state_w, _ = solve(A, a, B, r, ridge, lower, upper, state=warm,
                                          max_iter=100)  # fmt: skip
        assert status == status_w == status_f == OK
        np.testing.assert_array_equal(state, state_w)
        np.testing.assert_allclose(x, x_w, rtol=0, atol=1e-10)
        np.testing.assert_allclose(x, x_f, rtol=0, atol=1e-10)
        return count

    assert joined(True, False) == joined(True, True) == 1
    assert joined(False, False) == 4


@pytest.mark.parametrize("m, p", [(6, 30), (12, 9)])
def test_a_held_row_releases_first_the_bounds_its_miss_at_the_last_answer_pushes_inwards(
    monkeypatch, m, p
):  # fmt: skip
    """Rows on variables the warm set holds (``held``: halfway in, or ``lifted``: a
    combination of the level's rows and a held variable), each joining a solved random level
    (``lsq.INWARD_RELEASE``, the default, compiled): the row's miss and the bounds'
    multipliers are taken at the last call's answer, which the work space keeps — the same
    subproblems whatever x the caller passes (zeros here, the last answer in the tick); on
    these 2 × 12 levels they take fewer subproblems in sum than releasing every bound in the
    row (off, as Python), with the same answers and active sets."""
    counts = {"zeros": 0, "last": 0, "off": 0}
    for seed in range(12):
        for kind in ("held", "lifted"):
            A, a, B, r, ridge, lower, upper = random_level(seed, m, p, 1e-6)
            rng = np.random.default_rng(seed)
            space = level_space(m + 1, N, p)
            x0 = np.zeros(N)
            warm = np.zeros(N, np.int8)
            status, _ = solve_level_in(A, a, B, r, ridge, lower, upper, warm, x0, 1e-9, 100,
                                       space, np.bool_(False), 0)  # fmt: skip
            assert status == OK and np.any(warm != 0)
            row, target = _row(kind, rng, A, a, warm, x0)
            A2, a2 = np.vstack([A, row]), np.r_[a, target]
            out = {}
            for how in counts:
                level = _as_python if how == "off" else solve_level_in
                monkeypatch.setattr(lsq, "INWARD_RELEASE", how != "off")
                space = level_space(m + 1, N, p)  # (the base call again: its factors, x)
                x, state = np.zeros(N), np.zeros(N, np.int8)
                level(A, a, B, r, ridge, lower, upper, state, x, 1e-9, 100, space,
                      np.bool_(False), 0)  # fmt: skip
                if how == "zeros":
                    x[:] = 0.0
                status, count = level(A2, a2, B, r, ridge, lower, upper, state, x, 1e-9, 100,
                                      space, np.bool_(True), 0)  # fmt: skip
                counts[how] += count
                out[how] = (status, x, state)
            assert out["zeros"][0] == out["last"][0] == out["off"][0]
            if out["off"][0] != OK:
                continue
            np.testing.assert_array_equal(out["zeros"][1], out["last"][1])
            np.testing.assert_array_equal(out["last"][2], out["off"][2])
            np.testing.assert_allclose(out["last"][1], out["off"][1], rtol=0, atol=1e-10)
    assert counts["zeros"] == counts["last"] < counts["off"]


def _as_python(A, a, B, r, ridge, lower, upper, state, x, rank_rtol, max_iter, space, cont, ties):
    """:func:`~wbc.compiled.lsq.solve_level_in` with its solver run as Python (the module's
    switches read at the call; the kernels it calls compiled)."""
    return lsq._solve.py_func(
        A, a, B, r, float(ridge), lower, upper, state, x, float(rank_rtol), int(max_iter), space,
        np.bool_(cont), np.bool_(True), int(ties), np.bool_(False),
    )  # fmt: skip
