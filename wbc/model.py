"""Robot model on Pinocchio: loading, kinematics, Jacobians, named configurations.

Configurations follow Pinocchio's free-flyer convention: ``q = [x, y, z, qx, qy, qz, qw,
joints...]`` (nq = 7 + n) and velocities/increments ``v = [v_lin, v_ang, joint rates]``
(nv = 6 + n), base twist expressed in the base frame. The joint order is the model's
(:attr:`Robot.joint_names`) everywhere in wbc.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from .exceptions import ConfigurationError, ModelError, ServoMapError
from .paths import robots_dir
from .robot_data import RobotData
from .servo_map import ServoMap

WORLD = pin.ReferenceFrame.WORLD
LOCAL = pin.ReferenceFrame.LOCAL
LOCAL_WORLD_ALIGNED = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_REFERENCES = {"world": WORLD, "local": LOCAL, "local_world_aligned": LOCAL_WORLD_ALIGNED}


def available_robots() -> list[str]:
    """Names accepted by :func:`load_robot` (folders of ``robots/`` holding a URDF)."""
    root = robots_dir()
    return sorted(p.name for p in root.iterdir() if p.is_dir() and any(p.glob("*.urdf")))


def load_robot(name_or_path: str | Path = "bioloid", servo_map: str | Path | None = None) -> Robot:
    """Load a robot by name (``"bioloid"``) or by the path of a URDF file.

    A robot folder holds ``<name>.urdf`` and, optionally, ``servos.toml``, ``poses.toml`` and
    ``robot.toml`` (named poses, standing pose, feet, frame names, walking settings:
    :mod:`wbc.robot_data`); a URDF path picks up the ones next to it (``servo_map`` names
    another servo map).
    """
    path = Path(name_or_path)
    if path.suffix.lower() == ".urdf" or path.is_file():
        urdf = path
    else:
        folder = robots_dir() / str(name_or_path)
        if not folder.is_dir():
            raise ModelError(
                f"unknown robot {str(name_or_path)!r}: not a URDF path and not one of "
                f"{available_robots()}"
            )
        urdf = folder / f"{folder.name}.urdf"
    if servo_map is None and (urdf.parent / "servos.toml").is_file():
        servo_map = urdf.parent / "servos.toml"
    return Robot(urdf, servo_map, urdf.parent)


class Robot:
    """A floating-base robot: Pinocchio model and data plus joint/frame bookkeeping."""

    def __init__(
        self,
        urdf: str | Path,
        servo_map: str | Path | None = None,
        data_dir: str | Path | None = None,
    ) -> None:
        urdf = Path(urdf)
        if not urdf.is_file():
            raise ModelError(f"URDF not found: {urdf}")
        try:
            self.model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
        except Exception as exc:  # pinocchio raises ValueError/RuntimeError with XML details
            raise ModelError(f"malformed URDF {urdf}: {exc}") from exc
        self.urdf_path = urdf
        self.name = self.model.name or urdf.stem
        self.data = self.model.createData()
        if self.model.njoints < 3 or self.model.joints[1].shortname() != "JointModelFreeFlyer":
            raise ModelError(f"URDF {urdf} has no actuated joints")
        names = list(self.model.names)[2:]
        for j, jm in zip(names, list(self.model.joints)[2:], strict=True):
            if jm.nq != 1 or jm.nv != 1:
                raise ModelError(f"URDF {urdf}: joint {j!r} is not a 1-DOF joint")
        self.joint_names: tuple[str, ...] = tuple(names)
        self.n_joints = len(names)
        self.nq = self.model.nq
        self.nv = self.model.nv
        self._joint_index = {n: i for i, n in enumerate(names)}
        self.q_min = np.array(self.model.lowerPositionLimit[7:])
        self.q_max = np.array(self.model.upperPositionLimit[7:])
        self.v_max = np.array(self.model.velocityLimit[6:])
        self.total_mass = float(pin.computeTotalMass(self.model))
        self.frame_names = tuple(f.name for f in self.model.frames)
        self.servo_map: ServoMap | None = None
        if servo_map is not None:
            try:
                self.servo_map = ServoMap.from_file(servo_map, self.joint_names)
            except ServoMapError:
                raise
            except Exception as exc:
                raise ServoMapError(f"cannot read servo map {servo_map}: {exc}") from exc
        #: named poses, standing pose, feet, frame names, walking settings (the robot folder's
        #: poses.toml and robot.toml, read from ``data_dir``; defaults without them)
        self.robot_data = (
            RobotData() if data_dir is None else RobotData.from_folder(data_dir, names)
        )
        for alias, actual in self.robot_data.frames.items():
            if not self.model.existFrame(actual):
                raise ModelError(
                    f"{self.robot_data.source}: [frames] maps {alias!r} to {actual!r}, which is "
                    f"not a frame of {urdf.name}"
                )

    @property
    def stand_pose(self) -> str:
        """Name of the pose walks, stacks and deployments start from (``robot.toml``'s
        ``stand``; else ``walk_ready`` if the servo map has it; else ``zero``)."""
        if self.robot_data.stand is not None:
            return self.robot_data.stand
        if self.servo_map is not None and "walk_ready" in self.servo_map.poses:
            return "walk_ready"
        return "zero"

    @property
    def foot_size(self) -> tuple[float, float]:
        """(length, width) in m of the foot rectangle under each sole frame."""
        return self.robot_data.foot_length, self.robot_data.foot_width

    def pose_names(self) -> list[str]:
        """Names accepted by :meth:`configuration`."""
        names = {"zero", "stand", *self.robot_data.poses}
        if self.servo_map is not None:
            names |= set(self.servo_map.poses)
        return sorted(names)

    # ------------------------------------------------------------------ names and indices
    def joint_index(self, name: str) -> int:
        """Index of a joint in the actuated-joint vector (0..n_joints-1)."""
        try:
            return self._joint_index[name]
        except KeyError:
            raise ModelError(
                f"unknown joint {name!r}; joints of {self.name}: {', '.join(self.joint_names)}"
            ) from None

    def q_index(self, name: str) -> int:
        """Index of a joint in the configuration vector q."""
        return 7 + self.joint_index(name)

    def v_index(self, name: str) -> int:
        """Index of a joint in the velocity / increment vector."""
        return 6 + self.joint_index(name)

    def frame_id(self, name: str) -> int:
        """Pinocchio frame id of a frame (link or fixed frame) by name; the names of
        ``robot.toml``'s ``[frames]`` (``torso``, ``l_sole``, ...) map to the URDF's."""
        if isinstance(name, str):
            name = self.robot_data.frames.get(name, name)
        if not isinstance(name, str) or not self.model.existFrame(name):
            known = ", ".join(n for n in self.frame_names if not n.endswith("_fixed"))
            raise ModelError(f"unknown frame {name!r}; frames of {self.name}: {known}")
        return self.model.getFrameId(name)

    def frame_support(self, frame_id: int) -> np.ndarray:
        """The velocity coordinates (nv bools) that move a frame: its joint's ancestors and
        the joint itself (cached; read-only)."""
        cache = self.__dict__.setdefault("_frame_supports", {})
        if frame_id not in cache:
            model = self.model
            mask = np.zeros(self.nv, dtype=np.bool_)
            for j in model.supports[model.frames[frame_id].parentJoint]:
                if j:
                    joint = model.joints[j]
                    mask[joint.idx_v : joint.idx_v + joint.nv] = True
            mask.flags.writeable = False
            cache[frame_id] = mask
        return cache[frame_id]

    # ------------------------------------------------------------------ configurations
    def check_configuration(self, q: Sequence[float] | np.ndarray, what: str = "q") -> np.ndarray:
        """Return ``q`` as a C-contiguous float array after checking its size and finiteness."""
        q = np.ascontiguousarray(q, dtype=float)
        if q.shape != (self.nq,):
            raise ConfigurationError(
                f"{what}: expected a configuration of size nq={self.nq} (7 base + "
                f"{self.n_joints} joints), got shape {q.shape}"
            )
        # q·q is finite when every entry is (and cheap): the exact test only when it is not
        if not math.isfinite(q.dot(q)) and not np.isfinite(q).all():
            idx = np.flatnonzero(~np.isfinite(q))
            names = [self._q_name(i) for i in idx]
            raise ConfigurationError(f"{what}: non-finite values at {names}")
        return q

    def _q_name(self, i: int) -> str:
        base = ("base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw")
        return base[i] if i < 7 else self.joint_names[i - 7]

    def neutral(self) -> np.ndarray:
        """Base at the origin, identity orientation, all joints at zero."""
        return pin.neutral(self.model)

    def joints(self, q: np.ndarray) -> np.ndarray:
        """The actuated-joint part of a configuration (a view)."""
        return q[7:]

    def with_joints(
        self,
        joints: Sequence[float] | np.ndarray | Mapping[str, float],
        q: np.ndarray | None = None,
    ) -> np.ndarray:
        """A configuration with the given joint angles (vector in model order, or by name)."""
        out = self.neutral() if q is None else self.check_configuration(q).copy()
        if isinstance(joints, Mapping):
            for name, value in joints.items():
                out[self.q_index(name)] = value
        else:
            j = np.asarray(joints, dtype=float)
            if j.shape != (self.n_joints,):
                raise ConfigurationError(
                    f"expected {self.n_joints} joint values, got shape {j.shape}"
                )
            out[7:] = j
        return self.check_configuration(out)

    def configuration(self, name: str) -> np.ndarray:
        """A named configuration, standing on the ground.

        * ``"zero"``: all joints zero, soles on the ground.
        * ``"stand"``: the robot's standing pose (:attr:`stand_pose`).
        * a pose of ``poses.toml`` (radians), or of the servo map (``"walk_ready"``: ticks
          through the map); left sole flat at z = 0, the soles' midpoint at the origin.
        """
        if name == "stand":
            name = self.stand_pose
        if name == "zero":
            q = self.neutral()
        elif name in self.robot_data.poses:
            q = self.with_joints(self.robot_data.poses[name])
        else:
            if self.servo_map is None or name not in self.servo_map.poses:
                raise ModelError(f"unknown configuration {name!r}; known: {self.pose_names()}")
            q = self.with_joints(self.servo_map.ticks_to_angles(self.servo_map.pose_ticks(name)))
        return self.center_between_soles(self.place_on_ground(q, "l_sole"))

    def within_limits(self, q: np.ndarray, tol: float = 0.0) -> bool:
        """True if every joint lies in [q_min - tol, q_max + tol]."""
        j = self.joints(self.check_configuration(q))
        return bool(np.all(j >= self.q_min - tol) and np.all(j <= self.q_max + tol))

    def clip_to_limits(self, q: np.ndarray) -> np.ndarray:
        """A copy of q with the joints clipped into their limits."""
        out = self.check_configuration(q).copy()
        out[7:] = np.clip(out[7:], self.q_min, self.q_max)
        return out

    def random_configuration(self, rng: np.random.Generator, margin: float = 0.0) -> np.ndarray:
        """Joints uniform within limits (shrunk by ``margin`` rad), base at the origin."""
        q = self.neutral()
        lo, hi = self.q_min + margin, self.q_max - margin
        q[7:] = lo + rng.random(self.n_joints) * (hi - lo)
        return q

    def integrate(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """q ⊕ dq on the configuration manifold (free-flyer base on SE(3))."""
        return pin.integrate(self.model, q, dq)

    def difference(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """The increment dq with q0 ⊕ dq = q1."""
        return pin.difference(self.model, q0, q1)

    # ------------------------------------------------------------------ kinematics (one-off)
    def frame_placement(self, q: np.ndarray, frame: str) -> pin.SE3:
        """World placement of a frame at configuration q."""
        fid = self.frame_id(frame)
        q = self.check_configuration(q)
        pin.framesForwardKinematics(self.model, self.data, q)
        return pin.SE3(self.data.oMf[fid])

    def com(self, q: np.ndarray) -> np.ndarray:
        """Centre of mass in the world frame."""
        q = self.check_configuration(q)
        return pin.centerOfMass(self.model, self.data, q).copy()

    def frame_jacobian(
        self, q: np.ndarray, frame: str, reference: str = "local_world_aligned"
    ) -> np.ndarray:
        """6 x nv frame Jacobian [linear; angular].

        ``reference``: ``"local_world_aligned"`` (frame-origin velocity in world axes, the
        default), ``"local"`` (frame axes) or ``"world"`` (spatial velocity at the world
        origin).
        """
        fid = self.frame_id(frame)
        try:
            ref = _REFERENCES[reference]
        except KeyError:
            raise ModelError(
                f"unknown reference {reference!r}; use one of {sorted(_REFERENCES)}"
            ) from None
        q = self.check_configuration(q)
        return pin.computeFrameJacobian(self.model, self.data, q, fid, ref).copy()

    def com_jacobian(self, q: np.ndarray) -> np.ndarray:
        """3 x nv Jacobian of the centre of mass (world axes)."""
        q = self.check_configuration(q)
        return pin.jacobianCenterOfMass(self.model, self.data, q).copy()

    # ------------------------------------------------------------------ placing on the ground
    def place_on_ground(
        self, q: np.ndarray, sole: str = "l_sole", at: pin.SE3 | None = None
    ) -> np.ndarray:
        """Move the floating base so that ``sole`` lies flat at z = 0.

        The sole keeps its current x, y and heading (yaw) unless ``at`` gives the sole's
        target placement (which must itself be flat for the result to be on the ground).
        """
        q = self.check_configuration(q).copy()
        oMs = self.frame_placement(q, sole)
        if at is None:
            R = oMs.rotation
            yaw = np.arctan2(R[1, 0], R[0, 0])
            at = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.array([*oMs.translation[:2], 0]))
        oMb = pin.XYZQUATToSE3(q[:7])
        new_base = at * oMs.inverse() * oMb
        q[:7] = pin.SE3ToXYZQUAT(new_base)
        return q

    def center_between_soles(self, q: np.ndarray) -> np.ndarray:
        """Shift the base horizontally so the midpoint between the soles is at x = y = 0."""
        q = self.check_configuration(q).copy()
        left = self.frame_placement(q, "l_sole").translation
        right = self.frame_placement(q, "r_sole").translation
        q[:2] -= 0.5 * (left[:2] + right[:2])
        return q


class Kinematics:
    """Kinematic state of one configuration, computed once and shared by every task.

    ``update(q)`` runs forward kinematics, all joint Jacobians, frame placements, the CoM
    and its Jacobian in one pass; the accessors then only read the cached Pinocchio data.
    """

    def __init__(self, robot: Robot, q: np.ndarray | None = None) -> None:
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.q = robot.neutral()
        self._rotations: dict[int, np.ndarray] = {}
        self._translations: dict[int, np.ndarray] = {}
        self.update(self.q if q is None else q)

    def update(self, q: np.ndarray) -> None:
        """Recompute every kinematic quantity at q (checked for size and finiteness)."""
        q = self.robot.check_configuration(q)
        self.q = q
        model, data = self.model, self.data
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        pin.jacobianCenterOfMass(model, data, False)

    @property
    def com(self) -> np.ndarray:
        """Centre of mass (world), a view into the Pinocchio data."""
        return self.data.com[0]

    @property
    def com_jacobian(self) -> np.ndarray:
        """3 x nv CoM Jacobian (world axes), a view into the Pinocchio data."""
        return self.data.Jcom

    def placement(self, frame_id: int) -> pin.SE3:
        """World placement of a frame (a reference into the Pinocchio data)."""
        return self.data.oMf[frame_id]

    def rotation(self, frame_id: int) -> np.ndarray:
        """World rotation of a frame: a cached view that follows every :meth:`update`."""
        try:
            return self._rotations[frame_id]
        except KeyError:
            view = self._rotations[frame_id] = self.data.oMf[frame_id].rotation
            return view

    def translation(self, frame_id: int) -> np.ndarray:
        """World position of a frame: a cached view that follows every :meth:`update`."""
        try:
            return self._translations[frame_id]
        except KeyError:
            view = self._translations[frame_id] = self.data.oMf[frame_id].translation
            return view

    def frame_jacobian(self, frame_id: int, reference=LOCAL_WORLD_ALIGNED) -> np.ndarray:
        """6 x nv frame Jacobian from the cached joint Jacobians."""
        return pin.getFrameJacobian(self.model, self.data, frame_id, reference)
