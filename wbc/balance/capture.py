"""LIPM capturability bounds: the largest impulse at mid single support a step can catch, per
direction (:func:`capture_bounds`), the yardstick beside the push benchmark's results
(``wbc.bench.pushes``, benchmarks/pushes.md)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..recording import SUPPORT_DOUBLE
from ..walking.footsteps import Footstep, FootstepPlan
from ..walking.legs import LegGeometry
from ..walking.reference import WalkingReference
from ..walking.schedule import GaitTiming, SwingParams, build_phases
from .footholds import bend_rate, feasible_shift
from .stepping import SteppingParams


def capture_bounds(
    ref: WalkingReference,
    mass: float,
    legs: LegGeometry,
    min_clearance: float = 0.005,
    swing_down: float = 0.05,
    step_time: float | None = None,
    max_foot_speed: float = SteppingParams.max_foot_speed,
) -> dict[str, Any]:
    """LIPM capturability of an impulse at mid first single support of ``ref``: the largest
    DCM offset ``Δξ`` a strategy catches, as an impulse ``m ω Δξ`` (N·s). ``t`` = the swing's
    remaining time; the CoP anywhere in the support (optimistic: no double support time).

    * ``away`` (sideways, away from the swing foot, the benchmark's lateral push): the swing
      sole cannot land beyond the stance sole's outer edge ``e`` (the feet would cross), so
      one step catches ``Δξ ≤ e − ξ``. Two steps: the swing sole down at its closest to the
      stance sole after ``swing_down`` s (``t₁``), then the stance sole stepping outward as far
      as the legs reach (``w``) in ``step_time`` s (``t₂``, default the walk's single
      support) with the CoP at the landed sole's inner edge ``p``:
      ``Δξ ≤ e + (p + (e + w − p) e^{−ω t₂} − e) e^{−ω t₁} − ξ``.
    * ``forward`` / ``backward`` / ``toward`` (the swing foot's side): the swing sole lands
      at its planned place (``*_planned_ns``) or as far as the legs reach (``*_ns``) after
      ``t``, with the
      DCM inside the landed sole's far edge: ``Δξ ≤ f + (f' − f) e^{−ω t} − ξ`` (``f`` the
      stance sole's edge on that side, ``f'`` the landed sole's); ``*_in_time_ns``: the
      landing moved only as far as the swing sole gets in ``t`` with the bend of
      :class:`StepAdjuster` at ``max_foot_speed`` (m/s) added.
    """
    omega = ref.omega
    a, b, _ = next(p for p in ref.phases() if p[2] != SUPPORT_DOUBLE)
    i = (a + b) // 2
    stance = ref.stance_side(i)
    xi = ref.dcm_at(i)
    st = ref.sole(stance)[0][i, :2]
    u = 1.0 if stance == "left" else -1.0  # world y of "away from the swing foot"
    half_w, half_l = 0.5 * ref.foot.width, 0.5 * ref.foot.length
    plan, step = ref.plan, ref.plan.steps[0]
    t = max((b - i) * ref.dt, swing_down)
    to_ns = mass * omega
    decay = math.exp(-omega * t)

    def reach(plan: FootstepPlan, direction: tuple[float, float]) -> float:
        wanted = 0.3 * np.asarray(direction, dtype=float)
        s = feasible_shift(plan, 0, wanted, legs, ref.com_height, ref.foot, min_clearance)
        return float(np.linalg.norm(s))

    out: dict[str, Any] = {"omega": omega, "mass": mass, "t_swing_left_s": t}
    phase = next(p for p in build_phases(plan, GaitTiming(**ref.meta["timing"])) if p.i0 == a)
    in_time = max_foot_speed / bend_rate(phase, i, ref.dt, SwingParams(**ref.meta["swing"]))
    out["in_time_reach_mm"] = 1e3 * in_time
    # away: one step (the DCM within the stance sole's outer edge)
    e = u * st[1] + half_w
    xi_u = u * xi[1]
    out["away_one_step_ns"] = to_ns * (e - xi_u)
    # away: two steps (swing sole down at its closest, then the stance sole steps outward)
    closest = reach(plan, (0.0, u))
    landed = Footstep(step.side, step.x, step.y + u * closest, step.yaw)
    here = Footstep(stance, float(st[0]), float(st[1]), step.yaw)
    pair = (here, landed) if stance == "left" else (landed, here)
    wide = reach(FootstepPlan(*pair, (here,)), (0.0, u))
    p = u * landed.y + half_w
    t2 = step_time if step_time is not None else (b - a) * ref.dt
    lift = p + (e + wide - p) * math.exp(-omega * t2)
    d2 = e + (lift - e) * math.exp(-omega * swing_down) - xi_u
    out["away_two_step_ns"] = to_ns * d2
    out["away_ns"] = to_ns * max(e - xi_u, d2)
    out["away_detail_mm"] = {
        "xi": 1e3 * xi_u, "outer_edge": 1e3 * e, "closest_landing_shift": 1e3 * closest,
        "widest_outward_step": 1e3 * wide, "inner_cop": 1e3 * p,
    }  # fmt: skip
    # forward: the swing sole lands further ahead
    fwd = reach(plan, (1.0, 0.0))
    f = st[0] + half_l
    out["forward_planned_ns"] = to_ns * (f + (step.x + half_l - f) * decay - xi[0])
    out["forward_ns"] = to_ns * (f + (step.x + fwd + half_l - f) * decay - xi[0])
    out["forward_in_time_ns"] = to_ns * (
        f + (step.x + min(fwd, in_time) + half_l - f) * decay - xi[0]
    )
    out["forward_reach_mm"] = 1e3 * fwd
    # backward: the swing sole lands further behind (the DCM within its back edge)
    bwd = reach(plan, (-1.0, 0.0))
    f = st[0] - half_l
    out["backward_planned_ns"] = to_ns * (xi[0] - f - (step.x - half_l - f) * decay)
    out["backward_ns"] = to_ns * (xi[0] - f - (step.x - bwd - half_l - f) * decay)
    out["backward_in_time_ns"] = to_ns * (
        xi[0] - f - (step.x - min(bwd, in_time) - half_l - f) * decay
    )
    out["backward_reach_mm"] = 1e3 * bwd
    # toward the swing foot: the swing sole lands further out
    tow = reach(plan, (0.0, -u))
    f = -(u * st[1] - half_w)  # the stance sole's inner edge, toward the swing foot
    land = -u * step.y + half_w
    out["toward_planned_ns"] = to_ns * (f + (land - f) * decay + u * xi[1])
    out["toward_ns"] = to_ns * (f + (land + tow - f) * decay + u * xi[1])
    out["toward_in_time_ns"] = to_ns * (f + (land + min(tow, in_time) - f) * decay + u * xi[1])
    out["toward_reach_mm"] = 1e3 * tow
    # with step timing: the landing after t' in [swing_down, t] (the sole's added reach
    # in_time t'/t), the best t' (``*_timed_ns``, ``*_timed_s``)
    ts = np.linspace(swing_down, t, 60)
    reach_t, dec = in_time * ts / t, np.exp(-omega * ts)
    f, half_l = st[0], 0.5 * ref.foot.length
    cases = {
        "forward": f + half_l + (step.x + np.minimum(fwd, reach_t) - st[0]) * dec - xi[0],
        "backward": xi[0] - f + half_l - (step.x - np.minimum(bwd, reach_t) - st[0]) * dec,
        "toward": -(u * st[1] - half_w) + (land + np.minimum(tow, reach_t) + u * st[1] - half_w)
        * dec + u * xi[1],
    }  # fmt: skip
    for name, margin in cases.items():
        j = int(np.argmax(margin))
        out[f"{name}_timed_ns"], out[f"{name}_timed_s"] = to_ns * float(margin[j]), float(ts[j])
    return out
