"""Gait timing: phases, swing-sole trajectories and the planned ZMP path.

A walk is ``start`` (double support, the CoM/ZMP moves onto the first stance sole), then per
step a *single support* phase (the step's sole swings) and a *double support* phase (both
soles down, the ZMP moves to the sole that just landed), the last one replaced by ``end``
(double support, the ZMP returns between the feet and the CoM settles). Phase boundaries
are rounded to the tick grid ``dt``.

The swing sole follows a minimum-jerk quintic (or the thesis's clamped cubic) from lift-off
to landing in x, y and yaw; its height rises to ``apex`` and back (zero velocity at
lift-off, apex and touch-down), so it never goes below its start/landing height. The apex is
at ``1 - landing`` of the single support (:class:`SwingParams`; half-way by default: a later
apex lands slower and lifts faster, measured worse in the simulator, benchmarks/balance.md).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..exceptions import TrajectoryError
from ..geometry import mean_angle, wrap_angle
from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from .footsteps import Footstep, FootstepPlan
from .geometry import rot2
from .spline import min_jerk, smoothstep

PhaseKind = Literal["start", "single", "double", "end"]


@dataclass(frozen=True)
class GaitTiming:
    """Durations (s). ``step_time`` = single support + double support of one step.

    Defaults: quick steps (0.24 s single + 0.16 s double support). A longer single support
    lets the CoM drift toward the stance foot, further than the Bioloid's hip roll allows
    (see :func:`wbc.walking.gait.walk`); the MPC generator handles longer steps.
    """

    step_time: float = 0.4
    double_support_ratio: float = 0.4
    start_time: float = 0.8
    end_time: float = 1.0
    dt: float = 0.01

    def validate(self) -> None:
        for name in ("step_time", "start_time", "end_time", "dt"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise TrajectoryError(f"gait timing: {name} must be positive, got {v}")
        r = self.double_support_ratio
        if not (np.isfinite(r) and 0.0 <= r < 1.0):
            raise TrajectoryError(f"gait timing: double_support_ratio must be in [0, 1), got {r}")
        if self.single_support_time < 2 * self.dt:
            raise TrajectoryError(
                f"gait timing: single support lasts {self.single_support_time:.3f} s, "
                f"less than two ticks of dt = {self.dt} s"
            )
        if r > 0 and self.double_support_time < self.dt:
            raise TrajectoryError(
                f"gait timing: double support lasts {self.double_support_time:.4f} s, "
                f"less than one tick of dt = {self.dt} s"
            )
        for name in ("start_time", "end_time"):
            if getattr(self, name) < 2 * self.dt:
                raise TrajectoryError(f"gait timing: {name} is shorter than two ticks")

    @property
    def single_support_time(self) -> float:
        return self.step_time * (1.0 - self.double_support_ratio)

    @property
    def double_support_time(self) -> float:
        return self.step_time * self.double_support_ratio


@dataclass(frozen=True)
class SwingParams:
    """Swing-sole shape: apex height above the higher of lift-off/landing (m), profile, and
    ``landing``: the share of the single support the sole spends coming down from its apex
    (the rise takes the rest; 0.5: apex half-way)."""

    apex: float = 0.02
    profile: Literal["quintic", "cubic"] = "quintic"
    landing: float = 0.5

    def validate(self) -> None:
        if not (np.isfinite(self.apex) and self.apex > 0):
            raise TrajectoryError(f"swing: the apex height must be positive, got {self.apex}")
        if not (np.isfinite(self.landing) and 0.0 < self.landing < 1.0):
            raise TrajectoryError(
                f"swing: landing (the descent's share of the swing) must be in (0, 1), got "
                f"{self.landing}"
            )
        if self.profile not in ("quintic", "cubic"):
            raise TrajectoryError(
                f"swing: profile must be 'quintic' or 'cubic', got {self.profile!r}"
            )


@dataclass(frozen=True)
class Phase:
    """A gait phase on ticks ``[i0, i1)`` (times ``[t0, t1)``)."""

    kind: PhaseKind
    i0: int
    i1: int
    t0: float
    t1: float
    support: int
    step: int | None = None  # single: the swinging step; double: the step that just landed


def build_phases(plan: FootstepPlan, timing: GaitTiming) -> list[Phase]:
    """Phases of a plan on the tick grid (the last tick is the last phase's end)."""
    timing.validate()
    dt = timing.dt

    def ticks(duration: float) -> int:
        return max(1, round(duration / dt))

    n_start = ticks(timing.start_time)
    n_ss = ticks(timing.single_support_time)
    n_ds = round(timing.double_support_time / dt)
    n_end = ticks(timing.end_time)
    phases: list[Phase] = []
    i = 0

    def add(kind: PhaseKind, n: int, support: int, step: int | None) -> None:
        nonlocal i
        phases.append(Phase(kind, i, i + n, i * dt, (i + n) * dt, support, step))
        i += n

    add("start", n_start, SUPPORT_DOUBLE, None)
    for k, step in enumerate(plan.steps):
        add("single", n_ss, SUPPORT_RIGHT if step.side == "left" else SUPPORT_LEFT, k)
        if k < len(plan.steps) - 1 and n_ds > 0:
            add("double", n_ds, SUPPORT_DOUBLE, k)
    last = len(plan.steps) - 1 if plan.steps else None
    add("end", n_end + 1, SUPPORT_DOUBLE, last)  # +1: the final tick closes the walk
    return phases


@dataclass
class SoleTracks:
    """Sampled sole targets: positions (N, 3), yaws (N,), velocities (N, 3), support (N,)."""

    t: np.ndarray
    l_pos: np.ndarray
    l_yaw: np.ndarray
    l_vel: np.ndarray
    r_pos: np.ndarray
    r_yaw: np.ndarray
    r_vel: np.ndarray
    support: np.ndarray

    def torso_yaw(self) -> np.ndarray:
        """The yaw half-way between the soles' (wrapped): the walks' torso heading."""
        return mean_angle(self.l_yaw, self.r_yaw)

    def reference_fields(self) -> dict[str, np.ndarray]:
        """The :class:`~wbc.walking.reference.WalkingReference` fields these tracks give:
        both soles' positions, yaws and velocities, the support and the torso yaw."""
        return {
            "l_sole": self.l_pos,
            "l_sole_yaw": self.l_yaw,
            "r_sole": self.r_pos,
            "r_sole_yaw": self.r_yaw,
            "support": self.support,
            "torso_yaw": self.torso_yaw(),
            "l_sole_vel": self.l_vel,
            "r_sole_vel": self.r_vel,
        }


def sole_tracks(
    plan: FootstepPlan, phases: list[Phase], dt: float, swing: SwingParams
) -> SoleTracks:
    """Both soles' targets: fixed when in contact, swing trajectory in single support."""
    swing.validate()
    n = phases[-1].i1
    t = np.arange(n) * dt
    pos = {s: np.zeros((n, 3)) for s in ("left", "right")}
    yaw = {s: np.zeros(n) for s in ("left", "right")}
    vel = {s: np.zeros((n, 3)) for s in ("left", "right")}
    support = np.zeros(n, dtype=np.int8)
    cur = {"left": plan.start_left, "right": plan.start_right}
    for ph in phases:
        sl = slice(ph.i0, ph.i1)
        support[sl] = ph.support
        for side in ("left", "right"):
            pos[side][sl] = cur[side].position
            yaw[side][sl] = cur[side].yaw
        if ph.kind != "single":
            continue
        step = plan.steps[ph.step]
        a, b = cur[step.side], step
        T = ph.t1 - ph.t0
        # the sole lands at the end of the phase: s = 1 at tick i1 (first tick of the next phase)
        s = (np.arange(ph.i0, ph.i1) - ph.i0) * dt / T
        p, v = _swing_profile(a, b, s, swing)
        pos[step.side][sl] = p
        vel[step.side][sl] = v / T
        yaw_a = a.yaw
        yaw_b = a.yaw + wrap_angle(b.yaw - a.yaw)
        prof = min_jerk(s)[0] if swing.profile == "quintic" else smoothstep(s)[0]
        yaw[step.side][sl] = yaw_a + (yaw_b - yaw_a) * prof
        cur[step.side] = dataclasses.replace(b, yaw=float(yaw_b))
    return SoleTracks(
        t, pos["left"], yaw["left"], vel["left"], pos["right"], yaw["right"], vel["right"], support
    )


def _swing_profile(a, b, s: np.ndarray, swing: SwingParams):
    """Swing position (len(s), 3) and its derivative d/ds for lift-off ``a``, landing ``b``.

    Horizontal (and the base line of the height): ``a + (b - a) f(s)``; height: the base line
    raised toward ``top = max(z_a, z_b) + apex`` by ``h(s)``: the profile over the rise
    ``s < r = 1 - landing`` (``h = f(s / r)``) and mirrored over the descent
    (``h = f((1 - s) / landing)``), so ``z(s) >= base line >= min(z_a, z_b)``.
    """
    prof = min_jerk if swing.profile == "quintic" else smoothstep
    f, df, _ = prof(s)
    rise = 1.0 - swing.landing  # the apex's s
    up = s < rise
    h, dh, _ = prof(np.where(up, s / rise, (1.0 - s) / swing.landing))
    dh = np.where(up, dh / rise, -dh / swing.landing)
    pa, pb = a.position, b.position
    pos = pa[None, :] + (pb - pa)[None, :] * f[:, None]
    dpos = (pb - pa)[None, :] * df[:, None]
    base_z, dbase_z = pos[:, 2].copy(), dpos[:, 2].copy()
    top = max(pa[2], pb[2]) + swing.apex
    pos[:, 2] = base_z + (top - base_z) * h
    dpos[:, 2] = dbase_z * (1.0 - h) + (top - base_z) * dh
    return pos, dpos


def zmp_knots(
    plan: FootstepPlan,
    phases: list[Phase],
    com0_xy: np.ndarray,
    offset: tuple[float, float] = (0.0, 0.0),
    transfer_time: float | None = None,
    start_hold: float = 0.2,
    ramp_knots: int = 8,
    transfer: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Piecewise-linear planned ZMP: knot times (K,) and points (K, 2).

    Start: held at the CoM's ground projection for ``start_hold`` of the start phase, then
    a min-jerk shaped transfer (``ramp_knots`` linear pieces) to the first stance sole.
    Single support: on the stance sole (plus ``offset`` in its frame: x forward, y toward
    the other foot). Double support: to the sole that just landed, linearly within the
    first ``transfer`` (0–1] of the phase, then held there (1: over the whole phase). End:
    to the feet's midpoint within ``transfer_time`` (default: half the end phase; min-jerk
    shaped), then held. Two knots at the same time are a jump (support exchange without
    double support).
    """
    if not (np.isfinite(transfer) and 0.0 < transfer <= 1.0):
        raise TrajectoryError(f"zmp path: transfer must be in (0, 1], got {transfer}")

    def anchor(step) -> np.ndarray:
        sign = -1.0 if step.side == "left" else 1.0  # toward the other foot
        return step.xy + rot2(step.yaw) @ np.array([offset[0], sign * offset[1]])

    def ramp(t0: float, t1: float, a: np.ndarray, b: np.ndarray) -> None:
        # min-jerk shaped transfer as a polyline (a smooth start asks less counter-motion)
        s = np.linspace(0.0, 1.0, ramp_knots + 1)[1:]
        for sj, fj in zip(s, min_jerk(s)[0], strict=True):
            times.append(t0 + sj * (t1 - t0))
            points.append(a + fj * (b - a))

    com0 = np.asarray(com0_xy, dtype=float)[:2]
    times = [phases[0].t0]
    points = [com0]
    for ph in phases:
        if ph.kind == "start" and plan.steps:
            t_move = ph.t0 + start_hold * (ph.t1 - ph.t0)
            times.append(t_move)
            points.append(com0)
            ramp(t_move, ph.t1, com0, anchor(plan.stance(0)))
        elif ph.kind == "single":
            stance = anchor(plan.stance(ph.step))
            times += [ph.t0, ph.t1]
            points += [stance, stance]
        elif ph.kind == "double":
            landed = anchor(plan.steps[ph.step])
            times.append(ph.t0 + transfer * (ph.t1 - ph.t0))
            points.append(landed)
            if transfer < 1.0:
                times.append(ph.t1)
                points.append(landed)
        elif ph.kind == "end":
            left, right = plan.placements()[-1]
            mid = 0.5 * (left.xy + right.xy)
            dur = ph.t1 - ph.t0
            tt = 0.5 * dur if transfer_time is None else min(max(transfer_time, 0.0), dur)
            if tt > 0 and plan.steps:
                ramp(ph.t0, ph.t0 + tt, points[-1], mid)
            times.append(ph.t1)
            points.append(mid)
    t = np.asarray(times)
    p = np.asarray(points)
    same = np.concatenate(
        [[False], (np.diff(t) <= 1e-12) & (np.linalg.norm(np.diff(p, axis=0), axis=1) <= 1e-12)]
    )
    return t[~same], p[~same]


def sample_knots(knot_t: np.ndarray, knot_p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Piecewise-linear path through (K, d) knots at times ``t``; held outside.

    Repeated knot times are jumps; a tick at a jump takes the value after it.
    """
    knot_t = np.asarray(knot_t, dtype=float)
    knot_p = np.asarray(knot_p, dtype=float).reshape(len(knot_t), -1)
    t = np.asarray(t, dtype=float)
    j = np.clip(np.searchsorted(knot_t, t, side="right") - 1, 0, len(knot_t) - 1)
    nxt = np.minimum(j + 1, len(knot_t) - 1)
    span = knot_t[nxt] - knot_t[j]
    w = np.where(span > 0, (t - knot_t[j]) / np.where(span > 0, span, 1.0), 0.0)
    w = np.clip(w, 0.0, 1.0)[:, None]
    return (1.0 - w) * knot_p[j] + w * knot_p[nxt]


def settled_swing(
    pos: np.ndarray, yaw: np.ndarray, lift: Footstep, land: Footstep, settle: float
) -> tuple[np.ndarray, np.ndarray]:
    """The swing's samples (``pos`` (n, 3), ``yaw`` (n,); tick i at s = i / n of the
    swing) with the horizontal move and the turn from ``lift`` to ``land`` done by
    s = 1 − ``settle`` (the same min-jerk profile, compressed; the height as given)."""
    n = len(yaw)
    f = min_jerk(np.arange(n) / (n * (1.0 - settle)))[0]
    out = pos.copy()
    out[:, :2] = lift.xy[None, :] + (land.xy - lift.xy)[None, :] * f[:, None]
    turn = wrap_angle(land.yaw - lift.yaw)
    return out, lift.yaw + turn * f
