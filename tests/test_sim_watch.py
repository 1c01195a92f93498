"""What ``wbc deploy --sim`` says the physics did: :class:`wbc.sim.watch.UprightWatch`."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mujoco")

from wbc.model import load_robot
from wbc.sim.simulator import Simulation
from wbc.sim.watch import UprightWatch


@pytest.fixture(scope="module")
def kokone():
    return load_robot("kokone")


def test_upright_watch_reports_a_fall_and_when(kokone):
    for impulse, fell in ((0.0, False), (1.0, True)):
        sim = Simulation(kokone)
        sim.write_goals(np.rint(sim.servos.pulses(sim.q()[7:])))
        watch = UprightWatch(sim)
        sim.push([0.0, impulse / 0.01, 0.0], 0.01, start=0.2)
        for _ in range(75):  # 1.5 s of 20 ms ticks
            sim.advance(0.02)
            watch()
        assert (watch.fell_at is not None) == fell
        if fell:
            assert 0.2 < watch.fell_at < 1.5 and watch.line().startswith("sim: FELL at ")
        else:
            assert watch.tilt_max < 10.0 and watch.line().startswith("sim: stayed up")
