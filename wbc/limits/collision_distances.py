"""The distances of a self-collision limit's pairs: :class:`PairDistances`, compiled
(:mod:`wbc.limits.collision_kernels`), and the close pairs it finds (:class:`Witness`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ..model import Kinematics, Robot
from .collision_boxes import CollisionModel, _box_in_frame, _box_vertices, lipschitz_bounds
from .collision_kernels import close_pairs, sparse_arms, work_sizes


class Witness(NamedTuple):
    """The pairs closer than the query distance: indices into the pair list, signed
    distances (m), witness points on the first / second geometry and unit normals (world)."""

    index: np.ndarray  # type: ignore[assignment]  # the field shadows tuple.index
    distance: np.ndarray
    p1: np.ndarray
    p2: np.ndarray
    normal: np.ndarray


class PairDistances:
    """Distances of a fixed pair list at a configuration, with a conservative cache.

    One compiled call per query (:func:`wbc.limits.collision_kernels.close_pairs`): each pair
    keeps a lower bound on its distance, lowered by Σ_i L_ki |Δq_i| for every joint motion
    since it was last computed (valid along any sequence of configurations, by the triangle
    inequality); a pair whose bound is below the query gets its boxes' bounding-sphere bound,
    then the gap along its last separating axis, then their separating-axis bound (15 axes),
    and only if all are below the query its exact distance
    (GJK on the two boxes, :func:`~wbc.limits.collision_kernels.box_distance`). A geometry
    that is not a box is replaced by its bounding box (a conservative hull).
    """

    def __init__(self, robot: Robot, cm: CollisionModel, pairs: Sequence[tuple[int, int]]):
        self.robot = robot
        self.pairs = list(pairs)
        self.geometry = cm.geometry
        self.L = lipschitz_bounds(robot, cm, self.pairs)
        #: the lever arms by joint without their zeros (the kernels': ~1/3 of L on a walk)
        self._L_start, self._L_pair, self._L_arm = sparse_arms(self.L)
        #: box corners of each geometry in its parent joint's frame (ngeoms x 8 x 3)
        self.corners = np.array([_box_vertices(g) for g in self.geometry.geometryObjects])
        self._geom_joint = np.asarray(cm.joints, dtype=int)
        self._pair_geoms = np.array(self.pairs, dtype=int).reshape(-1, 2)
        self._R = np.zeros((robot.model.njoints, 3, 3))  # joint placements of a call
        self._t = np.zeros((robot.model.njoints, 3))
        K = len(self.pairs)
        self.joint_1 = cm.joints[[p[0] for p in self.pairs]] if K else np.zeros(0, int)
        self.joint_2 = cm.joints[[p[1] for p in self.pairs]] if K else np.zeros(0, int)
        # the boxes in their parent frames, for the kernels
        model = robot.model
        boxes = [_box_in_frame(model, g) for g in self.geometry.geometryObjects]
        self.box_frame = np.array([g.parentFrame for g in self.geometry.geometryObjects], np.int64)
        self.box_R = np.array([b[0] for b in boxes]).reshape(-1, 3, 3)
        self.box_p = np.array([b[1] for b in boxes]).reshape(-1, 3)
        self.half = np.array([b[2] for b in boxes]).reshape(-1, 3)
        self.radius = np.linalg.norm(self.half, axis=1)
        #: the velocity coordinates that move each geometry (ngeoms x nv)
        self.support = np.array(
            [robot.frame_support(int(f)) for f in self.box_frame], dtype=np.bool_
        ).reshape(-1, robot.nv)
        self.pair_a = np.ascontiguousarray(self._pair_geoms[:, 0], dtype=np.int64)
        self.pair_b = np.ascontiguousarray(self._pair_geoms[:, 1], dtype=np.int64)
        G = len(self.geometry.geometryObjects)
        self.Rw, self.cw = np.zeros((G, 3, 3)), np.zeros((G, 3))
        self._placed = np.zeros(G, dtype=np.bool_)
        self._bound = np.full(K, -np.inf)  # -inf: never computed
        #: the number of the separating axis of each pair's last separating-axis gap (-1: none)
        self._last_axis = np.full(K, -1, np.int64)
        #: the kernels' scratch (:func:`~wbc.limits.collision_kernels.work_sizes`)
        n_work, n_iwork = work_sizes(K, robot.nv)
        self._work, self._iwork = np.zeros(n_work), np.zeros(n_iwork, np.int64)
        self._q = np.zeros(robot.n_joints)
        #: the close pairs of the last query: pair index, distance, witnesses, normal
        self.out_k, self.out_d, self.out_p1, self.out_p2, self.out_n = self.out_buffers()
        self._counts = np.zeros(5, np.int64)
        self._kin: Kinematics | None = None
        self._frames: tuple[np.ndarray, np.ndarray] | None = None
        self.jacobians = np.zeros((6, robot.nv))  # (of the Kinematics of :meth:`frames`)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_kin"] = state["_frames"] = None  # (views of one Kinematics: a copy re-binds)
        return state

    def out_buffers(self) -> tuple[np.ndarray, ...]:
        """New arrays for :meth:`close`'s output: pair index, distance, witnesses, normal."""
        K = len(self.pairs)
        return (np.zeros(K, np.int64), np.zeros(K), *(np.zeros((K, 3)) for _ in range(3)))

    @property
    def exact_computations(self) -> int:
        """Exact (GJK) distance computations so far (benchmarks and tests)."""
        return int(self._counts[0])

    def frames(self, kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
        """Every frame's world rotation and position at ``kin`` (views, else copies); its
        joints' Jacobians into :attr:`jacobians` (a view)."""
        if kin is not self._kin or self._frames is None:
            self._kin = kin
            self._frames = kin.frame_placements()
            self.jacobians = kin.data.J  # (Pinocchio's data.J: the same array at every update)
        if self._frames is None:  # (copies: made again at every call)
            n = kin.model.nframes
            R = np.array([kin.rotation(f) for f in range(n)])
            p = np.array([kin.translation(f) for f in range(n)])
            return R, p
        return self._frames

    def close(self, kin: Kinematics, distance: float) -> int:
        """The number of pairs closer than ``distance`` at ``kin`` (updated): their indices,
        distances, witnesses and normals are the first of :attr:`out_k`, :attr:`out_d`..."""
        if not self.pairs:
            return 0
        Rf, pf = self.frames(kin)
        joints = np.ascontiguousarray(kin.q[7:], dtype=float)
        return close_pairs(
            joints, self._q, self._bound, self._L_start, self._L_pair, self._L_arm, Rf, pf,
            self.box_frame, self.box_R, self.box_p, self.half, self.radius, self.pair_a,
            self.pair_b, float(distance), self.Rw, self.cw, self._placed, self.out_k,
            self.out_d, self.out_p1, self.out_p2, self.out_n, self._counts, self._last_axis,
            self._work, self._iwork,
        )  # fmt: skip

    def vertices(self, kin: Kinematics, pairs: Sequence[int]) -> np.ndarray:
        """World corners (P x 2 x 8 x 3) of the two boxes of each pair, at ``kin``."""
        if not len(pairs):
            return np.zeros((0, 2, 8, 3))
        g = self._pair_geoms[np.asarray(pairs)]  # P x 2 geometry indices
        joints = self._geom_joint[g]  # P x 2
        oMi, R, t = kin.data.oMi, self._R, self._t
        for j in np.unique(joints).tolist():
            M = oMi[j]
            R[j] = M.rotation
            t[j] = M.translation
        return self.corners[g] @ R[joints].transpose(0, 1, 3, 2) + t[joints][:, :, None]

    def below(self, kin: Kinematics, distance: float) -> Witness:
        """The pairs closer than ``distance`` at the configuration of ``kin`` (its placements
        must be up to date: :meth:`Kinematics.update`)."""
        n = self.close(kin, distance)
        out = (self.out_k, self.out_d, self.out_p1, self.out_p2, self.out_n)
        return Witness(*(a[:n].copy() for a in out))
