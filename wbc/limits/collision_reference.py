"""The self-collision rows in numpy: the reference forms that
``tests/test_limits_collision_kernels.py`` compares the compiled rows
(:func:`wbc.limits.collision_kernels.plane_rows`) to, and the finite-difference tests check."""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..model import Robot

if TYPE_CHECKING:
    from .self_collision import Witness


def joint_masks(robot: Robot) -> np.ndarray:
    """(njoints x nv) bools: the velocity coordinates that move each pinocchio joint."""
    model = robot.model
    out = np.zeros((model.njoints, robot.nv), dtype=bool)
    for j in range(1, model.njoints):
        for s in model.supports[j]:
            if s:
                jm = model.joints[s]
                out[j, jm.idx_v : jm.idx_v + jm.nv] = True
    return out


def distance_jacobian(
    J_world: np.ndarray,
    mask_1: np.ndarray,
    mask_2: np.ndarray,
    p1: np.ndarray,
    p2: np.ndarray,
    normal: np.ndarray,
    common: bool = False,
) -> np.ndarray:
    """J_d (K x nv) = nᵀ (J_p2 − J_p1) for K pairs (``common``: 0 on the columns that move
    both bodies, n fixed in their common frame).

    ``J_world``: pinocchio's joint Jacobians in the world frame (6 x nv, ``data.J`` after
    ``computeJointJacobians``): the velocity of a point p carried by a joint is
    J_v + J_ω × p over the joint's support columns, so nᵀ J_p = nᵀ J_v + (p × n)ᵀ J_ω.
    ``mask_i`` (K x nv) selects each pair's supports.
    """
    Jv, Jw = J_world[:3], J_world[3:]
    a = normal @ Jv
    row_2 = a + np.cross(p2, normal) @ Jw  # (the kernels' reference: tests)
    row_1 = a + np.cross(p1, normal) @ Jw
    own_1, own_2 = (mask_1 & ~mask_2, mask_2 & ~mask_1) if common else (mask_1, mask_2)
    return np.where(own_2, row_2, 0.0) - np.where(own_1, row_1, 0.0)


class PlaneRows(NamedTuple):
    """Points a (on the first body) and b (on the second) whose gap nᵀ(b − a) along the
    pair's normal n must stay above the margin; ``pair`` indexes the Witness rows."""

    pair: np.ndarray
    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    gap: np.ndarray


def _boxes(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centres (... x 3), unit axes (... x 3 x 3, columns) and half sides (... x 3) of boxes
    from their corners (... x 8 x 3, x slowest, z fastest: ``_box_vertices``' order)."""
    c = vertices.mean(axis=-2)
    E = np.stack([vertices[..., k, :] - vertices[..., 0, :] for k in (4, 2, 1)], axis=-1) / 2
    half = np.linalg.norm(E, axis=-2)
    return c, E / half[..., None, :], half


def _nearest_on_box(x: np.ndarray, c: np.ndarray, U: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The points of the boxes (centres c, axes U's columns, half sides) nearest to x (... x 3)."""
    local = np.clip(np.einsum("...mi,...m->...i", U, x - c), -half, half)
    return c + np.einsum("...mi,...i->...m", U, local)


def separating_plane_rows(w: Witness, vertices: np.ndarray, below: float) -> PlaneRows:
    """The box corners nearer than ``below`` to the separating planes through the witness
    points, and the witness pair where it stands for itself.

    With n the unit normal from body 1 to body 2 and p1, p2 the witness points, every corner
    v of body 2 has nᵀ(v − p1) >= d and every corner u of body 1 has nᵀ(p2 − u) >= d: keeping
    these gaps above the margin (n held for the tick) keeps the bodies apart. Each corner's
    row pairs it with its projection on the plane brought onto the other box (its nearest
    point there): on a face, the exact derivative of the corner's gap to that face. The
    witness alone is not enough for boxes: two nearly parallel faces (the feet side by side)
    have their witness flip between corners, and a tick that turns one face lets the
    unprotected corner through.

    The rows do not depend on which witness a tie picks (continuous in q): a witness that
    is a corner is that corner's row (p2 one of body 2's corners, its projection p1 on body
    1; or the converse), and two features parallel to the plane
    that share a direction along it (a face and a face or an edge, two parallel edges, to
    :data:`~wbc.limits.collision_kernels.PARALLEL`) have any point of their overlap as a
    witness — their corners' rows stand for it. The witness row is kept otherwise (an edge
    across an edge: the closest points in the middle of both).
    """
    from .collision_kernels import PARALLEL

    R = w.index.size
    if R == 0:
        z = np.zeros((0, 3))
        return PlaneRows(np.zeros(0, int), z, z, z, np.zeros(0))
    V1, V2 = vertices[:, 0], vertices[:, 1]  # R x 8 x 3 corners of body 1 / body 2
    n, p1, p2 = w.normal, w.p1, w.p2
    c1, U1, h1 = _boxes(V1)
    c2, U2, h2 = _boxes(V2)

    def is_corner(p, c, U, h):
        local = np.einsum("rmi,rm->ri", U, p - c)
        return ((np.abs(local) - h) ** 2).sum(axis=1) <= 1e-18

    along1 = np.abs(np.einsum("rmi,rm->ri", U1, n)) <= PARALLEL  # axes along the plane
    along2 = np.abs(np.einsum("rmi,rm->ri", U2, n)) <= PARALLEL
    k1, k2 = along1.sum(axis=1), along2.sum(axis=1)
    edges = np.linalg.norm(
        np.cross(
            U1[np.arange(R), :, along1.argmax(axis=1)], U2[np.arange(R), :, along2.argmax(axis=1)]
        ),
        axis=1,
    )
    tie = (k1 > 0) & (k2 > 0) & ((k1 >= 2) | (k2 >= 2) | (edges <= PARALLEL))
    corner2 = is_corner(p2, c2, U2, h2)
    witness = ~(corner2 | is_corner(p1, c1, U1, h1)) & ~tie
    rw = np.nonzero(witness)[0]
    gap2 = ((V2 - p1[:, None]) @ n[:, :, None])[:, :, 0]  # corners of body 2 vs plane at p1
    gap1 = ((p2[:, None] - V1) @ n[:, :, None])[:, :, 0]  # corners of body 1 vs plane at p2
    d1 = V1 - p1[:, None]
    keep2 = gap2 < below
    # both witnesses corners: body 1's corner row would be body 2's
    keep1 = (gap1 < below) & ~(corner2[:, None] & ((d1 * d1).sum(axis=2) <= 1e-18))
    r2, r1 = np.nonzero(keep2)[0], np.nonzero(keep1)[0]
    foot2 = V2 - gap2[:, :, None] * n[:, None]  # on the plane at p1
    foot1 = V1 + gap1[:, :, None] * n[:, None]  # on the plane at p2
    on1 = _nearest_on_box(foot2, c1[:, None], U1[:, None], h1[:, None])
    on2 = _nearest_on_box(foot1, c2[:, None], U2[:, None], h2[:, None])
    return PlaneRows(
        np.concatenate([rw, r2, r1]),
        np.concatenate([p1[rw], on1[keep2], V1[keep1]]),
        np.concatenate([p2[rw], V2[keep2], on2[keep1]]),
        np.concatenate([n[rw], n[r2], n[r1]]),
        np.concatenate([w.distance[rw], gap2[keep2], gap1[keep1]]),
    )
