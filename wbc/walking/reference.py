"""The walking reference: what the control loop tracks, tick by tick.

A :class:`WalkingReference` is pre-sampled on a uniform time grid ``t`` (N,) with step
``dt``. Per tick it gives the CoM (position, velocity, acceleration), both soles' target
placements (position + yaw; soles stay flat), the torso heading, and the support schedule
(``wbc.recording.SUPPORT_DOUBLE/LEFT/RIGHT``). World frame: z up, ground at z = 0.

Stability quantities are derived, never stored twice: the ZMP of the reference CoM
(cart-table model) is

    p_xy = c_xy - c_z c''_xy / (g + c''_z),

and the support polygon at tick i is the convex hull of the foot rectangles of the soles in
contact (``foot.length x foot.width`` centred under each sole frame).
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pinocchio as pin

from ..exceptions import TrajectoryError
from ..geometry import yaw_of
from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT
from .footsteps import Footstep, FootstepPlan, Side
from .geometry import Foot, halfplanes, shrink_polygon, signed_distance, support_polygon
from .legs import LegGeometry
from .lipm import GRAVITY

Gait = Literal["static", "dynamic"]


@dataclass(frozen=True)
class StandingState:
    """Where the robot starts: CoM (3,) and both sole placements on the ground; made from a
    robot (:meth:`from_robot`), also the robot's :attr:`foot` and :attr:`legs`."""

    com: np.ndarray
    left: Footstep
    right: Footstep
    #: the robot and configuration it was measured on (:meth:`from_robot`; None: made by hand)
    robot: Any = field(default=None, repr=False, compare=False)
    q: np.ndarray | None = field(default=None, repr=False, compare=False)

    @classmethod
    def from_robot(cls, robot: Any, q: np.ndarray | None = None) -> StandingState:
        """From a robot configuration (default ``robot.configuration("stand")``)."""
        q = robot.configuration("stand") if q is None else q
        soles = {}
        for side in ("left", "right"):
            M = robot.frame_placement(q, f"{side[0]}_sole")
            yaw = yaw_of(M.rotation)
            p = M.translation
            soles[side] = Footstep(side, float(p[0]), float(p[1]), yaw, float(p[2]))
        com = np.asarray(robot.com(q), dtype=float)
        return cls(com, soles["left"], soles["right"], robot, np.array(q, dtype=float))

    @functools.cached_property
    def foot(self) -> Foot:
        """The robot's foot (:attr:`wbc.model.Robot.foot_size`), what a reference built from
        this start uses unless given one; TrajectoryError for a start made by hand."""
        return Foot(*self._robot("foot", "Foot(length, width)").foot_size)

    @functools.cached_property
    def legs(self) -> LegGeometry:
        """The robot's legs measured at the start's configuration
        (:meth:`~wbc.walking.legs.LegGeometry.from_robot`), what a reference built from this
        start uses unless given them; TrajectoryError for a start made by hand."""
        return LegGeometry.from_robot(self._robot("legs", "LegGeometry.from_robot(robot)"), self.q)

    def _robot(self, what: str, hint: str) -> Any:
        if self.robot is None:
            raise TrajectoryError(
                f"no {what} given, and the start was made by hand, not from a robot "
                f"(StandingState.from_robot): pass {what}={hint}"
            )
        return self.robot


def _no_foot() -> Foot:
    raise TrajectoryError("a walking reference needs its robot's foot: foot=Foot(*robot.foot_size)")


@dataclass
class WalkingReference:
    """Time-indexed references for a walk (all arrays have N rows, one per tick)."""

    t: np.ndarray
    com: np.ndarray
    com_vel: np.ndarray
    com_acc: np.ndarray
    l_sole: np.ndarray
    l_sole_yaw: np.ndarray
    r_sole: np.ndarray
    r_sole_yaw: np.ndarray
    support: np.ndarray
    torso_yaw: np.ndarray
    com_height: float
    plan: FootstepPlan
    gait: Gait = "dynamic"
    name: str = "walk"
    l_sole_vel: np.ndarray | None = None
    r_sole_vel: np.ndarray | None = None
    zmp_ref: np.ndarray | None = None
    foot: Foot = field(default_factory=_no_foot)  # (required: the robot's)
    margin: float = 0.0
    g: float = GRAVITY
    meta: dict[str, Any] = field(default_factory=dict)
    #: (N,) planned torso roll about the heading axis (rad; positive tilts its top to the
    #: right), on top of the start pose's own lean; None: upright (a whole-body reference
    #: leans the torso over the stance foot, :mod:`.window`)
    torso_roll: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float)
        n = self.t.size
        if self.t.ndim != 1 or n < 2:
            raise TrajectoryError(f"reference {self.name!r}: t must be 1-D with >= 2 ticks")
        dts = np.diff(self.t)
        if not np.all(np.isfinite(self.t)) or np.any(dts <= 0):
            raise TrajectoryError(f"reference {self.name!r}: t must be finite and increasing")
        if np.ptp(dts) > 1e-9 * max(1.0, dts[0]) + 1e-12:
            raise TrajectoryError(f"reference {self.name!r}: t must be uniformly sampled")
        shapes = {
            "com": (n, 3),
            "com_vel": (n, 3),
            "com_acc": (n, 3),
            "l_sole": (n, 3),
            "r_sole": (n, 3),
            "l_sole_yaw": (n,),
            "r_sole_yaw": (n,),
            "torso_yaw": (n,),
            "l_sole_vel": (n, 3),
            "r_sole_vel": (n, 3),
            "zmp_ref": (n, 2),
            "torso_roll": (n,),
        }
        for name, shape in shapes.items():
            val = getattr(self, name)
            if val is None:
                continue
            arr = np.asarray(val, dtype=float)
            if arr.shape != shape:
                raise TrajectoryError(
                    f"reference {self.name!r}: {name} has shape {arr.shape}, expected {shape}"
                )
            if not np.all(np.isfinite(arr)):
                raise TrajectoryError(f"reference {self.name!r}: {name} has non-finite values")
            setattr(self, name, arr)
        self.support = np.asarray(self.support).astype(np.int8)
        if self.support.shape != (n,):
            raise TrajectoryError(f"reference {self.name!r}: support must have shape ({n},)")
        bad = ~np.isin(self.support, (SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT))
        if np.any(bad):
            raise TrajectoryError(
                f"reference {self.name!r}: unknown support code {self.support[bad][0]} at tick "
                f"{int(np.argmax(bad))}"
            )
        if self.gait not in ("static", "dynamic"):
            raise TrajectoryError(f"reference {self.name!r}: gait must be 'static' or 'dynamic'")
        if self.l_sole_vel is None:
            self.l_sole_vel = np.gradient(self.l_sole, self.t, axis=0)
        if self.r_sole_vel is None:
            self.r_sole_vel = np.gradient(self.r_sole, self.t, axis=0)
        self._polygons: dict[tuple, np.ndarray] = {}

    # ------------------------------------------------------------------ basics
    def __len__(self) -> int:
        return self.t.size

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def footsteps(self) -> tuple[Footstep, ...]:
        return self.plan.steps

    def index_at(self, time: float) -> int:
        """The tick at or just before ``time`` (clamped to the reference)."""
        return int(np.clip(np.searchsorted(self.t, time + 1e-12, side="right") - 1, 0, self.n - 1))

    @property
    def omega(self) -> float:
        """The LIPM's natural frequency ``ω = √(g / z_c)`` (1/s)."""
        return math.sqrt(self.g / self.com_height)

    def dcm_at(self, i: int) -> np.ndarray:
        """(2,) the planned DCM at tick ``i``: ``ξ = c_xy + ċ_xy / ω``."""
        return self.com[i, :2] + self.com_vel[i, :2] / self.omega

    @property
    def zmp(self) -> np.ndarray:
        """(N, 2) ZMP of the reference CoM: ``c_xy - c_z c''_xy / (g + c''_z)``."""
        return self.com[:, :2] - self.com[:, 2:3] * self.com_acc[:, :2] / (
            self.g + self.com_acc[:, 2:3]
        )

    # ------------------------------------------------------------------ support schedule
    def swing_side(self, i: int) -> Side | None:
        """The swinging sole at tick ``i`` (``None`` in double support)."""
        s = int(self.support[i])
        return "right" if s == SUPPORT_LEFT else "left" if s == SUPPORT_RIGHT else None

    def stance_side(self, i: int) -> Side | None:
        """The single supporting sole at tick ``i`` (``None`` in double support)."""
        s = int(self.support[i])
        return "left" if s == SUPPORT_LEFT else "right" if s == SUPPORT_RIGHT else None

    def contact_sides(self, i: int) -> tuple[Side, ...]:
        """Soles in contact at tick ``i``."""
        s = int(self.support[i])
        if s == SUPPORT_DOUBLE:
            return ("left", "right")
        return ("left",) if s == SUPPORT_LEFT else ("right",)

    def in_contact(self, side: Side) -> np.ndarray:
        """(N,) bool: is ``side`` in contact at each tick."""
        swing = SUPPORT_RIGHT if side == "left" else SUPPORT_LEFT
        return self.support != swing

    def swing_mask(self, side: Side) -> np.ndarray:
        """(N,) bool: is ``side`` the swing sole at each tick."""
        return ~self.in_contact(side)

    def phases(self) -> Iterator[tuple[int, int, int]]:
        """Runs of constant support: ``(first_tick, last_tick + 1, support_code)``."""
        change = np.flatnonzero(np.diff(self.support)) + 1
        bounds = [0, *change.tolist(), self.n]
        for a, b in itertools.pairwise(bounds):
            yield a, b, int(self.support[a])

    def support_changes(self) -> np.ndarray:
        """Ticks at which the support differs from the previous tick."""
        return np.flatnonzero(np.diff(self.support)) + 1

    # ------------------------------------------------------------------ soles
    def sole(self, side: Side) -> tuple[np.ndarray, np.ndarray]:
        """``(position (N, 3), yaw (N,))`` of a sole."""
        if side == "left":
            return self.l_sole, self.l_sole_yaw
        if side == "right":
            return self.r_sole, self.r_sole_yaw
        raise TrajectoryError(f"side must be 'left' or 'right', got {side!r}")

    def sole_velocity(self, side: Side) -> np.ndarray:
        return self.l_sole_vel if side == "left" else self.r_sole_vel

    def sole_placement(self, i: int, side: Side) -> pin.SE3:
        """The sole's target placement at tick ``i`` (flat: rotation about z only)."""
        pos, yaw = self.sole(side)
        return pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, float(yaw[i])), pos[i].copy())

    def sole_xyzquat(self, side: Side) -> np.ndarray:
        """(N, 7) sole placements as xyz + quaternion (x, y, z, w), the recording format."""
        pos, yaw = self.sole(side)
        quat = np.zeros((self.n, 4))
        quat[:, 2] = np.sin(0.5 * yaw)
        quat[:, 3] = np.cos(0.5 * yaw)
        return np.column_stack([pos, quat])

    def swing_position(self) -> np.ndarray:
        """(N, 3) position of the swinging sole; NaN in double support."""
        out = np.full((self.n, 3), np.nan)
        left = self.support == SUPPORT_RIGHT
        right = self.support == SUPPORT_LEFT
        out[left] = self.l_sole[left]
        out[right] = self.r_sole[right]
        return out

    # ------------------------------------------------------------------ support polygons
    def _key(self, i: int) -> tuple:
        sides = self.contact_sides(i)
        key: list[Any] = []
        for side in sides:
            pos, yaw = self.sole(side)
            key += [
                side,
                round(float(pos[i, 0]), 9),
                round(float(pos[i, 1]), 9),
                round(float(yaw[i]), 9),
            ]
        return tuple(key)

    def support_polygon(self, i: int, margin: float = 0.0) -> np.ndarray:
        """(M, 2) counter-clockwise support polygon at tick ``i`` shrunk by ``margin`` (m)."""
        key = self._key(i)
        poly = self._polygons.get(key)
        if poly is None:
            poly = support_polygon(
                int(self.support[i]),
                self.l_sole[i, :2],
                float(self.l_sole_yaw[i]),
                self.r_sole[i, :2],
                float(self.r_sole_yaw[i]),
                self.foot,
            )
            self._polygons[key] = poly
        return shrink_polygon(poly, margin) if margin else poly.copy()

    def support_halfplanes(self, i: int, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``A p <= b`` form of the support polygon at tick ``i`` shrunk by ``margin``."""
        return halfplanes(self.support_polygon(i), margin)

    def signed_distance(self, i: int, point: np.ndarray) -> float:
        """Signed distance (m) of a point to the support polygon at tick ``i`` (> 0 inside)."""
        return float(signed_distance(self.support_polygon(i), np.asarray(point, float)[:2]))

    def margins(self, points: np.ndarray) -> np.ndarray:
        """(N,) signed distance of ``points[i]`` (N, >=2) to the support polygon at tick i."""
        pts = np.asarray(points, dtype=float)[:, :2]
        out = np.empty(self.n)
        groups: dict[tuple, list[int]] = {}
        for i in range(self.n):
            groups.setdefault(self._key(i), []).append(i)
        for idx in groups.values():
            out[idx] = signed_distance(self.support_polygon(idx[0]), pts[idx])
        return out

    def com_margin(self) -> np.ndarray:
        """(N,) signed distance of the CoM's ground projection to the support polygon."""
        return self.margins(self.com)

    def zmp_margin(self) -> np.ndarray:
        """(N,) signed distance of the reference ZMP to the support polygon."""
        return self.margins(self.zmp)

    def stability_margin(self) -> np.ndarray:
        """The margin the gait relies on: CoM (static gait) or ZMP (dynamic gait)."""
        return self.com_margin() if self.gait == "static" else self.zmp_margin()

    # ------------------------------------------------------------------ export
    def to_channels(self) -> dict[str, np.ndarray]:
        """Reference channels for a :class:`wbc.recording.Recording` (``*_ref`` names)."""
        ch = {
            "com_ref": self.com.copy(),
            "zmp_ref": self.zmp,
            "swing_ref": self.swing_position(),
            "l_sole_ref": self.sole_xyzquat("left"),
            "r_sole_ref": self.sole_xyzquat("right"),
            "support": self.support.copy(),
            "torso_yaw_ref": self.torso_yaw.copy(),
        }
        if self.torso_roll is not None:
            ch["torso_roll_ref"] = self.torso_roll.copy()
        return ch

    def torso_rotations(self, start_lean: np.ndarray | None = None) -> np.ndarray:
        """(N, 3, 3) torso rotations asked for: ``Rz(yaw) Rx(roll) L`` with ``L`` the start
        pose's lean (its rotation with the heading removed; identity if None)."""
        L = np.eye(3) if start_lean is None else np.asarray(start_lean, dtype=float)
        roll = np.zeros(self.n) if self.torso_roll is None else self.torso_roll
        cy, sy = np.cos(self.torso_yaw), np.sin(self.torso_yaw)
        cr, sr = np.cos(roll), np.sin(roll)
        R = np.zeros((self.n, 3, 3))
        # Rz(yaw) @ Rx(roll)
        R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = cy, -sy * cr, sy * sr
        R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = sy, cy * cr, -cy * sr
        R[:, 2, 1], R[:, 2, 2] = sr, cr
        return R @ L

    def describe(self) -> dict[str, Any]:
        """JSON-able summary for recording metadata."""
        return {
            "name": self.name,
            "gait": self.gait,
            "dt": self.dt,
            "duration": self.duration,
            "ticks": self.n,
            "com_height": self.com_height,
            "n_steps": len(self.plan.steps),
            "margin": self.margin,
            **self.meta,
        }
