"""The `wbc` command line: dispatch, the demo, clear messages for missing extras and errors."""

from __future__ import annotations

import wbc.demo
from wbc.cli import main


def test_demo_prints_mass_com_and_soles(capsys):
    assert main(["demo"]) == 0
    out = capsys.readouterr().out
    assert "18 actuated joints, mass 1.9144 kg" in out
    assert "l_sole" in out and "r_sole" in out and "CoM (mm)" in out


def test_missing_optional_package_names_the_extra(monkeypatch, capsys):
    def run(args):
        raise ModuleNotFoundError("No module named 'meshcat'", name="meshcat")

    monkeypatch.setattr(wbc.demo, "run", run)
    assert main(["demo"]) == 2
    assert "pip install 'wbc[viewer]'" in capsys.readouterr().err


def test_errors_are_reported_not_raised(capsys):
    assert main(["demo", "--pose", "handstand"]) == 2
    assert "unknown configuration 'handstand'" in capsys.readouterr().err


def test_no_command_prints_help(capsys):
    assert main([]) == 2
    assert "bench" in capsys.readouterr().out
