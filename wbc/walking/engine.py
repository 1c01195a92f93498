"""An omnidirectional walk engine driven by velocity commands ``(vx, vy, ωz)``.

Where :func:`wbc.walking.gait.walk` plans a whole walk before it starts, :class:`WalkEngine`
plans it while it walks, one tick at a time (:meth:`WalkEngine.tick`):

* **footsteps, online** — at the start of every double support (and at :meth:`start`) the
  step about to be taken is planned from the *current* command, so a new command takes
  effect at the next lift-off (within one step). A walking frame moves to where the
  commanded pose (the command integrated since :meth:`start`) will be when the step lands —
  in steady walking by the command times the step time, ``(vx T, vy T, ωz T)`` in its own
  axes; after a start or a change, or short landings (leg odometry, :attr:`on_landing`), the
  displacement lost is made up in the room the velocity limits leave beside the command —
  and the swinging sole lands beside it as :func:`wbc.walking.footsteps.plan_footsteps`
  places its soles (the leading sole opens sideways, the trailing one closes; the soles head
  with the frame). Each planned step is checked by :meth:`FootstepPlan.validate` (no
  crossing, the feet's clearance along the swing, relative yaw, the legs' reach at the CoM
  height); a step that fails is shortened (halved, up to four times, then a step in place);
* **CoM, receding horizon** — the ZMP path through the planned footsteps (as
  :func:`wbc.walking.schedule.zmp_knots` lays it: onto each landed sole within ``transfer``
  of the double support, on the stance sole in single support, ``zmp_offset`` toward the
  other sole) is re-planned over the next ``horizon_steps`` steps at every step, and the
  CoM follows it by Kajita's preview control run tick by tick (:class:`PreviewController`'s
  gains; its jerk input from the ZMP error, its integral and the next second of the path);
* **swing** — the swing sole's min-jerk path to its landing with an apex
  (:func:`wbc.walking.schedule.sole_tracks` for the one step; its horizontal move and turn
  done by the last ``settle`` share of the swing, which only comes down: a sole that touches
  down early lands in place instead of dragging), the torso heading the mean of the soles',
  and, with a :class:`~wbc.walking.window.BalanceWindow`, the torso roll the whole body
  needs for the CoM's lateral offset (as the whole-body walks plan it).

Why the preview controller and not the casadi MPC: measured on the Bioloid, one receding
MPC solve of a 1.5 s window costs tens of milliseconds (``benchmarks/drive.md``), beyond a
whole control tick (10 ms at 100 Hz, ≤ 2 ms for the walk tick), while one preview tick costs
microseconds and keeps the walk's ZMP margin on the same steps.

:meth:`stop` finishes with a closing step (the soles side by side again) and brings the ZMP
back between the feet; a command of zero walks on the spot. The velocity limits
(:class:`VelocityLimits`) come from the legs and the servos: :meth:`VelocityLimits.from_robot`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..exceptions import ConfigurationError, TrajectoryError
from ..geometry import mean_angle, relative_pose, wrap_angle
from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from ..roles import SOLE_FRAMES
from .engine_params import EngineParams, VelocityLimits
from .footgaps import rectangle_gaps
from .footsteps import Footstep, FootstepPlan, Side, check_stance, other_side
from .geometry import Foot, rot2
from .legs import LegGeometry
from .preview import PreviewController
from .reference import StandingState, WalkingReference
from .schedule import Phase, sample_knots, settled_swing, sole_tracks
from .spline import min_jerk
from .window import BalanceWindow

State = Literal["standing", "walking", "stopping"]
#: m and rad: a measured landing further than this from the planned one is not believed
MAX_LANDING_ERROR = 0.03
#: rad: the largest heading difference of the two soles (:meth:`FootstepPlan.validate`'s)
MAX_RELATIVE_YAW = 0.6
SegmentKind = Literal["start", "double", "single", "end"]
#: points checked along a stance contact's move (:meth:`WalkEngine.clear_of_landing`)
SLIDE_SAMPLES = 9
#: m per rad: a finish step's miss of the commanded pose, heading against position
#: (:meth:`WalkEngine.finish_step`; 1.75 mm a degree)
FINISH_YAW_M = 0.1


@dataclass
class EngineTick:
    """What the engine asks for at one tick (world frame, ground at z = 0)."""

    t: float
    support: int  # wbc.recording.SUPPORT_DOUBLE / LEFT / RIGHT
    #: the support and swing sole frames ("l_sole"/"r_sole"); in double support those of the
    #: next single support (or of the last one when standing)
    support_frame: str
    swing_frame: str
    com: np.ndarray  # (3,)
    com_vel: np.ndarray  # (3,)
    l_sole: np.ndarray  # (3,)
    l_yaw: float
    r_sole: np.ndarray
    r_yaw: float
    torso_yaw: float
    torso_roll: float
    zmp_ref: np.ndarray  # (2,) the planned ZMP
    state: State
    new_phase: bool  # the first tick of a phase


@dataclass
class _Segment:
    kind: SegmentKind
    n: int  # ticks
    support: int
    step: Footstep | None = None  # single: where the swing sole lands; double: the next step
    lift: Footstep | None = None  # single: where it lifts from
    stance: Footstep | None = None


class WalkEngine:
    """The walk engine (module docstring). ``start`` is where the robot stands (its CoM and
    soles); ``window``: plan the whole-body torso roll (None: upright torso)."""

    def __init__(
        self,
        start: StandingState,
        params: EngineParams | None = None,
        limits: VelocityLimits | None = None,
        foot: Foot | None = None,
        legs: LegGeometry | None = None,
        window: BalanceWindow | None = None,
        com_height: float | None = None,
    ) -> None:
        self.params = (params or EngineParams()).check()
        inf = math.inf
        self.limits = (limits or VelocityLimits(inf, inf, inf, inf)).check()
        self.foot = foot or start.foot
        self.legs = legs or start.legs
        self.window = window
        timing = self.params.timing
        self.dt = timing.dt
        self.height = float(start.com[2]) if com_height is None else float(com_height)
        self.legs.check_com_height(self.height, "walk engine")
        FootstepPlan(start.left, start.right).validate(
            self.foot, self.legs, self.height, self.params.min_clearance
        )
        self.feet: dict[Side, Footstep] = {"left": start.left, "right": start.right}
        #: where the soles in contact are held: the planned placements, or the measured ones
        #: (:attr:`on_landing`); the steps are planned (and checked) on :attr:`feet`
        self.contact: dict[Side, Footstep] = dict(self.feet)
        self.half_width = 0.5 * float(
            (
                rot2(mean_angle(start.left.yaw, start.right.yaw)).T
                @ (start.left.xy - start.right.xy)
            )[1]
        )
        self.centre = self.mid_frame()  #: (x, y, yaw): the planned frame between the feet
        self.n_ss = max(2, round(timing.single_support_time / self.dt))
        self.n_ds = max(1, round(timing.double_support_time / self.dt))
        self.n_start = max(2, round(timing.start_time / self.dt))
        self.n_end = max(2, round(timing.end_time / self.dt))
        self.preview = PreviewController(self.dt, self.height, self.params.preview)
        self._Gp = self.preview.Gp
        self.NL = self.preview.n_preview
        self.x = np.zeros((3, 2))  # preview state [c, c', c''] per axis
        self.x[0] = start.com[:2]
        self.err = np.zeros(2)
        # the planned ZMP from absolute tick _z0 on (held at its last value beyond)
        self._z0 = 0
        self._zbuf = np.repeat(start.com[None, :2], self.NL + 2, axis=0)
        self.k = 0  # ticks done
        self.state: State = "standing"
        self._cmd = (0.0, 0.0, 0.0)
        #: the commanded pose (x, y, heading; world): the command integrated while walking
        self.pose_cmd = self.centre.copy()
        #: the commanded pose at the last :meth:`start` (x, y, heading; world)
        self.start_pose = self.pose_cmd.copy()
        self._start_requested = False
        self._stop_requested = False
        self._finishing = False  # the requested start is a finish step (:meth:`finish_step`)
        self._segments: list[_Segment] = []
        self._seg_i = 0  # tick within the current segment
        self._swing: tuple[np.ndarray, np.ndarray] | None = None  # (pos (n,3), yaw (n,))
        self._next_side: Side = "left"
        self._roles = ("l_sole", "r_sole")  # (support, swing) frames
        self.steps_taken = 0
        self.shortened = 0  # planned steps shortened to pass the checks
        self.planned: list[Footstep] = []  # every committed step, in order
        #: leg odometry: called with each landed sole at the end of the double support that
        #: follows its landing (the last tick before the other sole lifts), returns where it
        #: is (measured, e.g. from the encoders; None: as planned). The targets hold it there
        #: (:attr:`contact`) until it lifts; the steps are planned on the planned soles (with
        #: the measured ones, turning on the spot failed every step's clearance check at the
        #: limits and ran at half the commanded rate)
        self.on_landing: Callable[[Footstep], Footstep | None] | None = None
        self.landing_errors: list[float] = []  # m, |measured − planned| of each landing
        #: odometry's offset (x, y, heading; world, m and rad): where the body really is is
        #: the walking frame plus it, and the steps aim the commanded pose from there. The
        #: engine sums the measured landings' xy offsets from their plans since :meth:`start`;
        #: a caller with a better estimate (the Walker's IMU-aided odometry) overwrites it
        self.odometry_offset = np.zeros(3)
        #: the soles' midpoint measured less planned (x, y, heading; world) if a caller's
        #: odometry measures it (None: :attr:`odometry_offset` is it); a closing step aims
        #: the commanded pose from it
        self.frame_error: np.ndarray | None = None
        #: the point the command moves (x, y in the walking frame, m; default the soles'
        #: midpoint): the commanded pose is this point's, e.g. the Walker's base
        self.origin = np.zeros(2)
        #: the planned stride × this (x, y, heading; then within the limits): a caller that
        #: measures the steps falling short (compliant servos) plans them longer
        self.stride_gain = np.ones(3)

    @property
    def frame_offset(self) -> np.ndarray:
        """The walking frame's error as the commanded pose is aimed from it (x, y, heading;
        world): :attr:`frame_error` if a caller's odometry measures it, else odometry_offset."""
        return self.odometry_offset if self.frame_error is None else self.frame_error

    # ------------------------------------------------------------------ commands
    @property
    def command_velocity(self) -> tuple[float, float, float]:
        """The command in force (clipped to the limits)."""
        return self._cmd

    def command(self, vx: float, vy: float, wz: float) -> tuple[float, float, float]:
        """Set the velocity command (m/s forward and left, rad/s counter-clockwise, in the
        walking frame); returns it clipped to :attr:`limits`. Taken at the next lift-off."""
        vals = (vx, vy, wz)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
            raise ConfigurationError(f"walk command must be three finite numbers, got {vals}")
        self._cmd = self.limits.clip(float(vx), float(vy), float(wz))
        return self._cmd

    def start(self) -> None:
        """Start walking (from standing: the ZMP moves onto the first stance sole first)."""
        self._stop_requested = False
        self._finishing = False
        if self.state == "standing":
            self._start_requested = True

    def stop(self) -> None:
        """Finish with a closing step and stand (the walk ends a step or two later)."""
        if self.state == "standing":
            self._start_requested = self._finishing = False
        else:
            self._stop_requested = True

    def finish_step(self, frame_error: np.ndarray, side: Side | None = None) -> None:
        """Standing after a walk (:meth:`stop`): one more closing step of ``side``, aimed
        (as the closing step is: ``EngineParams.close_on_target``) at the commanded pose the
        walk ended with, from the walking frame's measured error ``frame_error`` (x, y,
        heading; world: the soles' midpoint measured less planned, :attr:`frame_error`) —
        a walker's finish step, the closing step's landing (which no later step measures)
        found off. A start phase, the step, the end phase; the commanded pose kept. ``side``
        None: the sole whose step ends nearer it (m + ``FINISH_YAW_M`` × rad)."""
        if self.state != "standing" or not self.params.close_on_target:
            raise ConfigurationError(
                "walk engine: a finish step is taken standing, with close_on_target on"
            )
        if side is not None and side not in ("left", "right"):
            raise ConfigurationError(f"walk engine: a finish step's side is left or right, "
                                     f"got {side!r}")  # fmt: skip
        error = np.asarray(frame_error, dtype=float)
        if error.shape != (3,) or not np.all(np.isfinite(error)):
            raise ConfigurationError(f"walk engine: frame_error must be 3 finite numbers, "
                                     f"got {frame_error}")  # fmt: skip
        self.frame_error = error.copy()
        if side is None:
            want = self.commanded_frame() - error

            def miss(s: Side) -> float:
                frame, _ = self._closing(self.feet, s, on_target=True)
                d = want - frame
                return float(np.hypot(*d[:2]) + FINISH_YAW_M * abs(wrap_angle(d[2])))

            side = min(("left", "right"), key=miss)
        self._next_side = side
        self._start_requested = self._stop_requested = self._finishing = True

    @property
    def starting(self) -> bool:
        """A start (or a finish step) asked for, taken at the next tick."""
        return self._start_requested

    def commanded_frame(self) -> np.ndarray:
        """The walking frame's commanded pose (x, y, heading; world): pose_cmd less the origin."""
        want = self.pose_cmd.copy()
        want[:2] -= rot2(want[2]) @ self.origin
        return want

    @property
    def walking(self) -> bool:
        return self.state != "standing"

    @property
    def ending(self) -> bool:
        """In a walk's end phase: its closing step (or a finish step) landed, the CoM settling."""
        return self.state != "standing" and self._segments[0].kind == "end"

    # ------------------------------------------------------------------ planning
    def mid_frame(self) -> np.ndarray:
        """(x, y, yaw) midway between the planned soles, heading their mean."""
        left, right = self.feet["left"], self.feet["right"]
        mid = 0.5 * (left.xy + right.xy)
        return np.array([mid[0], mid[1], mean_angle(left.yaw, right.yaw)])

    def _landing(self, centre: np.ndarray, side: Side, stride: np.ndarray) -> tuple:
        """The walking frame advanced by ``stride`` and where ``side`` lands beside it."""
        dx, dy, dyaw = stride
        c = centre[:2] + rot2(centre[2]) @ np.array([dx, dy])
        yaw = float(wrap_angle(centre[2] + dyaw))
        sign = 1.0 if side == "left" else -1.0
        lateral = sign * self.half_width + (dy if sign * dy > 0 else 0.0)
        xy = c + rot2(yaw) @ np.array([0.0, lateral])
        return np.array([c[0], c[1], yaw]), Footstep(side, float(xy[0]), float(xy[1]), yaw)

    def _closing(
        self, feet: dict[Side, Footstep], side: Side, on_target: bool = False
    ) -> tuple[np.ndarray, Footstep]:
        """The closing step of ``side`` beside the stance sole and the walking frame between
        them. ``on_target`` (``EngineParams.close_on_target``): moved so that the frame, with
        the odometry's error (:attr:`frame_error`, else :attr:`odometry_offset`), ends on the
        commanded pose (frozen at :meth:`stop`) — the whole way, half or a quarter of it,
        whichever first passes the checks with the frame's move within the velocity limits
        and the soles no closer than side by side (the feet's self-collision margin: closer,
        the standing robot's solves failed) —, not half a stride and up to a step's latency
        of the last command beyond it."""
        stance = feet[other_side(side)]
        sign = 1.0 if side == "left" else -1.0
        xy = stance.xy + rot2(stance.yaw) @ np.array([0.0, 2.0 * sign * self.half_width])
        step = Footstep(side, float(xy[0]), float(xy[1]), stance.yaw)
        if on_target and self.params.close_on_target:
            want = self.commanded_frame() - self.frame_offset
            plain = np.array([step.x, step.y, step.yaw])
            aim = 2.0 * want - np.array([stance.x, stance.y, stance.yaw])
            aim[2] = stance.yaw + 2.0 * wrap_angle(want[2] - stance.yaw)
            now = self.mid_frame()
            gap = self._gap(step, stance)  # (never closer than side by side: the feet's links)
            out = rot2(stance.yaw) @ np.array([0.0, sign])
            for scale in (1.0, 0.5, 0.25):
                x, y, yaw = plain + scale * (aim - plain)
                moved = Footstep(side, float(x), float(y), float(yaw))
                short = gap - self._gap(moved, stance)  # (a turned sole: moved outward)
                if short > 0:
                    xy = moved.xy + short * out
                    moved = Footstep(side, float(xy[0]), float(xy[1]), float(yaw))
                mid = np.r_[0.5 * (moved.xy + stance.xy), mean_angle(moved.yaw, stance.yaw)]
                stride = relative_pose(now, mid) / self.params.timing.step_time
                if (_inside(self.limits, stride) and self._gap(moved, stance) >= gap - 1e-3
                        and self._valid(feet, moved)):  # fmt: skip
                    step = moved  # (the frame's move within the velocity limits, as a step's)
                    break
        mid = 0.5 * (step.xy + stance.xy)
        return np.array([mid[0], mid[1], mean_angle(step.yaw, stance.yaw)]), step

    @property
    def landing(self) -> Footstep | None:
        """Where the swinging sole lands (its planned step) in single support, else None."""
        if self.state == "standing" or not self._segments:
            return None
        seg = self._segments[0]
        return seg.step if seg.kind == "single" else None

    def clear_of_landing(self, stance: Footstep, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """The point furthest along the straight move of the sole ``stance`` (its heading)
        from ``start`` to ``end`` (positions) that keeps the feet's ``min_clearance`` from
        :attr:`landing` all the way (``SLIDE_SAMPLES`` points; from a ``start`` closer than
        that, no closer than ``start``): a controller's stance contact moved off its plan
        (the Walker's, toward the measured sole) must not take the double support that
        follows inside the feet's margin, where two hard contacts and the feet's
        self-collision rows cannot hold together. ``end`` if nothing swings."""
        step = self.landing
        if step is None or step.side == stance.side:
            return end
        s = np.linspace(0.0, 1.0, SLIDE_SAMPLES)
        xy = start[None, :2] + s[:, None] * (end[:2] - start[:2])[None, :]
        yaw = np.full(SLIDE_SAMPLES, stance.yaw)
        gap = rectangle_gaps(xy, yaw, step.xy, step.yaw, self.foot)
        ok = np.logical_and.accumulate(gap >= min(self.params.min_clearance, gap[0]))
        k = int(np.count_nonzero(ok)) - 1  # (ok[0] holds: the last sample of the clear run)
        return end if k == SLIDE_SAMPLES - 1 else start + s[k] * (end - start)

    def _gap(self, step: Footstep, stance: Footstep) -> float:
        """The soles' gap (m) with ``step`` landed beside ``stance``."""
        xy, yaw = step.xy[None, :], np.array([step.yaw])
        return float(np.min(rectangle_gaps(xy, yaw, stance.xy, stance.yaw, self.foot)))

    def _valid(self, feet: dict[Side, Footstep], step: Footstep) -> bool:
        """Whether ``step`` can be walked from ``feet``: the checks of
        :meth:`FootstepPlan.validate` (no crossing, relative yaw, the feet's clearance on
        landing and along the straight swing, the legs' reach), vectorised over the swing's
        samples (``swing_samples``) for the control tick (tests/test_walking_engine.py: they
        agree with :meth:`~FootstepPlan.validate`)."""
        side = step.side
        stance = feet[other_side(side)]
        lift = feet[side]
        left, right = (step, stance) if side == "left" else (stance, step)
        if left.relative_to(right)[1] <= 0 or -right.relative_to(left)[1] <= 0:
            return False
        if abs(wrap_angle(left.yaw - right.yaw)) > MAX_RELATIVE_YAW:
            return False
        s = np.linspace(0.0, 1.0, self.params.swing_samples)
        xy = lift.xy[None, :] + s[:, None] * (step.xy - lift.xy)[None, :]
        yaw = lift.yaw + s * wrap_angle(step.yaw - lift.yaw)  # (the short way round)
        gap = rectangle_gaps(xy, yaw, stance.xy, stance.yaw, self.foot)
        if np.min(gap) < self.params.min_clearance:
            return False
        try:
            check_stance(self.legs, left, right, self.height, "step")
        except TrajectoryError:
            return False
        return True

    def _plan_step(
        self,
        feet: dict[Side, Footstep],
        centre: np.ndarray,
        side: Side,
        closing: bool,
        check: bool = True,
        stride: np.ndarray | None = None,
    ) -> tuple[np.ndarray, Footstep, bool]:
        """The next step of ``side`` (``stride``: the walking frame's move, default the
        command × the step time), shortened until it passes the checks (``check=False``: as
        asked, a prediction for the ZMP path only); returns (walking frame, step, shortened)."""
        if closing:
            return (*self._closing(feet, side, on_target=True), False)
        if stride is None:
            stride = np.asarray(self._cmd) * self.params.timing.step_time
        for k in range(6):
            scale = 0.5**k if k < 5 else 0.0
            new_centre, step = self._landing(centre, side, stride * scale)
            if not check or self._valid(feet, step):
                return new_centre, step, k > 0
        # in place failed too (the feet are off their nominal stance): close the feet
        return (*self._closing(feet, side), True)

    def _tracking_stride(self, ahead: float) -> np.ndarray:
        """The walking frame's move for the step landing ``ahead`` s from now: to where the
        commanded pose (the command integrated since :meth:`start`) will be then, in the
        frame's axes, within the velocity limits × the step time. In steady walking this is
        the command × the step time; after a start or a command change it recovers what the
        step latency lost, so the walk covers the commanded displacement."""
        T = self.params.timing.step_time
        target = _advance_pose(self.pose_cmd, self._cmd, ahead)
        target[:2] -= rot2(target[2]) @ self.origin  # the walking frame under that origin
        c = self.centre + self.odometry_offset  # where the body is (odometry), not planned
        v = relative_pose(c, target) / T
        cmd = np.asarray(self._cmd)
        extra = v - cmd  # the make-up, at most catch_up × the limits (diamond norm)
        lim = self.limits
        norm = sum(
            abs(e) / m if m > 0 else 0.0
            for e, m in zip(
                extra,
                (lim.vx_forward if extra[0] >= 0 else lim.vx_backward, lim.vy, lim.wz),
                strict=True,
            )
        )
        if norm > self.params.catch_up:
            extra *= self.params.catch_up / norm
        # the make-up takes only the room the limits leave beside the command: a sideways
        # make-up at the forward limit must not slow the forward walk (the largest share of
        # it inside the limits, by bisection)
        share = 1.0
        if not _inside(lim, cmd + extra):
            lo, hi = 0.0, 1.0
            for _ in range(12):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if _inside(lim, cmd + mid * extra) else (lo, mid)
            share = lo
        return np.asarray(lim.clip(*(self.stride_gain * (cmd + share * extra)))) * T

    def _replan(self, first: SegmentKind) -> None:
        """At the start of a double support (or the start phase): commit the next step from
        the command and re-plan the ZMP over the horizon."""
        p = self.params
        side = self._next_side
        closing = self._stop_requested
        n_first = self.n_start if first == "start" else self.n_ds
        stride = self._tracking_stride((n_first + self.n_ss) * self.dt)
        centre, step, short = self._plan_step(self.feet, self.centre, side, closing,
                                              stride=stride)  # fmt: skip
        self.shortened += int(short)
        stance = self.feet[other_side(side)]
        segs = [
            _Segment(first, n_first, SUPPORT_DOUBLE, step, None, stance),
            _Segment("single", self.n_ss, _single(side), step, self.feet[side], stance),
        ]
        # the horizon: the same command on (or the end), for the ZMP path only
        feet = dict(self.feet)
        feet[side] = step
        future = list(segs)
        c = centre
        s = side
        last_closing = closing
        for _ in range(p.horizon_steps - 1):
            if last_closing:
                break
            s = other_side(s)
            c, nxt, _ = self._plan_step(feet, c, s, False, check=False)
            future.append(_Segment("double", self.n_ds, SUPPORT_DOUBLE, nxt, None, feet[side]))
            future.append(
                _Segment("single", self.n_ss, _single(s), nxt, feet[s], feet[other_side(s)])
            )
            feet[s] = nxt
            side = s
        if last_closing:
            future.append(_Segment("end", self.n_end, SUPPORT_DOUBLE))
            segs.append(future[-1])
        self._commit(segs, step, centre)
        self._plan_zmp(future, feet_after=feet)

    def _commit(self, segs: list[_Segment], step: Footstep, centre: np.ndarray) -> None:
        self._segments = segs
        self._seg_i = 0
        self._pending = (step, centre)
        self.planned.append(step)
        single = segs[1]
        plan = FootstepPlan(
            *(
                (single.lift, single.stance)
                if step.side == "left"
                else (single.stance, single.lift)
            ),
            (step,),
        )
        ph = Phase("single", 0, self.n_ss, 0.0, self.n_ss * self.dt, single.support, 0)
        tracks = sole_tracks(plan, [ph], self.dt, self.params.swing)
        pos, yaw = (
            (tracks.l_pos, tracks.l_yaw) if step.side == "left" else (tracks.r_pos, tracks.r_yaw)
        )
        if self.params.settle > 0:
            pos, yaw = settled_swing(pos, yaw, single.lift, step, self.params.settle)
        self._swing = (pos, yaw)
        self._roles = (SOLE_FRAMES[other_side(step.side)], SOLE_FRAMES[step.side])

    def _measured(self, step: Footstep, landed: Footstep | None) -> Footstep:
        """Where the landed sole is held: ``landed``'s position (at most
        ``MAX_LANDING_ERROR`` m and rad from ``step``, else ``step``); the planned heading,
        height and side kept."""
        if landed is None:
            return step
        err = float(np.hypot(landed.x - step.x, landed.y - step.y))
        dyaw = abs(wrap_angle(landed.yaw - step.yaw))
        if not (err <= MAX_LANDING_ERROR and dyaw <= MAX_LANDING_ERROR):
            return step
        self.landing_errors.append(err)
        self.odometry_offset[:2] += landed.xy - step.xy
        return Footstep(step.side, landed.x, landed.y, step.yaw, step.z)

    def _anchor(self, step: Footstep) -> np.ndarray:
        ox, oy = self.params.zmp_offset
        sign = -1.0 if step.side == "left" else 1.0
        return step.xy + rot2(step.yaw) @ np.array([ox, sign * oy])

    def _plan_zmp(self, future: list[_Segment], feet_after: dict[Side, Footstep]) -> None:
        """The ZMP path (knots as :func:`wbc.walking.schedule.zmp_knots`) over ``future``,
        sampled from the current tick on into the preview's buffer."""
        p = self.params
        dt = self.dt
        z_now = self._zref(self.k)
        times, points = [0.0], [z_now]
        t = 0.0
        ramp = 8

        def ramp_to(t0: float, t1: float, a: np.ndarray, b: np.ndarray) -> None:
            s = np.linspace(0.0, 1.0, ramp + 1)[1:]
            for sj, fj in zip(s, min_jerk(s)[0], strict=True):
                times.append(t0 + sj * (t1 - t0))
                points.append(a + fj * (b - a))

        for seg in future:
            T = seg.n * dt
            if seg.kind == "start":
                hold = t + p.start_hold * T
                times.append(hold)
                points.append(z_now)
                ramp_to(hold, t + T, z_now, self._anchor(seg.stance))
            elif seg.kind == "double":
                times.append(t + p.transfer * T)
                points.append(self._anchor(seg.stance))
                times.append(t + T)
                points.append(points[-1])
            elif seg.kind == "single":
                a = self._anchor(seg.stance)
                times += [t, t + T]
                points += [a, a]
            else:  # end: to the feet's midpoint within half the phase
                mid = 0.5 * (feet_after["left"].xy + feet_after["right"].xy)
                ramp_to(t, t + 0.5 * T, points[-1], mid)
                times.append(t + T)
                points.append(mid)
            t += T
        kt, kp = np.asarray(times), np.asarray(points)
        n = max(round(t / dt), 1) + self.NL + 2
        self._zbuf = sample_knots(kt, kp, np.arange(n) * dt)
        self._z0 = self.k

    def _zref(self, k: int) -> np.ndarray:
        j = k - self._z0
        return self._zbuf[min(max(j, 0), len(self._zbuf) - 1)]

    def _window(self, k: int) -> np.ndarray:
        """The planned ZMP at ticks k+1 … k+NL (held at the buffer's last value)."""
        j = k + 1 - self._z0
        buf = self._zbuf
        if j + self.NL > len(buf):  # past the plan: drop what is done, hold the last point
            done = max(j - 1, 0)
            self._zbuf = buf = np.vstack([buf[done:], np.repeat(buf[-1:], 2 * self.NL, axis=0)])
            self._z0 += done
            j -= done
        return buf[j : j + self.NL]

    # ------------------------------------------------------------------ ticking
    def _advance_segment(self) -> bool:
        """Move to the next segment when the current one is over; True at a phase start."""
        if self.state == "standing":
            if self._start_requested:
                self._start_requested = False
                self.state = "walking"
                if self._finishing:  # one closing step more, aimed at the same pose
                    self._finishing = False
                    self.centre = self.mid_frame()
                    self._replan("start")
                    return True
                _, vy, wz = self._cmd
                lead = vy if abs(vy) > 1e-12 else wz
                self._next_side = "left" if lead > 0 else "right"
                self.centre = self.mid_frame()
                self.pose_cmd = self.centre.copy()
                self.pose_cmd[:2] += rot2(self.centre[2]) @ self.origin
                self.start_pose = self.pose_cmd.copy()
                self.odometry_offset[:] = 0.0
                self.frame_error = None
                self._replan("start")
                return True
            return False
        seg = self._segments[0]
        if self._seg_i < seg.n:
            return False
        self._segments.pop(0)
        self._seg_i = 0
        if seg.kind == "single":  # the swing sole has landed
            step, centre = self._pending
            self.feet[step.side] = self.contact[step.side] = step
            self.centre = centre
            self.steps_taken += 1
            self._next_side = other_side(step.side)
        if seg.kind == "end":
            self.state = "standing"
            self._stop_requested = False
            return True
        if not self._segments:
            if self._stop_requested:
                self.state = "stopping"
            self._replan("double")
        return True

    def advance_command(self, dt: float) -> None:
        """The commanded pose moved on by ``dt`` s of the command in force (while walking)."""
        if self.state == "walking" and not (self._stop_requested and self.params.close_on_target):
            self.pose_cmd = _advance_pose(self.pose_cmd, self._cmd, dt)

    def tick(self) -> EngineTick:
        """The targets of the next tick (the engine advances by one ``dt``)."""
        new = self._advance_segment()
        if self.on_landing is not None and self._segments:
            seg = self._segments[0]
            if seg.kind == "double" and self._seg_i == seg.n - 1 and len(self._segments) > 1:
                # the last tick before the lift-off: where the landed sole really is
                side = seg.stance.side
                self.contact[side] = self._measured(seg.stance, self.on_landing(seg.stance))
        self.advance_command(self.dt)
        k = self.k
        dt = self.dt
        left, right = self.contact["left"], self.contact["right"]
        l_pos, l_yaw, r_pos, r_yaw = left.position, left.yaw, right.position, right.yaw
        support = SUPPORT_DOUBLE
        if self.state != "standing" and self._segments:
            seg = self._segments[0]
            support = seg.support
            if seg.kind == "single" and self._swing is not None:
                pos, yaw = self._swing
                i = min(self._seg_i, len(yaw) - 1)
                if seg.step.side == "left":
                    l_pos, l_yaw = pos[i], float(yaw[i])
                else:
                    r_pos, r_yaw = pos[i], float(yaw[i])
            self._seg_i += 1
        # the CoM: one tick of preview control on the planned ZMP
        x = self.x
        zc = self.preview.C
        com_xy, vel_xy = x[0].copy(), x[1].copy()
        zmp = zc @ x
        self.err += zmp - self._zref(k)
        future = self._Gp @ self._window(k)
        u = -self.preview.Gi * self.err - self.preview.Gx @ x - future
        self.x = self.preview.A @ x + np.outer(self.preview.B, u)
        self.k += 1
        torso_yaw = mean_angle(l_yaw, r_yaw)
        roll = 0.0
        if self.window is not None:
            mid = 0.5 * (l_pos[:2] + r_pos[:2])
            lateral = float((com_xy - mid) @ np.array([-math.sin(torso_yaw), math.cos(torso_yaw)]))
            roll = float(self.window.roll_for(lateral))
        com = np.array([com_xy[0], com_xy[1], self.height])
        cv = np.array([vel_xy[0], vel_xy[1], 0.0])
        return EngineTick(
            k * dt, int(support), self._roles[0], self._roles[1], com, cv, np.array(l_pos, float),
            float(l_yaw), np.array(r_pos, float), float(r_yaw), torso_yaw, roll,
            self._zref(k).copy(), self.state, new,
        )  # fmt: skip

    def standing_reference(self) -> WalkingReference:
        """A two-tick reference of the robot standing where the engine starts (what a
        :class:`~wbc.walking.controller.Controller` is started on)."""
        left, right = self.feet["left"], self.feet["right"]
        n = 2
        com = np.tile([*self.x[0], self.height], (n, 1))
        return WalkingReference(
            t=np.arange(n) * self.dt, com=com, com_vel=np.zeros((n, 3)),
            com_acc=np.zeros((n, 3)), l_sole=np.tile(left.position, (n, 1)),
            l_sole_yaw=np.full(n, left.yaw), r_sole=np.tile(right.position, (n, 1)),
            r_sole_yaw=np.full(n, right.yaw), support=np.full(n, SUPPORT_DOUBLE),
            torso_yaw=np.full(n, mean_angle(left.yaw, right.yaw)), com_height=self.height,
            plan=FootstepPlan(left, right), name="drive", foot=self.foot,
        )  # fmt: skip


def rollout(
    engine: WalkEngine, commands: list[tuple[float, float, float, float]], settle: float = 2.0
) -> WalkingReference:
    """Run ``engine`` through ``commands`` (``(duration s, vx, vy, ωz)`` each, walking from
    the first; then :meth:`WalkEngine.stop` and ``settle`` s more) without a robot: the
    targets as a :class:`WalkingReference`, for the walks' own checks
    (:func:`wbc.walking.checks.check_reference`) and for planning."""
    rows: list[EngineTick] = []
    engine.start()
    for duration, vx, vy, wz in commands:
        engine.command(vx, vy, wz)
        for _ in range(max(1, round(duration / engine.dt))):
            rows.append(engine.tick())
    engine.stop()
    while engine.walking:
        rows.append(engine.tick())
    for _ in range(round(settle / engine.dt)):
        rows.append(engine.tick())
    n = len(rows)
    t = np.arange(n) * engine.dt
    com = np.array([r.com for r in rows])
    vel = np.array([r.com_vel for r in rows])
    acc = np.gradient(vel, t, axis=0)
    ref = WalkingReference(
        t=t, com=com, com_vel=vel, com_acc=acc, l_sole=np.array([r.l_sole for r in rows]),
        l_sole_yaw=np.array([r.l_yaw for r in rows]), r_sole=np.array([r.r_sole for r in rows]),
        r_sole_yaw=np.array([r.r_yaw for r in rows]), support=np.array([r.support for r in rows]),
        torso_yaw=np.array([r.torso_yaw for r in rows]), com_height=engine.height,
        plan=FootstepPlan(*_starts(engine, rows), tuple(engine.planned)), name="drive",
        zmp_ref=np.array([r.zmp_ref for r in rows]), foot=engine.foot,
        torso_roll=np.array([r.torso_roll for r in rows]) if engine.window else None,
    )  # fmt: skip
    return ref


def _starts(engine: WalkEngine, rows: list[EngineTick]) -> tuple[Footstep, Footstep]:
    r = rows[0]
    return (
        Footstep("left", float(r.l_sole[0]), float(r.l_sole[1]), r.l_yaw, float(r.l_sole[2])),
        Footstep("right", float(r.r_sole[0]), float(r.r_sole[1]), r.r_yaw, float(r.r_sole[2])),
    )


def _inside(limits: VelocityLimits, v: np.ndarray) -> bool:
    """Whether the velocity ``v`` is within ``limits`` (:meth:`VelocityLimits.clip` keeps it)."""
    return limits.clip(*v) == tuple(float(x) for x in v)


def _advance_pose(pose: np.ndarray, cmd: tuple[float, float, float], t: float) -> np.ndarray:
    """``pose`` (x, y, heading) moved for ``t`` s at ``cmd`` (body-frame velocities; arc)."""
    vx, vy, wz = cmd
    th = float(pose[2])
    if abs(wz) < 1e-9:
        ix, iy = math.cos(th) * t, math.sin(th) * t
    else:
        ix = (math.sin(th + wz * t) - math.sin(th)) / wz
        iy = (math.cos(th) - math.cos(th + wz * t)) / wz
    return np.array(
        [pose[0] + ix * vx - iy * vy, pose[1] + iy * vx + ix * vy, wrap_angle(th + wz * t)]
    )


def _single(side: Side) -> int:
    """The support code of the single support in which ``side`` swings."""
    return SUPPORT_RIGHT if side == "left" else SUPPORT_LEFT


__all__ = ["EngineParams", "EngineTick", "VelocityLimits", "WalkEngine", "rollout"]
