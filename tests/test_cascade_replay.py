"""benchmarks/cascade_replay.py: a walk's captured cascade inputs replay to its answers."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

import cascade_replay as R


@pytest.fixture(scope="module")
def captured():
    return R.capture("walk10", "walk_strict")


def test_the_replay_reproduces_the_captured_answers(captured):
    from wbc.solvers.carry import CarriedRows
    from wbc.solvers.plan import CascadePlan, _Plan

    # the capture's wrappers are gone: nothing it patched is left on a class that inherited it
    # (a CascadePlan.solve left behind hides later patches of _Plan.solve in this process)
    assert "solve" not in CascadePlan.__dict__ and CascadePlan.solve is _Plan.solve
    assert _Plan.forget_warm_start.__name__ == "forget_warm_start"
    assert CarriedRows.carry.__name__ == "carry"
    ticks = captured["ticks"]
    assert {t["tick"] for t in ticks} == set(range(len(captured["support"])))
    # (the capture is worth its name: ticks with inequality rows, and warm sets)
    assert any(t["g_rows"][-1] > 0 for t in ticks)
    assert any(t["states"].any() for t in ticks)
    out = R.replay(ticks, 1)
    dq = np.array([t["dq_out"] for t in ticks])
    assert np.abs(out["dq"] - dq).max() <= 1e-12
    np.testing.assert_array_equal(out["status"], [t["status"] for t in ticks])
    assert (out["t"] > 0).all()


def test_the_levels_one_by_one_give_the_rows_joining_deferred_answers(captured):
    """walk_strict walk10 is captured with the rows joining the deferred solve (the default,
    ``params[0]`` = 3 with ``skip_degenerate``, which never acts on this walk):
    replayed with the levels above solved one by one on the row ticks (``params[0]`` = 1),
    every tick's Δq is the captured one to rounding (a strictly convex last level over the
    same set: the deferral holds only where the levels above are met exactly with the rows,
    and its answer is not degenerate), and some ticks took the other path."""
    ticks = captured["ticks"]
    assert all(t["params"][0] == 3.0 for t in ticks)
    apart = [dict(t, params=np.concatenate([[1.0], t["params"][1:]])) for t in ticks]
    out = R.replay(apart, 1)
    diff = np.abs(out["dq"] - np.array([t["dq_out"] for t in ticks])).max(axis=1)
    assert diff.max() <= 1e-14, diff.max()
    assert (diff > 0).sum() >= 3
    np.testing.assert_array_equal(out["status"], [t["status"] for t in ticks])


def test_the_warm_sets_are_inputs(captured):
    """The captured warm sets are what the ticks started from: replayed from cold sets the
    answers move (the damped last level's rounding, its one minimiser the same to 1e-9)."""
    warm = [i for i, t in enumerate(captured["ticks"]) if t["states"].any()]
    cold = [dict(captured["ticks"][i], states=np.zeros_like(captured["ticks"][i]["states"]))
            for i in warm]  # fmt: skip
    out = R.replay(cold, 1)
    dq = np.array([captured["ticks"][i]["dq_out"] for i in warm])
    assert 0.0 < np.abs(out["dq"] - dq).max() <= 1e-9


def test_the_slowest_ticks_are_counted(captured, monkeypatch):
    """The subproblem counts (the kernels as Python) name each call's level and kinds."""
    import os

    if os.environ.get("NUMBA_DISABLE_JIT") != "1":
        out = R._run_child(R.ROOT, _dump(captured), 1, "300")
        calls = out["counts"][300]
    else:  # pragma: no cover
        calls = R.counts(captured["ticks"], [300])[300]
    assert calls and all(c["count"] >= 1 for c in calls)
    assert {c["level"] for c in calls} <= set(range(len(captured["ticks"][300]["level_rows"])))
    last = [c for c in calls if c["level"] == len(captured["ticks"][300]["level_rows"]) - 2]
    assert last and sum(sum(c["kinds"].values()) for c in last) >= sum(c["count"] for c in last)


def _dump(captured) -> str:
    import pickle
    import tempfile

    f = tempfile.NamedTemporaryFile(suffix=".pkl", delete=False)
    pickle.dump(captured, f)
    f.close()
    return f.name


def test_the_weak_bounds_marked_and_released_keep_the_answers(captured):
    """``release_small`` (``params[5]``, :mod:`wbc.compiled.lsq_release`): a tick solved with
    it marks weakly held bounds in the last level's carried set (with 0, main's path, never);
    the next tick started from that marked set, the marks released, gives the captured Δq
    (main's start) within 1e-12, on every tick where the capture carried that set."""
    from wbc.compiled.ticks import cascade_solve

    ticks = captured["ticks"]
    space = R.work_space(ticks)
    last = len(ticks[0]["level_rows"]) - 1  # (states[L]: the last level's set without rows)
    i_states, i_dq = R.ARGS.index("states"), R.ARGS.index("dq")

    def solved(tick, ratio, states=None):
        params = tick["params"].copy()
        params[5] = ratio
        args = R.call_args(dict(tick, params=params), space)
        if states is not None:
            args[i_states] = states.copy()
        cascade_solve(*args)
        return args[i_states], args[i_dq]

    chained = 0
    for t in range(len(ticks) - 1):
        off, _ = solved(ticks[t], 0.0)
        assert not (np.abs(off) == 2).any()
        on, _ = solved(ticks[t], 0.03)
        nxt = ticks[t + 1]
        if not (np.abs(on[last]) == 2).any() or ticks[t + 1]["tick"] != ticks[t]["tick"] + 1:
            continue
        if not np.array_equal(np.sign(on[last]), nxt["states"][last]):
            continue  # (the set the next tick started from is not this one's: forgotten)
        states = nxt["states"].copy()
        states[last] = on[last]
        _, dq = solved(nxt, 0.03, states)
        assert np.abs(dq - nxt["dq_out"]).max() <= 1e-12
        chained += 1
    assert chained >= 20
