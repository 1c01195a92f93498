"""Checks on a walking reference, run before any motion is produced (issue 5, item 5).

:func:`check_reference` raises :class:`~wbc.exceptions.TrajectoryError` naming the first
problem and the tick where it happens:

* stability: the CoM (static gait) or the ZMP (dynamic gait) inside the support polygon
  with the configured margin;
* ground: no sole below the ground; soles in contact stay put on the ground;
* feet: the two foot rectangles (yaw included) keep a minimum clearance at every tick;
* legs: every hip-to-ankle distance within the leg's reach, and every leg's frontal lean
  (its hip roll, torso upright) within the hip roll limits (:class:`LegGeometry`).

Hip positions are estimated from the CoM and the soles with a linear pelvis model measured
at Walk Ready (:class:`LegGeometry`). It is an approximation, so the bounds keep margins;
:mod:`.feasibility` tracks a reference with a bounded whole-body IK as the real judge.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..exceptions import TrajectoryError
from .footsteps import CLEARANCE_TOL
from .geometry import polygon_distance
from .legs import LegGeometry

if TYPE_CHECKING:
    from .reference import WalkingReference
    from .window import BalanceWindow


@dataclass(frozen=True)
class CheckReport:
    """Worst values found by :func:`check_reference` (m): all passed if it was returned."""

    stability_margin: float
    com_margin: float
    zmp_margin: float
    foot_clearance: float
    min_sole_height: float
    max_leg_length: float
    min_leg_length: float
    max_adduction: float
    max_contact_slip: float
    #: whole-body references: smallest distance (m) of the CoM's lateral offset to the edge
    #: of the balance window (NaN: a legs-only reference, checked by the hip roll model)
    window_margin: float = float("nan")

    def as_dict(self) -> dict[str, float]:
        return dict(self.__dict__)


def check_reference(
    ref: WalkingReference,
    margin: float | None = None,
    min_clearance: float = 0.005,
    legs: LegGeometry | None = None,
    ground_tolerance: float = 1e-6,
    slip_tolerance: float = 1e-6,
    check_reach: bool = True,
    window: BalanceWindow | None = None,
) -> CheckReport:
    """Check a reference before motion; raise :class:`TrajectoryError` on the first failure.

    ``margin`` defaults to the reference's own (``ref.margin``). The stability criterion is
    the CoM for a static gait and the ZMP for a dynamic one.

    ``window``: a whole-body reference (torso lean planned, arms free): the legs-only hip
    roll and reach estimates (torso upright) do not apply; instead the CoM's lateral offset
    from the soles' midpoint (heading frame) must stay inside the whole-body balance window
    (:class:`~wbc.walking.window.BalanceWindow`), whose solves hold every joint limit.
    """
    margin = ref.margin if margin is None else margin
    if not (np.isfinite(margin) and margin >= 0):
        raise TrajectoryError(f"{ref.name}: the stability margin must be >= 0, got {margin}")
    if legs is None:
        raise TrajectoryError(
            f"{ref.name}: no legs to check against: pass legs=LegGeometry.from_robot(robot)"
        )
    t = ref.t

    def at(i: int) -> str:
        return f"{ref.name}: tick {i} (t = {t[i]:.3f} s, support {_support_name(ref, i)})"

    com_m = ref.com_margin()
    zmp_m = ref.zmp_margin()
    stab = com_m if ref.gait == "static" else zmp_m
    i = int(np.argmin(stab))
    if stab[i] < margin - 1e-9:
        what = "CoM" if ref.gait == "static" else "ZMP"
        raise TrajectoryError(
            f"{at(i)}: the {what} is {stab[i] * 1000:.2f} mm inside the support polygon "
            f"(negative = outside), less than the {margin * 1000:.1f} mm margin"
        )

    heights = np.minimum(ref.l_sole[:, 2], ref.r_sole[:, 2])
    i = int(np.argmin(heights))
    if heights[i] < -ground_tolerance:
        raise TrajectoryError(f"{at(i)}: a sole goes {-heights[i] * 1000:.2f} mm below the ground")

    slip = 0.0
    for side in ("left", "right"):
        pos, yaw = ref.sole(side)
        contact = ref.in_contact(side)
        both = contact[1:] & contact[:-1]
        move = np.linalg.norm(np.diff(pos, axis=0), axis=1) + np.abs(np.diff(yaw)) * 0.05
        move = np.where(both, move, 0.0)
        j = int(np.argmax(move))
        slip = max(slip, float(move[j]))
        if move[j] > slip_tolerance:
            raise TrajectoryError(
                f"{at(j + 1)}: the {side} sole moves {move[j] * 1000:.3f} mm while in contact"
            )
        lifted = contact & (pos[:, 2] > 0.002)
        if np.any(lifted):
            j = int(np.argmax(lifted))
            raise TrajectoryError(
                f"{at(j)}: the {side} sole is in contact but {pos[j, 2] * 1000:.1f} mm above "
                "the ground"
            )

    clearance = _foot_clearances(ref)
    i = int(np.argmin(clearance))
    if clearance[i] < min_clearance - CLEARANCE_TOL:
        raise TrajectoryError(
            f"{at(i)}: the feet are {clearance[i] * 1000:.1f} mm apart (overlap if negative), "
            f"less than the {min_clearance * 1000:.1f} mm clearance"
        )

    lengths = legs.leg_lengths(ref.com, ref.torso_yaw, ref.l_sole, ref.r_sole)
    window_margin = float("nan")
    if window is not None:
        lateral = lateral_offsets(ref)
        slack = window.max_lateral - np.abs(lateral)
        i = int(np.argmin(slack))
        window_margin = float(slack[i])
        if slack[i] < -1e-9:
            raise TrajectoryError(
                f"{at(i)}: unreachable — the CoM is {abs(lateral[i]) * 1000:.1f} mm sideways "
                f"from the soles' midpoint, beyond the whole body's balance window of "
                f"{window.max_lateral * 1000:.1f} mm (torso lean up to "
                f"{np.rad2deg(window.max_lean):.1f} deg)"
            )
        check_reach = False
    if check_reach:
        i, j = np.unravel_index(int(np.argmax(lengths)), lengths.shape)
        if lengths[i, j] > legs.max_reach:
            raise TrajectoryError(
                f"{at(int(i))}: unreachable — the {('left', 'right')[j]} ankle is "
                f"{lengths[i, j] * 1000:.1f} mm from its hip, beyond the leg reach of "
                f"{legs.max_reach * 1000:.1f} mm"
            )
        i, j = np.unravel_index(int(np.argmin(lengths)), lengths.shape)
        if lengths[i, j] < legs.min_reach:
            raise TrajectoryError(
                f"{at(int(i))}: the {('left', 'right')[j]} ankle is {lengths[i, j] * 1000:.1f} "
                f"mm from its hip, closer than the legs can fold ({legs.min_reach * 1000:.1f} mm)"
            )
    rolls = legs.leg_rolls(ref.com, ref.torso_yaw, ref.l_sole, ref.r_sole)
    if check_reach:
        add_limit = legs.max_adduction - legs.roll_margin
        i, j = np.unravel_index(int(np.argmin(rolls)), rolls.shape)
        if -rolls[i, j] > add_limit + 1e-9:
            raise TrajectoryError(
                f"{at(int(i))}: unreachable — the {('left', 'right')[j]} hip would roll "
                f"{-rolls[i, j]:.4f} rad toward the other leg, beyond its "
                f"{legs.max_adduction:.4f} rad limit less a {legs.roll_margin:.4f} rad safety: "
                "the CoM goes too far sideways for the hips (keep the ZMP/CoM nearer the "
                "mid-stance)"
            )
        abd_limit = legs.max_abduction - legs.roll_margin
        i, j = np.unravel_index(int(np.argmax(rolls)), rolls.shape)
        if rolls[i, j] > abd_limit + 1e-9:
            raise TrajectoryError(
                f"{at(int(i))}: unreachable — the {('left', 'right')[j]} hip would roll "
                f"{rolls[i, j]:.3f} rad outward, beyond its {legs.max_abduction:.3f} rad limit"
            )
    return CheckReport(
        stability_margin=float(np.min(stab)),
        com_margin=float(np.min(com_m)),
        zmp_margin=float(np.min(zmp_m)),
        foot_clearance=float(np.min(clearance)),
        min_sole_height=float(np.min(heights)),
        max_leg_length=float(np.max(lengths)),
        min_leg_length=float(np.min(lengths)),
        max_adduction=float(-np.min(rolls)),
        max_contact_slip=slip,
        window_margin=window_margin,
    )


def _heading_left(ref: WalkingReference) -> np.ndarray:
    """(N, 2) the torso heading frame's left axis in the ground plane."""
    return np.column_stack([-np.sin(ref.torso_yaw), np.cos(ref.torso_yaw)])


def lateral_offsets(ref: WalkingReference) -> np.ndarray:
    """(N,) the CoM's lateral offset (m, + = left) from the midpoint of the two soles, in
    the torso heading frame: what the whole-body balance window bounds."""
    mid = 0.5 * (ref.l_sole[:, :2] + ref.r_sole[:, :2])
    return np.einsum("ij,ij->i", ref.com[:, :2] - mid, _heading_left(ref))


def sole_half_widths(ref: WalkingReference) -> np.ndarray:
    """(N,) half the soles' lateral separation (m, left minus right) in the torso heading
    frame: the stance width :func:`lateral_offsets` are measured across."""
    return 0.5 * np.einsum("ij,ij->i", ref.l_sole[:, :2] - ref.r_sole[:, :2], _heading_left(ref))


def _support_name(ref: WalkingReference, i: int) -> str:
    from ..recording import SUPPORT_NAMES

    return SUPPORT_NAMES.get(int(ref.support[i]), "?")


def _foot_clearances(ref: WalkingReference) -> np.ndarray:
    """(N,) distance between the two foot rectangles (ground projection, yaw included)."""
    out = np.empty(ref.n)
    cache: dict[tuple, float] = {}
    for i in range(ref.n):
        key = tuple(
            np.round(
                [*ref.l_sole[i, :2], ref.l_sole_yaw[i], *ref.r_sole[i, :2], ref.r_sole_yaw[i]], 9
            )
        )
        d = cache.get(key)
        if d is None:
            d = polygon_distance(
                ref.foot.rectangle(ref.l_sole[i], ref.l_sole_yaw[i]),
                ref.foot.rectangle(ref.r_sole[i], ref.r_sole_yaw[i]),
            )
            cache[key] = d
        out[i] = d
    return out
