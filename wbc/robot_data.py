"""Per-robot data beside the URDF: named poses, the standing pose, the feet (``robot.toml``).

What the library used to assume of the Bioloid (a Walk Ready pose in the Dynamixel servo map,
its 101 x 61 mm feet) is read from the robot's folder instead::

    stand = "crouch"                 # the pose every walk/stack/deploy starts from
    [frames]                         # the frames wbc's stacks use, if the URDF names differ
    torso = "base_link"
    l_sole = "left_foot"
    [feet]
    length = 0.07                    # m, foot rectangle centred under each sole frame
    width = 0.04
    [poses.crouch]                   # degrees of our joint angles, by joint (others: 0)
    l_knee = 46.7
    [walking.walk10]                 # keyword overrides of a walking reference's builder
    step_length = 0.02

Every key is optional; a robot without the file keeps the defaults (Walk Ready from the servo
map if it has one, else the zero pose; the Bioloid's feet).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from .exceptions import ModelError
from .geometry import FOOT_LENGTH, FOOT_WIDTH
from .paths import read_toml

FILE_NAME = "robot.toml"


@dataclass(frozen=True)
class RobotData:
    """Named poses (rad, by joint name), the standing pose's name, the foot size (m)."""

    poses: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    stand: str | None = None
    foot_length: float = FOOT_LENGTH
    foot_width: float = FOOT_WIDTH
    #: the project's frame names -> the URDF's (``[frames]``, e.g. ``torso = "base_link"``)
    frames: Mapping[str, str] = field(default_factory=dict)
    #: per-trajectory keyword overrides for the walking references (``[walking.<name>]``)
    walking: Mapping[str, Mapping[str, object]] = field(default_factory=dict)
    source: str = "<defaults>"

    @classmethod
    def from_file(cls, path: str | Path, joint_names: Sequence[str]) -> RobotData:
        """Read and check a ``robot.toml`` against the model's joints."""
        path = Path(path)
        raw = read_toml(path, "robot data", ModelError)
        where = f"robot data {path}"
        allowed = ("feet", "frames", "poses", "stand", "walking")
        extra = sorted(set(raw) - set(allowed))
        if extra:
            raise ModelError(f"{where}: unknown keys {extra}; allowed: {', '.join(allowed)}")
        frames = raw.get("frames", {})
        if not isinstance(frames, Mapping) or not all(isinstance(v, str) for v in frames.values()):
            raise ModelError(f"{where}: [frames] maps names to URDF frame names (strings)")
        walking = raw.get("walking", {})
        if not all(isinstance(v, Mapping) for v in walking.values()):
            raise ModelError(f"{where}: [walking.<trajectory>] entries must be tables")
        known = set(joint_names)
        poses: dict[str, dict[str, float]] = {}
        for name, pose in raw.get("poses", {}).items():
            if not isinstance(pose, Mapping):
                raise ModelError(f"{where}: [poses.{name}] must be a table of joint = degrees")
            unknown = sorted(set(pose) - known)
            if unknown:
                raise ModelError(f"{where}: pose {name!r} names unknown joints {unknown}")
            for joint, deg in pose.items():
                if isinstance(deg, bool) or not isinstance(deg, (int, float)):
                    raise ModelError(f"{where}: pose {name!r} {joint} = {deg!r}: not a number")
                if not math.isfinite(deg):
                    raise ModelError(f"{where}: pose {name!r} {joint} = {deg!r}: not finite")
            poses[name] = {j: math.radians(float(v)) for j, v in pose.items()}
        stand = raw.get("stand")
        if stand is not None and stand not in poses and stand != "zero":
            raise ModelError(
                f"{where}: stand = {stand!r} is not one of its poses {sorted(poses)} or 'zero'"
            )
        feet = raw.get("feet", {})
        extra = sorted(set(feet) - {"length", "width"})
        if extra:
            raise ModelError(f"{where}: [feet] has unknown keys {extra}; allowed: length, width")
        size = {}
        for key, default in (("length", FOOT_LENGTH), ("width", FOOT_WIDTH)):
            v = feet.get(key, default)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < 1:
                raise ModelError(f"{where}: [feet] {key} = {v!r}: must be in (0, 1) m")
            size[key] = float(v)
        return cls(poses, stand, size["length"], size["width"], frames, walking, str(path))
