"""benchmarks/plant_sweep.py: its settings side by side (``--gains`` × ``--stepping``)."""

from __future__ import annotations

import argparse

import pytest


@pytest.fixture(scope="module")
def sweep(benchmark_script):
    return benchmark_script("plant_sweep")


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


def test_the_deviation_is_split_into_tilt_and_heading(sweep):
    """``--margins``' split of the fall criterion's angle: a pure heading change is no tilt,
    a pure pitch no heading; both together give each its own."""
    import numpy as np
    import pinocchio as pin

    R = pin.exp3(np.array([0.0, 0.0, 0.4]))  # a planned heading
    yaw, pitch = pin.exp3(np.array([0.0, 0.0, 0.3])), pin.exp3(np.array([0.0, 0.2, 0.0]))
    assert sweep.tilt_and_heading(R, yaw @ R) == pytest.approx((0.0, np.degrees(0.3)), abs=1e-6)
    assert sweep.tilt_and_heading(R, R @ pitch) == pytest.approx((np.degrees(0.2), 0.0), abs=1e-6)
    tilt, heading = sweep.tilt_and_heading(R, yaw @ R @ pitch)
    assert tilt == pytest.approx(np.degrees(0.2), abs=1e-6)
    assert heading == pytest.approx(np.degrees(0.3), abs=0.5)  # (a pitch moves x a little)


def test_the_margins_line_ranks_the_plants_nearest_a_fall(sweep):
    """The ``--margins`` line: the survivors' median and worst-five deviation and true tilt,
    then the plants by deviation, the fallen marked, each with its split and probe; then the
    servos' measured lag per plant."""
    plants = [(k, None) for k in range(6)]
    worst = [10.0, 44.0, 20.0, 5.0, 30.0, 12.0]
    probes = {k: ((w / 2, w), (0.1 * k, 11.5, 30.0 + k)) for k, w in enumerate(worst)}
    line = sweep.margins(plants, worst, [1], probes)
    assert "median 12.0°, worst five 15.4°" in line  # survivors 5, 10, 12, 20, 30
    assert "true tilt median 6.0°, worst five 7.7°" in line
    order = line.split("nearest a fall: ")[1]
    assert order.startswith("1: 44.0° fell (tilt 22.0°, heading 44.0°; tilt cmd at clip 10%")
    assert order.index("4: 30.0°") < order.index("2: 20.0°") < order.index("3: 5.0°")
    assert "heading cmd 11.5°, lag 31 ms)" in order  # the servos' measured lag (plant 1)
    assert line.endswith("per plant: 0: 30, 1: 31, 2: 32, 3: 33, 4: 34, 5: 35")
