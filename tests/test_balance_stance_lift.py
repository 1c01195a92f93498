"""The CoM target lifted on servos identified soft at rest (``Gains.lift``, issue 30): no
move unidentified or on servos at or above ``lift_stiff``, a ramp into the lift on softer
ones; through ``closed_loop`` the solved CoM rises on a soft plant only; off, the closed
loop builds main's stabilizer."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.balance.stabilizer import Gains, Stabilizer
from wbc.balance.stance_lift import LIFT_RAMP, LiftedStabilizer, lift_height
from wbc.exceptions import ConfigurationError
from wbc.model import load_robot


@pytest.fixture(scope="module")
def robot():
    return load_robot()


def test_lift_height_only_on_servos_identified_softer_and_ramped():
    assert lift_height(0.008, 0.75, None, 5.0) == 0.0  # (not identified)
    assert lift_height(0.008, 0.75, 0.75, 5.0) == 0.0  # (not softer)
    assert lift_height(0.0, 0.75, 0.5, 5.0) == 0.0  # (off)
    assert lift_height(0.008, 0.75, 0.5, 0.0) == 0.0
    assert lift_height(0.008, 0.75, 0.5, 0.5 * LIFT_RAMP) == pytest.approx(0.004)
    assert lift_height(-0.008, 0.75, 0.5, 5.0) == pytest.approx(-0.008)
    with pytest.raises(ConfigurationError):
        Gains(lift=float("nan")).check()


@pytest.mark.parametrize("stiffness", [0.55, 1.8])
def test_closed_loop_lifts_the_com_on_servos_identified_soft(robot, soft_plant_loop, stiffness):
    """Through :func:`wbc.balance.live.closed_loop` on the simulated robot (walk10_wb's
    first 1.2 s after a 0.5 s rest): with ``lift`` −8 mm the soft plant's solved CoM stands
    ~8 mm below the reference once ramped in and the loop says so; the stiff plant's
    stays on it (no lift said); without ``lift`` the stabilizer is main's class."""
    said: list[str] = []
    g = Gains(k_d=0.03, joint_lag=1.0, k_dcm_i=0.25, lift=-0.008)
    loop = soft_plant_loop(stiffness, g, said)
    ref = loop.session.ref
    assert isinstance(loop.stabilizer, LiftedStabilizer)
    rise: list[float] = []
    session = loop.session
    tick = session.tick

    def solved(i: int) -> np.ndarray:  # the solved CoM's height against the reference's
        q = tick(i)
        if ref.t[i] - ref.t[0] > LIFT_RAMP + 0.1:
            rise.append(float(robot.com(q)[2] - ref.com[i, 2]))
        return q

    session.tick = solved  # type: ignore[method-assign]
    loop.deployment.run()
    soft = stiffness < 1.0
    assert bool(loop.stabilizer.stiffness_scale < 0.75) is soft
    assert rise, "the walk ran past the ramp"
    assert bool(np.median(rise) < -0.006) is soft
    assert bool(abs(np.median(rise)) < 0.002) is not soft
    assert any("CoM target lift -8.0 mm" in s for s in said) is soft
    plain = soft_plant_loop(stiffness, Gains(k_d=0.03, joint_lag=1.0, k_dcm_i=0.25), said, 0.1)
    assert type(plain.stabilizer) is Stabilizer
