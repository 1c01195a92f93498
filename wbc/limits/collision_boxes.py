"""The robot's collision boxes (:mod:`wbc.limits.self_collision`'s geometry): the URDF's
``<collision>`` model, each box's corners and its frame, and the Lipschitz bounds of the
pairs' distances in the joints (the broad phase of
:class:`~wbc.limits.self_collision.PairDistances`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError
from ..model import Robot


class CollisionModel(NamedTuple):
    """The robot's collision geometry and the link of each geometry."""

    geometry: pin.GeometryModel
    links: tuple[str, ...]  # link name of each geometry object
    joints: np.ndarray  # parent joint of each geometry object


def collision_model(robot: Robot) -> CollisionModel:
    """The URDF's ``<collision>`` boxes as a pinocchio GeometryModel (no pairs added)."""
    if not pin.WITH_HPP_FCL:
        raise ConfigurationError("self-collision needs pinocchio built with hpp-fcl/coal")
    geometry = pin.buildGeomFromUrdf(robot.model, str(robot.urdf_path), pin.GeometryType.COLLISION)
    if geometry.ngeoms == 0:
        raise ConfigurationError(f"URDF {robot.urdf_path} has no <collision> geometry")
    links = tuple(robot.model.frames[g.parentFrame].name for g in geometry.geometryObjects)
    joints = np.array([g.parentJoint for g in geometry.geometryObjects], dtype=int)
    return CollisionModel(geometry, links, joints)


def _box_vertices(geom: pin.GeometryObject) -> np.ndarray:
    """Corners of a box (8 x 3), or a bounding box's, in its parent joint's frame."""
    g = geom.geometry
    g.computeLocalAABB()
    aabb = g.aabb_local
    lo, hi = np.asarray(aabb.min_), np.asarray(aabb.max_)
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    M = geom.placement
    return corners @ M.rotation.T + M.translation


def _box_in_frame(model: pin.Model, geom: pin.GeometryObject):
    """(R, p, half sides) of a geometry's box — or, for any other shape, its local bounding
    box — in its parent frame."""
    g = geom.geometry
    if type(g).__name__ == "Box":  # (hpp-fcl or coal)
        centre, half = np.zeros(3), np.asarray(g.halfSide, dtype=float)
    else:
        g.computeLocalAABB()
        lo, hi = np.asarray(g.aabb_local.min_), np.asarray(g.aabb_local.max_)
        centre, half = (lo + hi) / 2, (hi - lo) / 2
    M = model.frames[geom.parentFrame].placement.inverse() * geom.placement
    return M.rotation.copy(), M.rotation @ centre + M.translation, half


def lipschitz_bounds(
    robot: Robot, cm: CollisionModel, pairs: Sequence[tuple[int, int]]
) -> np.ndarray:
    """L (K x n_joints) with |d_k(q) − d_k(q')| <= Σ_i L_ki |q_i − q'_i| for every pair k.

    A revolute joint i moves a point p of a geometry it carries at speed <= |p − o_i| (o_i
    on its axis); a joint that carries both geometries (or neither) does not change their
    distance. |p − o_i| is bounded, whatever the configuration, by the lengths of the joint
    offsets from joint i down to the geometry's joint plus the geometry's farthest corner.
    """
    model = robot.model
    n = robot.n_joints
    offset = np.array(
        [np.linalg.norm(model.jointPlacements[j].translation) for j in range(model.njoints)]
    )
    reach_geom = []
    for geom in cm.geometry.geometryObjects:
        reach_geom.append(float(np.max(np.linalg.norm(_box_vertices(geom), axis=1))))
    supports = [list(model.supports[j]) for j in range(model.njoints)]

    def reach(gi: int) -> np.ndarray:
        """Per actuated joint: bound on the distance from its axis to geometry gi (0 if the
        joint does not carry it)."""
        out = np.zeros(n)
        chain = supports[int(cm.joints[gi])]  # root .. geometry's joint
        # distance from joint chain[k] to the geometry <= Σ offsets of chain[k+1..] + corner
        total = reach_geom[gi]
        for k in range(len(chain) - 1, 0, -1):
            j = chain[k]
            if j >= 2:  # actuated joints (1 is the free flyer)
                out[j - 2] = total
            total += offset[j]
        return out

    L = np.zeros((len(pairs), n))
    for k, (a, b) in enumerate(pairs):
        ra, rb = reach(a), reach(b)
        only_a = (ra > 0) & (rb == 0)
        only_b = (rb > 0) & (ra == 0)
        L[k] = np.where(only_a, ra, 0.0) + np.where(only_b, rb, 0.0)
    return L
