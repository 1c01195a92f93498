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
) -> np.ndarray:
    """J_d (K x nv) = nᵀ (J_p2 − J_p1) for K pairs.

    ``J_world``: pinocchio's joint Jacobians in the world frame (6 x nv, ``data.J`` after
    ``computeJointJacobians``): the velocity of a point p carried by a joint is
    J_v + J_ω × p over the joint's support columns, so nᵀ J_p = nᵀ J_v + (p × n)ᵀ J_ω.
    ``mask_i`` (K x nv) selects each pair's supports.
    """
    Jv, Jw = J_world[:3], J_world[3:]
    a = normal @ Jv
    row_2 = a + np.cross(p2, normal) @ Jw  # (the kernels' reference: tests)
    row_1 = a + np.cross(p1, normal) @ Jw
    return np.where(mask_2, row_2, 0.0) - np.where(mask_1, row_1, 0.0)


class PlaneRows(NamedTuple):
    """Points a (on the first body) and b (on the second) whose gap nᵀ(b − a) along the
    pair's normal n must stay above the margin; ``pair`` indexes the Witness rows."""

    pair: np.ndarray
    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    gap: np.ndarray


def separating_plane_rows(w: Witness, vertices: np.ndarray, below: float) -> PlaneRows:
    """The witness pair of each close pair, plus every box corner nearer than ``below`` to the
    separating planes through the witness points.

    With n the unit normal from body 1 to body 2 and p1, p2 the witness points, every corner
    v of body 2 has nᵀ(v − p1) >= d and every corner u of body 1 has nᵀ(p2 − u) >= d: keeping
    these gaps above the margin (n held for the tick) keeps the bodies apart. The witness
    alone is not enough for boxes: two nearly parallel faces (the feet side by side) have
    their witness flip between corners, and a tick that turns one face lets the unprotected
    corner through.
    """
    R = w.index.size
    if R == 0:
        z = np.zeros((0, 3))
        return PlaneRows(np.zeros(0, int), z, z, z, np.zeros(0))
    V1, V2 = vertices[:, 0], vertices[:, 1]  # R x 8 x 3 corners of body 1 / body 2
    n, p1, p2 = w.normal, w.p1, w.p2
    gap2 = ((V2 - p1[:, None]) @ n[:, :, None])[:, :, 0]  # corners of body 2 vs plane at p1
    gap1 = ((p2[:, None] - V1) @ n[:, :, None])[:, :, 0]  # corners of body 1 vs plane at p2
    # a corner that is the witness point itself is the witness row already (other corners
    # at the same gap stay: parallel faces, where the witness may flip to them)
    d2 = V2 - p2[:, None]
    d1 = V1 - p1[:, None]
    keep2 = (gap2 < below) & ((d2 * d2).sum(axis=2) > 1e-18)
    keep1 = (gap1 < below) & ((d1 * d1).sum(axis=2) > 1e-18)
    r2, r1 = np.nonzero(keep2)[0], np.nonzero(keep1)[0]
    return PlaneRows(
        np.concatenate([np.arange(R), r2, r1]),
        np.concatenate([p1, p1[r2], V1[keep1]]),
        np.concatenate([p2, V2[keep2], p2[r1]]),
        np.concatenate([n, n[r2], n[r1]]),
        np.concatenate([w.distance, gap2[keep2], gap1[keep1]]),
    )
