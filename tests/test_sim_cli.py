"""``wbc sim``: a recording played on the simulated robot, the physics printed and saved."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("mujoco")

from wbc.cli import main
from wbc.recording import Recording


def test_wbc_sim_plays_a_recording(robot, tmp_path, capsys):
    t = np.arange(0.0, 0.5 + 1e-9, 0.02)
    q = np.tile(robot.configuration("walk_ready"), (t.size, 1))
    path = tmp_path / "stand.npz"
    Recording(t, q, robot.joint_names).save(path)
    out_json, out_rec = tmp_path / "sim.json", tmp_path / "sim.npz"
    rc = main(["sim", str(path), "--settle", "0.3", "--json", str(out_json),
               "--record", str(out_rec)])  # fmt: skip
    out = capsys.readouterr().out
    assert rc == 0
    assert "fell: False" in out and "max base orientation deviation" in out
    record = json.loads(out_json.read_text())
    assert record["fell"] is False and record["deploy_completed"] is True
    sim = Recording.load(out_rec)
    assert sim.meta["simulated"] is True
    assert sim.t[-1] == pytest.approx(0.8, abs=0.05)  # the recording plus the settle time
    np.testing.assert_allclose(sim.q[-1, 7:], q[-1, 7:], atol=np.radians(3))


def test_wbc_sim_push_needs_a_single_support(robot, tmp_path, capsys):
    t = np.arange(0.0, 0.2 + 1e-9, 0.02)
    q = np.tile(robot.configuration("walk_ready"), (t.size, 1))
    path = tmp_path / "stand.npz"
    Recording(t, q, robot.joint_names).save(path)
    assert main(["sim", str(path), "--push", "0", "0.1"]) == 2
    assert "no single-support phase" in capsys.readouterr().err


def test_wbc_sim_refuses_bad_options(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:  # argparse: wbc.cli.number, one line
        main(["sim", "--settle", "-1"])
    assert exit_.value.code == 2
    assert "--settle: must be a finite number in [0, 600]" in capsys.readouterr().err
    assert main(["sim", str(tmp_path / "missing.npz")]) == 2
    assert "recording not found" in capsys.readouterr().err


def test_wbc_sim_runs_the_closed_loop_by_default(capsys):
    """`wbc sim --solver ...`: the controller live, closed loop with the simulated IMU, the
    feed-forward x0.5 and fall detection (step adjustment where the walk allows it)."""
    assert main(["sim", "--solver", "wqp-daqp", "--trajectory", "thesis_step",
                 "--settle", "0"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    said = "closed loop: IMU on, feed-forward x0.5 on servos.toml (nominal), step adjustment off"
    assert said in out and "(closed loop)" in out and "fell: False" in out
    ticks = int(out.split("live solves: 0 of ")[1].split(" walking ticks failed")[0])
    assert ticks > 50 and "held), 0 relaxed" in out  # (the step's 99 ticks, each solved)


def test_wbc_sim_on_hobby_servos_plays_open_loop_unless_closed_loop_is_given(capsys):
    """Kokone's servos report no position: `wbc sim --robot kokone` plays open loop (it
    measured better, benchmarks/kokone_sim.md section 00) and says why; `--closed-loop` runs
    the closed loop through the IMU and the commanded joints, said in one line."""
    args = ["sim", "--robot", "kokone", "--trajectory", "keyposes", "--settle", "0"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "open loop: kokone's hobby servos report no positions" in out
    assert "(open loop)" in out
    main([*args, "--closed-loop"])  # (it falls: its exit status is the run's)
    out = capsys.readouterr().out
    assert out.count("the estimator uses the IMU and the commanded joint positions") == 1
    assert "(closed loop)" in out
    assert main([*args, "--closed-loop", "--open-loop"]) == 2
    assert "--closed-loop and --open-loop: give one" in capsys.readouterr().err
