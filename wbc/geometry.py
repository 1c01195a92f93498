"""Plane geometry of feet and support polygons (pure numpy, no robot).

Polygons are (k, 2) arrays of counter-clockwise vertices; ``halfplanes`` gives their
``A p <= b`` form with unit outward normals. Shared by the QP constraints
(:mod:`wbc.limits`), the walking references (:mod:`wbc.walking`) and the viewer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import overload

import numpy as np


def sole_corners(length: float, width: float) -> np.ndarray:
    """The 4 corners (4, 3) of a ``length x width`` sole in its own frame, counter-clockwise
    seen from above (front-left first), on the sole plane z = 0."""
    hl, hw = 0.5 * length, 0.5 * width
    return np.array([[hl, hw, 0.0], [-hl, hw, 0.0], [-hl, -hw, 0.0], [hl, -hw, 0.0]])


def rect_corners(rect: tuple[float, float, float, float]) -> np.ndarray:
    """The 4 corners (4, 3) of a sole footprint ``(x_min, x_max, y_min, y_max)`` in its own
    frame (not necessarily centred), counter-clockwise seen from above, on z = 0."""
    x0, x1, y0, y1 = rect
    return np.array([[x1, y1, 0.0], [x0, y1, 0.0], [x0, y0, 0.0], [x1, y0, 0.0]])


def world_corners(rotation: np.ndarray, translation: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Corners given in a sole's frame (k, 3), in the world: ``t + R c`` (k, 3)."""
    return np.asarray(translation) + np.asarray(corners) @ np.asarray(rotation).T


def support_hull(support: int, left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """The support polygon (k, 2, counter-clockwise): the convex hull of the ground projections
    of the soles in contact, for a support code of :mod:`wbc.recording` (``SUPPORT_DOUBLE``,
    ``SUPPORT_LEFT``, ``SUPPORT_RIGHT``); ``left``/``right``: each sole's corners (k, 2 or 3).
    Raises :class:`~wbc.exceptions.ConfigurationError` for another code."""
    from .exceptions import ConfigurationError
    from .types import SUPPORT_DOUBLE, SUPPORT_LEFT, SUPPORT_RIGHT

    parts = {
        SUPPORT_DOUBLE: (left, right),
        SUPPORT_LEFT: (left,),
        SUPPORT_RIGHT: (right,),
    }.get(int(support))
    if parts is None:
        raise ConfigurationError(
            f"unknown support code {support}; use {SUPPORT_DOUBLE} (double), {SUPPORT_LEFT} "
            f"(left) or {SUPPORT_RIGHT} (right)"
        )
    return convex_hull(np.vstack([np.asarray(c, dtype=float)[:, :2] for c in parts]))


def yaw_of(rotation: np.ndarray) -> float:
    """The heading (rad) of a 3-D rotation: the angle of its x axis in the ground plane,
    ``atan2(R₁₀, R₀₀)``."""
    return math.atan2(rotation[1, 0], rotation[0, 0])


def clip_norm(v: np.ndarray, limit: float) -> np.ndarray:
    """``v`` shortened to length ``limit`` if it is longer (its direction kept)."""
    n = math.sqrt(float(v @ v))
    return v if n <= limit else v * (limit / n)


def heading_free(rotation: np.ndarray) -> np.ndarray:
    """The rotation with its heading removed, ``Rz(−yaw) R`` (``yaw = yaw_of(R)``): the tilt
    (pitch and roll) seen from a frame turned with the body."""
    yaw = yaw_of(rotation)
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ rotation


def rot_z(yaw: float) -> np.ndarray:
    """The 3-D rotation about the vertical by ``yaw`` (rad), ``Rz(yaw)``."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot2(yaw: float) -> np.ndarray:
    """2-D rotation matrix."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def relative_pose(frame: Sequence[float], pose: Sequence[float]) -> np.ndarray:
    """The planar pose ``pose`` (x, y, heading) in the axes of ``frame`` (x, y, heading):
    ``(Rz(ψ_f)ᵀ (p − p_f), wrap(ψ − ψ_f))``."""
    f, p = np.asarray(frame, dtype=float), np.asarray(pose, dtype=float)
    d = rot2(f[2]).T @ (p[:2] - f[:2])
    return np.array([d[0], d[1], wrap_angle(p[2] - f[2])])


def foot_rectangle(xy: np.ndarray, yaw: float, length: float, width: float) -> np.ndarray:
    """Corners (4, 2), counter-clockwise, of a ``length x width`` rectangle centred at ``xy``."""
    return np.asarray(xy, dtype=float)[:2] + sole_corners(length, width)[:, :2] @ rot2(yaw).T


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of 2-D points (n, 2) (Andrew's monotone chain, O(n log n));
    repeated and collinear points dropped, degenerate inputs give 1 or 2 vertices. Raises
    :class:`~wbc.exceptions.ConfigurationError` for another shape or non-finite points."""
    from .exceptions import ConfigurationError

    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] == 0:
        raise ConfigurationError(f"convex_hull: expected (n >= 1, 2) points, got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ConfigurationError("convex_hull: points must be finite")
    pts = np.unique(np.round(pts, 12), axis=0)
    if len(pts) < 3:
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


def halfplanes(polygon: np.ndarray, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Half-plane form ``A p <= b`` of a counter-clockwise convex polygon shrunk by ``margin``.

    Row i of ``A`` is the unit outward normal of edge (v_i, v_i+1); ``b_i = a_i . v_i - margin``.
    """
    poly = np.asarray(polygon, dtype=float)
    edges = np.roll(poly, -1, axis=0) - poly
    normals = np.column_stack([edges[:, 1], -edges[:, 0]])
    lengths = np.linalg.norm(normals, axis=1)
    keep = lengths > 1e-12
    normals = normals[keep] / lengths[keep, None]
    b = np.einsum("ij,ij->i", normals, poly[keep]) - margin
    return normals, b


def signed_distance(polygon: np.ndarray, points: np.ndarray) -> np.ndarray | float:
    """Signed distance from point(s) to a convex polygon's boundary: positive inside.

    Inside, it is the distance to the nearest edge line, ``min_i (b_i - a_i . p)``; outside,
    minus the Euclidean distance to the polygon.
    """
    poly = np.asarray(polygon, dtype=float)
    pts = np.asarray(points, dtype=float)
    single = pts.ndim == 1
    pts = np.atleast_2d(pts)[:, :2]
    A, b = halfplanes(poly)
    inside = np.min(b[None, :] - pts @ A.T, axis=1)
    out = inside.copy()
    outside = inside < 0
    if np.any(outside):
        out[outside] = -_distance_to_boundary(poly, pts[outside])
    return float(out[0]) if single else out


def _distance_to_boundary(poly: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Euclidean distance from each point to the polygon's edges (segments)."""
    a = poly
    d = np.roll(poly, -1, axis=0) - poly
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-30)
    rel = pts[:, None, :] - a[None, :, :]
    s = np.clip(np.einsum("pij,ij->pi", rel, d) / dd, 0.0, 1.0)
    closest = a[None] + s[..., None] * d[None]
    return np.min(np.linalg.norm(pts[:, None, :] - closest, axis=2), axis=1)


def polygon_distance(p: np.ndarray, q: np.ndarray) -> float:
    """Distance between two convex polygons; minus the penetration depth if they overlap.

    Separated: the Euclidean distance between the closest points. Overlapping: the
    separating-axis value (the smallest translation along an edge normal that separates them),
    negated.
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    sep = -np.inf
    for a, b in (p, q), (q, p):
        A, bb = halfplanes(a)
        # max over b's vertices is the worst; separation along normal n: min_v (n.v) - b_n
        sep = max(sep, float(np.max(np.min(b @ A.T, axis=0) - bb)))
    if sep <= 0:
        return sep
    return float(min(np.min(_distance_to_boundary(p, q)), np.min(_distance_to_boundary(q, p))))


def shrink_polygon(polygon: np.ndarray, margin: float) -> np.ndarray:
    """Vertices of the convex polygon shrunk by ``margin`` (empty (0, 2) if nothing is left)."""
    poly = np.asarray(polygon, dtype=float)
    if margin == 0.0:
        return poly.copy()
    A, b = halfplanes(poly, margin)
    # Vertices of {A p <= b}: intersections of every pair of lines that satisfy all rows.
    verts = []
    m = len(b)
    for i in range(m):
        for j in range(i + 1, m):
            M = np.array([A[i], A[j]])
            if abs(np.linalg.det(M)) < 1e-12:
                continue
            v = np.linalg.solve(M, np.array([b[i], b[j]]))
            if np.all(A @ v <= b + 1e-12):
                verts.append(v)
    if len(verts) < 3:
        return np.zeros((0, 2))
    return convex_hull(np.array(verts))


def polygon_area(polygon: np.ndarray) -> float:
    """Area of a simple polygon (shoelace)."""
    p = np.asarray(polygon, dtype=float)
    if len(p) < 3:
        return 0.0
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


# ---------------------------------------------------------------------------- angles
@overload
def wrap_angle(angle: float) -> float: ...
@overload
def wrap_angle(angle: np.ndarray) -> np.ndarray: ...
def wrap_angle(angle: float | np.ndarray) -> float | np.ndarray:
    """The angle in (−π, π] (headings, joint angles): ``π − ((π − a) mod 2π)``, the one
    angle wrap of the package.

    A number gives a float, an array an array (elementwise, the same bits: Python's float
    ``%`` and numpy's ``%`` round alike). Accuracy: the rounding of ``π − a``, within one ulp
    of ``max(π, |a|)`` (4.4e-16 for |a| <= π) of the exact ``a − 2πk``, an angle already in
    range included (0.1 gives 0.10000000000000009); the rounding that would give −π just
    above π gives π."""
    if np.ndim(angle) == 0:
        r = math.pi - (math.pi - float(angle)) % (2.0 * math.pi)
        return math.pi if r == -math.pi else r
    out = np.pi - (np.pi - np.asarray(angle, dtype=float)) % (2.0 * np.pi)
    out[out == -np.pi] = np.pi
    return out


@overload
def mean_angle(a: float, b: float) -> float: ...
@overload
def mean_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray: ...
def mean_angle(a: float | np.ndarray, b: float | np.ndarray) -> float | np.ndarray:
    """The angle half-way from ``a`` to ``b`` the short way round: ``a + wrap(b − a) / 2``
    (the heading between two soles' yaws). Equidistant from both on the circle; ``a`` and
    ``b`` exactly opposite give the one a quarter turn counter-clockwise of ``a`` (the wrap
    takes +π). Numbers give a float, arrays an array."""
    if np.ndim(a) == 0 and np.ndim(b) == 0:
        return float(a) + 0.5 * wrap_angle(float(b) - float(a))
    a = np.asarray(a, dtype=float)
    return a + 0.5 * wrap_angle(np.asarray(b, dtype=float) - a)
