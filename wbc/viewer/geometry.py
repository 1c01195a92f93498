"""Pure geometry for the viewer: the robot's visual shapes, support polygons and the camera.

Nothing here talks to meshcat, so all of it is unit-tested without a server or a browser.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError, ModelError
from ..geometry import (  # noqa: F401 (convex_hull, polygon_area: re-exported)
    convex_hull,
    polygon_area,
    rect_corners,
    support_hull,
    world_corners,
)
from ..model import Robot
from ..recording import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT

#: A sole is taken to touch the ground when its origin is at most this high (m).
CONTACT_HEIGHT = 0.003


@dataclass(frozen=True)
class VisualShape:
    """One visual primitive of the robot, rigidly attached to a Pinocchio joint.

    ``kind`` is ``"box"`` (``size`` = full lengths x, y, z), ``"sphere"`` (``size`` =
    (radius,)) or ``"cylinder"`` (``size`` = (radius, length), axis along the shape's z).
    ``placement`` is the 4x4 pose of the shape in its joint's frame.
    """

    name: str
    joint: int
    placement: np.ndarray
    kind: str
    size: tuple[float, ...]
    rgba: tuple[float, float, float, float]

    @property
    def color_hex(self) -> int:
        """0xRRGGBB colour as meshcat materials want it."""
        r, g, b = (round(255 * min(max(c, 0.0), 1.0)) for c in self.rgba[:3])
        return (r << 16) | (g << 8) | b


def visual_shapes(robot: Robot) -> list[VisualShape]:
    """The URDF's visual primitives (boxes, spheres, cylinders) with their colours.

    Read through Pinocchio's visual geometry model, which resolves named URDF materials.
    Mesh visuals are skipped with a warning (our robots use primitives only).
    """
    try:
        gmodel = pin.buildGeomFromUrdf(robot.model, str(robot.urdf_path), pin.GeometryType.VISUAL)
    except Exception as exc:
        raise ModelError(f"cannot read the visual geometry of {robot.urdf_path}: {exc}") from exc
    shapes = []
    skipped = []
    for obj in gmodel.geometryObjects:
        geom = obj.geometry
        kind = type(geom).__name__
        if kind == "Box":
            size = tuple(float(2 * h) for h in geom.halfSide)
            kind = "box"
        elif kind == "Sphere":
            size = (float(geom.radius),)
            kind = "sphere"
        elif kind == "Cylinder":
            size = (float(geom.radius), float(2 * geom.halfLength))
            kind = "cylinder"
        else:
            skipped.append(f"{obj.name} ({kind})")
            continue
        rgba = tuple(float(c) for c in obj.meshColor)
        shapes.append(
            VisualShape(obj.name, int(obj.parentJoint), obj.placement.homogeneous, kind, size, rgba)
        )
    if skipped:
        warnings.warn(
            f"viewer: {len(skipped)} visual geometries of {robot.name} are not primitives and are "
            f"not drawn: {', '.join(skipped)}",
            stacklevel=2,
        )
    if not shapes:
        raise ModelError(f"{robot.urdf_path} has no box, sphere or cylinder visuals to draw")
    return shapes


def sole_rectangle(
    robot: Robot, sole: str, shapes: Sequence[VisualShape] | None = None
) -> tuple[float, float, float, float]:
    """Footprint (x_min, x_max, y_min, y_max) of a sole in its own frame (m).

    Taken from the largest visual box (of ``shapes``, default the robot's) whose bottom face
    lies in the sole plane (within 1 mm) on the sole's parent joint; if there is none, the
    robot's foot (:attr:`wbc.model.Robot.foot_size`: ``robot.toml`` ``[feet]`` or the sole
    link's collision box; ModelError naming what to add if neither) centred on the sole.
    """
    fid = robot.frame_id(sole)
    frame = robot.model.frames[fid]
    joint_M_sole = frame.placement
    sole_M_joint = joint_M_sole.inverse().homogeneous
    best = None
    for shape in visual_shapes(robot) if shapes is None else shapes:
        if shape.kind != "box" or shape.joint != frame.parentJoint:
            continue
        corners = _box_corners(shape.size) @ shape.placement[:3, :3].T + shape.placement[:3, 3]
        in_sole = corners @ sole_M_joint[:3, :3].T + sole_M_joint[:3, 3]
        if abs(in_sole[:, 2].min()) < 1e-3:
            rect = (
                in_sole[:, 0].min(),
                in_sole[:, 0].max(),
                in_sole[:, 1].min(),
                in_sole[:, 1].max(),
            )
            area = (rect[1] - rect[0]) * (rect[3] - rect[2])
            if best is None or area > best[0]:
                best = (area, tuple(float(v) for v in rect))
    if best is None:
        length, width = robot.foot_size
        return (-length / 2, length / 2, -width / 2, width / 2)
    return best[1]


def _box_corners(size: Sequence[float]) -> np.ndarray:
    half = 0.5 * np.asarray(size, dtype=float)
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return signs * half


def support_polygon(
    l_sole: np.ndarray,
    r_sole: np.ndarray,
    support: int | None,
    l_rect: Sequence[float],
    r_rect: Sequence[float],
) -> np.ndarray:
    """The support polygon (k, 2), counter-clockwise, from the two sole placements (4x4):
    :func:`wbc.geometry.support_hull` of the footprints ``l_rect``/``r_rect``.

    ``support`` is a recording code (:data:`~wbc.recording.SUPPORT_DOUBLE`, ``_LEFT``,
    ``_RIGHT``); ``None`` means "the soles whose origin is within :data:`CONTACT_HEIGHT` of the
    ground" (both if neither is).
    """
    if support is None:
        on_ground = [abs(M[2, 3]) <= CONTACT_HEIGHT for M in (l_sole, r_sole)]
        if all(on_ground) or not any(on_ground):
            support = SUPPORT_DOUBLE
        else:
            support = SUPPORT_LEFT if on_ground[0] else SUPPORT_RIGHT
    left = world_corners(l_sole[:3, :3], l_sole[:3, 3], rect_corners(tuple(l_rect)))
    right = world_corners(r_sole[:3, :3], r_sole[:3, 3], rect_corners(tuple(r_rect)))
    return support_hull(support, left, right)


@dataclass(frozen=True)
class Camera:
    """A perspective camera looking from ``eye`` at ``target`` (world, m), z up.

    ``fov`` is the vertical field of view in degrees, as for three.js's PerspectiveCamera.
    """

    target: tuple[float, float, float]
    eye: tuple[float, float, float]
    fov: float = 35.0

    def __post_init__(self) -> None:
        t, e = np.asarray(self.target, float), np.asarray(self.eye, float)
        if t.shape != (3,) or e.shape != (3,) or not np.all(np.isfinite(np.r_[t, e])):
            raise ConfigurationError(f"camera: target and eye must be finite 3-vectors: {self}")
        d = e - t
        if np.linalg.norm(d) < 1e-6:
            raise ConfigurationError("camera: eye and target coincide")
        if np.linalg.norm(d[:2]) < 1e-6:
            raise ConfigurationError("camera: eye straight above/below the target (z is up)")
        if not 1.0 <= self.fov <= 170.0:
            raise ConfigurationError(f"camera: fov must be in [1, 170] degrees, got {self.fov}")

    @cached_property
    def rotation(self) -> np.ndarray:
        """World-from-camera rotation, columns = camera x (right), y (up), z (backwards)."""
        back = np.asarray(self.eye, float) - np.asarray(self.target, float)
        z = back / np.linalg.norm(back)
        x = np.cross([0.0, 0.0, 1.0], z)
        x /= np.linalg.norm(x)
        return np.column_stack([x, np.cross(z, x), z])

    def project(self, points: np.ndarray, width: int, height: int) -> np.ndarray:
        """Pixel coordinates (u right, v down) of world points in a ``width x height`` view.

        Pinhole model of three.js: ``u = W/2 (1 + x_c / (-z_c tan(fov/2) W/H))``,
        ``v = H/2 (1 - y_c / (-z_c tan(fov/2)))`` with (x_c, y_c, z_c) in the camera frame.
        Points behind the camera give NaN.
        """
        p = np.atleast_2d(np.asarray(points, dtype=float))
        cam = (p - np.asarray(self.eye, float)) @ self.rotation
        depth = -cam[:, 2]
        tan_half = np.tan(np.radians(self.fov) / 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            ndc_y = np.where(depth > 0, cam[:, 1] / (depth * tan_half), np.nan)
            ndc_x = np.where(depth > 0, cam[:, 0] / (depth * tan_half * width / height), np.nan)
        return np.column_stack([0.5 * width * (1 + ndc_x), 0.5 * height * (1 - ndc_y)])


def fit_camera(
    points: np.ndarray,
    azimuth: float = 35.0,
    elevation: float = 18.0,
    fov: float = 35.0,
    fill: float = 0.8,
    min_radius: float = 0.18,
) -> Camera:
    """A camera aimed at the centre of ``points`` (world, m) that keeps them all in view.

    The eye sits at ``azimuth`` degrees from +x towards +y and ``elevation`` degrees above
    the horizontal; its distance ``d = r / (fill sin(fov/2))`` puts the bounding sphere
    (radius ``r``, at least ``min_radius``) within ``fill`` of the vertical field of view.
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    if pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise ConfigurationError(f"fit_camera: expected finite (n, 3) points, got {pts.shape}")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    center = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), min_radius)
    dist = radius / (fill * np.sin(np.radians(fov) / 2))
    az, el = np.radians(azimuth), np.radians(elevation)
    direction = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    eye = center + dist * direction
    return Camera(tuple(center.tolist()), tuple(eye.tolist()), fov)
