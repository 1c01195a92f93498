"""The thesis's one step (ch. 4, sec. 4.1.1): cubic splines, static gait, 100 poses.

Poses are numbered 1..n (100 by default) and evenly spaced in time. Following the thesis's
pose sequence (fig. 4.1):

* poses 1 .. ``shift_end_pose`` (30): double support, the CoM shifts over the left (support)
  sole along a clamped cubic spline through three waypoints (start, midpoint, target), at
  constant height. On the Bioloid the target cannot be the sole's centre: with the torso
  upright the stance hip may roll only 5.6 deg inward (Annex A limits), so the CoM stops
  ~30 mm short of it, only ~0.4 mm inside the foot's inner edge
  (:meth:`LegGeometry.max_com_lateral`; more if the arms swing to help);
* until ``swing_start_pose`` (40): double support, the CoM holds over the left sole;
* ``swing_start_pose`` .. n: left single support; the right sole swings forward (+x in its
  own heading) by ``step_length`` along clamped cubic splines through lift-off, apex
  (halfway, ``apex`` above the ground) and landing; the soles stay flat;
* pose n: the right sole has landed (double support) and the step ends.

The start (CoM and soles) comes from the robot (:meth:`StandingState.from_robot`), so the
defaults fit the Bioloid at Walk Ready (soles at y = +-41.4 mm, CoM ~173 mm high).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import TrajectoryError
from ..geometry import mean_angle
from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT
from .checks import check_reference
from .footsteps import Footstep, FootstepPlan
from .geometry import Foot, rot2
from .legs import LegGeometry
from .reference import StandingState, WalkingReference
from .spline import CubicSpline


@dataclass(frozen=True)
class ThesisStepParams:
    """Parameters of the thesis step (lengths in m, durations in s, poses 1-based)."""

    step_length: float = 0.03
    apex: float = 0.02
    com_height: float | None = None  # default: the start CoM height
    n_poses: int = 100
    duration: float = 3.0
    shift_end_pose: int = 30
    swing_start_pose: int = 40
    # CoM target over the left sole, in its frame; None: toward the sole centre as far as
    # the hip roll limits allow (LegGeometry.max_com_lateral; ~30 mm short on the Bioloid)
    com_target: tuple[float, float] | None = None
    margin: float = 0.0  # required CoM distance inside the support polygon

    def validate(self) -> None:
        n = self.n_poses
        if int(n) != n or n < 5:
            raise TrajectoryError(f"thesis step: n_poses must be an integer >= 5, got {n}")
        if not (np.isfinite(self.duration) and self.duration > 0):
            raise TrajectoryError(
                f"thesis step: the duration must be positive, got {self.duration}"
            )
        if not (2 <= self.shift_end_pose < self.swing_start_pose < n - 1):
            raise TrajectoryError(
                "thesis step: need 2 <= shift_end_pose < swing_start_pose < n_poses - 1, got "
                f"{self.shift_end_pose}, {self.swing_start_pose}, {n}"
            )
        if not (np.isfinite(self.step_length) and np.isfinite(self.apex) and self.apex > 0):
            raise TrajectoryError(
                f"thesis step: step_length must be finite and apex positive, got "
                f"{self.step_length}, {self.apex}"
            )
        if not self.margin >= 0:
            raise TrajectoryError(f"thesis step: margin must be >= 0, got {self.margin}")

    @property
    def dt(self) -> float:
        return self.duration / (self.n_poses - 1)

    def pose_time(self, pose: int) -> float:
        """Time (s) of a 1-based pose number."""
        return (pose - 1) * self.dt


def thesis_step(
    start: StandingState,
    params: ThesisStepParams | None = None,
    foot: Foot | None = None,
    legs: LegGeometry | None = None,
    min_clearance: float = 0.005,
    check: bool = True,
) -> WalkingReference:
    """The thesis's one step from ``start``: CoM over the left sole, then the right sole
    swings ``step_length`` forward. Checked as a static gait (CoM in the support polygon)."""
    p = params or ThesisStepParams()
    p.validate()
    foot = foot or start.foot
    legs = legs or start.legs
    height = float(start.com[2]) if p.com_height is None else float(p.com_height)
    legs.check_com_height(height, "thesis step")
    n = int(p.n_poses)
    t = np.arange(n) * p.dt
    left, right = start.left, start.right

    # CoM: start -> over the left sole (three waypoints), then held.
    target = np.empty(3)
    if p.com_target is None:
        half = 0.5 * float((rot2(left.yaw).T @ (left.xy - right.xy))[1])
        # 0.05 mm short of the limit: the check's hip estimate uses the mean heading
        reach = legs.max_com_lateral(height, half, left.z) - 5e-5
        offset = (0.0, -max(0.0, half - reach))
    else:
        offset = p.com_target
    target[:2] = left.xy + rot2(left.yaw) @ np.asarray(offset, dtype=float)
    target[2] = height
    c0 = np.asarray(start.com, dtype=float)
    t_shift = p.pose_time(p.shift_end_pose)
    com_spline = CubicSpline([0.0, 0.5 * t_shift, t_shift], [c0, 0.5 * (c0 + target), target])
    com, com_vel, com_acc = com_spline.evaluate(t)

    # Right sole: lift-off, apex, landing (three waypoints), flat, heading kept.
    landing_xy = right.xy + rot2(right.yaw) @ np.array([p.step_length, 0.0])
    landing = Footstep("right", float(landing_xy[0]), float(landing_xy[1]), right.yaw, 0.0)
    t_sw0 = p.pose_time(p.swing_start_pose)
    t_sw1 = p.pose_time(n)
    a, b = right.position, landing.position
    apex = 0.5 * (a + b)
    apex[2] = max(a[2], b[2]) + p.apex
    swing = CubicSpline([t_sw0, 0.5 * (t_sw0 + t_sw1), t_sw1], [a, apex, b])
    r_pos, r_vel, _ = swing.evaluate(t)

    support = np.full(n, SUPPORT_DOUBLE, dtype=np.int8)
    support[p.swing_start_pose - 1 : n - 1] = SUPPORT_LEFT
    l_pos = np.tile(left.position, (n, 1))
    yaw_l = np.full(n, left.yaw)
    yaw_r = np.full(n, right.yaw)
    torso = mean_angle(left.yaw, right.yaw)
    plan = FootstepPlan(left, right, (landing,))
    ref = WalkingReference(
        t=t,
        com=com,
        com_vel=com_vel,
        com_acc=com_acc,
        l_sole=l_pos,
        l_sole_yaw=yaw_l,
        r_sole=r_pos,
        r_sole_yaw=yaw_r,
        support=support,
        torso_yaw=np.full(n, torso),
        com_height=height,
        plan=plan,
        gait="static",
        name="thesis-step",
        l_sole_vel=np.zeros((n, 3)),
        r_sole_vel=r_vel,
        foot=foot,
        margin=p.margin,
        meta={
            "generator": "cubic-splines",
            "params": {k: (list(v) if isinstance(v, tuple) else v) for k, v in p.__dict__.items()},
            "poses": {"shift_end": p.shift_end_pose, "swing_start": p.swing_start_pose, "end": n},
        },
    )
    if check:
        report = check_reference(ref, margin=p.margin, min_clearance=min_clearance, legs=legs)
        ref.meta["check"] = report.as_dict()
    return ref


def thesis_lipm_step(
    start: StandingState,
    params: ThesisStepParams | None = None,
    end_time: float = 1.0,
    margin: float = 0.0,
    **walk_kwargs,
) -> WalkingReference:
    """The thesis's step with the CoM of the 3-D LIPM instead of splines (sec. 4.1.2).

    Same pose grid as :func:`thesis_step` (``dt = duration / (n_poses - 1)``): double support
    until ``swing_start_pose`` while the ZMP moves onto the left sole, then the right sole
    swings ``step_length`` forward until pose ``n_poses``; the LIPM pivots on the planned
    ZMP with its initial velocities solved per phase (:func:`.lipm.lipm_walk_com`). A
    dynamic gait needs the CoM to come to rest afterwards, so an ``end_time`` double-support
    phase follows pose ``n_poses`` (the reference has more ticks than poses). The 1.8 s
    single support brings the CoM nearly onto its ZMP, which must therefore sit where the
    hips let the CoM go: on the Bioloid only ~0.3 mm inside the stance foot (margin 0).
    """
    from .footsteps import plan_footsteps
    from .gait import walk
    from .schedule import GaitTiming, SwingParams

    p = params or ThesisStepParams()
    p.validate()
    legs = walk_kwargs.pop("legs", None) or start.legs
    height = float(start.com[2]) if p.com_height is None else float(p.com_height)
    if "zmp_offset" not in walk_kwargs:
        # a long single support brings the LIPM's CoM almost onto its ZMP: put the ZMP
        # where the hips let the CoM go, 0.1 mm further in
        half = 0.5 * float((rot2(start.left.yaw).T @ (start.left.xy - start.right.xy))[1])
        reach = legs.max_com_lateral(height, half, start.left.z) - 1e-4
        walk_kwargs["zmp_offset"] = (0.0, half - reach)
    dt = p.dt
    timing = GaitTiming(
        step_time=p.pose_time(p.n_poses) - p.pose_time(p.swing_start_pose),
        double_support_ratio=0.0,
        start_time=p.pose_time(p.swing_start_pose),
        end_time=end_time,
        dt=dt,
    )
    plan = plan_footsteps(start.left, start.right, 1, (p.step_length, 0.0, 0.0), "right")
    ref = walk(
        start,
        plan,
        timing=timing,
        swing=SwingParams(apex=p.apex, profile="cubic"),
        generator="lipm",
        com_height=p.com_height,
        margin=margin,
        legs=legs,
        name="thesis-lipm-step",
        **walk_kwargs,
    )
    ref.meta["params"] = {
        k: (list(v) if isinstance(v, tuple) else v) for k, v in p.__dict__.items()
    }
    return ref
