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
