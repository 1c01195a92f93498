"""The servos' lag measured online (wbc.balance.servo_lag)."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.balance.servo_lag import LAG_MAX, lag_state, servo_lag


def _run(present_of, n: int = 3, dt: float = 0.01, seconds: float = 4.0) -> float:
    """servo_lag over goals g_j(t) = a_j sin(2π f_j t) with the reads ``present_of(k, goals)``."""
    state = lag_state(n)
    amp, freq = np.linspace(0.2, 0.5, n), np.linspace(0.8, 1.6, n)
    history, tau = [], 0.0
    for k in range(int(seconds / dt)):
        goal = amp * np.sin(2 * np.pi * freq * k * dt)
        history.append(goal)
        tau = servo_lag(present_of(k, history), goal, dt, state)
    return tau


@pytest.mark.parametrize("delay", [0, 2, 4])
def test_a_pure_delay_is_measured(delay: int) -> None:
    """Reads that are the goals ``delay`` ticks late measure ``delay · dt`` (to 10 %)."""
    tau = _run(lambda k, h: h[max(k - delay, 0)])
    assert tau == pytest.approx(delay * 0.01, abs=0.1 * delay * 0.01 + 1e-6)


def test_a_first_order_lag_and_a_sag_are_told_apart() -> None:
    """A first-order follower (time constant 30 ms) sagging by a constant offset per joint
    measures its time constant: the offset (a load's sag) is taken out with the means."""
    dt, T = 0.01, 0.03
    p = np.zeros(3)

    def follower(k, h):
        p[:] += (1 - np.exp(-dt / T)) * (h[-1] - p)
        return p - np.array([0.1, -0.2, 0.05])

    tau = _run(follower, dt=dt)
    # the exact discrete follower lags by its time constant's discretisation, ≈ T − dt/2 + dt
    assert 0.02 < tau < 0.045
    shifted = _run(lambda k, h: h[max(k - 3, 0)] + 0.3)
    assert shifted == pytest.approx(0.03, abs=0.003)


def test_unread_joints_are_skipped_and_the_answer_is_clipped() -> None:
    """NaN reads (not read this tick) leave that joint's moments alone; the answer stays in
    [0, LAG_MAX] (reads ahead of their goals: 0; far behind: LAG_MAX)."""

    def some_unread(k, h):
        out = h[max(k - 2, 0)].copy()
        out[k % 3] = np.nan
        return out

    assert _run(some_unread) == pytest.approx(0.02, abs=0.002)
    assert _run(lambda k, h: h[min(k + 3, len(h) - 1)] if k + 3 < len(h) else h[-1]) >= 0.0
    # e = 0.5 s × the goals' rate: clipped to LAG_MAX
    assert _run(lambda k, h: h[-1] - 0.5 * (h[-1] - h[max(k - 1, 0)]) / 0.01) == LAG_MAX
    assert _run(lambda k, h: h[0]) >= 0.0  # (frozen reads: error = goal; no crash)
