"""The benchmark CLI: records with the promised keys, recordings, figures, honest errors."""

from __future__ import annotations

import contextlib
import io
import json
import os

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc.bench import metrics, solvers
from wbc.cli import main
from wbc.exceptions import ConfigurationError
from wbc.recording import Recording

REQUIRED = {
    "solver", "family", "trajectory", "mode", "com_err_max_mm", "com_err_mean_mm",
    "foot_err_max_mm", "foot_err_mean_mm", "limit_violations", "limit_violation_max_rad",
    "penetration_max_mm", "com_margin_min_mm", "time_median_us", "time_p99_us", "failures",
}  # fmt: skip


def test_keys_match_the_issue():
    assert set(metrics.KEYS) == REQUIRED


#: the tests of :func:`bench_run` in one worker: it runs once (~20 s), not once per worker
on_bench_run = pytest.mark.xdist_group("bench_run")


@pytest.fixture(scope="module")
def bench_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    # pytest's capture is per test: keep this run's printout for the table tests
    with contextlib.redirect_stdout(io.StringIO()) as printed:
        code = main([
            "bench", "--solvers", "hqp-daqp", "wqp-quadprog", "pinv-vat", "qp-cj_com", "placo",
            "--trajectories", "thesis_step", "--json", str(out / "b.json"),
            "--record", str(out / "runs"), "--plots", str(out / "plots"),
        ])  # fmt: skip
    assert code == 0
    (out / "stdout.txt").write_text(printed.getvalue())
    return out


@on_bench_run
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
        assert r["time_clock"] == "cpu"  # (the default: the thread's CPU time)
    by = {r["solver"]: r for r in records}
    # the kinematic benchmark's hierarchy (walk_strict: CoM and swing above torso and posture)
    # tracks the static step almost exactly, and never leaves the joint limits
    assert by["hqp-daqp"]["stack"] == solvers.BENCH_STACKS["kinematic"] == "walk_strict"
    assert by["hqp-daqp"]["com_err_max_mm"] < 0.1
    assert by["hqp-daqp"]["limit_violations"] == 0


@on_bench_run
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


@on_bench_run
def test_figures_one_per_quantity_png_and_svg(bench_run):
    from wbc.bench.plots import QUANTITIES

    plots = bench_run / "plots"
    for name in [*(f"thesis_step__{q}" for q in QUANTITIES), "time_per_tick"]:
        assert (plots / f"{name}.png").stat().st_size > 10_000, name
        svg = (plots / f"{name}.svg").read_text()
        assert svg.lstrip().startswith("<?xml") and "<svg" in svg
    # every solver is in each figure, and the time axis is in seconds
    svg = (plots / "thesis_step__com.svg").read_text()
    for solver in ("hqp-daqp", "wqp-quadprog", "pinv-vat", "qp-cj_com", "placo"):
        assert solver in svg
    assert "time (s)" in svg


@on_bench_run
def test_reference_and_achieved_share_a_colour(robot, bench_run, tmp_path):
    pytest.importorskip("matplotlib")
    from matplotlib import pyplot as plt

    from wbc.bench import plots

    recs = [Recording.load(bench_run / "runs" / f"{s}__thesis_step.npz") for s in ("hqp-daqp",
            "pinv-vat")]  # fmt: skip
    captured = []
    real_save = plots._save

    def keep(fig, path):
        if path.name.endswith("__com.png"):
            captured.append([(ln.get_color(), ln.get_linestyle()) for ln in fig.axes[0].lines])
        return real_save(fig, path)

    try:
        plots._save = keep
        plots.quantity_figures(recs, tmp_path)
    finally:
        plots._save = real_save
        plt.close("all")
    (lines,) = captured
    solid = [c for c, style in lines if style == "-"]
    dashed = [c for c, style in lines if style == "--"]
    assert len(solid) == len(dashed) == 2
    assert solid == dashed and solid[0] != solid[1]


@on_bench_run
def test_default_table_fits_100_columns_with_units_and_legend(bench_run):
    text = (bench_run / "stdout.txt").read_text()
    lines = text.splitlines()
    assert max(len(line) for line in lines) <= 100
    assert "CoM err mm" in text and "cpu µs/tick" in text and "margin mm" in text
    assert "iter" not in text  # one QP per tick: always 1
    assert "thesis mm" not in text  # the thesis figures: beside converged runs only
    assert "…" not in text  # nothing cut
    words = " ".join(text.split())
    assert "the ZMP on a dynamic one" in words  # the legend explains the margins


def test_wall_clock_on_request_is_named_in_the_header_and_records(capsys, tmp_path):
    path = tmp_path / "b.json"
    args = ["bench", "--solvers", "qp-cj_com", "--trajectories", "thesis_step", "--json"]
    assert main([*args, str(path), "--clock", "wall"]) == 0
    assert "wall µs/tick" in capsys.readouterr().out
    (record,) = json.loads(path.read_text())["records"]
    assert record["time_clock"] == "wall" and record["time_p99_us"] > 0
    with pytest.raises(SystemExit):
        main([*args, str(path), "--clock", "cycles"])


def test_wide_table_has_every_column(capsys):
    assert main(["bench", "--solvers", "qp-cj_com", "--trajectories", "thesis_step", "--wide"]) == 0
    out = capsys.readouterr().out
    header = " ".join(out.split("qp-cj_com")[0].split())
    for column in ("family", "iter", "ZMP", "CoM margin", "thesis", "fail"):
        assert column in header


def test_while_the_ticks_compile_the_baselines_show_their_errors(monkeypatch, tmp_path, capsys):
    """A fresh install: while the ticks compile, the runs without them print their errors;
    then every run of the tables, in display order, after the compilation (the times of the
    baselines' first runs, taken beside the compiler, are not kept)."""
    from wbc.bench import runner
    from wbc.cli import bench as cli

    order = []
    run_entry = runner.run_entry

    def recorded(entry, *args):
        order.append(entry.name)
        return run_entry(entry, *args)

    waited = []
    monkeypatch.setattr(cli, "_compile_in_background", lambda console: True)
    monkeypatch.setattr(cli, "_wait_for_ticks", lambda: waited.append(len(order)))
    monkeypatch.setattr(runner, "run_entry", recorded)
    names = ["qp-cj_com", "pinv-vat", "placo"]
    code = main([
        "bench", "--solvers", *names, "--trajectories", "thesis_step",
        "--json", str(tmp_path / "b.json"),
    ])  # fmt: skip
    assert code == 0
    assert order == ["pinv-vat", "placo", *names] and waited == [2]
    out = capsys.readouterr().out
    records = json.loads((tmp_path / "b.json").read_text())["records"]
    assert [r["solver"] for r in records] == names
    for r in records:
        line = cli._errors_line(r)  # the errors: the same in both runs
        assert (line in out) == (r["solver"] != "qp-cj_com")
        assert f"CoM err {r['com_err_max_mm']:.2g} / {r['com_err_mean_mm']:.2g} mm" in line
    assert out.index("placo on thesis_step") < out.index("thesis_step (tick mode)")


def test_no_background_compilation_for_runs_without_compiled_ticks(monkeypatch):
    from wbc.cli import bench as cli

    def compile_in_background(console):
        raise AssertionError("nothing of this run uses the compiled ticks")

    monkeypatch.setattr(cli, "_compile_in_background", compile_in_background)
    assert main(["bench", "--solvers", "placo", "pinv-vat", "--trajectories", "thesis_step"]) == 0


def test_solver_output_is_silenced_unless_verbose(capfd):
    from wbc.cli.bench import solver_output

    def chatty():
        os.write(1, b"Polishing not needed\n")  # as C code would: straight to fd 1

    with solver_output(verbose=False) as out:
        chatty()
        print("table", file=out)
    captured = capfd.readouterr().out
    assert "table" in captured and "Polishing" not in captured
    with solver_output(verbose=True):
        chatty()
    assert "Polishing" in capfd.readouterr().out


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


def test_each_benchmark_has_its_stack_and_another_is_named():
    """The kinematic benchmark compares the strict hierarchy, the physics one the recommended
    ``walk``; another stack (``--stack``) shows in the entries' names, the former name of
    walk_strict loads it, and a stack that does not exist is refused in one line."""
    kin, _ = solvers.select(["hqp-daqp", "wqp-daqp", "qp-vat"], None, "tick", "kinematic")
    assert [e.stack for e in kin] == ["walk_strict", "walk_strict", "vat"]
    body, _ = solvers.select(["hqp-daqp"], None, "tick")  # the physics benchmark by default
    assert [(e.name, e.stack) for e in body] == [("hqp-daqp", "walk")]
    for stack in ("walk_strict", "walk_lexicographic"):
        strict, _ = solvers.select(["hqp-daqp"], None, "tick", "physics", stack)
        assert [(e.name, e.stack) for e in strict] == [("hqp-daqp@walk_strict", "walk_strict")]
    other, _ = solvers.select(["wqp-daqp"], None, "tick", "kinematic", "walk")
    assert [e.name for e in other] == ["wqp-daqp@walk"]
    with pytest.raises(ConfigurationError, match="--stack 'walk_loose': not a stack in tasks/"):
        solvers.select(None, None, "tick", "kinematic", "walk_loose")
    with pytest.raises(ConfigurationError, match="unknown benchmark 'paper'"):
        solvers.registry("paper")


def test_bad_names_are_rejected(capsys):
    with pytest.raises(ConfigurationError, match="unknown solver"):
        solvers.select(["gurobi"], None, "tick")
    with pytest.raises(ConfigurationError, match="unknown families"):
        solvers.select(None, ["magic"], "tick")
    assert main(["bench", "--solvers", "hqp-daqp", "--trajectories", "moonwalk"]) == 2
    assert "unknown trajectory 'moonwalk'" in capsys.readouterr().err


def test_identical_motions_are_drawn_once_with_all_names():
    from wbc.bench.plots import _identical_runs

    t = np.arange(3) * 0.01
    q = np.zeros((3, 8))
    recs = [
        Recording(t, q + d, ("j",), meta={"solver": name})
        for name, d in (("a", 0.0), ("b", 0.0), ("c", 1e-6), ("d", 1e-12))
    ]
    assert _identical_runs(recs) == {"a": "a (= b, d)", "c": "c"}


@given(st.floats(min_value=-1e6, max_value=1e6, allow_nan=False).filter(lambda x: abs(x) > 1e-12))
def test_short_cells_keep_two_significant_digits(x):
    from wbc.cli.bench import _short

    text = _short(x)
    assert len(text) <= 8
    assert float(text) == pytest.approx(x, rel=0.05 if abs(x) < 100 else 0.006, abs=0.5)


def test_static_com_table_runs(capsys):
    # its rows carry no stack: the table's stack note crashed on them (KeyError: 'stack')
    assert main(["bench", "--trajectories", "static_com", "--solvers", "wqp-daqp"]) == 0
    assert "static_com" in capsys.readouterr().out


@pytest.mark.parametrize("peer", ["placo", "pink"])
def test_peers_use_the_mapped_frame_names(tmp_path, peer):
    """placo and pink get the URDF's names of torso/l_sole/r_sole (robot.toml [frames])."""
    from wbc.bench import trajectories as traj
    from wbc.bench.runner import run_entry
    from wbc.model import load_robot
    from wbc.paths import robots_dir
    from wbc.urdf_writer import transform_urdf

    pytest.importorskip(peer)
    names = {"torso": "body", "l_sole": "sole_left", "r_sole": "sole_right"}
    folder = tmp_path / "mapped"
    folder.mkdir()
    text = (robots_dir() / "bioloid" / "bioloid.urdf").read_text()
    (folder / "mapped.urdf").write_text(transform_urdf(text, 1.0, names))
    (folder / "servos.toml").write_text((robots_dir() / "bioloid" / "servos.toml").read_text())
    (folder / "robot.toml").write_text(
        "[frames]\n" + "".join(f'{k} = "{v}"\n' for k, v in names.items())
    )
    robot = load_robot(folder)
    entries, _ = solvers.select([peer], None, "tick")
    _, rec = run_entry(entries[0], robot, traj.build("thesis_step", robot), "tick")
    m = metrics.compute(rec, robot)
    assert m["failures"] == 0 and m["com_err_max_mm"] < 5.0


def test_peers_take_the_robot_folders_stack_and_say_what_they_leave_out(tmp_path):
    """Issue 29: placo, pink and the weighted NLP read the stack a command runs on the robot
    (its folder's stack.toml, else walk), as the stack loader built it (the weights scaled to
    the robot by its design_leg), and name what they cannot express; a stack without their
    tasks is refused in one line."""
    import importlib.util

    from wbc.bench.peers import peer_stack
    from wbc.exceptions import TaskError
    from wbc.model import load_robot
    from wbc.paths import stacks_dir
    from wbc.stacks import load_stack
    from wbc.tasks import ComTask

    op3 = load_robot("robots/op3")
    tasks = peer_stack(op3)
    assert (tasks.stack, tasks.torso, tasks.posture) == ("op3", 10.0, 0.2)
    assert (tasks.com, tasks.swing_position, tasks.swing_orientation) == (1000.0, 100.0, 100.0)
    assert tasks.cannot == ("self_collision 5 mm", "ground_clearance")
    assert tasks.com_margin is None
    for name in ("placo", "pink"):
        assert solvers.registry("kinematic")[name].make(op3).tasks == tasks
    if importlib.util.find_spec("casadi") is not None:  # the weighted NLP: the same weights
        nlp = solvers.registry("kinematic")["nlp-ipopt"].make(op3)
        assert (nlp.stack, nlp.nlp_options["weights"].torso) == ("op3", 10.0)
    bioloid = load_robot("bioloid")
    walk = peer_stack(bioloid)
    assert (walk.stack, walk.com, walk.swing_position, walk.torso, walk.posture) == (
        "walk", 1000.0, 100.0, 1.0, 0.01,
    )  # fmt: skip
    kokone = load_robot("kokone")  # its stack.toml states the Bioloid's leg: weights scaled
    com = next(t for t in load_stack(kokone.default_stack, kokone).stack.tasks()
               if isinstance(t, ComTask))  # fmt: skip
    assert peer_stack(kokone).com == float(com.weight[0]) > 1000.0
    strict = peer_stack(bioloid, "walk_strict")
    assert "2 soft levels (flattened into one weighted level)" in strict.cannot
    text = (
        (stacks_dir() / "walk.toml")
        .read_text()
        .replace(
            'constraints = [{ type = "ground_clearance"',
            'constraints = [{ type = "com_polygon", margin = 0.012 }, { type = "ground_clearance"',
        )
    )
    (tmp_path / "poly.toml").write_text(text)
    poly = peer_stack(bioloid, tmp_path / "poly.toml")
    assert poly.com_margin == 0.012 and poly.cannot[1].startswith("com_polygon 0.012 m")
    with pytest.raises(TaskError, match=r"the peers cannot run stack cj_foot .* no .*posture"):
        peer_stack(bioloid, "cj_foot")
