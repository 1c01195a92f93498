"""Planar geometry of feet and support polygons (world frame, z up, ground at z = 0).

A foot is a ``length x width`` rectangle centred under its sole frame and turned by the
sole's yaw. The support polygon is the convex hull of the feet in contact. Polygons are
``(M, 2)`` arrays of vertices in counter-clockwise order; their half-plane form is
``A p <= b`` with unit outward normals in the rows of ``A``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import ConfigurationError, TrajectoryError
from ..geometry import (  # the plane geometry shared with wbc.limits and the viewer
    convex_hull,
    foot_rectangle,
    halfplanes,
    polygon_area,
    polygon_distance,
    rot2,
    shrink_polygon,
    signed_distance,
    support_hull,
)

__all__ = [
    "Foot",
    "convex_hull",
    "foot_rectangle",
    "halfplanes",
    "polygon_area",
    "polygon_distance",
    "rot2",
    "shrink_polygon",
    "signed_distance",
    "support_polygon",
]


@dataclass(frozen=True)
class Foot:
    """Rectangular foot plate centred under the sole frame: ``length x width`` (m), the
    robot's (:attr:`wbc.model.Robot.foot_size`: ``Foot(*robot.foot_size)``)."""

    length: float
    width: float

    def __post_init__(self) -> None:
        if not (self.length > 0 and self.width > 0):
            raise TrajectoryError(f"foot size must be positive, got {self.length} x {self.width} m")

    def rectangle(self, xy: np.ndarray, yaw: float) -> np.ndarray:
        """The 4 corners (counter-clockwise) of the foot at sole ``xy``, heading ``yaw``."""
        return foot_rectangle(xy, yaw, self.length, self.width)


def support_polygon(
    support: int,
    l_xy: np.ndarray,
    l_yaw: float,
    r_xy: np.ndarray,
    r_yaw: float,
    foot: Foot,
) -> np.ndarray:
    """Convex hull of the ``foot`` rectangles in contact for a support code
    (``wbc.recording.SUPPORT_DOUBLE/LEFT/RIGHT``): :func:`wbc.geometry.support_hull`."""
    try:
        return support_hull(support, foot.rectangle(l_xy, l_yaw), foot.rectangle(r_xy, r_yaw))
    except ConfigurationError as exc:
        raise TrajectoryError(str(exc)) from None
