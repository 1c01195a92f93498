"""The start-up goal probe (``Gains.probe_step``, issue 30): the fit recovers a dead time and
a response time from quantised encoder samples; the probe steps only its joints, only in its
window; through ``closed_loop`` on the simulated robot a plant whose goals arrive 15 ms late
reads 15 ms more latency (within a tick) than the same plant without (nothing of the plant
read)."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.balance.goal_probe import GoalProbe, fit_response, probe_joints
from wbc.balance.stabilizer import Gains
from wbc.exceptions import ConfigurationError


@pytest.mark.parametrize(("L", "T"), [(0.004, 0.026), (0.017, 0.012), (0.031, 0.06)])
def test_fit_recovers_the_dead_time_and_response(L, T):
    """10 ms samples of g (1 − exp(−(t − L) / T)), quantised to the AX-12A's 0.29° on a
    0.05 rad step: L within 2 ms, T within 25 %."""
    t = np.arange(0.0, 0.25, 0.01) + 0.003
    y = 0.9 * np.where(t > L, 1 - np.exp(-np.maximum(t - L, 0) / T), 0.0)
    q = np.radians(0.293) / 0.05
    fit = fit_response(t, np.round(y / q) * q, 0.0)
    assert fit[0] == pytest.approx(L, abs=0.002)
    assert fit[1] == pytest.approx(T, rel=0.25)
    assert fit[2] == pytest.approx(0.9, abs=0.05)


def test_probe_steps_its_window_and_fits_what_it_read():
    probe = GoalProbe([3, 5], step=0.05, start=0.095, hold=0.2, pre=0.05)  # (off the ticks)
    seen = []
    for k in range(60):  # 10 ms ticks from t = 2 s; the servo follows 8 ms late, T 20 ms
        t = 2.0 + 0.01 * k
        off = probe.offset(t)
        seen.append(None if off is None else off[0])
        prev = t - 0.01
        s = (prev - 2.1 - 0.008) if prev >= 2.1 else -1.0
        x = np.zeros(8)
        x[[3, 5]] = 0.05 * (1 + (1 - np.exp(-s / 0.02) if s > 0 else 0.0))
        probe.sample(t, x if k else None)
    want = [0.1 if 10 <= k < 30 else 0.05 if 5 <= k < 10 else None for k in range(60)]
    assert seen == want
    fit = probe.result()
    assert fit.latency == pytest.approx(0.008, abs=0.002)
    assert fit.response == pytest.approx(0.02, rel=0.2)
    with pytest.raises(ConfigurationError, match="goal probe: step"):
        GoalProbe([1], step=0.0)
    with pytest.raises(ConfigurationError, match="probe_step"):
        Gains(probe_step=-0.01).check()


def test_probe_joints_are_the_elbows(robot):
    names = [robot.joint_names[i] for i in probe_joints(robot)]
    assert sorted(names) == sorted(a["elbow"] for a in robot.roles.arms.values())


def test_closed_loop_probe_reads_a_late_plant(soft_plant_loop):
    """The same plant with its goals 15 ms late reads 15 ms more goal latency within one
    control tick (10 ms: the encoders are sampled at the ticks and the response's shape is
    not the fit's first order; measured +20.5 ms, benchmarks/physics.md: the probe's
    accuracy, not better than that); the loop says it."""
    fits = []
    for delay in (0.0, 0.015):
        said: list[str] = []
        g = Gains(k_d=0.03, joint_lag=1.0, k_dcm_i=0.25, lift=-0.008, probe_step=0.05)
        loop = soft_plant_loop(1.0, g, said, duration=0.6)  # (the 0.5 s rest, 0.1 s walk)
        loop.deployment.bus.sim.goal_delay = delay
        loop.deployment.run()
        assert loop.goal_probe is not None, said
        assert any("goal probe at rest: goal latency" in s for s in said)
        fits.append(loop.goal_probe)
    assert fits[1].latency - fits[0].latency == pytest.approx(0.015, abs=0.010)
    assert fits[0].gain > 0.5
