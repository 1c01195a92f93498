"""A whole-body static walk: the CoM well inside the stance sole throughout single support.

The thesis's step (:mod:`.thesis_step`) keeps the torso upright, so on the Bioloid its CoM
reaches only ~0.4 mm inside the stance sole. This walk uses the whole-body balance window
(:class:`.window.BalanceWindow`): the torso leans over the stance foot and the arms are
free, so the CoM can sit over the stance sole (``com_offset`` from its centre toward the
other foot) while the other foot swings.

Phases (:func:`.schedule.build_phases` with the static timing below):

* ``start`` (double support, ``shift_time``): the CoM moves over the first stance sole;
* per step: single support (``swing_time``): the swing sole lifts to ``apex``, moves to its
  footstep and lands (min-jerk), the CoM held; then double support (``shift_time``): the
  CoM moves over the sole that just landed (min-jerk, at rest at both ends);
* ``end`` (``end_time``): the CoM returns between the feet.

The torso roll follows the CoM (:func:`.gait.lean_from_window`). The reference is checked as
a static gait with ``margin`` (CoM inside the support polygon at every tick).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..exceptions import TrajectoryError
from .checks import check_reference
from .footsteps import plan_footsteps
from .gait import lean_from_window
from .geometry import Foot, rot2
from .legs import LegGeometry
from .reference import StandingState, WalkingReference
from .schedule import GaitTiming, SwingParams, build_phases, sole_tracks
from .spline import min_jerk
from .window import BalanceWindow, lateral_reach


@dataclass(frozen=True)
class StaticWalkParams:
    """Lengths in m, durations in s. ``com_offset``: the CoM's place in single support,
    from the stance sole's centre (x forward, y toward the other foot)."""

    n_steps: int = 4
    step_length: float = 0.03
    shift_time: float = 1.0
    swing_time: float = 1.0
    end_time: float = 1.0
    apex: float = 0.02
    com_offset: tuple[float, float] = (0.0, 0.012)
    margin: float = 0.015
    dt: float = 0.01
    #: the share of the whole body's lateral reach (:func:`.window.lateral_reach`) the CoM
    #: may use at each stance (the rest a margin for the tracking stack)
    reach_share: float = 0.9

    def validate(self) -> None:
        if int(self.n_steps) != self.n_steps or self.n_steps < 1:
            raise TrajectoryError(
                f"static walk: n_steps must be an integer >= 1, got {self.n_steps}"
            )
        for name in ("shift_time", "swing_time", "end_time", "apex", "dt"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise TrajectoryError(f"static walk: {name} must be positive, got {v}")
        if not np.isfinite(self.step_length):
            raise TrajectoryError(
                f"static walk: step_length must be finite, got {self.step_length}"
            )
        if len(self.com_offset) != 2 or not np.all(np.isfinite(self.com_offset)):
            raise TrajectoryError(
                f"static walk: com_offset must be two finite numbers (x, y), got {self.com_offset}"
            )
        if not (np.isfinite(self.margin) and self.margin >= 0):
            raise TrajectoryError(f"static walk: margin must be >= 0, got {self.margin}")
        if not (np.isfinite(self.reach_share) and 0 < self.reach_share <= 1):
            raise TrajectoryError(
                f"static walk: reach_share must be in (0, 1], got {self.reach_share}"
            )

    def timing(self) -> GaitTiming:
        step = self.swing_time + self.shift_time
        return GaitTiming(
            step_time=step,
            double_support_ratio=self.shift_time / step,
            start_time=self.shift_time,
            end_time=self.end_time,
            dt=self.dt,
        )


def static_walk(
    start: StandingState,
    window: BalanceWindow,
    params: StaticWalkParams | None = None,
    foot: Foot | None = None,
    legs: LegGeometry | None = None,
    min_clearance: float = 0.005,
    check: bool = True,
) -> WalkingReference:
    """A whole-body static walk from ``start`` (see the module docstring)."""
    p = params or StaticWalkParams()
    p.validate()
    foot = foot or start.foot
    legs = legs or start.legs
    height = float(start.com[2])
    legs.check_com_height(height, "static walk")
    plan = plan_footsteps(start.left, start.right, int(p.n_steps), (p.step_length, 0.0, 0.0))
    plan.validate(foot, legs, height, min_clearance)
    lateral = _fit_lateral(start, window, plan, p, foot, height)
    timing = p.timing()
    phases = build_phases(plan, timing)
    soles = sole_tracks(plan, phases, p.dt, SwingParams(apex=p.apex))
    t = soles.t

    def over(step) -> np.ndarray:
        sign = -1.0 if step.side == "left" else 1.0  # toward the other foot
        off = np.array([p.com_offset[0], sign * lateral])
        return step.xy + rot2(step.yaw) @ off

    # CoM knots: (time, xy) at rest; min-jerk between consecutive knots
    knots: list[tuple[float, np.ndarray]] = [(0.0, np.asarray(start.com[:2], dtype=float))]
    for ph in phases:
        if ph.kind == "start":
            knots.append((ph.t1, over(plan.stance(0))))
        elif ph.kind == "double":  # held through the single support before it
            knots.append((ph.t0, knots[-1][1]))
            knots.append((ph.t1, over(plan.steps[ph.step])))
        elif ph.kind == "end":
            left, right = plan.placements()[-1]
            knots.append((ph.t0, knots[-1][1]))
            knots.append((ph.t0 + 0.6 * (ph.t1 - ph.t0), 0.5 * (left.xy + right.xy)))
    n = t.size
    pos = np.empty((n, 2))
    vel = np.zeros((n, 2))
    acc = np.zeros((n, 2))
    pos[:] = knots[-1][1]
    for (ta, a), (tb, b) in itertools.pairwise(knots):
        sel = (t >= ta - 1e-12) & (t < tb - 1e-12)
        if tb - ta <= 1e-12:
            continue
        s = (t[sel] - ta) / (tb - ta)
        f, df, ddf = min_jerk(s)
        pos[sel] = a + np.outer(f, b - a)
        vel[sel] = np.outer(df, b - a) / (tb - ta)
        acc[sel] = np.outer(ddf, b - a) / (tb - ta) ** 2
    com = np.column_stack([pos, np.full(n, height)])
    com_vel = np.column_stack([vel, np.zeros(n)])
    com_acc = np.column_stack([acc, np.zeros(n)])
    ref = WalkingReference(
        t=t,
        com=com,
        com_vel=com_vel,
        com_acc=com_acc,
        **soles.reference_fields(),
        com_height=height,
        plan=plan,
        gait="static",
        name="static-walk",
        foot=foot,
        margin=p.margin,
        meta={
            "generator": "static-min-jerk",
            "params": {k: (list(v) if isinstance(v, tuple) else v) for k, v in p.__dict__.items()},
            # the CoM's offset toward the other foot used (com_offset's y, or less to stay
            # within the whole body's reach at the walk's stances)
            "com_offset_y": lateral,
        },
    )
    lean_from_window(ref, window)
    if check:
        report = check_reference(
            ref, margin=p.margin, min_clearance=min_clearance, legs=legs, window=window
        )
        ref.meta["check"] = report.as_dict()
    return ref


def _fit_lateral(
    start: StandingState,
    window: BalanceWindow,
    plan,
    p: StaticWalkParams,
    foot: Foot,
    height: float,
) -> float:
    """The CoM's offset (m) from the stance sole's centre toward the other foot: ``com_offset``'s
    y, raised (nearer the midpoint) to keep the CoM within ``reach_share`` of the whole body's
    lateral reach at every double-support stance of ``plan`` (:func:`.window.lateral_reach`,
    arms held: the CoM over the sole that just landed, a step ahead of the other, and over
    the one behind before), measured on the robot ``start`` was made from (a start made by
    hand: the window's ``max_lateral``). Raises :class:`TrajectoryError` (one line) if the
    CoM cannot then stay ``margin`` inside the stance sole."""
    want = float(p.com_offset[1])
    placements = plan.placements()
    robot, q = start.robot, start.q
    cache: dict[tuple[float, float], float] = {}

    def reach(stagger: float, forward: float) -> float:
        key = (round(stagger, 6), round(forward, 6))
        if key not in cache:
            cache[key] = lateral_reach(
                robot, q, stagger, forward, window.max_lean, com_height=height
            )
        return cache[key]

    # (stagger, forward, half-width) of each double-support stance, seen from the sole the CoM
    # is over (+ stagger: that sole ahead; a right sole mirrors a left one): the start's over
    # the first stance sole; after step k, over the stance sole, then over the landed one
    over_pairs = [(placements[0], plan.stance(0))]
    for k, step in enumerate(plan.steps):
        over_pairs += [(placements[k + 1], plan.stance(k)), (placements[k + 1], step)]
    stances: list[tuple[float, float, float]] = []
    for pair, over in over_pairs:
        other = pair[1] if over.side == "left" else pair[0]
        fwd = np.array([np.cos(over.yaw), np.sin(over.yaw)])
        left = np.array([-fwd[1], fwd[0]])
        mid = 0.5 * (over.xy + other.xy)
        stances.append(
            (
                float((over.xy - other.xy) @ fwd),
                float((over.xy - mid) @ fwd) + float(p.com_offset[0]),
                abs(float((over.xy - mid) @ left)),
            )
        )
    if robot is None or q is None:
        bounds = [(window.max_lateral, s, h) for s, _, h in stances]
    else:
        bounds = [(reach(s, f), s, h) for s, f, h in stances]
    # the offset from the sole's centre that keeps the CoM within the share of each reach
    lateral = want
    worst = None
    for r, s, h in bounds:
        need = h - p.reach_share * r
        if need > lateral:
            lateral, worst = need, (r, s, h)
    inside = foot.width / 2 - p.margin  # the CoM's largest offset from the sole's centre
    if worst is not None and lateral > inside + 1e-9:
        r, s, h = worst
        longest = _longest_step(reach, h - inside, p.reach_share, abs(s)) if robot else 0.0
        where = f"the front sole of a {abs(s) * 1e3:.1f} mm step" if abs(s) > 1e-9 else "a sole"
        fix = f"shorten step_length (to {longest * 1e3:.1f} mm) or " if longest > 0 else ""
        raise TrajectoryError(
            f"static walk: unreachable — the whole body's balance window (torso roll <= "
            f"{np.rad2deg(window.max_lean):.0f} deg, arms held; {p.reach_share:.0%} of it used) "
            f"carries the CoM over {where} only {p.reach_share * r * 1e3:.1f} mm sideways from "
            f"the soles' midpoint; keeping it {p.margin * 1e3:.1f} mm inside the stance sole "
            f"needs {(h - inside) * 1e3:.1f} mm: {fix}lower margin"
        )
    return lateral


def _longest_step(reach, lateral: float, share: float, step: float) -> float:
    """The largest stagger (<= ``step``) at which ``share`` of the reach over the front sole
    covers ``lateral`` (bisection; 0 if none)."""
    if share * reach(0.0, 0.0) < lateral:
        return 0.0
    lo, hi = 0.0, step
    for _ in range(8):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if share * reach(mid, 0.5 * mid) >= lateral else (lo, mid)
    return lo
