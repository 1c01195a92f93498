"""The angular-momentum (hip strategy) capture bound: the flywheel law and the robot's parts."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wbc.balance.angular import (
    GRAVITY,
    flywheel_shift,
    hip_strategy_bound,
    point_push_bound,
    push_point,
)
from wbc.exceptions import ConfigurationError
from wbc.model import load_robot

B = 1.5 / 6.18  # AX-12A back-EMF damping (N·m·s/rad)


def test_unlimited_range_gives_the_closed_form():
    """With range to spare: Δξ = (I/(m h)) v∞ (1/ω₀ − 1/(ω₀ + 1/T)), v∞ = τ/b, T = I_eff/b."""
    inertia, mass, h, tau, arm = 0.02, 1.9, 0.17, 0.75, 0.005
    omega = math.sqrt(GRAVITY / h)
    T = (inertia + arm) / B
    expected = inertia / (mass * h) * (tau / B) * (1 / omega - 1 / (omega + 1 / T))
    got = flywheel_shift(inertia, mass, h, tau, B, 100.0, arm)
    assert got == pytest.approx(expected, rel=1e-3)


@settings(max_examples=30, deadline=None)
@given(
    st.floats(0.001, 0.05),
    st.floats(0.1, 1.5),
    st.floats(0.05, 1.5),
    st.floats(0.0, 0.1),
)
def test_more_torque_range_or_inertia_buy_more_and_a_delay_costs_its_decay(
    inertia, tau, rng, delay
):
    """Δξ grows with the torque, the joint range and the inertia; starting ``delay`` later
    multiplies it by e^{−ω₀ delay}; and it never exceeds the unlimited-range closed form."""
    m, h = 1.9, 0.17
    base = flywheel_shift(inertia, m, h, tau, B, rng)
    assert base > 0
    assert flywheel_shift(inertia, m, h, 1.2 * tau, B, rng) > base
    assert flywheel_shift(inertia, m, h, tau, B, 1.2 * rng) >= base
    assert flywheel_shift(1.2 * inertia, m, h, tau, B, rng) > base
    omega = math.sqrt(GRAVITY / h)
    assert flywheel_shift(inertia, m, h, tau, B, rng, delay=delay) == pytest.approx(
        base * math.exp(-omega * delay), rel=1e-12
    )
    assert base <= flywheel_shift(inertia, m, h, tau, B, 1e3) * (1 + 1e-9)


def test_no_torque_or_no_range_buys_nothing_and_bad_input_is_refused():
    assert flywheel_shift(0.02, 1.9, 0.17, 0.0, B, 0.5) == 0.0
    assert flywheel_shift(0.02, 1.9, 0.17, 0.5, B, 0.0) == 0.0
    with pytest.raises(ConfigurationError, match="inertia"):
        flywheel_shift(-0.02, 1.9, 0.17, 0.5, B, 0.5)
    robot = load_robot()
    with pytest.raises(ConfigurationError, match="stance"):
        hip_strategy_bound(robot, robot.neutral(), "up", np.array([0, 1.0]), 0.17)


def test_the_stance_hip_throws_the_upper_body_over_its_abduction_range():
    """Standing on the left sole pushed +y: the left hip roll turns everything above the left
    leg (the heaviest part: 1.49 kg of 1.91) toward +y, over the left hip's range up to its
    upper (abduction) limit; the parts add up and buy a positive impulse."""
    robot = load_robot()
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    out = hip_strategy_bound(robot, q, "left", np.array([0.0, 1.0]), 0.17)
    hip = out["parts"][0]
    assert hip["joint"] == "l_hip_roll"
    k = robot.joint_names.index("l_hip_roll")
    assert hip["range_deg"] == pytest.approx(math.degrees(robot.q_max[k] - q[7 + k]))
    assert hip["inertia_kgm2"] > max(p["inertia_kgm2"] for p in out["parts"][1:])
    assert out["ns"] > out["stance_hip_ns"] > 0
    assert out["shift_mm"] == pytest.approx(sum(p["shift_mm"] for p in out["parts"]))
    # the mirror push on the right sole: the right hip's range to its lower limit
    out_r = hip_strategy_bound(robot, q, "right", np.array([0.0, -1.0]), 0.17)
    k = robot.joint_names.index("r_hip_roll")
    assert out_r["parts"][0]["range_deg"] == pytest.approx(math.degrees(q[7 + k] - robot.q_min[k]))


def test_a_spin_the_push_gave_is_counted_then_driven_on_within_the_same_range():
    """``speed0``: θ̇ = v∞ + (s₀ − v∞) e^{−t/T}, so with range to spare Δξ = (I/(m h))
    (v∞/ω₀ + (s₀ − v∞)/(ω₀ + 1/T)); coasting alone (no torque) (I/(m h)) s₀/(ω₀ + 1/T);
    more initial spin buys more, never more than the range itself, (I/(m h)) × range."""
    inertia, mass, h, tau, arm = 0.02, 1.9, 0.17, 0.75, 0.005
    omega = math.sqrt(GRAVITY / h)
    k = omega + B / (inertia + arm)
    scale = inertia / (mass * h)
    v = tau / B
    for s0 in (0.0, 1.0, 5.0):
        got = flywheel_shift(inertia, mass, h, tau, B, 100.0, arm, speed0=s0)
        assert got == pytest.approx(scale * (v / omega + (s0 - v) / k), rel=1e-6)
    assert flywheel_shift(inertia, mass, h, 0.0, B, 100.0, arm, speed0=2.0) == pytest.approx(
        scale * 2.0 / k, rel=1e-6
    )
    rng = 0.3
    last = 0.0
    for s0 in (0.0, 1.0, 3.0, 10.0, 100.0):
        for delay in (0.0, 0.03):
            got = flywheel_shift(inertia, mass, h, tau, B, rng, arm, delay, s0)
            assert 0 < got <= scale * rng
        got = flywheel_shift(inertia, mass, h, tau, B, rng, arm, 0.0, s0)
        assert got > last
        last = got
    # a delay with a spin: the spin coasts first (worth more than starting from rest late)
    assert flywheel_shift(inertia, mass, h, tau, B, rng, arm, 0.03, 3.0) > flywheel_shift(
        inertia, mass, h, tau, B, rng, arm, 0.03, 0.0
    )
    with pytest.raises(ConfigurationError, match="speed0"):
        flywheel_shift(inertia, mass, h, tau, B, rng, arm, 0.0, -1.0)


def test_a_push_above_the_com_moves_the_dcm_with_its_spin_by_its_height_over_h():
    """The simulator pushes the root body's CoM: above the robot's CoM, so per N·s the DCM
    with the angular momentum returned moves ``z_p / h`` times a push at the CoM; the bound
    with the push's spin given back is the push-at-the-CoM bound × ``h / z_p``, and with the
    spin kept by the upper body it lies between the two."""
    robot = load_robot()
    q = robot.place_on_ground(robot.configuration("stand"), "l_sole")
    u, h = np.array([0.0, 1.0]), 0.17
    cop = 0.05  # m of DCM margin the CoP alone catches
    p = push_point(robot, q)
    c = robot.com(q)
    assert p[2] > c[2] + 0.05  # the torso's CoM well above the robot's
    out = point_push_bound(robot, q, "left", u, h, cop)
    assert out["push_height_mm"] == pytest.approx(1e3 * p[2])
    assert out["above_com_mm"] == pytest.approx(1e3 * (p[2] - c[2]))
    assert out["eta_per_ns_mm"] == pytest.approx(out["lipm_per_ns_mm"] * p[2] / h)
    parts = hip_strategy_bound(robot, q, "left", u, h)
    at_com = (1e3 * cop + parts["shift_mm"]) / out["lipm_per_ns_mm"]  # N·s
    assert out["returned_ns"] == pytest.approx(at_com * h / p[2])
    assert out["returned_ns"] < out["kept_ns"] < at_com
    late = point_push_bound(robot, q, "left", u, h, cop, delay=0.03)
    assert late["returned_ns"] < out["returned_ns"] and late["kept_ns"] < out["kept_ns"]
