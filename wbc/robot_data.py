"""Per-robot data beside the URDF: named poses, the standing pose, feet, frames, walking.

What the library used to assume of the Bioloid (a Walk Ready pose in the Dynamixel servo map,
its feet, its frame names, walking settings tuned to its hips) is read from the robot's folder
and model instead. Two optional files:

``poses.toml``: named poses in radians of the model's joints (joints not named are 0)::

    [poses.crouch]
    LKnee = 0.8154

``robot.toml``::

    stand = "crouch"                 # the pose walks, stacks, viewer and deploy start from
    [frames]                         # the names wbc's stacks use -> the URDF's, if they differ
    torso = "base_link"
    [feet]
    length = 0.07                    # m, foot rectangle centred under each sole frame
    width = 0.04
    [joints.left]                    # joint roles the kinematic tree does not tell (wbc.roles)
    knee = "LKnee"
    [legs]                           # leg measurements stated by hand (LegGeometry fields)
    pelvis_gain = 1.3
    [walking]
    fit_speed = true                 # fit the sized walks to the servos' speed (default;
                                     # false: only on servos, wbc.walking.sizing)
    fit_torque = false               # shorten their steps to 0.8 of stall torque (default off)
    [walking.walk10]                 # keyword overrides of a walking reference's builder
    step_length = 0.02
    fit_speed = false                # (this walk's own choice)
    [servo]                          # the simulator's servo model (wbc.sim.actuator)
    law = "hobby_pwm"
    [imu]                            # where the IMU sits (simulator and closed loop)
    frame = "torso"
    rpy_deg = [0, 0, 0]              # its axes in that frame (roll, pitch, yaw, degrees)
    [balance.stepping]               # the closed loop's step adjustment (wbc.balance.stepping)
    band_x = 0.06                    # m: the DCM error its unpushed walks show

Without them a robot keeps the defaults: Walk Ready from the servo map if it has one, else the
zero pose; feet from the sole link's collision box; joint roles and legs measured from the
model; the URDF's own frame names; walking settings derived from the legs and the servos.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .exceptions import ModelError
from .paths import read_toml

ROBOT_FILE = "robot.toml"
POSES_FILE = "poses.toml"
ROBOT_KEYS = (
    "balance", "feet", "frames", "imu", "joints", "legs", "servo", "stand", "walking",
)  # fmt: skip
#: ``[balance.<table>]`` keys a robot may state, with the range allowed (upper bound, unit):
#: the closed loop's settings measured on the robot — what its unpushed walks show
#: (:class:`wbc.balance.stepping.SteppingParams` ``band_x`` / ``band_y``)
BALANCE_KEYS: dict[str, dict[str, tuple[float, str]]] = {
    # the dead bands and the push trigger's DCM jump per tick (wbc.balance.stepping_params)
    "stepping": {"band_x": (1.0, "m"), "band_y": (1.0, "m"), "trigger_jump": (1.0, "m")},
}


@dataclass(frozen=True)
class RobotData:
    """Named poses (rad, by joint name), standing pose, foot size (m), frame names, walking."""

    poses: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    stand: str | None = None
    #: the foot size stated in ``[feet]`` (m; None: measured from the model,
    #: :attr:`wbc.model.Robot.foot_size`)
    foot_length: float | None = None
    foot_width: float | None = None
    #: the project's frame names -> the URDF's (``[frames]``, e.g. ``torso = "base_link"``)
    frames: Mapping[str, str] = field(default_factory=dict)
    #: per-trajectory keyword overrides for the walking references (``[walking.<name>]``)
    walking: Mapping[str, Mapping[str, object]] = field(default_factory=dict)
    source: str = "<defaults>"
    #: the servo model of the joints (``[servo]``, checked by :mod:`wbc.sim.actuator`)
    servo: Mapping[str, object] = field(default_factory=dict)
    #: the IMU placement (``[imu]`` frame, offset m, rpy_deg: its mount, used by the
    #: simulator and the closed loop, :func:`wbc.sim.model.imu_mount`)
    imu: Mapping[str, object] = field(default_factory=dict)
    #: joint roles named by hand (``[joints.left]`` / ``[joints.right]``: role = joint name;
    #: :mod:`wbc.roles` finds the others from the kinematic tree)
    joints: Mapping[str, Mapping[str, str]] = field(default_factory=dict)
    #: the leg measurements stated by hand (``[legs]``: :class:`wbc.walking.legs.LegGeometry`
    #: fields, m and rad), replacing the ones measured from the model
    legs: Mapping[str, object] = field(default_factory=dict)
    #: ``[walking] fit_speed``: fit the sized walking references (slower, then a lower swing)
    #: until no joint is asked for more than its share of its speed (:mod:`wbc.walking.sizing`);
    #: false: only where a walk is played on servos (``build(on_servos=True)``)
    fit_speed: bool = True
    #: ``[walking] fit_torque``: shorten the sized walks' steps until the predicted peak joint
    #: torque is within its share of stall (:func:`wbc.walking.sizing.fit_torque_share`; off)
    fit_torque: bool = False
    #: the closed loop's settings measured on this robot (``[balance.<table>]``, m; the keys
    #: of :data:`BALANCE_KEYS`), e.g. ``{"stepping": {"band_y": 0.045}}``
    balance: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    @property
    def feet_given(self) -> tuple[str, ...]:
        """Which of the foot's length and width ``[feet]`` states (the others come from the
        model)."""
        stated = (("length", self.foot_length), ("width", self.foot_width))
        return tuple(k for k, v in stated if v is not None)

    @classmethod
    def from_folder(cls, folder: str | Path, joint_names: Sequence[str]) -> RobotData:
        """Read a robot folder's ``robot.toml`` and ``poses.toml`` (both optional)."""
        folder = Path(folder)
        robot_file, poses_file = folder / ROBOT_FILE, folder / POSES_FILE
        poses = read_poses(poses_file, joint_names) if poses_file.is_file() else {}
        if not robot_file.is_file():
            return cls(poses=poses, source=str(folder))
        raw = read_toml(robot_file, "robot file", ModelError)
        where = f"robot file {robot_file}"
        extra = sorted(set(raw) - set(ROBOT_KEYS))
        if extra:
            raise ModelError(f"{where}: unknown keys {extra}; allowed: {', '.join(ROBOT_KEYS)}")
        frames = raw.get("frames", {})
        if not isinstance(frames, Mapping) or not all(isinstance(v, str) for v in frames.values()):
            raise ModelError(f"{where}: [frames] maps names to URDF frame names (strings)")
        walking = dict(raw.get("walking", {}))
        fit_speed = walking.pop("fit_speed", True)
        fit_torque = walking.pop("fit_torque", False)
        for key, flag in (("fit_speed", fit_speed), ("fit_torque", fit_torque)):
            if not isinstance(flag, bool):
                raise ModelError(f"{where}: [walking] {key} = {flag!r}: true or false")
        if not all(isinstance(v, Mapping) for v in walking.values()):
            raise ModelError(f"{where}: [walking.<trajectory>] entries must be tables")
        tables = {}
        for key in ("servo", "imu", "legs"):
            tables[key] = raw.get(key, {})
            if not isinstance(tables[key], Mapping):
                raise ModelError(f"{where}: [{key}] must be a table")
        stand = raw.get("stand")
        if stand is not None and stand not in poses and stand != "zero":
            raise ModelError(
                f"{where}: stand = {stand!r} is not 'zero' or a pose of {poses_file.name} "
                f"{sorted(poses)}"
            )
        feet = raw.get("feet", {})
        extra = sorted(set(feet) - {"length", "width"})
        if extra:
            raise ModelError(f"{where}: [feet] has unknown keys {extra}; allowed: length, width")
        size: dict[str, float | None] = {"length": None, "width": None}
        for key in (k for k in size if k in feet):
            v = feet[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < 1:
                raise ModelError(f"{where}: [feet] {key} = {v!r}: must be in (0, 1) m")
            size[key] = float(v)
        return cls(
            poses,
            stand,
            size["length"],
            size["width"],
            frames,
            walking,
            str(folder),
            joints=read_joint_roles(raw.get("joints", {}), joint_names, where),
            fit_speed=fit_speed,
            fit_torque=fit_torque,
            balance=read_balance(raw.get("balance", {}), where),
            **tables,
        )


def read_balance(table: object, where: str) -> dict[str, dict[str, float]]:
    """``[balance.<table>]``: the keys of :data:`BALANCE_KEYS`, each in its range."""
    if not isinstance(table, Mapping) or not all(isinstance(v, Mapping) for v in table.values()):
        raise ModelError(f"{where}: [balance] holds tables: {', '.join(BALANCE_KEYS)}")
    out: dict[str, dict[str, float]] = {}
    for name, values in table.items():
        allowed = BALANCE_KEYS.get(name)
        if allowed is None:
            raise ModelError(
                f"{where}: unknown table [balance.{name}]; allowed: {', '.join(BALANCE_KEYS)}"
            )
        extra = sorted(set(values) - set(allowed))
        if extra:
            raise ModelError(
                f"{where}: [balance.{name}] has unknown keys {extra}; allowed: {', '.join(allowed)}"
            )
        for key, v in values.items():
            hi, unit = allowed[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < hi:
                raise ModelError(
                    f"{where}: [balance.{name}] {key} = {v!r}: must be in [0, {hi:g}) {unit}"
                )
        out[name] = {k: float(v) for k, v in values.items()}
    return out


def read_joint_roles(
    table: object, joint_names: Sequence[str], where: str
) -> dict[str, dict[str, str]]:
    """``[joints.left]`` / ``[joints.right]``: role = joint name (roles of :mod:`wbc.roles`)."""
    from .roles import ROLES, SIDES

    if not isinstance(table, Mapping):
        raise ModelError(f"{where}: [joints] must hold [joints.left] / [joints.right] tables")
    extra = sorted(set(table) - set(SIDES))
    if extra:
        raise ModelError(f"{where}: [joints] has unknown keys {extra}; allowed: left, right")
    out: dict[str, dict[str, str]] = {}
    for side, roles in table.items():
        if not isinstance(roles, Mapping):
            raise ModelError(f"{where}: [joints.{side}] must be a table of role = joint name")
        for role, joint in roles.items():
            if role not in ROLES:
                raise ModelError(
                    f"{where}: [joints.{side}] {role}: unknown role; allowed: {', '.join(ROLES)}"
                )
            if joint not in joint_names:
                raise ModelError(
                    f"{where}: [joints.{side}] {role} = {joint!r} is not a joint of the model"
                )
        out[side] = dict(roles)
    return out


def read_poses(path: Path, joint_names: Sequence[str]) -> dict[str, dict[str, float]]:
    """``poses.toml``: ``[poses.<name>]`` tables of joint = radians, checked against the joints."""
    raw = read_toml(path, "poses file", ModelError)
    where = f"poses file {path}"
    extra = sorted(set(raw) - {"poses"})
    if extra:
        raise ModelError(f"{where}: unknown keys {extra}; allowed: [poses.<name>] tables")
    known = set(joint_names)
    poses: dict[str, dict[str, float]] = {}
    for name, pose in raw.get("poses", {}).items():
        if not isinstance(pose, Mapping):
            raise ModelError(f"{where}: [poses.{name}] must be a table of joint = radians")
        unknown = sorted(set(pose) - known)
        if unknown:
            raise ModelError(f"{where}: pose {name!r} names unknown joints {unknown}")
        for joint, value in pose.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ModelError(f"{where}: pose {name!r} {joint} = {value!r}: not a number")
            if not math.isfinite(value):
                raise ModelError(f"{where}: pose {name!r} {joint} = {value!r}: not finite")
        poses[name] = {j: float(v) for j, v in pose.items()}
    return poses
