"""The Kokone thesis's static walk: key poses, feet flat, the hip translating (its ch. 5.4).

The thesis walks with 12 precomputed poses played 0.8 s apart: pose 1 lowers the centre of
gravity (crouch), poses 2-4 make a half step with the left foot, and poses 5-12 are a cycle
repeated at will, single and double support alternating, "the centre of mass moved towards
the support polygon by moving the hip from one side to the other and advancing". It publishes
no pose values, so they are rebuilt here (kokone-thesis.md §3.2, §7.2):

====  =========================================================================
pose  what moves (CoM = its ground projection; soles flat; torso upright)
====  =========================================================================
1     the crouch: the start state (the robot's ``stand`` pose); CoM mid-stance
2     CoM over the right sole
3     left sole lifted ``clearance`` and half a stride forward (first half step)
4     left sole down
5     CoM over the left (front) sole              ┐
6     right sole lifted, level with the left one  │
7     right sole forward, still lifted             │ the cycle (8 poses),
8     right sole down, a half stride ahead         │ repeated ``n_cycles`` times
9     CoM over the right (front) sole              │
10    left sole lifted, level with the right one   │
11    left sole forward, still lifted              │
12    left sole down, a half stride ahead          ┘
====  =========================================================================

The thesis placed the hip; here the CoM is placed, the quantity its stability rule (CoM inside
the support polygon in every pose) is about; the hip follows it with the torso upright. The
CoM goes over the stance sole's centre moved ``inset`` toward the other foot, so each key pose
keeps it ``foot.width / 2 - inset`` inside the stance foot; between poses every quantity moves
on a minimum-jerk profile over ``pose_time`` (the thesis sent each pose at once and let the
servos run). The reference is checked as a static gait (:func:`.checks.check_reference`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import TrajectoryError
from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from .checks import check_reference
from .footsteps import Footstep, FootstepPlan
from .geometry import Foot
from .legs import LegGeometry
from .reference import StandingState, WalkingReference
from .spline import min_jerk


@dataclass(frozen=True)
class KeyPoseParams:
    """Key-pose gait settings (m, s). Defaults: the thesis's hints at Kokone's scale."""

    stride: float = 0.04  # each step puts the swing sole this far ahead of where it was
    clearance: float = 0.012  # swing sole lift (thesis: 1-1.5 cm)
    inset: float = 0.005  # CoM target: stance sole centre moved this far toward the other foot
    pose_time: float = 0.8  # thesis App. A: usleep(800000) between poses
    n_cycles: int = 2
    dt: float = 0.02
    margin: float = 0.005  # required CoM distance inside the support polygon

    def validate(self) -> None:
        for name in ("stride", "clearance", "pose_time", "dt"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise TrajectoryError(f"key-pose walk: {name} must be positive, got {v}")
        if not (np.isfinite(self.inset) and self.inset >= 0 and self.margin >= 0):
            raise TrajectoryError("key-pose walk: inset and margin must be >= 0")
        if int(self.n_cycles) != self.n_cycles or self.n_cycles < 0:
            raise TrajectoryError("key-pose walk: n_cycles must be an integer >= 0")
        if self.dt > self.pose_time / 4:
            raise TrajectoryError("key-pose walk: dt must be at most pose_time / 4")


@dataclass(frozen=True)
class KeyPose:
    """One key pose: CoM ground target, both sole positions, the sole in the air (or None)."""

    com_xy: np.ndarray
    left: np.ndarray
    right: np.ndarray
    lifted: str | None


def key_poses(start: StandingState, p: KeyPoseParams) -> list[KeyPose]:
    """Poses 1..4 + 8 per cycle (see the module docstring); straight ahead of the start."""
    left, right = start.left.position.copy(), start.right.position.copy()
    if abs(start.left.yaw) > 1e-9 or abs(start.right.yaw) > 1e-9:
        raise TrajectoryError("key-pose walk: the start soles must face +x (yaw 0)")
    lift = np.array([0.0, 0.0, p.clearance])

    def over(sole: np.ndarray, other: np.ndarray) -> np.ndarray:
        d = other[:2] - sole[:2]
        inward = np.array([0.0, np.sign(d[1]) * p.inset])
        return sole[:2] + inward

    poses = [KeyPose(0.5 * (left[:2] + right[:2]), left.copy(), right.copy(), None)]  # 1
    com = over(right, left)
    poses.append(KeyPose(com, left.copy(), right.copy(), None))  # 2
    half = np.array([0.5 * p.stride, 0.0, 0.0])
    poses.append(KeyPose(com, left + half + lift, right.copy(), "left"))  # 3
    left = left + half
    poses.append(KeyPose(com, left.copy(), right.copy(), None))  # 4
    for _ in range(int(p.n_cycles)):
        for stance, swing in (("left", "right"), ("right", "left")):
            feet = {"left": left, "right": right}
            s, w = feet[stance], feet[swing]
            com = over(s, w)
            poses.append(KeyPose(com, left.copy(), right.copy(), None))  # 5 / 9
            mid = np.array([s[0], w[1], w[2]]) + lift
            ahead = w + np.array([p.stride, 0.0, 0.0])
            for pos, up in ((mid, True), (ahead + lift, True), (ahead, False)):  # 6-8 / 10-12
                feet[swing] = pos
                poses.append(
                    KeyPose(com, feet["left"].copy(), feet["right"].copy(), swing if up else None)
                )
            feet[swing] = ahead
            left, right = feet["left"], feet["right"]
    return poses


def keypose_walk(
    start: StandingState,
    params: KeyPoseParams | None = None,
    foot: Foot | None = None,
    legs: LegGeometry | None = None,
    min_clearance: float = 0.004,
    check: bool = True,
) -> WalkingReference:
    """The key-pose static walk from ``start`` as a checked :class:`WalkingReference`."""
    p = params or KeyPoseParams()
    p.validate()
    foot = foot or start.foot
    poses = key_poses(start, p)
    per = round(p.pose_time / p.dt)
    n = (len(poses) - 1) * per + 1
    t = np.arange(n) * p.dt
    height = float(start.com[2])
    com = np.zeros((n, 3))
    com_vel = np.zeros((n, 3))
    com_acc = np.zeros((n, 3))
    l_pos, r_pos = np.zeros((n, 3)), np.zeros((n, 3))
    l_vel, r_vel = np.zeros((n, 3)), np.zeros((n, 3))
    support = np.full(n, SUPPORT_DOUBLE, dtype=np.int8)
    T = per * p.dt
    s = np.arange(per) / per
    f, df, ddf = min_jerk(s)
    for k in range(len(poses) - 1):
        a, b = poses[k], poses[k + 1]
        sl = slice(k * per, (k + 1) * per)
        dc = b.com_xy - a.com_xy
        com[sl, :2] = a.com_xy + np.outer(f, dc)
        com_vel[sl, :2] = np.outer(df, dc) / T
        com_acc[sl, :2] = np.outer(ddf, dc) / T**2
        for pos, vel, pa, pb in ((l_pos, l_vel, a.left, b.left), (r_pos, r_vel, a.right, b.right)):
            pos[sl] = pa + np.outer(f, pb - pa)
            vel[sl] = np.outer(df, pb - pa) / T
        swing = a.lifted or b.lifted
        if swing is not None:
            support[sl] = SUPPORT_RIGHT if swing == "left" else SUPPORT_LEFT
    last = poses[-1]
    com[-1, :2], l_pos[-1], r_pos[-1] = last.com_xy, last.left, last.right
    com[:, 2] = height
    steps = []
    for k in range(1, len(poses)):
        if poses[k - 1].lifted is not None and poses[k].lifted is None:
            side = poses[k - 1].lifted
            x, y, z = poses[k].left if side == "left" else poses[k].right
            steps.append(Footstep(side, float(x), float(y), 0.0, float(z)))
    zeros = np.zeros(n)
    ref = WalkingReference(
        t=t,
        com=com,
        com_vel=com_vel,
        com_acc=com_acc,
        l_sole=l_pos,
        l_sole_yaw=zeros.copy(),
        r_sole=r_pos,
        r_sole_yaw=zeros.copy(),
        support=support,
        torso_yaw=zeros.copy(),
        com_height=height,
        plan=FootstepPlan(start.left, start.right, tuple(steps)),
        gait="static",
        name="keyposes",
        l_sole_vel=l_vel,
        r_sole_vel=r_vel,
        foot=foot,
        margin=p.margin,
        meta={
            "generator": "key poses (Kokone thesis ch. 5.4)",
            "params": dict(p.__dict__),
            "n_poses": len(poses),
            "key_poses": [
                {
                    "com_xy": pose.com_xy.tolist(),
                    "left": pose.left.tolist(),
                    "right": pose.right.tolist(),
                    "lifted": pose.lifted,
                }
                for pose in poses
            ],
        },
    )
    if check:
        report = check_reference(
            ref, margin=p.margin, min_clearance=min_clearance, legs=legs or start.legs
        )
        ref.meta["check"] = report.as_dict()
    return ref
