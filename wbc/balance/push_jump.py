"""The push test both push triggers share: a jump in one tick, against the jitter before it.

A push shows as a DCM offset that jumps in one tick. Two triggers read it: the step
adjustment's (:class:`wbc.balance.swing_catch.PushTrigger`, ``trigger_jump``: the DCM error
along the walk, either way) and the hip strategy's (:func:`wbc.balance.hip_roll._hip_roll`,
``hip_jump``: the offset outward of the stance sole, one-sided). Both ask the same of the
per-tick change ``d``: beyond the threshold *and* beyond ``sigma`` × the running RMS of the
changes before it (a jittery plant is no push), the mean square then updated with ``d``
(time constant ``tau``). :func:`jumped` is that test, one compiled function for both.
"""

from __future__ import annotations

import math

import numba

#: the jitter guard's default: the jump must beat this × the running RMS of the per-tick
#: change (``SteppingParams.trigger_sigma``; the hip strategy's ``hip_jump`` uses it as is)
JUMP_SIGMA = 5.0
#: s: the time constant of that running mean square (``SteppingParams.trigger_tau``; the hip
#: strategy's)
JUMP_TAU = 0.3


@numba.njit(cache=True, error_model="numpy")
def jumped(
    d: float, two_sided: bool, threshold: float, sigma: float, share: float, ms: float
) -> tuple[bool, float]:
    """(the jump test, the mean square after it) for a per-tick change ``d``: ``|d|``
    (``two_sided``; else ``d``: one way only) beyond ``max(threshold, sigma · √ms)``, and
    ``ms + (d² − ms) · share`` (``share = min(dt / tau, 1)``: the running mean's step)."""
    size = abs(d) if two_sided else d
    return size > max(threshold, sigma * math.sqrt(ms)), ms + (d * d - ms) * share
