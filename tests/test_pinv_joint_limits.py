"""Joint-limit costs, gradient projection (1.44) and Chan–Dubey weights (wbc.limits.joint_costs)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wbc.exceptions import ConfigurationError
from wbc.limits.joint_costs import (
    COSTS,
    ChanDubeyWeights,
    marey_chaumette_gradient,
    zghal_cost,
    zghal_gradient,
)
from wbc.pinv.joint_limits import gradient_projection
from wbc.pinv.pseudoinverse import moore_penrose

seeds = st.integers(0, 2**32 - 1)
fractions = st.floats(0.02, 0.98)


def _limits(seed: int, n: int = 6):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-2.0, 0.0, n)
    hi = lo + rng.uniform(0.5, 3.0, n)
    return rng, lo, hi


@given(seeds, st.sampled_from(sorted(COSTS)))
def test_gradients_match_finite_differences_of_the_costs(seed, name):
    rng, lo, hi = _limits(seed)
    cost, grad = COSTS[name]
    # inside the range (and, for Marey–Chaumette, also beyond it)
    span = (1.3 if name == "marey_chaumette" else 0.9) * (hi - lo)
    theta = 0.5 * (lo + hi) + (rng.random(lo.size) - 0.5) * span
    h = 1e-6
    fd = np.array([(cost(theta + h * ei, lo, hi) - cost(theta - h * ei, lo, hi)) / (2 * h)
                   for ei in np.eye(lo.size)])  # fmt: skip
    np.testing.assert_allclose(grad(theta, lo, hi), fd, rtol=1e-4, atol=1e-6)


@given(seeds)
def test_costs_are_smallest_at_mid_range(seed):
    rng, lo, hi = _limits(seed)
    mid = 0.5 * (lo + hi)
    theta = lo + rng.uniform(0.05, 0.95, lo.size) * (hi - lo)
    for name, (cost, grad) in COSTS.items():
        np.testing.assert_allclose(grad(mid, lo, hi), 0.0, atol=1e-12, err_msg=name)
        assert cost(theta, lo, hi) >= cost(mid, lo, hi) - 1e-12, name
    assert zghal_cost(mid, lo, hi) == pytest.approx(lo.size)  # H = n at mid-range


def test_zghal_is_infinite_at_a_limit_and_marey_chaumette_acts_only_outside():
    lo, hi = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    assert zghal_cost(np.array([1.0, 0.0]), lo, hi) == np.inf
    assert zghal_gradient(np.array([1.0, 0.0]), lo, hi)[0] == np.inf
    assert zghal_gradient(np.array([-1.0, 0.0]), lo, hi)[0] == -np.inf
    g = marey_chaumette_gradient(np.array([0.9, 1.2]), lo, hi, beta=2.0)
    assert g[0] == 0.0 and g[1] > 0.0  # descent (−∇) brings the joint above θM back
    assert marey_chaumette_gradient(np.array([-1.5, 0.0]), lo, hi)[0] < 0.0


@given(seeds, st.integers(1, 4), st.floats(1e-3, 1.0))
def test_gradient_projection_keeps_the_primary_task_and_descends_the_cost(seed, m, gain):
    rng, lo, hi = _limits(seed, 8)
    J = rng.normal(size=(m, 8))
    dx = rng.normal(size=m)
    theta = lo + rng.uniform(0.05, 0.95, 8) * (hi - lo)
    grad = COSTS["zghal"][1](theta, lo, hi)
    dq = gradient_projection(J, dx, grad, gain)
    np.testing.assert_allclose(J @ dq, dx, atol=1e-8)  # primary task untouched
    # the null-space part is a descent direction of the cost
    null_part = dq - moore_penrose(J) @ dx
    assert grad @ null_part <= 1e-12


def test_gradient_projection_checks_the_gradient_size():
    with pytest.raises(ConfigurationError, match="4 entries"):
        gradient_projection(np.ones((1, 4)), np.ones(1), np.ones(3))


@given(seeds, fractions, st.floats(0.005, 0.2), st.integers(2, 6))
def test_chan_dubey_weights_grow_only_while_a_joint_moves_towards_a_limit(seed, f, step, n):
    _, lo, hi = _limits(seed, 1)
    cd = ChanDubeyWeights(lo, hi)
    mid = 0.5 * (lo + hi)
    theta = lo + f * (hi - lo)
    towards = np.sign(theta - mid)  # the nearer limit
    if towards[0] == 0.0:
        towards[:] = 1.0
    cd.update(theta)
    previous = cd.weights.copy()
    d = step * (hi - lo) * (0.5 - abs(f - 0.5)) / n  # steps that stay inside the range
    for _ in range(n):  # moving towards the limit: weights above 1 and increasing
        theta = theta + towards * d
        w = cd.update(theta).copy()
        assert w[0] > 1.0 and w[0] >= previous[0]
        previous = w
    for _ in range(n):  # moving back towards mid-range: weight 1
        theta = theta - towards * d
        assert cd.update(theta)[0] == 1.0


def test_chan_dubey_weights_are_one_at_mid_range_and_infinite_at_a_limit():
    lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    cd = ChanDubeyWeights(lo, hi)
    w = cd.update(np.array([0.0, 0.5, 1.0]))
    assert w[0] == 1.0 and w[1] > 1.0 and w[2] == np.inf
    cd.reset()
    assert np.all(cd.weights == 1.0) and np.all(cd.previous == 0.0)
    with pytest.raises(ConfigurationError, match="shape"):
        cd.update(np.zeros(2))
    with pytest.raises(ConfigurationError, match="lower < upper"):
        ChanDubeyWeights(hi, lo)
