"""Bus budget per tick, health schedule and proposed rates (``wbc deploy --plan``)."""

from __future__ import annotations

import pytest

from wbc.servos.config import DeployConfig
from wbc.servos.dynamixel import DynamixelBus
from wbc.servos.plan import LOAD_LIMIT, load, overload_warning, plan_lines, proposed_rate


@pytest.fixture(scope="module")
def bus(robot):
    return DynamixelBus("unused", robot.servo_map)  # never opened


@pytest.mark.parametrize(
    ("rate", "read", "expected"),
    [
        (50.0, True, 35.0),  # 18 READs at 1 ms each: at most 35 Hz
        (50.0, False, 50.0),  # fits: 66 %
        # below 40 Hz every servo is checked every tick (the 100 ms bound): 35 Hz write-only
        # overloads (82 %); the nearest lower rate that fits is proposed
        (35.0, False, 34.0),
    ],
)
def test_proposed_rate_is_the_nearest_that_fits(bus, rate, read, expected):
    cfg = DeployConfig(rate=rate, read=read)
    r = proposed_rate(bus, cfg, read, 1e-3)
    assert r == expected
    assert load(bus, cfg, read, r, 1e-3) <= LOAD_LIMIT
    if r < rate:  # one more Hz would not fit
        assert load(bus, cfg, read, r + 1, 1e-3) > LOAD_LIMIT
    warning = overload_warning(bus, cfg, 1e-3)
    assert (warning is None) == (r == rate)
    if warning:
        assert f"use --rate {r:g} or lower" in warning


def test_plan_states_the_bound_and_its_limits(bus):
    lines = "\n".join(plan_lines(bus, DeployConfig(rate=100.0), 1e-3))
    assert "4 health READs per tick" in lines and "every 7 ticks" in lines
    assert "within 90 ms" in lines  # (7 + 3 - 1) ticks of 10 ms
    slow = "\n".join(plan_lines(bus, DeployConfig(rate=30.0), 1e-3))
    assert "leaves no tick for lateness" in slow and "use at least 40 Hz" in slow
