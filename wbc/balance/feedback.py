"""Gyro feedback on the leg goals (a first closed-loop step, Robotis OP3 style).

Only what a Bioloid-class robot can sense: the torso IMU's gyro (:class:`wbc.imu.Imu`). Each
leg joint's goal gets an offset that turns the torso against its measured angular velocity::

    δ_j = s · k_j · (a_j · ω)      clipped to ±max_offset, then into the joint limits

with ``ω`` the gyro rate (IMU frame = torso frame), ``a_j`` joint j's axis in the torso frame
at the planned configuration, ``k_j`` the OP3 walking module's gains (hip roll 0.35, knee
0.3, ankle roll 0.7, ankle pitch 0.9, rad per rad/s: ../shared/reference/physics.md §3) and
``s`` a scale. Why the sign: with the sole held by the floor, turning a leg joint by dθ about
``a_j`` turns the torso by ``−a_j dθ``, so the torso's induced rotation
``−Σ_j s k_j a_j a_jᵀ ω`` opposes ω (a damping of the torso's rotation).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..exceptions import ConfigurationError
from ..imu import Imu
from ..model import Robot
from ..roles import LEG_ROLES, joint_axis
from ..servos.sources import TargetSource

#: OP3 walking module gyro gains (rad per rad/s), by leg joint role (:mod:`wbc.roles`)
OP3_GAINS = {"hip_roll": 0.35, "knee": 0.3, "ankle_roll": 0.7, "ankle_pitch": 0.9}


class GyroFeedback:
    """Goal offsets from the torso gyro (module docstring)."""

    def __init__(
        self,
        robot: Robot,
        imu: Imu | None,
        scale: float = 1.0,
        gains: dict[str, float] | None = None,
        max_offset: float = 0.2,
    ) -> None:
        if not (np.isfinite(scale) and scale >= 0):
            raise ConfigurationError(
                f"gyro feedback scale must be a finite number >= 0, got {scale}"
            )
        gains = OP3_GAINS if gains is None else gains
        self.robot = robot
        self.imu = imu
        self.max_offset = float(max_offset)
        unknown = sorted(set(gains) - set(LEG_ROLES))
        if unknown:
            raise ConfigurationError(
                f"gyro feedback gains: unknown roles {unknown}; allowed: {', '.join(LEG_ROLES)}"
            )
        self.k = np.zeros(robot.n_joints)
        for side in ("left", "right"):
            for role, g in gains.items():
                self.k[robot.joint_index(robot.roles.joint(side, role))] = scale * g
        model = robot.model
        self.data = model.createData()
        self.joint_ids = [model.getJointId(n) for n in robot.joint_names]
        self.local_axes = np.array([_local_axis(model, j) for j in self.joint_ids])

    def axes(self, joints: np.ndarray) -> np.ndarray:
        """Joint axes (n, 3) in the torso frame at ``joints``."""
        q = self.robot.with_joints(joints)  # base at the origin: world = torso frame
        pin.forwardKinematics(self.robot.model, self.data, q)
        return np.array(
            [
                self.data.oMi[j].rotation @ a
                for j, a in zip(self.joint_ids, self.local_axes, strict=True)
            ]
        )

    def offsets(self, joints: np.ndarray) -> np.ndarray:
        """Goal offsets (rad) from the gyro's present reading at planned ``joints``."""
        if self.imu is None:
            raise ConfigurationError("gyro feedback: no IMU to read (built for its axes only)")
        omega = self.imu.read().angular_velocity
        d = self.k * (self.axes(joints) @ omega)
        return np.clip(d, -self.max_offset, self.max_offset)


def _local_axis(model: pin.Model, j: int) -> np.ndarray:
    return joint_axis(model, j, "gyro feedback")


class FeedbackSource:
    """A target source whose targets carry :class:`GyroFeedback` offsets (clamped into the
    joint limits)."""

    def __init__(self, source: TargetSource, feedback: GyroFeedback) -> None:
        self.source = source
        self.feedback = feedback
        self.joint_names = tuple(source.joint_names)
        if hasattr(source, "duration"):
            self.duration = source.duration

    def first(self) -> np.ndarray:
        return self.source.first()

    def __call__(self, tick: int, t: float) -> np.ndarray | None:
        q = self.source(tick, t)
        if q is None:
            return None
        q = np.asarray(q, dtype=float)
        r = self.feedback.robot
        return np.clip(q + self.feedback.offsets(q), r.q_min, r.q_max)
