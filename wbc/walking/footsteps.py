"""Footstep plans: where each sole lands, in order, with alternating support.

A :class:`FootstepPlan` holds the two soles' start placements and the sequence of steps;
step k lifts the sole ``steps[k].side`` while the other sole supports the robot, and puts it
down at ``(x, y, yaw)`` on the ground (soles stay flat). :func:`plan_footsteps` makes
forward, backward, lateral, turning (or any mix) walks from a per-step stride.
:meth:`FootstepPlan.validate` rejects plans that cannot be walked: non-alternating sides,
crossing or colliding feet (on landing and along the swing), too large turns, and steps the
legs cannot reach at the requested CoM height (see :class:`wbc.walking.legs.LegGeometry`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from ..exceptions import TrajectoryError
from ..geometry import mean_angle, relative_pose, wrap_angle
from .geometry import Foot, polygon_distance, rot2

if TYPE_CHECKING:
    from .legs import LegGeometry

Side = Literal["left", "right"]
SIDES: tuple[Side, Side] = ("left", "right")


def other_side(side: Side) -> Side:
    """``"right"`` for ``"left"`` and vice versa."""
    return "right" if side == "left" else "left"


def _check_side(side: str, what: str) -> None:
    if side not in SIDES:
        raise TrajectoryError(f"{what}: side must be 'left' or 'right', got {side!r}")


#: how far below a minimum clearance a gap may compute and still meet it (m): a float
#: round-off (5 mm apart computed as 0.0049999999999999975 m), not a gap
CLEARANCE_TOL = 1e-9


@dataclass(frozen=True)
class Footstep:
    """A flat sole placement on the ground: ``side``, position ``x, y`` (m), heading ``yaw``."""

    side: Side
    x: float
    y: float
    yaw: float = 0.0
    z: float = 0.0

    def __post_init__(self) -> None:
        _check_side(self.side, "footstep")
        vals = (self.x, self.y, self.yaw, self.z)
        if not all(np.isfinite(v) for v in vals):
            raise TrajectoryError(f"footstep ({self.side}) has non-finite values {vals}")

    @property
    def xy(self) -> np.ndarray:
        return np.array([self.x, self.y])

    @property
    def position(self) -> np.ndarray:
        return np.array([self.x, self.y, self.z])

    def relative_to(self, other: Footstep) -> np.ndarray:
        """``(dx, dy, dyaw)`` of this placement in the frame of ``other``."""
        return relative_pose((other.x, other.y, other.yaw), (self.x, self.y, self.yaw))


@dataclass(frozen=True)
class FootstepPlan:
    """Start placements of both soles and the ordered steps (alternating sides)."""

    start_left: Footstep
    start_right: Footstep
    steps: tuple[Footstep, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if self.start_left.side != "left" or self.start_right.side != "right":
            raise TrajectoryError("footstep plan: start_left/start_right have the wrong sides")
        object.__setattr__(self, "steps", tuple(self.steps))

    def __len__(self) -> int:
        return len(self.steps)

    def placements(self) -> list[tuple[Footstep, Footstep]]:
        """``(left, right)`` placements before step 0, after step 0, ..., after the last."""
        cur = {"left": self.start_left, "right": self.start_right}
        out = [(cur["left"], cur["right"])]
        for s in self.steps:
            cur[s.side] = s
            out.append((cur["left"], cur["right"]))
        return out

    def swing_from(self, k: int) -> Footstep:
        """Where the sole moved by step ``k`` starts from."""
        left, right = self.placements()[k]
        return left if self.steps[k].side == "left" else right

    def stance(self, k: int) -> Footstep:
        """The supporting sole during step ``k``."""
        left, right = self.placements()[k]
        return right if self.steps[k].side == "left" else left

    def validate(
        self,
        foot: Foot | None = None,
        legs: LegGeometry | None = None,
        com_height: float | None = None,
        min_clearance: float = 0.005,
        max_relative_yaw: float = 0.6,
        swing_samples: int = 21,
    ) -> None:
        """Raise :class:`TrajectoryError` naming the first step that cannot be walked.

        Checks: sides alternate; the swing sole stays on its own side of the stance sole
        (no crossing) and the two foot rectangles keep ``min_clearance`` on landing and along
        the straight swing path (yaw interpolated); the feet's relative yaw stays within
        ``max_relative_yaw``; with ``legs`` and ``com_height``, both ankles are within the leg
        reach from the hips when the pelvis is midway between the feet.
        """
        if foot is None:
            raise TrajectoryError(
                "footstep plan: no foot to check the clearance: pass foot=Foot(*robot.foot_size)"
            )
        prev_side: str | None = None
        left0, right0 = self.start_left, self.start_right
        _check_pair(left0, right0, foot, min_clearance, max_relative_yaw, "the start placement")
        if legs is not None and com_height is not None:
            check_stance(legs, left0, right0, com_height, "the start placement")
        for k, step in enumerate(self.steps):
            if prev_side is not None and step.side == prev_side:
                raise TrajectoryError(
                    f"footstep {k}: the {step.side} sole steps twice in a row; "
                    "support must alternate"
                )
            prev_side = step.side
            stance = self.stance(k)
            start = self.swing_from(k)
            left, right = (step, stance) if step.side == "left" else (stance, step)
            what = (
                f"footstep {k} ({step.side} to x={step.x:.3f}, y={step.y:.3f}, yaw={step.yaw:.2f})"
            )
            _check_pair(left, right, foot, min_clearance, max_relative_yaw, what)
            # Along the swing: straight path with yaw interpolated (what the references do).
            for s in np.linspace(0.0, 1.0, swing_samples)[1:-1]:
                xy = (1 - s) * start.xy + s * step.xy
                yaw = start.yaw + s * (step.yaw - start.yaw)
                gap = polygon_distance(
                    foot.rectangle(xy, yaw), foot.rectangle(stance.xy, stance.yaw)
                )
                if gap < min_clearance - CLEARANCE_TOL:
                    raise TrajectoryError(
                        f"{what}: the swinging foot passes {gap * 1000:.1f} mm from the "
                        f"{stance.side} foot (minimum clearance {min_clearance * 1000:.1f} mm)"
                    )
            if legs is not None and com_height is not None:
                check_stance(legs, left, right, com_height, what)


def check_stance(
    legs: LegGeometry, left: Footstep, right: Footstep, com_height: float, what: str
) -> None:
    """Raise :class:`TrajectoryError` if, with the pelvis midway between the two soles and the
    CoM at ``com_height``, either ankle is out of the legs' reach (a step too long, too wide
    or too narrow; ``what`` names the stance in the message)."""
    mid = 0.5 * (left.position + right.position)
    com = np.array([[mid[0], mid[1], com_height]])
    heading = np.array([mean_angle(left.yaw, right.yaw)])
    # pelvis midway between the soles: undo the forward hip offset
    com[0, :2] -= (
        legs.hip_offset[0] / legs.pelvis_gain * np.array([np.cos(heading[0]), np.sin(heading[0])])
    )
    lengths = legs.leg_lengths(com, heading, left.position[None], right.position[None])[0]
    for side, d in zip(("left", "right"), lengths, strict=True):
        if d > legs.max_reach:
            raise TrajectoryError(
                f"{what}: unreachable — the {side} ankle would be {d * 1000:.1f} mm from its "
                f"hip with the pelvis midway between the feet, beyond the leg reach of "
                f"{legs.max_reach * 1000:.1f} mm; shorten the step or lower the CoM"
            )
        if d < legs.min_reach:
            raise TrajectoryError(
                f"{what}: the {side} ankle would be {d * 1000:.1f} mm from its hip, closer "
                f"than the legs can fold ({legs.min_reach * 1000:.1f} mm)"
            )


def _check_pair(
    left: Footstep, right: Footstep, foot: Foot, min_clearance: float, max_yaw: float, what: str
) -> None:
    lat = left.relative_to(right)[1]
    lat2 = -right.relative_to(left)[1]
    if lat <= 0 or lat2 <= 0:
        raise TrajectoryError(
            f"{what}: the left sole is not to the left of the right sole (crossed feet, lateral "
            f"offset {min(lat, lat2) * 1000:.1f} mm)"
        )
    gap = polygon_distance(foot.rectangle(left.xy, left.yaw), foot.rectangle(right.xy, right.yaw))
    if gap < min_clearance - CLEARANCE_TOL:
        raise TrajectoryError(
            f"{what}: the feet are {gap * 1000:.1f} mm apart (overlap if negative); minimum "
            f"clearance {min_clearance * 1000:.1f} mm"
        )
    dyaw = abs(wrap_angle(left.yaw - right.yaw))
    if dyaw > max_yaw:
        raise TrajectoryError(
            f"{what}: the feet's headings differ by {np.degrees(dyaw):.1f} deg, more than the "
            f"{np.degrees(max_yaw):.1f} deg the hip yaw joints allow"
        )


def plan_footsteps(
    start_left: Footstep,
    start_right: Footstep,
    n_steps: int,
    stride: Sequence[float] = (0.035, 0.0, 0.0),
    first_side: Side | None = None,
    close: bool = True,
) -> FootstepPlan:
    """A walk of ``n_steps`` steps advancing the body by ``stride = (dx, dy, dyaw)`` per step.

    A mid-feet frame starts between the soles; each step moves it by ``(dx, dy)`` in its own
    axes and turns it by ``dyaw``, and the swinging sole lands at half the start stance width
    to its side, heading with it. ``dx`` is the step length (distance between successive
    footprints); backward walks use ``dx < 0``, turning ``dyaw != 0``. Side-stepping
    (``dy != 0``): the leading sole lands ``dy`` further out, so the feet open to the stance
    width + 2|dy| and the trailing sole closes them back to the stance width (each moves
    2|dy| per step; the body |dy| per step). The first swing side defaults to the leading
    foot (left when moving or turning left, right otherwise, as in the thesis). With
    ``close`` the last step puts the swinging sole beside the other at the start stance
    width and heading (feet together again).
    """
    if int(n_steps) != n_steps or n_steps < 1:
        raise TrajectoryError(f"plan_footsteps: n_steps must be a positive integer, got {n_steps}")
    stride = np.asarray(stride, dtype=float)
    if stride.shape != (3,) or not np.all(np.isfinite(stride)):
        raise TrajectoryError(f"plan_footsteps: stride must be finite (dx, dy, dyaw), got {stride}")
    dx, dy, dyaw = stride
    if first_side is None:
        lead = dy if abs(dy) > 1e-12 else dyaw
        first_side = "left" if lead > 0 else "right"
    _check_side(first_side, "plan_footsteps first_side")
    yaw = 0.5 * (start_left.yaw + start_right.yaw)
    centre = 0.5 * (start_left.xy + start_right.xy)
    half_width = 0.5 * float((rot2(yaw).T @ (start_left.xy - start_right.xy))[1])
    if half_width <= 0:
        raise TrajectoryError("plan_footsteps: the start left sole is not left of the right sole")
    steps: list[Footstep] = []
    cur = {"left": start_left, "right": start_right}
    side: Side = first_side
    for k in range(int(n_steps)):
        sign = 1.0 if side == "left" else -1.0
        if close and k == n_steps - 1 and n_steps > 1:
            other = cur[other_side(side)]
            xy = other.xy + rot2(other.yaw) @ np.array([0.0, 2.0 * sign * half_width])
            step = Footstep(side, float(xy[0]), float(xy[1]), float(other.yaw))
        else:
            centre = centre + rot2(yaw) @ np.array([dx, dy])
            yaw = yaw + dyaw
            lateral = sign * half_width + (dy if sign * dy > 0 else 0.0)
            xy = centre + rot2(yaw) @ np.array([0.0, lateral])
            step = Footstep(side, float(xy[0]), float(xy[1]), float(yaw))
        steps.append(step)
        cur[side] = step
        side = other_side(side)
    return FootstepPlan(start_left, start_right, tuple(steps))
