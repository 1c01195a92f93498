"""The hierarchy's compiled cascade with ``defer_rows_join`` (on by default): the levels above
the last stay deferred on ticks with inequality rows active, the rows joining the last level's
solve — the same answers to rounding, by another path; where its answer is degenerate, the
levels one by one from the sets they would have started from."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

from test_carried_rows import _watched_walk

from wbc.compiled import ticks
from wbc.compiled.space import cascade_space_size
from wbc.stacks import build_stack, load_stack

DATA = Path(__file__).parent / "data"


def _joined_walk(robot, on: bool, ticks: int):
    stack = load_stack("walk_strict", robot, defer_rows_join=on)
    assert stack.solver.defer_rows_join is on
    return _watched_walk(robot, stack, "carry", ticks)


def test_rows_join_the_deferred_solve_to_rounding(robot):
    """walk_strict along walk10's first 160 ticks (self-collision rows active around the
    touch-downs 104 and 144): each tick's Δq with the rows joining the deferred solve is the
    one without to 1e-12 (a strictly convex last level over the same set where the levels
    above are met exactly), and from the first tick that took the other path (84, rows
    active) the walk differs in its last bits: the option does something."""
    assert load_stack("walk_strict", robot).solver.defer_rows_join  # (the default)
    assert not build_stack({"solver": "hierarchical", "defer_rows_join": False, "levels": [
        {"tasks": [{"type": "com"}]}]}, robot).solver.defer_rows_join  # fmt: skip
    on = _joined_walk(robot, True, 160)
    off = _joined_walk(robot, False, 160)
    diffs = np.array([np.abs(a - b).max() for a, b in zip(on, off, strict=True)])
    assert diffs.max() <= 1e-12, diffs.max()
    moved = np.flatnonzero(diffs > 0)
    assert moved.size >= 3, moved  # (ticks whose path changed)


def _solve(
    tick, join: bool, space: bool, p0: float = 0.0, refused: int = 0, solve=ticks.cascade_solve
) -> tuple[int, np.ndarray, np.ndarray]:
    """The captured tick's cascade_solve, the rows joining the deferred solve or not (or with
    ``params[0]`` = ``p0`` if given, and ``refused`` as the last tick's degenerate answer's flag),
    in a work space of its size or none (allocated in the call): (status, Δq, its final sets)."""
    params = tick["params"].copy()
    params[0] = p0 or (2.0 if join else 1.0)
    f, i = cascade_space_size(tick["level_rows"], tick["dq"].shape[0], int(tick["g_rows"][-1]))
    fw, iw = (np.full(f, np.nan), np.full(i, -(1 << 40))) if space else (np.zeros(0),) * 2
    states, dq = tick["states"].copy(), np.zeros_like(tick["dq"])
    states[-1, 1] = refused
    status = solve(
        tick["J"], tick["b"], tick["level_rows"], tick["level_hard"], tick["G"], tick["h"],
        tick["g_rows"], tick["q"], tick["q_min"], tick["q_max"], params, tick["lower"],
        tick["upper"], states, tick["working"].copy(), np.zeros_like(tick["h_eff"]),
        np.zeros_like(tick["achieved"]), dq, np.zeros_like(tick["q_next"]), fw,
        iw.astype(np.int64),
    )  # fmt: skip
    return int(status), dq, states


def test_a_degenerate_answer_falls_back_to_the_levels_one_by_one():
    """The OP3's walk_strict walk10, tick 308 (captured with the levels one by one): four
    self-collision rows within 1e-9 of their bounds at the answer, two held. With the rows
    joining the deferred solve its answer held two others, 1.5e-8 from the levels one by one
    (the OP3's closed loop then departed 0.03 rad); seeing a hard row outside its working set
    at its bound, the cascade solves the levels one by one from the sets they start from
    without it: the same Δq and sets bit for bit, with the space or without."""
    tick = dict(np.load(DATA / "op3_walk_strict_degenerate_rows_tick.npz"))
    for space in (True, False):
        s1, dq1, st1 = _solve(tick, False, space)
        s2, dq2, st2 = _solve(tick, True, space)
        assert s1 == s2 == 0
        assert np.abs(dq1 - tick["dq_out"]).max() <= 1e-15
        np.testing.assert_array_equal(dq2, dq1)
        np.testing.assert_array_equal(st2, st1)


def test_after_a_degenerate_answer_the_deferral_is_not_tried(robot, monkeypatch):
    """``skip_degenerate`` (``params[0]`` = 3, on by default): the OP3's tick 308 again. Its
    answer is degenerate, so the cascade marks it for the next tick (``states[L + 1, 1]``);
    a tick after such a mark solves the levels one by one at once (one ``_cascade`` call, not
    deferred) where the guard tries the deferral first and refuses it (two calls): the same Δq
    and sets bit for bit, as without the rows joining."""
    assert load_stack("walk_strict", robot).solver.skip_degenerate  # (the default)
    tick = dict(np.load(DATA / "op3_walk_strict_degenerate_rows_tick.npz"))
    assert tick["states"][-1, 0] == 1  # (the last tick ended with a row active)
    s1, dq1, st1 = _solve(tick, False, True)
    calls: list[bool] = []
    cascade = ticks._cascade

    def counted(*args):
        calls.append(bool(args[15]))  # (defer_soft)
        return cascade(*args)

    monkeypatch.setattr(ticks, "_cascade", counted)
    python = ticks.cascade_solve.py_func  # (its calls to _cascade seen: the kernels compiled)
    for p0, refused, path in ((3.0, 0, [True, False]), (3.0, 1, [False]), (2.0, 1, [True, False])):
        calls.clear()
        status, dq, states = _solve(tick, True, True, p0, refused, python)
        assert status == s1 == 0 and calls == path, (p0, refused, calls)
        np.testing.assert_array_equal(dq, dq1)
        np.testing.assert_array_equal(states[:-1], st1[:-1])
        assert states[-1, 0] == st1[-1, 0] == 1
        assert states[-1, 1] == (p0 == 3.0)  # (degenerate again: marked, with the option)
