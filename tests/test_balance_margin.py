"""The torso feedback's gains sized to the servos' gain margin (wbc.balance.margin; issue 29
item 5: Kokone's closed loop fell on every walk with the Bioloid's gains)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wbc.balance.margin import (
    DESIGN_PLANT,
    TOLERANCE,
    _spread,
    default_sized_gains,
    gain_margin,
    torso_gains,
    torso_plant,
)
from wbc.balance.stabilizer import Gains, default_gains
from wbc.model import load_robot


def test_the_design_plant_is_the_bioloids_and_keeps_its_gains():
    """DESIGN_PLANT is what torso_plant computes on the Bioloid; the Bioloid and the OP3 keep
    the tuned gains at every tick their walks use (10, 20, 30 and 37 ms)."""
    bioloid = load_robot("bioloid")
    plant = torso_plant(bioloid)
    assert plant is not None
    for a, b in zip(
        (plant.inertia, plant.stiffness, plant.damping, plant.delay),
        (DESIGN_PLANT.inertia, DESIGN_PLANT.stiffness, DESIGN_PLANT.damping, DESIGN_PLANT.delay),
        strict=True,
    ):
        assert a == pytest.approx(b, rel=1e-9)
    for name in ("bioloid", "op3"):
        robot = load_robot(name)
        for dt in (0.01, 0.02, 0.0303, 0.037):
            for g in (Gains(), default_gains(0.0)):
                assert torso_gains(g, robot, dt) == (g, 1.0), (name, dt)


def test_kokones_hobby_servos_scale_the_torso_term_to_the_design_margin():
    """Kokone's BMS-380MAX (4x less damped than the AX-12A, a 20 ms analog drive hold): the
    model puts k_p's edge at 0.3-0.4 and k_d's at 0.01-0.03 s (the simulator: 0.3 / 0.005
    stand, 0.5 / 0.01 fall; benchmarks/kokone_sim.md), the default gains' margin below half
    the design's; scaled, the margin is at least the design's on the nominal servo and on the
    spread's least damped corner, only k_p, k_i, k_d and k_hip changed."""
    kokone = load_robot("kokone")
    plant = torso_plant(kokone)
    assert plant is not None and plant.delay == pytest.approx(0.02)
    assert plant.damping_ratio < DESIGN_PLANT.damping_ratio
    for dt in (0.01, 0.02):
        assert 0.3 < gain_margin(Gains(k_i=0.0, k_d=0.0), plant, dt) < 0.4
        assert 0.01 < gain_margin(Gains(k_p=0.0, k_i=0.0, k_d=1.0), plant, dt) < 0.03
        g, scale = torso_gains(Gains(), kokone, dt)
        assert scale < TOLERANCE
        ratios = [
            gain_margin(g, _spread(plant, c), dt)
            / gain_margin(Gains(), _spread(DESIGN_PLANT, c), dt)
            for c in (False, True)
        ]  # at least the design's margin on both, exactly on the worse
        assert min(ratios) == pytest.approx(1.0, rel=1e-6) and max(ratios) > 1.0
        assert (g.k_p, g.k_i, g.k_d) == pytest.approx((scale, scale, 0.05 * scale))
        # the hip strategy closes its loop through the same plant: the same factor
        assert g.k_hip == pytest.approx(Gains().k_hip * scale)
        assert g.max_hip == Gains().max_hip and g.max_tilt == Gains().max_tilt


def test_the_closed_loops_default_is_sized_per_robot():
    """default_sized_gains: the feed-forward's default gains (default_gains) through
    torso_gains, one definition for closed_loop and the push benchmarks: the Bioloid's and the
    OP3's as they are, Kokone's scaled (with or without the feed-forward)."""
    for name in ("bioloid", "op3", "kokone"):
        robot = load_robot(name)
        for comp in (0.0, 0.5, 1.0):
            g, scale = default_sized_gains(robot, comp, 0.01)
            assert (g, scale) == torso_gains(default_gains(comp), robot, 0.01)
            assert (scale == 1.0 and g == default_gains(comp)) is (name != "kokone"), name


def test_a_robot_without_a_servo_model_keeps_the_gains(monkeypatch):
    """No servo model, nothing to size: the gains pass unchanged."""
    from wbc.exceptions import ModelError

    kokone = load_robot("kokone")

    def none(robot):
        raise ModelError("no servo model")

    monkeypatch.setattr("wbc.sim.actuator.nominal_servo", none)
    assert torso_plant(kokone) is None
    assert torso_gains(Gains(), kokone, 0.01) == (Gains(), 1.0)


def _tilt_deg(log) -> float:
    """The torso's largest tilt from the vertical over a simulated run's log, degrees."""
    q = log["q"][:, 3:7]  # (x, y, z, w)
    x, y = q[:, 0], q[:, 1]
    cos = 1.0 - 2.0 * (x * x + y * y)  # the torso's z axis · world z
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max())


def test_kokones_closed_loop_stays_up_with_the_sized_gains():
    """Kokone's key-pose walk, closed through the IMU and the commanded joints (its PWM
    servos report nothing): with the Bioloid's gains the torso loop rings and the robot
    falls within the first two seconds (the fall detector stops it); with the default gains
    sized to its servos it stays up (~2-3 deg)."""
    pytest.importorskip("mujoco")
    from wbc.balance import best_compensate
    from wbc.balance.stepping import SteppingParams
    from wbc.bench.closed_loop import ClosedLoopSpec, play_closed_loop
    from wbc.bench.solvers import registry
    from wbc.bench.trajectories import build

    kokone = load_robot("kokone")
    ref = build("keyposes", kokone)
    make = registry()["hqp-daqp"].make
    tilts = {}
    for name, gains in (("bioloid", Gains()), ("sized", None)):
        spec = ClosedLoopSpec(make, ref, gains, stepping=SteppingParams(), calibrate_s=0.3)
        result, loop = play_closed_loop(spec, kokone, compensate=best_compensate(kokone),
                                        duration=2.3, settle=0.3)  # fmt: skip
        tilts[name] = (_tilt_deg(result.log), result.deploy.completed)
        if gains is None:
            assert loop.stabilizer.gains.k_p < 0.2 and loop.stabilizer.gains.k_d < 0.01
    assert tilts["bioloid"][0] > 20.0 and not tilts["bioloid"][1], tilts
    assert tilts["sized"][0] < 6.0 and tilts["sized"][1], tilts
    assert math.isfinite(tilts["sized"][0])
