"""The benchmark CLI: records with the promised keys, recordings, figures, honest errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from wbc.bench import metrics, solvers
from wbc.cli import main
from wbc.recording import Recording

REQUIRED = {
    "solver", "family", "trajectory", "mode", "com_err_max_mm", "com_err_mean_mm",
    "foot_err_max_mm", "foot_err_mean_mm", "limit_violations", "limit_violation_max_rad",
    "penetration_max_mm", "com_margin_min_mm", "time_median_us", "time_p99_us", "failures",
}  # fmt: skip


def test_keys_match_the_issue():
    assert set(metrics.KEYS) == REQUIRED


@pytest.fixture(scope="module")
def bench_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    code = main([
        "bench", "--solvers", "hqp-daqp", "wqp-quadprog", "pinv-vat", "qp-cj_com", "placo",
        "--trajectories", "thesis_step", "--json", str(out / "b.json"),
        "--record", str(out / "runs"), "--plots", str(out / "plots"),
    ])  # fmt: skip
    assert code == 0
    return out


def test_json_records(bench_run):
    payload = json.loads((bench_run / "b.json").read_text())
    assert {"date", "machine", "command", "records"} <= set(payload)
    records = payload["records"]
    assert {r["solver"] for r in records} == {
        "hqp-daqp",
        "wqp-quadprog",
        "pinv-vat",
        "qp-cj_com",
        "placo",
    }
    for r in records:
        assert REQUIRED <= set(r), r["solver"]
        assert r["trajectory"] == "thesis_step" and r["mode"] == "tick"
        assert r["time_median_us"] > 0 and r["failures"] == 0
    by = {r["solver"]: r for r in records}
    # the hierarchy tracks the static step almost exactly, and never leaves the joint limits
    assert by["hqp-daqp"]["com_err_max_mm"] < 0.1
    assert by["hqp-daqp"]["limit_violations"] == 0


def test_recordings_hold_the_promised_arrays(robot, bench_run):
    path = bench_run / "runs" / "hqp-daqp__thesis_step.npz"
    with np.load(path) as data:
        for key in ("t", "q", "com_ref", "swing_ref", "support", "joint_names"):
            assert key in data.files
    rec = Recording.load(path)
    assert rec.joint_names == robot.joint_names
    # errors in the record are recomputable from the saved joints (forward kinematics)
    com = np.array([robot.com(q) for q in rec.q])
    err = np.linalg.norm(com - rec["com_ref"], axis=1).max() * 1e3
    record = next(
        r
        for r in json.loads((bench_run / "b.json").read_text())["records"]
        if r["solver"] == "hqp-daqp"
    )
    assert err == pytest.approx(record["com_err_max_mm"], rel=1e-9, abs=1e-12)


def test_figures(bench_run):
    plots = bench_run / "plots"
    assert (plots / "time_per_tick.png").stat().st_size > 10_000
    assert (plots / "placo__thesis_step.png").stat().st_size > 10_000


def test_missing_peer_is_reported_and_skipped(monkeypatch):
    monkeypatch.setattr(solvers, "available", lambda: {"placo": False, "pink": True})
    entries, notes = solvers.select(["placo", "hqp-daqp"], None, "tick")
    assert [e.name for e in entries] == ["hqp-daqp"]
    assert any("placo: not installed" in n for n in notes)


def test_nlp_only_in_converged_mode():
    entries, notes = solvers.select(["nlp-ipopt"], None, "tick")
    assert entries == [] and any("--mode converge" in n for n in notes)
    entries, _ = solvers.select(["nlp-ipopt"], None, "converge")
    assert [e.name for e in entries] == ["nlp-ipopt"]


def test_bad_names_are_rejected(capsys):
    from wbc import WbcError

    with pytest.raises(WbcError, match="unknown solver"):
        solvers.select(["gurobi"], None, "tick")
    with pytest.raises(WbcError, match="unknown families"):
        solvers.select(None, ["magic"], "tick")
    assert main(["bench", "--solvers", "hqp-daqp", "--trajectories", "moonwalk"]) == 2
    assert "unknown trajectory 'moonwalk'" in capsys.readouterr().err
