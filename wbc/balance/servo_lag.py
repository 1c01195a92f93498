"""The servos' lag behind their goals, measured online from the encoders (issue 30).

A servo that follows its goal ``g(t)`` late — a transport delay, a soft (low-gain) position
loop, or both — reads ``p(t) ≈ g(t − τ)``, so its tracking error ``e = g − p ≈ τ ġ + b``
(``b``: what the load leaves, slow). :func:`servo_lag` fits ``τ`` by least squares over a
sliding window (exponential, :data:`LAG_WINDOW`), pooled over the joints (the ones that move
weigh the most; no joint named): ``τ = Σ_j cov_j(e, ġ) / Σ_j var_j(ġ)``, each joint's means
taken out (its sag, its mean rate). It needs only the goals sent and the positions read —
any robot, any servo law — and costs a few operations per joint and tick.
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: s: the window of :func:`servo_lag`'s running moments (the time constant of their means)
LAG_WINDOW = 0.5
#: s: :func:`servo_lag`'s answer is clipped to [0, LAG_MAX]
LAG_MAX = 0.2
#: 1/s: how fast :func:`clock_rate` moves the walk's clock rate
CLOCK_RAMP = 0.5


def lag_state(n: int) -> np.ndarray:
    """A fresh state for :func:`servo_lag` on ``n`` joints: ``[started, τ]`` then five rows
    of ``n`` (the last goal, the means of e, ġ, e ġ and ġ²)."""
    return np.zeros(2 + 5 * int(n))


@numba.njit(cache=True, error_model="numpy")
def servo_lag(present: np.ndarray, goal: np.ndarray, dt: float, state: np.ndarray) -> float:
    """One tick of the lag estimate (module docstring): ``present`` the positions read (NaN:
    not read, that joint skipped this tick), ``goal`` the goals they follow (rad), ``dt`` the
    tick (s); ``state`` (:func:`lag_state`) updated in place. Returns ``τ`` (s; 0 until the
    goals have moved: ``state[1]`` keeps the last fit while they stand still)."""
    n = goal.shape[0]
    if state[0] < 0.5 or dt <= 0.0:
        for j in range(n):
            state[2 + j] = goal[j]
        state[0] = 1.0
        return state[1]
    a = 1.0 - math.exp(-dt / LAG_WINDOW)
    num = den = 0.0
    for j in range(n):
        rate = (goal[j] - state[2 + j]) / dt
        state[2 + j] = goal[j]
        p = present[j]
        if p == p:  # (NaN: not read)
            err = goal[j] - p
            i = 2 + n + j
            state[i] += a * (err - state[i])
            state[i + n] += a * (rate - state[i + n])
            state[i + 2 * n] += a * (err * rate - state[i + 2 * n])
            state[i + 3 * n] += a * (rate * rate - state[i + 3 * n])
        me, mv = state[2 + n + j], state[2 + 2 * n + j]
        num += state[2 + 3 * n + j] - me * mv
        den += state[2 + 4 * n + j] - mv * mv
    if den > 1e-4:
        state[1] = min(max(num / den, 0.0), LAG_MAX)
    return state[1]


def clock_rate(clock: float, lag: float, lag_clock: float, clock_min: float, dt: float) -> float:
    """The walk's clock rate (reference s per real s) after one tick of ``dt`` s: from
    ``clock`` toward ``clip(lag_clock / lag, clock_min, 1)`` (``lag``: the servos' measured
    lag, s; 1 while unmeasured, 0), by at most :data:`CLOCK_RAMP` · dt. A plant whose servos
    follow late walks the same plan slower (``Gains.lag_clock``: issue 30, i30p's eighth
    round, benchmarks/physics.md)."""
    want = min(max(lag_clock / lag, clock_min), 1.0) if lag > 0.0 else 1.0
    step = CLOCK_RAMP * float(dt)
    return clock + min(max(want - clock, -step), step)


def phase_clock(clock: float, double: bool, single: float) -> float:
    """The clock rate of a tick: ``clock`` (:func:`clock_rate`) in a double support, in a
    single support only the share ``single`` of its slowing (``Gains.clock_single``; 0: a
    soft plant's single support, its knees near their stall torque, not made longer)."""
    return clock if double or single == 1.0 else 1.0 - single * (1.0 - clock)
