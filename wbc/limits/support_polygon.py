"""Support polygon of the soles in contact, and the CoM-in-polygon constraint."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..geometry import convex_hull, halfplanes, sole_corners, world_corners
from ..model import Kinematics, Robot
from .limit import Constraint


class SupportPolygon:
    """Convex hull of the soles in contact (foot rectangles), as vertices and half-spaces."""

    def __init__(self, vertices: np.ndarray, margin: float = 0.0) -> None:
        self.vertices = np.asarray(vertices, dtype=float)
        self.margin = margin
        A, b = halfplanes(self.vertices, margin)
        self.A = np.ascontiguousarray(A, dtype=float)
        self.b = np.ascontiguousarray(b, dtype=float)

    @classmethod
    def from_soles(
        cls,
        kin: Kinematics,
        sole_ids: Sequence[int],
        length: float,
        width: float,
        margin: float = 0.0,
    ) -> SupportPolygon:
        """The hull of ``length x width`` rectangles centred on the soles ``sole_ids`` (frame
        ids; the robot's foot: :attr:`wbc.model.Robot.foot_size`), shrunk by ``margin``."""
        sole = sole_corners(length, width)
        corners = np.vstack(
            [world_corners(kin.rotation(f), kin.translation(f), sole) for f in sole_ids]
        )
        return cls(convex_hull(corners[:, :2]), margin)


@njit(cache=True)
def com_polygon_rows(params, slots, Rs, ps, vs, supports, Jw, com, Jcom, hg, Ag, q, v, Jf, h, G):
    """The constraint kernel of :class:`ComPolygonConstraint` (the kernels' signature,
    :mod:`wbc.compiled.signature`): ``params`` = [A (k x 2, row-major), b (k)], the polygon's
    half-planes A x <= b; G = A J_c,xy and h = b − A c_xy (one row per edge)."""
    k = h.shape[0]
    A = np.ascontiguousarray(params[: 2 * k]).reshape((k, 2))
    G[:, :] = np.dot(A, np.ascontiguousarray(Jcom[:2]))
    h[:] = params[2 * k : 3 * k] - np.dot(A, np.ascontiguousarray(com[:2]))


class ComPolygonConstraint(Constraint):
    """CoM ground projection inside the support polygon shrunk by ``margin``:

    A (c + J_c,xy Δq) <= b  ⇔  A J_c,xy Δq <= b − A c_xy.

    The polygon is rebuilt from the soles in contact on :meth:`set_support` (rows change only
    when the support changes).
    """

    row_kernel = staticmethod(com_polygon_rows)
    param_fields = ("halfplanes_A", "halfplanes_b")

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
        self.polygon = SupportPolygon.from_soles(kin, self.sole_ids, *self.foot, self.margin)
        return self.polygon

    def prepare(self, kin: Kinematics) -> None:
        """The polygon of the soles in contact, from their placement at ``kin`` (once per
        :meth:`set_support`)."""
        if self.polygon is None:
            self.update_polygon(kin)

    @property
    def halfplanes_A(self) -> np.ndarray:
        """The polygon's half-planes A (k x 2; :meth:`prepare` first)."""
        assert self.polygon is not None, "prepare() builds the polygon"
        return self.polygon.A

    @property
    def halfplanes_b(self) -> np.ndarray:
        """The polygon's half-planes b (k)."""
        assert self.polygon is not None, "prepare() builds the polygon"
        return self.polygon.b

    @property
    def rows(self) -> int:
        return 0 if self.polygon is None else self.polygon.b.shape[0]
