"""The torso command's twist scaled on servos identified stiff at rest (``Gains.stiff_twist``,
issue 30): the factor only on an identified plant at or above ``lift_stiff``; through
``closed_loop`` the stiff plant's packed ``k_twist`` is scaled on every walking tick and the
soft plant's is not, and the loop says which; off, the closed loop builds main's class."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.balance import stabilizer as stabilizer_module
from wbc.balance.stabilizer import _K_TWIST, Gains, Stabilizer
from wbc.balance.stance_lift import LiftedStabilizer
from wbc.balance.stiff_twist import StiffStabilizer, stiff_class, twist_factor
from wbc.exceptions import ConfigurationError


def test_twist_factor_only_on_servos_identified_at_least_lift_stiff():
    assert twist_factor(0.0, 0.75, None) == 1.0  # (not identified)
    assert twist_factor(0.0, 0.75, 0.74) == 1.0  # (soft)
    assert twist_factor(0.0, 0.75, 0.75) == 0.0
    assert twist_factor(0.4, 0.75, 1.7) == 0.4
    with pytest.raises(ConfigurationError):
        Gains(stiff_twist=-0.1).check()


def test_stiff_class_runs_its_scaling_after_the_base_and_before_the_stabilizer():
    assert stiff_class(Stabilizer) is StiffStabilizer
    cls = stiff_class(LiftedStabilizer)
    assert cls is stiff_class(LiftedStabilizer)  # (one per base)
    assert cls.__mro__[1:4] == (LiftedStabilizer, StiffStabilizer, Stabilizer)


@pytest.mark.parametrize("stiffness", [0.55, 1.8])
def test_closed_loop_scales_the_twist_on_servos_identified_stiff(
    soft_plant_loop, stiffness, monkeypatch
):
    """Through :func:`wbc.balance.live.closed_loop` on the simulated robot (walk10_wb's first
    1.2 s after a 0.5 s rest): with ``stiff_twist`` 0.25 the stiff plant's feedback runs with
    ``k_twist`` × 0.25 packed on every walking tick, the soft plant's with ``k_twist``; the
    loop says which; without it the stabilizer is main's class (the lift's, by default)."""
    said: list[str] = []
    stiff = stiffness > 1.0
    g = Gains(k_d=0.03, joint_lag=1.0, k_dcm_i=0.25, lift=-0.008, stiff_twist=0.25)
    loop = soft_plant_loop(stiffness, g, said)
    stab = loop.stabilizer
    assert isinstance(stab, StiffStabilizer) and isinstance(stab, LiftedStabilizer)
    packed: list[float] = []  # the k_twist each walking tick's compiled feedback was given
    given = stab.gains
    adjust, tick = Stabilizer.adjust, stabilizer_module._feedback_tick
    ticked: list[float] = []

    def twisted(consts, *args):
        ticked.append(float(consts[_K_TWIST]))
        return tick(consts, *args)

    def recorded(self, targets, com_vel_ref, q_cmd, dt):
        ticked.clear()
        resting = self.calibrating  # (the rest's last tick ends it: no feedback yet)
        out = adjust(self, targets, com_vel_ref, q_cmd, dt)
        assert self.gains is given  # (never swapped)
        if not resting:
            packed.extend(ticked)
        return out

    monkeypatch.setattr(stabilizer_module, "_feedback_tick", twisted)
    monkeypatch.setattr(Stabilizer, "adjust", recorded)
    loop.deployment.run()
    monkeypatch.undo()
    assert stab.stiffness_scale is not None, said
    assert bool(stab.stiffness_scale >= 0.75) is stiff
    assert len(packed) > 20
    assert np.allclose(packed, 0.25 if stiff else 1.0)
    assert any("torso command's twist x0.25 (stiff_twist" in s for s in said) is stiff
    assert any("torso command's twist none (stiff_twist" in s for s in said) is not stiff
    off = soft_plant_loop(stiffness, Gains(k_d=0.03, lift=-0.008), [])
    assert type(off.stabilizer) is LiftedStabilizer
