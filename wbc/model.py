"""Robot model on Pinocchio: loading, kinematics, Jacobians, named configurations.

Configurations follow Pinocchio's free-flyer convention: ``q = [x, y, z, qx, qy, qz, qw,
joints...]`` (nq = 7 + n) and velocities/increments ``v = [v_lin, v_ang, joint rates]``
(nv = 6 + n), base twist expressed in the base frame. The joint order is the model's
(:attr:`Robot.joint_names`) everywhere in wbc.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from .exceptions import ConfigurationError, ModelError, ServoMapError
from .geometry import yaw_of
from .paths import read_toml, robots_dir
from .robot_data import ROBOT_KEYS, RobotData
from .roles import JointRoles, find_roles
from .servo_map import ServoMap

_F8 = np.dtype(np.float64)  # (the dtype of a float64 array: checked by identity)
_STRIDE = (8,)  # (the strides of a contiguous float64 vector)

WORLD = pin.ReferenceFrame.WORLD
#: how far the base quaternion of a configuration may be from unit norm
QUATERNION_TOL = 1e-6
LOCAL = pin.ReferenceFrame.LOCAL
LOCAL_WORLD_ALIGNED = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_REFERENCES = {"world": WORLD, "local": LOCAL, "local_world_aligned": LOCAL_WORLD_ALIGNED}


#: the pose every tool starts from (stacks' initial targets, walking references, the viewer);
#: a robot folder that does not define it stands in its zero pose instead
STANDING_POSE = "walk_ready"
#: the frames the stacks and the walking code name; ``robot.toml`` ``[frames]`` may map them
#: to a URDF's own names
STANDARD_FRAMES = ("torso", "l_sole", "r_sole")
#: the optional files of a robot folder (see ``wbc robot init`` and robots/README.md)
SERVO_MAP_FILE = "servos.toml"
POSES_FILE = "poses.toml"
STACK_FILE = "stack.toml"
ROBOT_FILE = "robot.toml"


def available_robots() -> list[str]:
    """Names accepted by :func:`load_robot` (folders of ``robots/`` holding a URDF)."""
    root = robots_dir()
    return sorted(p.name for p in root.iterdir() if p.is_dir() and any(p.glob("*.urdf")))


def folder_urdf(folder: Path) -> Path:
    """The URDF of a robot folder: ``<folder name>.urdf``, else the folder's only ``*.urdf``."""
    named = folder / f"{folder.name}.urdf"
    if named.is_file():
        return named
    urdfs = sorted(folder.glob("*.urdf"))
    if len(urdfs) != 1:
        found = [u.name for u in urdfs] or "none"
        raise ModelError(
            f"robot folder {folder}: needs {folder.name}.urdf or exactly one *.urdf (found {found})"
        )
    return urdfs[0]


def load_robot(name_or_path: str | Path = "bioloid", servo_map: str | Path | None = None) -> Robot:
    """Load a robot by name (``"bioloid"``), robot folder path or URDF path.

    A robot folder holds the URDF and, all optional: ``servos.toml`` (servo map, poses in
    ticks), ``poses.toml`` (named poses in radians), ``stack.toml`` (default task stack) and
    ``robot.toml`` (``[frames]``: the URDF names of ``torso``, ``l_sole``, ``r_sole``). A URDF
    path picks up those files next to it; ``servo_map`` names another servo map. What is
    missing is listed, one line each, in :attr:`Robot.notes`.
    """
    path = Path(name_or_path)
    if path.suffix.lower() == ".urdf" or path.is_file():
        urdf = path
    elif path.is_dir() and (len(path.parts) > 1 or not (robots_dir() / str(path)).is_dir()):
        urdf = folder_urdf(path)
    else:
        folder = robots_dir() / str(name_or_path)
        if not folder.is_dir():
            raise ModelError(
                f"unknown robot {str(name_or_path)!r}: not a URDF path, not a robot folder and "
                f"not one of {available_robots()}"
            )
        urdf = folder_urdf(folder)
    folder = urdf.parent
    if servo_map is None and (folder / SERVO_MAP_FILE).is_file():
        servo_map = folder / SERVO_MAP_FILE
    if servo_map is not None and _is_template(Path(servo_map)):
        servo_map = None  # a `wbc robot init` template not filled in yet (noted below)
    poses = folder / POSES_FILE
    meta = folder / ROBOT_FILE
    robot = Robot(
        urdf,
        servo_map,
        poses=poses if poses.is_file() else None,
        frames=read_frames(meta) if meta.is_file() else None,
        data_dir=folder,
    )
    stack = folder / STACK_FILE
    robot.default_stack = stack if stack.is_file() else None
    if urdf.is_file():
        robot.notes = _missing_parts(robot, folder)
    return robot


def print_notes(robot: Robot, command: str) -> None:
    """Print :attr:`Robot.notes` to stderr, one ``wbc <command>: note: ...`` line each."""
    for note in robot.notes:
        print(f"wbc {command}: note: {note}", file=sys.stderr)


def _is_template(path: Path) -> bool:
    """A servo map file with no TOML content at all (only comments): an unfilled template."""
    if not path.is_file():
        return False
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    return not any(line.strip() and not line.lstrip().startswith("#") for line in lines)


def read_frames(path: Path) -> dict[str, str]:
    """``robot.toml``'s ``[frames]`` table: standard frame name -> the URDF's frame name."""
    raw = read_toml(path, "robot file", ModelError)
    extra = sorted(set(raw) - set(ROBOT_KEYS))
    if extra:
        raise ModelError(f"robot file {path}: unknown keys {extra}; allowed: {list(ROBOT_KEYS)}")
    frames = raw.get("frames", {})
    if not isinstance(frames, dict) or not all(isinstance(v, str) for v in frames.values()):
        raise ModelError(f"robot file {path}: [frames] must map names to URDF frame names")
    unknown = sorted(set(frames) - set(STANDARD_FRAMES))
    if unknown:
        raise ModelError(
            f"robot file {path}: [frames] has unknown keys {unknown}; allowed: "
            f"{list(STANDARD_FRAMES)}"
        )
    return dict(frames)


def _missing_parts(robot: Robot, folder: Path) -> list[str]:
    """One line per optional part the robot folder lacks that changes what the tools do (a
    missing ``stack.toml`` does not: the stacks of ``tasks/`` serve; ``wbc robot check`` lists
    it)."""
    notes = []
    if robot.servo_map is None and not (folder / "ssc32.toml").is_file():
        state = "is an unfilled template" if (folder / SERVO_MAP_FILE).is_file() else "missing"
        notes.append(f"{folder / SERVO_MAP_FILE} {state}: no servo IDs (wbc deploy is unavailable)")
    if robot.stand_pose == "zero":
        notes.append(
            f"no pose {STANDING_POSE!r} in {folder / POSES_FILE} or the servo map: "
            "starting from the zero pose (all joints 0)"
        )
    missing = [f for f in STANDARD_FRAMES if not robot.has_frame(f)]
    if missing:
        notes.append(
            f"frames {missing} not in {robot.urdf_path.name} (nor mapped in "
            f"{folder / ROBOT_FILE}): the walking stacks need them"
        )
    return notes


def measure_foot(robot: Robot) -> tuple[float, float]:
    """(length, width) in m of the foot rectangle centred under the left sole frame: the
    collision boxes of the sole's link whose bottom lies within 5 mm of the sole plane, in
    the sole frame (the largest rectangle centred on the sole frame inside them).
    ModelError if there is none (state ``[feet]`` in robot.toml then)."""
    where = f"{robot.name}: the foot size"
    hint = f"state [feet] length and width in {ROBOT_FILE}"
    if not robot.has_frame("l_sole"):
        raise ModelError(f"{where}: no frame 'l_sole' ({hint})")
    sole = robot.model.frames[robot.frame_id("l_sole")]
    try:
        geometry = pin.buildGeomFromUrdf(
            robot.model, str(robot.urdf_path), pin.GeometryType.COLLISION
        )
    except Exception as exc:  # no hpp-fcl, or meshes that cannot be read
        raise ModelError(f"{where}: cannot read the collision geometry ({exc}); {hint}") from None
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for g in geometry.geometryObjects:
        half = getattr(g.geometry, "halfSide", None)
        if g.parentJoint != sole.parentJoint or half is None:
            continue
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        M = sole.placement.inverse() * g.placement
        corners = (M.rotation @ (signs * np.asarray(half)).T).T + M.translation
        if corners[:, 2].min() > 0.005 or corners[:, 2].max() < -0.005:
            continue
        lo, hi = np.minimum(lo, corners.min(axis=0)), np.maximum(hi, corners.max(axis=0))
    if not np.all(np.isfinite(lo)):
        raise ModelError(f"{where}: the sole's link has no collision box at the sole; {hint}")
    length, width = 2.0 * np.minimum(hi[:2], -lo[:2])
    if not (length > 0 and width > 0):
        raise ModelError(f"{where}: the sole frame lies outside its collision box; {hint}")
    return float(length), float(width)


class Robot:
    """A floating-base robot: Pinocchio model and data plus joint/frame bookkeeping."""

    def __init__(
        self,
        urdf: str | Path,
        servo_map: str | Path | None = None,
        poses: str | Path | Mapping[str, Mapping[str, float]] | None = None,
        frames: Mapping[str, str] | None = None,
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
        #: the joint limits that :meth:`checked_configuration` compares with (q_min and q_max
        #: as built: edited in place they follow, re-assigned they do not)
        self.checked_limits = (self.q_min, self.q_max)
        self.v_max = np.array(self.model.velocityLimit[6:])
        self.total_mass = float(pin.computeTotalMass(self.model))
        self.frame_names = tuple(f.name for f in self.model.frames)
        self._frame_ids: dict[str, int] = {}  # frame_id's answers, by name
        #: (|‖base quaternion‖² − 1| of a configuration, +inf if an entry is not finite; a
        #: joint outside :attr:`checked_limits`): the compiled check of
        #: :meth:`checked_configuration` (loaded at its first call)
        self._configuration_check: Callable[..., tuple[float, bool]] | None = None
        #: standard frame name (``torso``, ``l_sole``, ``r_sole``) -> this URDF's frame name
        self.frame_aliases: dict[str, str] = dict(frames or {})
        for alias, actual in self.frame_aliases.items():
            if not self.model.existFrame(actual):
                raise ModelError(
                    f"{self.name}: frame {alias!r} is mapped to {actual!r}, which is not a "
                    f"frame of {urdf.name}; links: {', '.join(self.link_names())}"
                )
        #: lines naming the optional parts of the robot folder that are missing
        self.notes: list[str] = []
        #: the robot folder's default task stack (``stack.toml``), if any
        self.default_stack: Path | None = None
        self.servo_map: ServoMap | None = None
        if servo_map is not None:
            try:
                self.servo_map = ServoMap.from_file(servo_map, self.joint_names)
            except ServoMapError:
                raise
            except Exception as exc:
                raise ServoMapError(f"cannot read servo map {servo_map}: {exc}") from exc
        #: named poses in radians by joint name (``poses.toml``; joints not named are 0)
        self.poses: dict[str, np.ndarray] = {}
        if poses is not None:
            self.poses = self._read_poses(poses)
        #: standing pose, feet and walking settings (the robot folder's robot.toml, read from
        #: ``data_dir``; defaults without it): :mod:`wbc.robot_data`
        self.robot_data = (
            RobotData() if data_dir is None else RobotData.from_folder(data_dir, self.joint_names)
        )

    @property
    def stand_pose(self) -> str:
        """Name of the pose walks, stacks and deployments start from (``robot.toml``'s
        ``stand``; else ``walk_ready`` if the robot has it; else ``zero``)."""
        if self.robot_data.stand is not None:
            return self.robot_data.stand
        mapped = self.servo_map.poses if self.servo_map is not None else {}
        return STANDING_POSE if STANDING_POSE in self.poses or STANDING_POSE in mapped else "zero"

    @property
    def foot_size(self) -> tuple[float, float]:
        """(length, width) in m of the foot rectangle under each sole frame: ``robot.toml``
        ``[feet]``, else the sole link's collision box (:func:`measure_foot`)."""
        cache = self.__dict__.setdefault("_foot_size", [])
        if not cache:
            length, width = self.robot_data.foot_length, self.robot_data.foot_width
            if length is None or width is None:
                measured = measure_foot(self)
                length = measured[0] if length is None else length
                width = measured[1] if width is None else width
            cache.append((length, width))
        return cache[0]

    @property
    def roles(self) -> JointRoles:
        """Each leg's and arm's joints by role, found from the kinematic tree
        (:func:`wbc.roles.find_roles`; ``robot.toml`` ``[joints]`` overrides); ModelError (one
        line) for a robot whose legs cannot be understood."""
        cache = self.__dict__.setdefault("_roles", [])
        if not cache:
            cache.append(find_roles(self, self.robot_data.joints))
        return cache[0]

    def _read_poses(self, source: str | Path | Mapping) -> dict[str, np.ndarray]:
        if isinstance(source, Mapping):
            where, raw = "poses", {"poses": source}
        else:
            where = f"poses file {source}"
            raw = read_toml(Path(source), "poses file", ModelError)
        extra = sorted(set(raw) - {"poses"})
        if extra:
            raise ModelError(f"{where}: unknown keys {extra}; allowed: [poses.<name>] tables")
        out = {}
        for name, pose in raw.get("poses", {}).items():
            if not isinstance(pose, Mapping):
                raise ModelError(f"{where}: [poses.{name}] must be a table of joint = radians")
            joints = np.zeros(self.n_joints)
            for joint, value in pose.items():
                if joint not in self._joint_index:
                    raise ModelError(
                        f"{where}: [poses.{name}] names unknown joint {joint!r}; joints: "
                        f"{', '.join(self.joint_names)}"
                    )
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise ModelError(
                        f"{where}: [poses.{name}] {joint} = {value!r}: must be a number (rad)"
                    )
                if not math.isfinite(value):
                    raise ModelError(f"{where}: [poses.{name}] {joint} = {value}: not finite")
                joints[self._joint_index[joint]] = float(value)
            out[name] = joints
        return out

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
        """Pinocchio frame id of a frame (link or fixed frame) by name; the standard names
        ``torso``, ``l_sole``, ``r_sole`` follow ``robot.toml``'s ``[frames]`` when it maps them."""
        ids = self._frame_ids
        key = name if isinstance(name, str) else None
        if key in ids:  # (a support switch looks its frames up: no Pinocchio call)
            return ids[key]
        if isinstance(name, str):
            name = self.frame_aliases.get(name, name)
        if not isinstance(name, str) or not self.model.existFrame(name):
            raise ModelError(
                f"unknown frame {name!r}; links of {self.name}: {', '.join(self.link_names())}"
            )
        fid = ids[key] = self.model.getFrameId(name)
        return fid

    def has_frame(self, name: str) -> bool:
        """True if :meth:`frame_id` knows ``name`` (directly or through ``[frames]``)."""
        return self.model.existFrame(self.frame_aliases.get(name, name))

    def link_names(self) -> list[str]:
        """The URDF's links (the frames tasks should name), without the floating base joint."""
        return [f.name for f in self.model.frames if f.type == pin.FrameType.BODY]

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
        """Return ``q`` as a C-contiguous float array after checking its size, its finiteness
        and its base quaternion (unit to :data:`QUATERNION_TOL`: a zero or scaled quaternion
        is no rotation, and is refused rather than normalised)."""
        return self.checked_configuration(q, what)[0]

    def checked_configuration(
        self, q: Sequence[float] | np.ndarray, what: str = "q"
    ) -> tuple[np.ndarray, bool]:
        """:meth:`check_configuration`'s q, and True if a joint of it is outside
        :attr:`checked_limits` (a NaN joint is not), both from one compiled call
        (:func:`wbc.compiled.prelude.configuration_check`: a tick's
        :meth:`Kinematics.update`, whose solver reads the second after its solve)."""
        # (1-D and contiguous: the strides' tuple, cheaper cold than the flags' object)
        if not (type(q) is np.ndarray and q.dtype is _F8 and q.strides == _STRIDE):
            q = np.ascontiguousarray(q, dtype=float)  # (else q itself, as this returns it)
        if q.shape != (self.nq,):
            raise ConfigurationError(
                f"{what}: expected a configuration of size nq={self.nq} (7 base + "
                f"{self.n_joints} joints), got shape {q.shape}"
            )
        q_min, q_max = self.checked_limits
        check = self._configuration_check
        if check is None:  # (numba is imported by the first check, not by ``import wbc``)
            from .compiled.prelude import configuration_entry

            check = self._configuration_check = configuration_entry()
        defect, outside = check(q, q_min, q_max)
        if defect <= 2.0 * QUATERNION_TOL:  # (one compiled call: the hot path)
            return q, outside
        if not np.isfinite(q).all():
            idx = np.flatnonzero(~np.isfinite(q))
            names = [self._q_name(i) for i in idx]
            raise ConfigurationError(f"{what}: non-finite values at {names}")
        x, y, z, w = q[3:7].tolist()
        norm2 = x * x + y * y + z * z + w * w
        if abs(norm2 - 1.0) > 2.0 * QUATERNION_TOL:  # |‖quat‖ − 1| <= 1e-6, to first order
            raise ConfigurationError(
                f"{what}: the base quaternion (base_qx, base_qy, base_qz, base_qw) = "
                f"{q[3:7].tolist()} has norm {math.sqrt(norm2):.6g}; it must be unit "
                f"(to {QUATERNION_TOL:g}): normalise it"
            )
        return q, outside

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
        * a pose of ``poses.toml`` (radians), or of the servo map (ticks through the map);
          left sole flat at z = 0, the soles' midpoint at the origin.
        * ``"walk_ready"`` (:data:`STANDING_POSE`) on a robot that defines no such pose: its
          standing pose (``robot.toml``'s ``stand``), else the zero pose (:attr:`notes` says
          so when the robot is loaded).
        """
        if name == "stand":  # the robot's standing pose (robot.toml's stand, else walk_ready)
            name = self.stand_pose
        elif name == STANDING_POSE and name not in self.pose_names():
            name = self.stand_pose  # a robot whose standing pose has another name (or zero)
        if name == "zero" or (name == STANDING_POSE and name not in self.pose_names()):
            q = self.neutral()
        elif name in self.poses:
            q = self.with_joints(self.poses[name])
        else:
            if self.servo_map is None or name not in self.servo_map.poses:
                raise ModelError(f"unknown configuration {name!r}; known: {self.pose_names()}")
            q = self.with_joints(self.servo_map.ticks_to_angles(self.servo_map.pose_ticks(name)))
        if not (self.has_frame("l_sole") and self.has_frame("r_sole")):
            return q  # nothing to stand on: base at the origin
        return self.center_between_soles(self.place_on_ground(q, "l_sole"))

    def pose_names(self) -> list[str]:
        """Names :meth:`configuration` accepts besides ``"zero"`` (poses.toml, servo map)."""
        mapped = sorted(self.servo_map.poses) if self.servo_map else []
        return ["zero", "stand", *sorted(self.poses), *(n for n in mapped if n not in self.poses)]

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

    def placements_in(self, q: np.ndarray, base: str, frames: Sequence[str]) -> list[pin.SE3]:
        """The placements of ``frames`` in frame ``base`` at configuration q (``base``⁻¹ ·
        each), from one forward kinematics pass."""
        ids = [self.frame_id(f) for f in (base, *frames)]
        q = self.check_configuration(q)
        pin.framesForwardKinematics(self.model, self.data, q)
        base_placement = self.data.oMf[ids[0]]
        return [base_placement.actInv(self.data.oMf[i]) for i in ids[1:]]

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
            yaw = yaw_of(R)
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
        q, outside = self.robot.checked_configuration(q)
        self.q = q
        #: True if a joint of :attr:`q` is outside the robot's range
        #: (:attr:`Robot.checked_limits`)
        self.outside = outside
        model, data = self.model, self.data
        # one pass: the joints' placements and Jacobians (data.oMi, data.J: what
        # computeJointJacobians gives, bitwise), the CoM and its Jacobian; then the frames
        pin.jacobianCenterOfMass(model, data, q, False)
        pin.updateFramePlacements(model, data)

    @property
    def com(self) -> np.ndarray:
        """Centre of mass (world), a copy: safe to keep after this object is gone.

        Pinocchio's ``data.com[0]`` is a view into memory owned by ``data``, which does not keep
        ``data`` alive (``Kinematics(robot, q).com`` read freed memory); hot paths that want the
        view use ``kin.data.com[0]`` while ``kin`` lives.
        """
        return self.data.com[0].copy()

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

    def frame_placements(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Every frame's world rotation (nframes x 3 x 3) and position (nframes x 3) as two
        strided views of Pinocchio's placements (``data.oMf``, one contiguous array of
        rotation-then-translation records) that follow every :meth:`update` — what the
        compiled tick reads its frames from (two arrays instead of two per frame). None if
        this Pinocchio lays the placements out otherwise (checked for every frame)."""
        oMf = self.data.oMf
        n = len(oMf)
        R0, p0 = self.rotation(0), self.translation(0)

        def address(a: np.ndarray) -> int:
            return a.__array_interface__["data"][0]

        stride = address(self.rotation(1)) - address(R0) if n > 1 else 96
        offset = address(p0) - address(R0)
        for f in range(n):
            R, p = self.rotation(f), self.translation(f)
            if (
                address(R) != address(R0) + f * stride
                or address(p) != address(R) + offset
                or R.strides != R0.strides
                or p.strides != p0.strides
            ):
                return None
        as_strided = np.lib.stride_tricks.as_strided
        return (
            as_strided(R0, shape=(n, 3, 3), strides=(stride, *R0.strides)),
            as_strided(p0, shape=(n, 3), strides=(stride, *p0.strides)),
        )

    def frame_jacobian(self, frame_id: int, reference=LOCAL_WORLD_ALIGNED) -> np.ndarray:
        """6 x nv frame Jacobian from the cached joint Jacobians."""
        return pin.getFrameJacobian(self.model, self.data, frame_id, reference)
