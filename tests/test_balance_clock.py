"""The walk's clock slowed by the servos' measured lag (``Gains.lag_clock``): the rate
(wbc.balance.servo_lag.clock_rate), the session walking its reference at that rate
(wbc.walking.loop.Session.at_time) and the physics record comparing a run with the reference
time it played (wbc.bench.sim_record.plan_time)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from wbc.balance.servo_lag import CLOCK_RAMP, clock_rate, phase_clock
from wbc.balance.stabilizer import Gains
from wbc.bench.sim_record import plan_time
from wbc.exceptions import ConfigurationError


def test_the_clock_follows_the_lag_ramped_and_clipped() -> None:
    """The rate moves toward ``clip(lag_clock / τ, clock_min, 1)`` by at most CLOCK_RAMP·dt a
    tick; an unmeasured lag (0) asks for 1; a lag below the threshold asks for 1."""
    g = (0.04, 0.7)  # lag_clock, clock_min
    dt = 0.01
    assert clock_rate(1.0, 0.0, *g, dt) == 1.0
    assert clock_rate(1.0, 0.03, *g, dt) == 1.0  # below the threshold: as planned
    assert clock_rate(1.0, 0.08, *g, dt) == pytest.approx(1.0 - CLOCK_RAMP * dt)  # ramped
    c = 1.0
    for _ in range(1000):  # settles on lag_clock / τ = 0.8
        c = clock_rate(c, 0.05, *g, dt)
    assert c == pytest.approx(0.8)
    for _ in range(1000):  # a lag far beyond: clock_min
        c = clock_rate(c, 0.2, *g, dt)
    assert c == pytest.approx(0.7)
    for _ in range(1000):  # back to 1 when the lag is gone
        c = clock_rate(c, 0.0, *g, dt)
    assert c == 1.0


def test_the_single_supports_take_their_share_of_the_slowing() -> None:
    """Double supports run at the clock; single supports at ``1 − share (1 − clock)``."""
    assert phase_clock(0.8, True, 0.0) == 0.8
    assert phase_clock(0.8, False, 0.0) == 1.0
    assert phase_clock(0.8, False, 1.0) == 0.8
    assert phase_clock(0.8, False, 0.5) == pytest.approx(0.9)


@pytest.mark.parametrize("bad", [0.0, -0.1, 1.5, math.nan])
def test_a_bad_clock_min_is_refused(bad: float) -> None:
    with pytest.raises(ConfigurationError, match="clock_min"):
        Gains(clock_min=bad).check()
    with pytest.raises(ConfigurationError, match="lag_clock"):
        Gains(lag_clock=-0.01).check()
    with pytest.raises(ConfigurationError, match="clock_single"):
        Gains(clock_single=1.5).check()


class _Slow:
    """A stand-in stabilizer: enabled, its DCM the plan's, its clock ``clock``."""

    def __init__(self, clock: float, gains: Gains | None = None) -> None:
        self.enabled, self.clock, self.dcm = True, clock, np.zeros(2)
        self.gains = gains or Gains()
        self.steps: list[float] = []  # the dt of every adjust

    @property
    def last(self):
        return self

    def adjust(self, targets, com_vel_ref, q, dt):
        self.steps.append(dt)
        return targets


@pytest.mark.parametrize("rate", [1.0, 0.5])
def test_a_session_walks_its_reference_at_the_stabilizers_clock(robot, walk10, rate) -> None:
    """At clock 0.5 the reference advances one tick per two ticks of time (the delay grows
    by half the time walked); at 1 it is the reference's own clock."""
    from wbc.stacks import load_stack
    from wbc.walking.loop import Session, StackController

    session = Session(StackController(load_stack("walk", robot)), robot, walk10,
                      stabilizer=_Slow(rate))  # fmt: skip
    dt = walk10.dt
    for k in range(41):
        session.at_time(k * dt)
    # (the first tick has no previous time: the clock counts from the second)
    assert session.index == round(40 * rate)
    assert session.delay == pytest.approx(40 * dt * (1 - rate))


@pytest.mark.parametrize("real", [0.0, 1.0])
def test_the_stabilizer_steps_by_the_real_time_with_real_step(robot, walk10, real) -> None:
    """A clock run at 3× (the step timing's catch_hurry) skips two reference ticks a tick:
    the stabilizer is stepped by the reference's 3 dt without ``real_step``, by the real
    time since the last tick (one dt) with it; at the reference's own pace (1 ms of jitter)
    both are dt."""
    from wbc.stacks import load_stack
    from wbc.walking.loop import Session, StackController

    stab = _Slow(3.0, Gains(real_step=real))
    session = Session(StackController(load_stack("walk", robot)), robot, walk10,
                      stabilizer=stab)  # fmt: skip
    dt = walk10.dt
    for k in range(11):
        session.at_time(k * dt)
    assert session.index == 30  # (the first tick has no previous time: 0, then 3 a tick)
    assert stab.steps[0] == pytest.approx(dt)
    assert stab.steps[1:] == pytest.approx([dt if real else 3 * dt] * 10)
    paced = _Slow(1.0, Gains(real_step=real))
    session = Session(StackController(load_stack("walk", robot)), robot, walk10,
                      stabilizer=paced)  # fmt: skip
    for k in range(5):
        session.at_time(k * dt + (0.001 if k % 2 else 0.0))  # (a paced loop's jitter)
    assert paced.steps == [dt] * 5  # (the reference's own number, bit for bit)


def test_the_physics_record_compares_a_run_with_the_reference_time_it_played() -> None:
    """Without ``played`` the plan's time is the log's; with it, the reference time the walk
    played, interpolated, and past the walk's last tick shifted by its last delay."""
    t = np.array([0.0, 0.5, 1.0, 1.5, 2.5])
    result = SimpleNamespace(log={"t": t + 3.0}, playback_start=3.0, played=None)
    assert np.array_equal(plan_time(result), t)
    result.played = np.array([[0.0, 1.0, 2.0], [0.0, 0.8, 1.5]])
    assert plan_time(result) == pytest.approx([0.0, 0.4, 0.8, 1.15, 2.0])


def test_the_lag_is_measured_only_when_read(robot) -> None:
    """The tick gets servo_lag's state (measured) with ``lag_yaw`` or ``lag_clock`` > 0 or
    ``measure_lag`` (a diagnostic), else an empty one (not measured: 0 cost)."""
    from wbc.balance.stabilizer import Stabilizer

    def measured(gains: Gains, diagnostic: bool = False) -> bool:
        stab = Stabilizer(robot, 0.2, lambda: None, None, gains)
        stab.measure_lag = diagnostic
        stab._consts()
        return stab._packed[4].size > 0

    assert not measured(Gains())
    assert measured(Gains(lag_clock=0.05))
    assert measured(Gains(lag_yaw=0.04))
    assert measured(Gains(), diagnostic=True)
