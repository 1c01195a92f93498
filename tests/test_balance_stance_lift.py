"""The CoM target lifted on servos identified soft at rest (``Gains.lift``, issue 30): no
move unidentified or on servos at or above ``lift_stiff``, a ramp into the lift on softer
ones; through ``closed_loop`` the solved CoM rises on a soft plant only; off, the closed
loop builds main's stabilizer. The walk's end re-timed on the same plants
(``Gains.end_clock``): the clock slowed from the final double support on, soft plants only.
The hip strategy held from each single support's start on the same plants (``Gains.soft_hip``)."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from wbc.balance import stabilizer as stabilizer_module
from wbc.balance.hip_roll import _K_BAND, _K_HIP_JUMP
from wbc.balance.stabilizer import Gains, Stabilizer
from wbc.balance.stance_lift import (
    HIP_OFF_BAND,
    LIFT_RAMP,
    LiftedStabilizer,
    end_rate,
    final_double_start,
    lift_height,
)
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


def test_end_rate_from_the_final_double_support_on_soft_servos_only(robot):
    from wbc.bench import trajectories as traj

    ref = traj.build("walk10_wb", robot)
    start = final_double_start(ref)
    assert start is not None
    assert ref.support[ref.index_at(start)] != ref.support[ref.index_at(start - 0.05)]
    assert 0.5 < ref.t[-1] - start < 1.5
    assert end_rate(0.5, 0.75, 0.5, start + 0.1, start) == 0.5
    assert end_rate(0.5, 0.75, 0.5, start - 0.1, start) == 1.0  # (before it)
    assert end_rate(0.5, 0.75, 0.8, start + 0.1, start) == 1.0  # (not softer)
    assert end_rate(0.5, 0.75, None, start + 0.1, start) == 1.0  # (not identified)
    assert end_rate(1.0, 0.75, 0.5, start + 0.1, start) == 1.0  # (off)
    assert end_rate(0.5, 0.75, 0.5, start + 0.1, None) == 1.0  # (no final double support)
    for bad in (0.0, 1.5, float("nan")):
        with pytest.raises(ConfigurationError):
            Gains(end_clock=bad).check()


@pytest.mark.parametrize("stiffness", [0.55, 1.8])
def test_closed_loop_slows_the_walks_end_on_servos_identified_soft(
    robot, soft_plant_loop, stiffness
):
    """Through :func:`wbc.balance.live.closed_loop` (walk10_wb's first 0.7 s after a 0.5 s
    rest, its final double support's start moved to 0.3 s so that the short run reaches
    it): with ``end_clock`` 0.5 the soft plant's played reference runs at half the walk's
    time from there on, and the loop says so; with ``end_leak`` 5 /s its DCM integral
    shrinks by exp(−5 dt) between ticks from there on (not before); the stiff plant's
    is neither slowed nor leaked."""
    said: list[str] = []
    soft = stiffness < 1.0
    g = Gains(k_d=0.03, joint_lag=1.0, k_dcm_i=0.25, end_clock=0.5, end_leak=5.0)
    loop = soft_plant_loop(stiffness, g, said)
    stab = loop.stabilizer
    assert isinstance(stab, LiftedStabilizer)
    assert stab.end_start == final_double_start(loop.session.ref)
    stab.end_start = t_end = float(loop.session.ref.t[0]) + 0.3
    seen: list[tuple[float, float, np.ndarray, np.ndarray]] = []  # (t, dt, integral in, out)
    shifted = stab._shifted

    def recorded(targets, com_vel_ref, est, e, dt):
        before = stab.dcm_integral.copy()
        out = shifted(targets, com_vel_ref, est, e, dt)
        seen.append((float(targets.t), float(dt), before, stab.dcm_integral.copy()))
        return out

    stab._shifted = recorded  # type: ignore[method-assign]
    loop.deployment.run()
    leak = [(t, dt, a[0] / b[-1][0]) for b, (t, dt, a, _) in pairwise(seen)
            if abs(b[-1][0]) > 1e-9]  # fmt: skip
    assert [k for t, _, k in leak if t < t_end - 1e-9] == pytest.approx(
        [1.0] * sum(t < t_end - 1e-9 for t, _, _ in leak)
    )
    after = [(k, np.exp(-5.0 * dt)) for t, dt, k in leak if t >= t_end]
    assert after
    assert [k for k, _ in after] == pytest.approx([e if soft else 1.0 for _, e in after])
    assert bool(stab.stiffness_scale < 0.75) is soft
    played = loop.source.played()
    assert (played is not None) is soft
    assert any("walk-end clock x0.5" in s for s in said) is soft
    if soft:
        walk, ref_time = played
        rate = np.diff(ref_time) / np.diff(walk)
        early, late = walk[1:] < 0.25, walk[1:] > 0.4
        assert early.any() and late.any()
        assert np.median(rate[early]) == pytest.approx(1.0, abs=0.02)
        assert np.median(rate[late]) == pytest.approx(0.5, abs=0.02)


@pytest.mark.parametrize("stiffness", [0.55, 1.8])
def test_closed_loop_holds_the_hip_strategy_early_in_single_support_on_soft_servos(
    robot, soft_plant_loop, stiffness, monkeypatch
):
    """Through :func:`wbc.balance.live.closed_loop` (walk10_wb's first 1.4 s after a 0.5 s
    rest: its first two single supports): with ``soft_hip`` 0.15 s the soft plant's
    stabilizer's compiled tick runs with the hip strategy's band out of reach during the
    first 0.15 s of each single support and with the given band everywhere else (the double
    supports, the rest of each single support), its gains never swapped, the hip-strategy
    roll never grows there, and the loop says so; the stiff plant's always runs the given band."""
    said: list[str] = []
    soft = stiffness < 1.0
    g = Gains(k_d=0.03, joint_lag=1.0, k_dcm_i=0.25, soft_hip=0.15)
    loop = soft_plant_loop(stiffness, g, said, 1.9)
    stab = loop.stabilizer
    assert isinstance(stab, LiftedStabilizer)
    given = stab.gains
    seen: list[tuple[str, str, float, float, float]] = []  # (phase, sole, dt, band, |h| out)
    ticked: list[float] = []  # the band the compiled tick was given
    adjust, tick = Stabilizer.adjust, stabilizer_module._feedback_tick

    def banded(consts, *args):
        ticked.append(float(consts[_K_BAND]))
        assert consts[_K_HIP_JUMP] == given.hip_jump * consts[_K_BAND]
        return tick(consts, *args)

    def recorded(self, targets, com_vel_ref, q_cmd, dt):
        ticked.clear()
        resting = self.calibrating  # (the rest's last tick ends it: no feedback yet)
        out = adjust(self, targets, com_vel_ref, q_cmd, dt)
        assert self.gains is given
        if not resting:
            h = float(np.hypot(*self.hip))
            (band,) = ticked
            seen.append((targets.phase, targets.support, float(dt), band, h))
        return out

    monkeypatch.setattr(stabilizer_module, "_feedback_tick", banded)
    monkeypatch.setattr(Stabilizer, "adjust", recorded)
    loop.deployment.run()
    monkeypatch.undo()
    assert bool(stab.stiffness_scale < 0.75) is soft
    into, last, early = 0.0, ("", ""), []
    for phase, sole, dt, _, _ in seen:  # the time into each single support
        into = into + dt if (phase, sole) == last and phase == "single" else 0.0
        last = (phase, sole)
        early.append(phase == "single" and into < 0.15 - 1e-9)
    assert any(early) and not all(early)
    bands = [band for _, _, _, band, _ in seen]
    want = [HIP_OFF_BAND if e and soft else g.hip_band for e in early]
    assert bands == want
    held = [(a[4], b[4]) for a, b, e in zip(seen, seen[1:], early[1:], strict=False) if e]
    assert all(b <= a + 1e-12 for a, b in held) or not soft
    assert (
        any("hip strategy held from each single support's start 0.15 s" in s for s in said) is soft
    )
    with pytest.raises(ConfigurationError):
        Gains(soft_hip=-0.1).check()
