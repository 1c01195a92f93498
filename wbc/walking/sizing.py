"""The walking references' settings sized to the robot: its legs, its feet, its servos.

The walks' default settings (step lengths, swing apex, ZMP and CoM offsets, margins, timing)
were tuned on one robot. On another they are scaled by its own dimensions:

* along the walk and up (step length and width, swing apex and clearance, the x of an
  offset) by the leg ratio ``λ = (thigh + shin) / DESIGN_LEG``;
* across the foot (the y of the ZMP and CoM offsets, the margins kept inside the support
  polygon, the clearance between the feet) by the foot ratio ``μ = width / DESIGN_FOOT_WIDTH``;
* in time by ``√λ``: a walk that is the same motion for a pendulum ``λ`` times as long (the
  linear inverted pendulum ``ẍ = g/z (x − p)`` keeps its solutions when lengths scale by ``λ``
  and times by ``√λ``); the ZMP preview's horizon with them, and its jerk weight as time⁶;
* not the control period ``dt`` (the servo bus's tick: a robot states its own);

and then, unless the robot's ``robot.toml`` says ``[walking] fit_speed = false``, fitted
until the reference asks no joint for more than :data:`SPEED_FRACTION` of its no-load speed
(the model's velocity limit), measured by :func:`wbc.walking.feasibility.kinematic_feasibility`:

1. slowed: every duration stretched alike. A slower walk sways further: if a slowed
   reference is refused (the hips' roll range), the slowest timing that builds is kept;
2. if it still asks more (a walk that cannot be slowed: the Bioloid's walk10, turn and
   lateral sway past its 5.6 deg hip roll at any slower timing), its swing is fitted
   (:func:`fit_swing`), footsteps, timing, ZMP and CoM unchanged: the swing sole's profile
   becomes the clamped cubic (its peak speed 1.5 times the mean where the quintic's is
   1.875, its peak acceleration about the same: 6 against 5.77 distance / time²), then its
   apex is lowered (not below :data:`MIN_APEX` of the sized one) until within the share.
   The trace (benchmarks/robots.md, "Issue 29's last gap"): what asks the 1.5-1.7x on those
   walks is the swing knee at mid-rise and mid-descent of each single support (the apex's
   vertical speed), then the swing ankle pitch (the step's forward speed); the start, the
   stop and the double supports ask at most 0.33.

Keys a robot states in ``[walking.<name>]`` are kept as stated: a walk whose timing is
stated is not fitted (a robot that times a walk has sized it), a stated ``swing`` is not
changed. A walk played on servos (:func:`wbc.bench.trajectories.build` ``on_servos``: the
simulator, the robot) is always fitted, whatever ``[walking] fit_speed`` says (the
Bioloid's false keeps the thesis's walks as recorded for the kinematic benchmark); a walk's
own ``[walking.<name>] fit_speed = false`` is kept there too.

With ``[walking] fit_torque = true`` (off by default: it measured no better, below) the steps
are then shortened (:data:`STRIDES`, ×:data:`SHRINK` a round) until the reference's predicted
peak joint torque — inverse dynamics of its tracked motion, the stance sole carrying the
weight in single support, the two split by the ZMP in double support
(:func:`wbc.walking.feasibility.joint_torques`) — is at most :data:`TORQUE_FRACTION` of the
joint's stall torque (the model's effort limit); a stated stride is kept, and if shortening
does not lower the peak the unshortened reference is kept. Why off: on the four robots of
benchmarks/robots.md the prediction is the static load of the stance leg (Bioloid ≤ 0.64,
Kokone 0.70–0.76, the long-legged robot's hip roll 0.9–1.0 at any step), while Kokone's fast_wb
peaks at 0.96 of stall in the simulator at 32.8 mm steps (0.75 predicted) from the servos'
response at lift-off and after touch-down, which the reference does not contain: the rule
would not find the 22 mm step the simulator asks for (benchmarks/robots.md, 2026-12-06
third round).

On the robot the defaults were tuned on, ``λ = μ = 1``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import fields, is_dataclass, replace
from typing import Any

from ..exceptions import TrajectoryError
from ..roles import design_robot, leg_ratio

#: the hip-to-ankle length (thigh + shin, m) and the foot width (m) the walking defaults
#: were tuned with: the design robot's, the Bioloid's (``tasks/walking/design.toml``, read by
#: :func:`wbc.roles.design_robot`), and the share of a servo's no-load speed a sized
#: reference may ask for (with the lag of a loaded servo, ~80 % leaves it a margin:
#: benchmarks/robots.md)
DESIGN_LEG = design_robot().leg
DESIGN_FOOT_WIDTH = design_robot().foot_width
SPEED_FRACTION = 0.8
#: the share of a joint's stall torque the torque fit lets a reference's predicted peak ask
#: for: the randomised plants' weakest servo (``wbc.bench.variation``: stall torque ×0.8–1);
#: Kokone's fast_wb lost the plants drawn ×0.81–0.91 at a simulated peak of 0.96 and kept them
#: at 0.79 (benchmarks/kokone_sim.md section 00000000)
TORQUE_FRACTION = 0.8
#: the step keys the torque fit shortens, and by how much a round
STRIDES = ("step_length", "step_width", "stride")
SHRINK = 0.75
#: keys along the walk or up (scaled by λ); across the foot (by μ); pairs (x by λ, y by μ);
#: durations (by √λ and the speed fit)
ALONG = ("step_length", "step_width", "apex", "stride", "clearance")
ACROSS = ("margin", "inset", "min_clearance")
PAIRS = ("zmp_offset", "com_offset", "com_target")
TIMES = (
    "step_time",
    "start_time",
    "end_time",
    "shift_time",
    "swing_time",
    "pose_time",
    "duration",
    "preview_time",
)
#: weights of a cost in time-scaled units: the ZMP preview's jerk weight (relative to the ZMP
#: error's) keeps its balance when it scales as time⁶ (jerk: length / time³)
JERK_WEIGHTS = ("r_input",)
#: how many times the timing is stretched at most to bring the joints within their speed
FIT_ROUNDS = 3
#: the most one round stretches the timing by
MAX_STRETCH = 2.0
#: the lowest swing apex the swing fit leaves, as a share of the sized apex
MIN_APEX = 0.25
#: the swing fit aims this far under :data:`SPEED_FRACTION` (the share is not linear in the
#: apex: a little under lands within it in fewer rounds)
SWING_AIM = 0.97
#: the CoM and sole errors (m) within which the tracking IK follows a reference (beyond, its
#: joint speeds are jumps, not what the timing asks)
TRACKED = 0.005


def scale_options(
    options: Mapping[str, Any], along: float, across: float, time: float
) -> dict[str, Any]:
    """``options`` with their lengths and durations scaled (module docstring); the
    dataclasses among them (:class:`~wbc.walking.schedule.GaitTiming`,
    :class:`~wbc.walking.schedule.SwingParams`) field by field."""
    out: dict[str, Any] = {}
    for key, value in options.items():
        if is_dataclass(value) and not isinstance(value, type):
            inner = {f.name: getattr(value, f.name) for f in fields(value)}
            out[key] = replace(value, **scale_options(inner, along, across, time))
        elif value is None or isinstance(value, bool):
            out[key] = value
        elif key in ALONG:
            out[key] = value * along
        elif key in ACROSS:
            out[key] = value * across
        elif key in PAIRS:
            out[key] = (value[0] * along, value[1] * across)
        elif key in TIMES:
            out[key] = value * time
        elif key in JERK_WEIGHTS:
            out[key] = value * time**6
        else:
            out[key] = value
    return out


def time_keys(options: Mapping[str, Any]) -> bool:
    """True if ``options`` hold a duration (what the speed fit stretches)."""
    for key, value in options.items():
        if key in TIMES:
            return True
        if is_dataclass(value) and not isinstance(value, type):
            if time_keys({f.name: getattr(value, f.name) for f in fields(value)}):
                return True
    return False


def max_turn(foot_length: float, foot_width: float, gap: float) -> float:
    """The largest turn (rad) between two side-by-side feet ``gap`` apart (inner edges) that
    keeps them apart: a ``length x width`` rectangle turned by θ about its centre reaches
    ``(width cos θ + length sin θ) / 2`` toward the other foot."""
    lo, hi = 0.0, math.pi / 2
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        reach = 0.5 * (foot_width * math.cos(mid) + foot_length * math.sin(mid))
        lo, hi = (mid, hi) if reach - 0.5 * foot_width < gap else (lo, mid)
    return lo


def sized(
    robot: Any,
    defaults: Mapping[str, Any],
    stated: Mapping[str, Any],
    leg: float,
    foot: tuple[float, float],
    build: Callable[[dict[str, Any]], Any],
    fit_speed: bool = True,
    gap: float = math.inf,
    fit_torque: bool = False,
) -> tuple[Any, dict[str, Any]]:
    """Build a reference with ``defaults`` sized to a robot whose hip-to-ankle length is
    ``leg`` and foot ``foot = (length, width)``, ``stated`` (robot.toml) on top; then, if
    ``fit_speed`` and the robot states no timing, stretch the durations until no joint is
    asked for more than :data:`SPEED_FRACTION` of its speed, and if that is not enough lower
    the swing (:func:`fit_swing`) unless the robot states it. ``gap``: between the feet's inner
    edges at the start; a turn per step is kept within 90 % of what it allows with the
    clearance (:func:`max_turn`); ``fit_torque``: then shorten the steps to the stall torque
    (:func:`fit_torque_share`). Returns (reference, options)."""
    # (rounded: the robot the defaults were tuned on gets exactly 1)
    along, across = leg_ratio(leg), round(foot[1] / DESIGN_FOOT_WIDTH, 9)
    time = math.sqrt(along)
    own = {k: v for k, v in defaults.items() if k not in stated}
    if "turn" in own:
        clearance = stated.get("min_clearance", own.get("min_clearance", 0.0) * across)
        room = max(gap - clearance, 0.0)
        own["turn"] = math.copysign(min(abs(own["turn"]), 0.9 * max_turn(*foot, room)), own["turn"])
    options = {**scale_options(own, along, across, time), **stated}
    ref = build(options)
    if fit_speed and time_keys(own) and not any(k in stated for k in ("timing", *TIMES)):
        ref, options, report = _fit_speed(
            robot, ref, options, own, stated, along, across, time, build
        )
        if "swing" not in stated:
            ref, options = fit_swing(robot, ref, options, build, report)
    if fit_torque:
        ref, options = fit_torque_share(robot, ref, options, stated, build)
    return ref, options


def _fit_speed(
    robot: Any,
    ref: Any,
    options: dict[str, Any],
    own: dict[str, Any],
    stated: Mapping[str, Any],
    along: float,
    across: float,
    time: float,
    build: Callable[[dict[str, Any]], Any],
) -> tuple[Any, dict[str, Any], Any]:
    """The speed fit of :func:`sized`: stretch the durations of ``own`` (×``time`` so far).
    Returns (reference, options, the reference's feasibility report, or None if the last
    stretched reference was not measured)."""
    from .feasibility import kinematic_feasibility

    last = math.inf
    report = None
    for _ in range(FIT_ROUNDS):
        report = kinematic_feasibility(robot, ref, iterations=2, torques=False)
        share = report.speed_fraction
        # done; or a reference the legs cannot track (the IK's jumps are no servo speed); or
        # a speed that slowing down does not lower
        untracked = max(report.max_com_error, report.max_sole_error) > TRACKED
        if not share > SPEED_FRACTION or untracked or share > 0.9 * last:
            break
        last = share
        good = time
        time *= min(1.05 * share / SPEED_FRACTION, MAX_STRETCH)
        for _ in range(3):  # a slower walk sways further: it may leave what the hips allow
            try:
                trial = {**scale_options(own, along, across, time), **stated}
                ref, options, report = build(trial), trial, None
                break
            except TrajectoryError:
                time = 0.5 * (good + time)  # the slowest timing that still builds
        else:
            break
    return ref, options, report


def _swing_of(options: Mapping[str, Any]) -> Any:
    """The swing sole's settings the swing fit changes: a ``swing``
    (:class:`~wbc.walking.schedule.SwingParams`), else None."""
    swing = options.get("swing")
    return swing if hasattr(swing, "apex") and hasattr(swing, "profile") else None


def fit_swing(
    robot: Any,
    ref: Any,
    options: dict[str, Any],
    build: Callable[[dict[str, Any]], Any],
    report: Any = None,
) -> tuple[Any, dict[str, Any]]:
    """Step 2 of the speed fit (module docstring): if ``ref`` (``report``: its feasibility,
    measured here if None) asks a joint for more than :data:`SPEED_FRACTION` of its speed,
    the swing of ``options`` (:func:`_swing_of`) takes the cubic profile, then the highest
    apex (secant steps on the measured share, :data:`FIT_ROUNDS` + 1 at most, not below
    :data:`MIN_APEX` of the sized apex) within the share. The first swing within it is
    kept; else the one asking least, if it asks less than ``ref``. A reference the legs
    cannot track (errors above :data:`TRACKED`) is kept as it is."""
    from .feasibility import kinematic_feasibility

    def measure(r: Any) -> Any:
        return kinematic_feasibility(robot, r, iterations=2, torques=False)

    report = report or measure(ref)
    swing = _swing_of(options)
    if not report.speed_fraction > SPEED_FRACTION or swing is None:
        return ref, options
    if max(report.max_com_error, report.max_sole_error) > TRACKED:
        return ref, options
    best = (report.speed_fraction, ref, options)
    floor = MIN_APEX * swing.apex
    # (apex, share) pairs measured with the cubic profile: the secant's two last
    tried: list[tuple[float, float]] = []
    apex = swing.apex
    for _ in range(FIT_ROUNDS + 1):
        trial = {**options, "swing": replace(swing, profile="cubic", apex=apex)}
        try:
            r = build(trial)
        except TrajectoryError:
            break
        share = measure(r).speed_fraction
        tried.append((apex, share))
        if share < best[0]:
            best = (share, r, trial)
        if not share > SPEED_FRACTION or apex <= floor:
            break
        aim = SWING_AIM * SPEED_FRACTION
        if len(tried) < 2 or tried[-2][1] == share:
            apex *= aim / share  # as if the share were the apex's alone
        else:
            (a0, s0), (a1, s1) = tried[-2:]
            apex = a1 + (aim - s1) * (a0 - a1) / (s0 - s1)
        apex = max(floor, min(apex, tried[-1][0]))
    return best[1], best[2]


def fit_torque_share(
    robot: Any,
    ref: Any,
    options: dict[str, Any],
    stated: Mapping[str, Any],
    build: Callable[[dict[str, Any]], Any],
) -> tuple[Any, dict[str, Any]]:
    """Shorten the unstated :data:`STRIDES` of ``options`` (×:data:`SHRINK` a round, at most
    :data:`FIT_ROUNDS` rounds) until the predicted peak joint torque of ``ref``
    (:attr:`~wbc.walking.feasibility.FeasibilityReport.torque_fraction`) is at most
    :data:`TORQUE_FRACTION` of stall; the first reference that fits is kept, else the one
    with the lowest peak if it is lower by a hundredth, else ``ref``. A reference the legs
    cannot track (errors above :data:`TRACKED`) is kept as it is."""
    from .feasibility import kinematic_feasibility

    keys = [k for k in STRIDES if k in options and k not in stated and options[k]]
    report = kinematic_feasibility(robot, ref, iterations=2)
    first = report.torque_fraction
    best = (first, ref, options)
    if not keys or max(report.max_com_error, report.max_sole_error) > TRACKED:
        return ref, options
    scale = 1.0
    for _ in range(FIT_ROUNDS):
        if not best[0] > TORQUE_FRACTION:
            break
        scale *= SHRINK
        trial = {**options, **{k: options[k] * scale for k in keys}}
        try:
            shorter = build(trial)
        except TrajectoryError:
            break
        report = kinematic_feasibility(robot, shorter, iterations=2)
        if max(report.max_com_error, report.max_sole_error) > TRACKED:
            break
        if report.torque_fraction < best[0]:
            best = (report.torque_fraction, shorter, trial)
    if best[0] > TORQUE_FRACTION and best[0] > first - 0.01:
        return ref, options  # shortening does not lower it: the stance leg's static load
    return best[1], best[2]
