"""Support polygon of the soles in contact, and the CoM-in-polygon constraint."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..geometry import (
    FOOT_LENGTH,
    FOOT_WIDTH,
    convex_hull,
    halfplanes,
    sole_corners,
    world_corners,
)
from ..model import Kinematics, Robot
from .limit import Constraint, Inequality


class SupportPolygon:
    """Convex hull of the soles in contact (foot rectangles), as vertices and half-spaces."""

    def __init__(self, vertices: np.ndarray, margin: float = 0.0) -> None:
        self.vertices = np.asarray(vertices, dtype=float)
        self.margin = margin
        self.A, self.b = halfplanes(self.vertices, margin)

    @classmethod
    def from_soles(
        cls,
        kin: Kinematics,
        sole_ids: Sequence[int],
        margin: float = 0.0,
        length: float = FOOT_LENGTH,
        width: float = FOOT_WIDTH,
    ) -> SupportPolygon:
        sole = sole_corners(length, width)
        corners = np.vstack(
            [world_corners(kin.rotation(f), kin.translation(f), sole) for f in sole_ids]
        )
        return cls(convex_hull(corners[:, :2]), margin)


class ComPolygonConstraint(Constraint):
    """CoM ground projection inside the support polygon shrunk by ``margin``:

    A (c + J_c,xy Δq) <= b  ⇔  A J_c,xy Δq <= b − A c_xy.

    The polygon is rebuilt from the soles in contact on :meth:`set_support` (rows change only
    when the support changes).
    """

    def __init__(
        self,
        robot: Robot,
        soles: Sequence[str] = ("l_sole", "r_sole"),
        margin: float = 0.01,
        name: str = "com_polygon",
        length: float | None = None,
        width: float | None = None,
    ) -> None:
        super().__init__(name)
        self.robot = robot
        self.margin = margin
        # the foot rectangle: the robot's (robot.toml [feet]) unless given
        self.foot = (
            length if length is not None else robot.foot_size[0],
            width if width is not None else robot.foot_size[1],
        )
        self.polygon: SupportPolygon | None = None
        self.set_support(soles)

    def set_support(self, soles: Sequence[str]) -> None:
        """Soles in contact; the polygon is taken from their placement at the next compute."""
        self.sole_ids = [self.robot.frame_id(s) for s in soles]
        self.soles = tuple(soles)
        self.polygon = None

    def update_polygon(self, kin: Kinematics) -> SupportPolygon:
        self.polygon = SupportPolygon.from_soles(kin, self.sole_ids, self.margin, *self.foot)
        return self.polygon

    def compute(self, kin: Kinematics) -> Inequality:
        if self.polygon is None:
            self.update_polygon(kin)
        A, b = self.polygon.A, self.polygon.b
        G = A @ kin.com_jacobian[:2]
        h = b - A @ kin.com[:2]
        return Inequality(G, h)
