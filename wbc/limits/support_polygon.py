"""Support polygon of the soles in contact, and the CoM-in-polygon constraint."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model import Kinematics, Robot
from .limit import Constraint, Inequality

#: Bioloid Premium foot plate, 101 x 61 mm centred under the ankle (bioloid-facts §1.3)
FOOT_LENGTH = 0.101
FOOT_WIDTH = 0.061


def foot_corners(
    placement_rotation: np.ndarray,
    placement_translation: np.ndarray,
    length: float = FOOT_LENGTH,
    width: float = FOOT_WIDTH,
) -> np.ndarray:
    """The four sole corners in the world (4 x 3), counter-clockwise seen from above."""
    hl, hw = 0.5 * length, 0.5 * width
    local = np.array([[hl, hw, 0.0], [-hl, hw, 0.0], [-hl, -hw, 0.0], [hl, -hw, 0.0]])
    return placement_translation + local @ placement_rotation.T


def convex_hull(points: np.ndarray) -> np.ndarray:
    """2-D convex hull (Andrew's monotone chain), counter-clockwise, no repeated point."""
    pts = np.unique(np.asarray(points, dtype=float)[:, :2], axis=0)
    if len(pts) <= 2:
        return pts

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[np.ndarray] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-15:
            lower.pop()
        lower.append(p)
    upper: list[np.ndarray] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-15:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def halfspaces(vertices: np.ndarray, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(A, b) with A p <= b ⇔ p inside the CCW polygon shrunk by ``margin``."""
    v = np.asarray(vertices, dtype=float)
    edges = np.roll(v, -1, axis=0) - v
    normals = np.column_stack([edges[:, 1], -edges[:, 0]])  # outward for CCW
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    b = np.einsum("ij,ij->i", normals, v) - margin
    return normals, b


def signed_distance(point: Sequence[float], vertices: np.ndarray) -> float:
    """Signed distance (m) from a 2-D point to the polygon's boundary; positive inside."""
    A, b = halfspaces(vertices)
    p = np.asarray(point, dtype=float)[:2]
    inside = float(np.min(b - A @ p))
    if inside >= 0:
        return inside
    # outside: true Euclidean distance to the boundary
    v = np.asarray(vertices, dtype=float)
    w = np.roll(v, -1, axis=0)
    d = w - v
    t = np.clip(np.einsum("ij,ij->i", p - v, d) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
    closest = v + t[:, None] * d
    return -float(np.min(np.linalg.norm(closest - p, axis=1)))


class SupportPolygon:
    """Convex hull of the soles in contact (foot rectangles), as vertices and half-spaces."""

    def __init__(self, vertices: np.ndarray, margin: float = 0.0) -> None:
        self.vertices = np.asarray(vertices, dtype=float)
        self.margin = margin
        self.A, self.b = halfspaces(self.vertices, margin)

    @classmethod
    def from_soles(
        cls,
        kin: Kinematics,
        sole_ids: Sequence[int],
        margin: float = 0.0,
        length: float = FOOT_LENGTH,
        width: float = FOOT_WIDTH,
    ) -> SupportPolygon:
        corners = np.vstack(
            [foot_corners(kin.rotation(f), kin.translation(f), length, width) for f in sole_ids]
        )
        return cls(convex_hull(corners), margin)

    def distance(self, point: Sequence[float]) -> float:
        """Signed distance of a point's ground projection to the (unshrunk) edge."""
        return signed_distance(point, self.vertices)


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
    ) -> None:
        super().__init__(name)
        self.robot = robot
        self.margin = margin
        self.polygon: SupportPolygon | None = None
        self.set_support(soles)

    def set_support(self, soles: Sequence[str]) -> None:
        """Soles in contact; the polygon is taken from their placement at the next compute."""
        self.sole_ids = [self.robot.frame_id(s) for s in soles]
        self.soles = tuple(soles)
        self.polygon = None

    def update_polygon(self, kin: Kinematics) -> SupportPolygon:
        self.polygon = SupportPolygon.from_soles(kin, self.sole_ids, self.margin)
        return self.polygon

    def compute(self, kin: Kinematics) -> Inequality:
        if self.polygon is None:
            self.update_polygon(kin)
        A, b = self.polygon.A, self.polygon.b
        G = A @ kin.com_jacobian[:2]
        h = b - A @ kin.com[:2]
        return Inequality(G, h)
