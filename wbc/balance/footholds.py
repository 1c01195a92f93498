"""Where a swing sole can land and how fast it can get there: the footstep shifts the step
adjuster (:mod:`.stepping`) and the capturability bounds (:mod:`.capture`) share — the
LIPM's prediction, a plan's steps moved, the landings the legs can make, and the bend a
re-plan adds to a swing under way."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np

from ..exceptions import TrajectoryError
from ..walking.footsteps import FootstepPlan
from ..walking.legs import LegGeometry
from ..walking.schedule import Phase, SwingParams
from ..walking.spline import min_jerk, smoothstep


def predicted_dcm(xi: np.ndarray, cop: np.ndarray, omega: float, horizon: float) -> np.ndarray:
    """LIPM DCM after ``horizon`` s with the CoP held at ``cop``: ``p + (ξ − p) e^{ω T}``."""
    xi, cop = np.asarray(xi, float), np.asarray(cop, float)
    return cop + (xi - cop) * math.exp(omega * max(horizon, 0.0))


def shifted_plan(plan: FootstepPlan, first: int, shift: np.ndarray) -> FootstepPlan:
    """``plan`` with steps ``first, first + 1, …`` moved by ``shift`` (x, y; world)."""
    dx, dy = float(shift[0]), float(shift[1])
    steps = tuple(
        replace(s, x=s.x + dx, y=s.y + dy) if k >= first else s for k, s in enumerate(plan.steps)
    )
    return FootstepPlan(plan.start_left, plan.start_right, steps)


def landing_ok(
    plan: FootstepPlan,
    k: int,
    legs: LegGeometry,
    com_height: float,
    foot: Any,
    min_clearance: float,
) -> bool:
    """Can step ``k`` of ``plan`` (and the step after it) be walked: no crossing, the
    clearance along the swing and on landing, both legs within reach and within their hip
    roll limits (the CoM midway between the feet, torso upright)?"""
    left, right = plan.placements()[k]
    local = FootstepPlan(left, right, plan.steps[k : k + 2])
    try:
        local.validate(foot, legs, com_height, min_clearance)
    except TrajectoryError:
        return False
    for left, right in local.placements()[1:]:
        mid = 0.5 * (left.position + right.position)
        com = np.array([[mid[0], mid[1], com_height]])
        heading = np.array([0.5 * (left.yaw + right.yaw)])
        rolls = legs.leg_rolls(com, heading, left.position[None], right.position[None])[0]
        if np.any(rolls < -legs.max_adduction) or np.any(rolls > legs.max_abduction):
            return False
    return True


def feasible_shift(
    plan: FootstepPlan,
    k: int,
    wanted: np.ndarray,
    legs: LegGeometry,
    com_height: float,
    foot: Any,
    min_clearance: float,
    iterations: int = 10,
) -> np.ndarray:
    """The shift of steps ``k, …`` closest to ``wanted`` (per axis, lateral first, by
    bisection) that :func:`landing_ok` accepts; zero if even the plan's own step is not."""
    out = np.zeros(2)
    for axis in (1, 0):
        target = out.copy()
        target[axis] = wanted[axis]
        if landing_ok(shifted_plan(plan, k, target), k, legs, com_height, foot, min_clearance):
            out = target
            continue
        lo, hi = 0.0, 1.0
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            trial = out.copy()
            trial[axis] = mid * wanted[axis]
            ok = landing_ok(shifted_plan(plan, k, trial), k, legs, com_height, foot, min_clearance)
            lo, hi = (mid, hi) if ok else (lo, mid)
        out[axis] = lo * wanted[axis]
    return out


def dead_zone(x: float, band: float) -> float:
    """``sign(x) max(|x| − band, 0)``."""
    return (1.0 if x > 0 else -1.0 if x < 0 else 0.0) * max(abs(x) - band, 0.0)


def bend(ph: Phase, i: int, dt: float, swing: SwingParams) -> tuple[np.ndarray, np.ndarray]:
    """The share ``g`` (0 → 1) of a landing change added to the swing sole from tick ``i`` to
    the end of its phase, and ``dg/dt``: ``g = (f(s) − f(s_i)) / (1 − f(s_i))`` with ``f``
    the swing's own profile, so the sole's target stays continuous and lands on time."""
    T = ph.t1 - ph.t0
    s = (np.arange(i, ph.i1) - ph.i0) * dt / T
    f, df, _ = (min_jerk if swing.profile == "quintic" else smoothstep)(s)
    f0 = float(f[0])
    return (f - f0) / (1.0 - f0), df / (1.0 - f0) / T


def bend_rate(ph: Phase, i: int, dt: float, swing: SwingParams) -> float:
    """Peak ``dg/dt`` (1/s) of :func:`bend` from tick ``i``: the swing sole's added peak
    speed per metre of landing change."""
    return float(np.max(bend(ph, i, dt, swing)[1]))
