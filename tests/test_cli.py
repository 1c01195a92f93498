"""The `wbc` command line: dispatch, the demo, clear messages for missing extras and errors."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import wbc.cli.demo
from wbc.cli import main
from wbc.paths import robots_dir, stacks_dir

REPO = Path(__file__).resolve().parent.parent


def test_demo_prints_mass_com_and_soles(capsys):
    assert main(["demo"]) == 0
    out = capsys.readouterr().out
    assert "18 actuated joints, mass 1.9144 kg" in out
    assert "l_sole" in out and "r_sole" in out and "CoM (mm)" in out


def test_missing_optional_package_names_the_extra(monkeypatch, capsys):
    def run(args):
        raise ModuleNotFoundError("No module named 'meshcat'", name="meshcat")

    monkeypatch.setattr(wbc.cli.demo, "run", run)
    assert main(["demo"]) == 2
    assert "pip install 'wbc[viewer]'" in capsys.readouterr().err


def test_errors_are_reported_not_raised(capsys):
    assert main(["demo", "--pose", "handstand"]) == 2
    assert "unknown configuration 'handstand'" in capsys.readouterr().err


def test_no_command_prints_help(capsys):
    assert main([]) == 2
    assert "bench" in capsys.readouterr().out


# ---------------------------------------------------------------------------- bad input
def _one_line(text: str) -> str:
    lines = [line for line in text.splitlines() if line.strip()]
    assert len(lines) == 1, text
    return lines[0]


def test_version(capsys):
    import wbc

    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"wbc {wbc.__version__}"


def _assert_usage_error(capsys, argv, argument, allowed):
    """``main(argv)`` exits 2 with one line naming ``argument`` and what is ``allowed``."""
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    line = _one_line(capsys.readouterr().err)
    assert argument in line and allowed in line


@pytest.mark.parametrize(
    "argv, argument, allowed",
    [
        (["bench", "--max-iterations", "-5"], "--max-iterations", "integer >= 1"),
        (["bench", "--tol", "-1"], "--tol", "number > 0"),
        (["bench", "--tol", "nan"], "--tol", "number > 0"),
        (["bench", "--mode", "fast"], "--mode", "choose from"),
    ],
)
def test_bad_arguments_give_one_line_naming_the_argument(capsys, argv, argument, allowed):
    _assert_usage_error(capsys, argv, argument, allowed)


@pytest.mark.parametrize(
    "argv, argument, allowed",
    [
        (["deploy", "x.npz", "--dry-run", "--limit-tol", "nan"], "--limit-tol", "in [0, 0.1]"),
        (["deploy", "x.npz", "--dry-run", "--soft-speed", "100"], "--soft-speed", "in (0, 1]"),
        (["deploy", "x.npz", "--dry-run", "--rate", "inf"], "--rate", "in (0, 100]"),
        (["deploy", "x.npz", "--dry-run", "--attempts", "2.5"], "--attempts", "integer in"),
        (["sim", "--push", "0", "nan"], "--push", "finite number"),
        (["view", "--speed", "0"], "--speed", "in (0, 100]"),
    ],
)
def test_numeric_options_are_checked_for_range_and_finiteness(capsys, argv, argument, allowed):
    _assert_usage_error(capsys, argv, argument, allowed)


def _actions(parser):
    import argparse

    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                for inner, act in _actions(sub):
                    yield f"{name} {inner}", act
        else:
            yield "", action


def test_every_numeric_option_goes_through_the_shared_check(capsys):
    """No option is parsed with a bare float/int (which take nan, inf, any range): each uses
    wbc.cli.number, and refuses nan in one line."""
    from wbc.cli import build_parser

    parser = build_parser()
    numeric = [(where, a) for where, a in _actions(parser) if a.type in (float, int)]
    assert not numeric, [f"{w}{a.option_strings}" for w, a in numeric]
    checked = [a for _, a in _actions(parser) if getattr(a.type, "__qualname__", "").startswith(
        "number.")]  # fmt: skip
    assert len(checked) >= 25
    for action in checked:
        with pytest.raises(Exception, match="must be"):
            action.type("nan")


def test_walking_the_static_com_set_says_it_cannot_be_walked(capsys):
    assert main(["walk", "--trajectory", "static_com"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "not a walking reference" in line
    assert "'static_com'" in line and "walk10" in line
    assert "choose from" not in line


def test_stack_with_a_word_for_a_weight_names_file_and_key(capsys, tmp_path):
    text = (stacks_dir() / "walk.toml").read_text().replace("weight = 1000.0", 'weight = "heavy"')
    path = tmp_path / "heavy.toml"
    path.write_text(text)
    assert main(["walk", "--stack", str(path)]) == 2
    line = _one_line(capsys.readouterr().err)
    assert str(path) in line and "weight = 'heavy'" in line and "number >= 0" in line


def test_unknown_frame_names_the_file_and_lists_only_links(capsys, tmp_path):
    text = (stacks_dir() / "walk.toml").read_text().replace('frame = "torso"', 'frame = "torsoo"')
    path = tmp_path / "frame.toml"
    path.write_text(text)
    assert main(["walk", "--stack", str(path)]) == 2
    line = _one_line(capsys.readouterr().err)
    assert str(path) in line and "unknown frame 'torsoo'" in line
    listed = line.split("links of bioloid: ")[1].split(", ")
    assert "l_sole" in listed and "torso" in listed
    assert not {"universe", "root_joint", "l_knee", "l_sole_fixed"} & set(listed)


def test_a_corrupted_recording_gives_one_line(capsys, tmp_path):
    path = tmp_path / "run.npz"
    path.write_bytes(bytes(range(256)) * 4)
    assert main(["view", str(path), "--no-browser", "--no-wait"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert str(path) in line and "not a .npz" in line and "allow_pickle" not in line


def test_plain_import_exposes_the_submodules_the_readme_uses():
    code = (
        "import wbc\n"
        "robot = wbc.load_robot('bioloid')\n"
        "control = wbc.stacks.load_stack('cj_com', robot)\n"
        "print(control.name, wbc.solvers.HierarchicalQP.__name__, wbc.tasks.ComTask.__name__)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["cj_com", "HierarchicalQP", "ComTask"]


# ---------------------------------------------------------------------------- own robot
def test_demo_on_a_bare_copy_of_the_urdf(capsys, tmp_path):
    urdf = tmp_path / "my.urdf"
    shutil.copyfile(robots_dir() / "bioloid" / "bioloid.urdf", urdf)
    assert main(["demo", "--robot", str(urdf)]) == 0
    out, err = capsys.readouterr()
    assert "18 actuated joints, mass 1.9144 kg" in out
    notes = [line for line in err.splitlines() if line.startswith("wbc demo: note: ")]
    assert len(notes) == 2, err
    assert any("servos.toml missing" in n for n in notes)
    assert any("zero pose" in n for n in notes)


def test_walk_uses_the_robot_folders_own_stack(monkeypatch, capsys, tmp_path):
    import wbc.stacks
    from wbc.exceptions import TaskError

    folder = tmp_path / "mine"
    folder.mkdir()
    for name, target in (("bioloid.urdf", "mine.urdf"), ("servos.toml", "servos.toml")):
        shutil.copyfile(robots_dir() / "bioloid" / name, folder / target)
    (folder / "stack.toml").write_text("")
    seen = []

    def load_stack(name, robot, **kw):
        seen.append(name)
        raise TaskError("stop here")

    monkeypatch.setattr(wbc.stacks, "load_stack", load_stack)
    assert main(["walk", "--robot", str(folder), "--trajectory", "thesis_step"]) == 2
    assert seen == [folder / "stack.toml"]
    assert main(["walk", "--robot", str(folder), "--stack", "cj_com"]) == 2
    assert seen[-1] == "cj_com"


def test_demo_on_a_urdf_without_soles_shows_what_exists(capsys, tmp_path):
    urdf = tmp_path / "nosoles.urdf"
    text = (robots_dir() / "bioloid" / "bioloid.urdf").read_text()
    urdf.write_text(text.replace('"l_sole"', '"l_plate"').replace('"r_sole"', '"r_plate"'))
    assert main(["demo", "--robot", str(urdf)]) == 0
    out, err = capsys.readouterr()
    assert "torso" in out and "l_sole" not in out
    assert "frames ['l_sole', 'r_sole'] not in nosoles.urdf" in err


def test_options_shared_by_deploy_drive_and_sim_are_declared_once():
    """``wbc deploy`` and ``wbc drive`` take the servo bus, the deployment's safety options,
    the torso IMU and the simulated robot from one declaration (wbc.cli.options): the same
    flags, types, choices, defaults and help (only the control rate's default differs: 50 Hz
    for a recording, 100 Hz for the walk); ``wbc sim`` and ``wbc bench`` share --robot,
    --encoders-only and the compliance feed-forward with ``wbc deploy``."""
    from wbc.cli import build_parser

    parser = build_parser()
    commands = {
        name: {a.dest: a for _, a in _actions(p) if a.option_strings}
        for name, p in next(a for a in parser._actions if a.choices).choices.items()
    }

    def allowed(action) -> str | None:  # what a numeric type allows: its refusal of nan
        if action.type is None:
            return None
        try:
            action.type("nan")
        except Exception as exc:
            return str(exc)
        return "accepts nan"

    def same(a, b) -> bool:
        key = (a.option_strings, a.help, a.choices, a.nargs, a.const, allowed(a))
        return key == (b.option_strings, b.help, b.choices, b.nargs, b.const, allowed(b))

    shared = ["servo_map", "backend", "port", "baud", "latency_ms", "torque_limit", "rate",
              "on_fault", "max_speed", "soft_speed", "log", "imu", "imu_baud", "encoders_only",
              "sim", "realtime", "view", "robot"]  # fmt: skip
    deploy, drive = commands["deploy"], commands["drive"]
    for dest in shared:
        assert same(deploy[dest], drive[dest]), dest
        assert dest == "rate" or deploy[dest].default == drive[dest].default, dest
    assert (deploy["rate"].default, drive["rate"].default) == (50.0, 100.0)
    for name in ("sim", "bench"):
        for dest in ("robot", "encoders_only", "compensate", "compensate_encoders"):
            assert same(commands[name][dest], commands["deploy"][dest]) or dest == "compensate"
            assert commands[name][dest].default == commands["deploy"][dest].default, (name, dest)
    for name in ("demo", "bench", "walk", "deploy", "drive", "view", "sim"):
        assert same(commands[name]["robot"], deploy["robot"]), name
