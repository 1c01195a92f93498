"""benchmarks/plant_sweep.py: its settings side by side (``--gains`` × ``--stepping``)."""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import pytest


@pytest.fixture(scope="module")
def sweep():
    path = Path(__file__).resolve().parents[1] / "benchmarks" / "plant_sweep.py"
    spec = importlib.util.spec_from_file_location("wbc_plant_sweep_benchmark", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_settings_pairs_every_gains_with_every_stepping(sweep):
    g = [{}, {"k_p": 2.0}]
    s = [{}, {"landing": 1.0}, {"band_y": 0.03}]
    pairs = sweep.settings(g, s)
    assert pairs == [(a, b) for a in g for b in s]
    assert (
        len(pairs) == 6 and pairs[0] == ({}, {}) and pairs[-1] == ({"k_p": 2.0}, {"band_y": 0.03})
    )


def test_several_stepping_settings_parse_like_gains(sweep):
    from wbc.balance.stabilizer import Gains
    from wbc.balance.stepping import SteppingParams

    p = argparse.ArgumentParser()
    p.add_argument("--gains", nargs="+", type=sweep.json_setting(Gains), default=[{}])
    p.add_argument("--stepping", nargs="+", type=sweep.json_setting(SteppingParams), default=[{}])
    a = p.parse_args(["--stepping", "{}", '{"landing": 1, "landing_tau": 0.3}'])
    assert a.gains == [{}] and a.stepping == [{}, {"landing": 1, "landing_tau": 0.3}]
    for bad, what in (("{", "not JSON"), ("[1]", "JSON object"), ('{"bandx": 1}', "no bandx")):
        with pytest.raises(argparse.ArgumentTypeError, match=what):
            sweep.json_setting(SteppingParams)(bad)


def test_the_lift_off_hold_is_set_per_run(sweep):
    """``--hold``: the HoldParams keywords reach the closed loop's spec (the default hold
    without them); an unknown keyword is refused, named."""
    from types import SimpleNamespace

    from wbc.balance.retime import HoldParams

    entry = SimpleNamespace(make=None)
    variant = sweep.VARIANTS["closed + step"]
    _, spec = sweep.spec_of(variant, entry, None, hold={"contact": True})
    assert spec.hold == HoldParams(contact=True)
    assert sweep.spec_of(variant, entry, None)[1].hold == HoldParams()
    with pytest.raises(argparse.ArgumentTypeError, match="no holdd"):
        sweep.json_setting(HoldParams)('{"holdd": 1}')
