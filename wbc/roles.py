"""Joint roles from the kinematic tree: which joint is a leg's hip yaw, knee, ankle roll, ...

The walking, balance, feedback and IK code needs to know what each leg and arm joint does,
not what it is called. :func:`find_roles` reads it from the model:

* **legs**: the chain of joints from each sole frame (``l_sole``, ``r_sole``, mapped by
  ``robot.toml`` ``[frames]``) up to the torso frame. Each joint's axis at the standing pose,
  in the sole's frame (x forward, z up: the sole is flat), is a *pitch* (≈ y), *roll* (≈ x) or
  *yaw* (≈ z) axis. A leg must have three pitch joints (hip, knee, ankle: the middle one is the
  knee), one yaw and one roll joint above the knee (the hip's) and one roll joint below it
  (the ankle's), and nothing else.
* **arms**: the other branches of the tree below the torso, the left one holding ``l_hand``
  (else lying at +y of the torso), the right one ``r_hand`` (else -y); a branch at y ≈ 0 is a
  head. The first pitch joint is the shoulder pitch, the first roll joint the shoulder roll,
  the last joint of the chain (if neither) the elbow. Every joint of the chain is an arm joint
  (what ``hold_arms`` holds).
* **side**: which sole is which comes from the frames; the left sole must lie at +y of the
  torso.

``robot.toml`` may name any role itself::

    [joints.left]
    knee = "LKneePitch"
    [joints.right]
    knee = "RKneePitch"

A named role replaces the detected one; a leg the tree does not explain is accepted if its six
roles are all named. Otherwise the robot is refused with one line saying why.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import pinocchio as pin

from .exceptions import ConfigurationError, ModelError
from .paths import read_toml, stacks_dir


class Robot(Protocol):
    """What the roles read of a robot (:class:`wbc.model.Robot`; roles rank below it, which
    asks for them: :attr:`wbc.model.Robot.roles`)."""

    name: str
    model: pin.Model

    def configuration(self, name: str) -> np.ndarray: ...
    def neutral(self) -> np.ndarray: ...
    def has_frame(self, name: str) -> bool: ...
    def frame_id(self, name: str) -> int: ...


#: a leg's joints, from the torso down (the order every leg-joint tuple of wbc uses)
LEG_ROLES = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
#: an arm's named joints (an arm may have more joints: :meth:`JointRoles.arm` lists them all)
ARM_ROLES = ("shoulder_pitch", "shoulder_roll", "elbow")
ROLES = (*LEG_ROLES, *ARM_ROLES)
SIDES = ("left", "right")
#: the standard sole and hand frames of each side (wbc.model.STANDARD_FRAMES)
SOLE_FRAMES = {"left": "l_sole", "right": "r_sole"}
HAND_FRAMES = {"left": "l_hand", "right": "r_hand"}
#: how close to x, y or z an axis must be to be a roll, pitch or yaw axis (cos 30 deg)
AXIS_COS = 0.866
_KINDS = ("roll", "pitch", "yaw")


def joint_axis(model: pin.Model, j: int, what: str = "joint roles") -> np.ndarray:
    """A revolute joint's axis in its own frame (unit 3-vector); ModelError otherwise."""
    kind = model.joints[j].shortname()
    if kind in ("JointModelRX", "JointModelRY", "JointModelRZ"):
        return np.eye(3)["XYZ".index(kind[-1])]
    if kind == "JointModelRevoluteUnaligned":
        return np.asarray(model.joints[j].extract().axis, dtype=float)
    raise ModelError(f"{what}: joint {model.names[j]} is not revolute ({kind})")


@dataclass(frozen=True)
class JointRoles:
    """Each side's leg and arm joints by role (joint names of the model)."""

    #: side -> role (:data:`LEG_ROLES`) -> joint name
    legs: Mapping[str, Mapping[str, str]]
    #: side -> role (:data:`ARM_ROLES`, those found) -> joint name
    arms: Mapping[str, Mapping[str, str]] = field(default_factory=dict)
    #: side -> every joint of the arm chain, from the torso out
    arm_chains: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    #: (side, role) pairs named in ``robot.toml`` ``[joints]``
    named: frozenset[tuple[str, str]] = frozenset()

    def joint(self, side: str, role: str) -> str:
        """The joint playing ``role`` on ``side`` ("left"/"right"); ModelError if none."""
        found = self.get(side, role)
        if found is None:
            raise ModelError(
                f"no {side} {role.replace('_', ' ')} joint found (name it in robot.toml "
                f'[joints.{side}] {role} = "<joint>")'
            )
        return found

    def get(self, side: str, role: str) -> str | None:
        """The joint playing ``role`` on ``side``, None if the robot has none."""
        if side not in SIDES or role not in ROLES:
            raise ModelError(f"unknown joint role {side!r} {role!r}; roles: {', '.join(ROLES)}")
        table = self.legs if role in LEG_ROLES else self.arms
        return table.get(side, {}).get(role)

    def leg(self, side: str) -> tuple[str, ...]:
        """The six leg joints of ``side`` in :data:`LEG_ROLES` order."""
        return tuple(self.joint(side, r) for r in LEG_ROLES)

    def arm(self, side: str) -> tuple[str, ...]:
        """Every joint of ``side``'s arm (empty if the robot has none)."""
        return tuple(self.arm_chains.get(side, ()))

    def lines(self) -> list[str]:
        """One line per limb: ``left leg: hip_yaw=<joint> ...`` (``*``: named in robot.toml)."""
        out = []
        for side in SIDES:
            for limb, table in (("leg", self.legs), ("arm", self.arms)):
                roles = table.get(side, {})
                if not roles:
                    out.append(f"{side} {limb}: none")
                    continue
                parts = [
                    f"{r}={j}{'*' if (side, r) in self.named else ''}" for r, j in roles.items()
                ]
                extra = [j for j in self.arm(side) if j not in roles.values()]
                if extra and limb == "arm":
                    parts.append(f"also {', '.join(extra)}")
                out.append(f"{side} {limb}: {' '.join(parts)}")
        return out


def find_roles(
    robot: Robot, overrides: Mapping[str, Mapping[str, str]] | None = None
) -> JointRoles:
    """The robot's joint roles (module docstring); ``overrides``: side -> role -> joint."""
    overrides = dict(overrides or {})
    model = robot.model
    data = model.createData()
    q = _standing(robot)
    pin.framesForwardKinematics(model, data, q)
    try:
        torso_frame = _frame(robot, "torso")
        l_pos = data.oMf[_frame(robot, SOLE_FRAMES["left"])].translation
        r_pos = data.oMf[_frame(robot, SOLE_FRAMES["right"])].translation
    except ModelError as exc:
        raise ModelError(f"{robot.name}: cannot understand the legs: {exc}") from None
    torso_joint = model.frames[torso_frame].parentJoint
    R_torso = data.oMf[torso_frame].rotation
    legs: dict[str, dict[str, str]] = {}
    leg_joints: set[int] = set()
    for side in SIDES:
        named = dict(overrides.get(side, {}))
        named_leg = {r: j for r, j in named.items() if r in LEG_ROLES}
        try:
            sole = _frame(robot, SOLE_FRAMES[side])
            chain = _chain(model, model.frames[sole].parentJoint, torso_joint, robot, side)
            leg_joints.update(chain)
            R = data.oMf[sole].rotation
            kinds = [_kind(model, data, j, R) for j in chain]
            found = _parse_leg(model, chain, kinds)
        except ModelError as exc:
            if set(named_leg) == set(LEG_ROLES):
                found = {}
            else:
                raise ModelError(
                    f"{robot.name}: cannot understand the {side} leg: {exc} (or name its joints "
                    f"in robot.toml [joints.{side}]: {', '.join(LEG_ROLES)})"
                ) from None
        legs[side] = {r: named_leg.get(r, found.get(r, "")) for r in LEG_ROLES}
    if float(R_torso.T @ (l_pos - r_pos) @ np.eye(3)[1]) <= 0:
        raise ModelError(
            f"{robot.name}: cannot understand the legs: {SOLE_FRAMES['left']} is not on the "
            f"left (+y) of the torso frame; check robot.toml [frames]"
        )
    arms, chains = _arms(robot, data, torso_joint, leg_joints, R_torso)
    for side in SIDES:
        for r, j in overrides.get(side, {}).items():
            if r in ARM_ROLES:
                arms.setdefault(side, {})[r] = j
                if j not in chains.get(side, ()):
                    chains[side] = (*chains.get(side, ()), j)
    named = frozenset((s, r) for s, table in overrides.items() for r in table)
    return JointRoles(legs, arms, chains, named)


def _standing(robot: Robot) -> np.ndarray:
    """The standing configuration (the zero pose if it cannot be built)."""
    try:
        return robot.configuration("stand")
    except ModelError:
        return robot.neutral()


def _frame(robot: Robot, name: str) -> int:
    if not robot.has_frame(name):
        raise ModelError(f"no frame {name!r} (map it in robot.toml [frames])")
    return robot.frame_id(name)


def _chain(model: pin.Model, j: int, top: int, robot: Robot, side: str) -> list[int]:
    """The joints from ``top`` (exclusive) down to ``j`` (inclusive), top first."""
    chain = []
    while j not in (top, 0):
        chain.append(j)
        j = model.parents[j]
    if j != top:
        raise ModelError(f"{SOLE_FRAMES[side]} does not hang below the torso frame")
    return chain[::-1]


def _kind(model: pin.Model, data: pin.Data, j: int, R: np.ndarray) -> str:
    a = R.T @ data.oMi[j].rotation @ joint_axis(model, j)
    k = int(np.argmax(np.abs(a)))
    if abs(a[k]) < AXIS_COS:
        axis = ", ".join(f"{v:.2f}" for v in a)
        raise ModelError(f"joint {model.names[j]}'s axis ({axis}) is not along x, y or z")
    return _KINDS[k]


def _parse_leg(model: pin.Model, chain: list[int], kinds: list[str]) -> dict[str, str]:
    """Roles of a leg chain (top first) from its axis kinds (module docstring)."""
    desc = ", ".join(f"{model.names[j]} ({k})" for j, k in zip(chain, kinds, strict=True))
    pitch = [i for i, k in enumerate(kinds) if k == "pitch"]
    if len(pitch) != 3:
        raise ModelError(
            f"its chain {desc or '(no joints)'} has {len(pitch)} pitch joints; a leg needs 3 "
            "(hip, knee, ankle)"
        )
    knee = pitch[1]
    roles: dict[str, str] = {
        "hip_pitch": model.names[chain[pitch[0]]],
        "knee": model.names[chain[knee]],
        "ankle_pitch": model.names[chain[pitch[2]]],
    }
    for role, kind, part in (
        ("hip_yaw", "yaw", range(knee)),
        ("hip_roll", "roll", range(knee)),
        ("ankle_roll", "roll", range(knee + 1, len(chain))),
    ):
        hits = [i for i in part if kinds[i] == kind]
        where = "above" if role.startswith("hip") else "below"
        if len(hits) != 1:
            raise ModelError(
                f"its chain {desc} has {len(hits)} {kind} joints {where} the knee; a leg needs 1"
            )
        roles[role] = model.names[chain[hits[0]]]
    if len(chain) != 6:
        raise ModelError(f"its chain {desc} has {len(chain)} joints; a leg has these 6")
    return roles


def _arms(
    robot: Robot, data: pin.Data, torso: int, legs: set[int], R_torso: np.ndarray
) -> tuple[dict[str, dict[str, str]], dict[str, tuple[str, ...]]]:
    """The arm roles and chains (module docstring)."""
    model = robot.model
    p_torso = data.oMi[torso].translation
    branches: dict[str, list[int]] = {}
    for c in range(1, model.njoints):
        if model.parents[c] != torso or c in legs:
            continue
        sub = list(model.subtrees[c])
        side = None
        for s in SIDES:
            hand = HAND_FRAMES[s]
            if robot.has_frame(hand) and model.frames[robot.frame_id(hand)].parentJoint in sub:
                side = s
        if side is None:
            y = float((R_torso.T @ (data.oMi[sub[-1]].translation - p_torso))[1])
            side = "left" if y > 0.01 else "right" if y < -0.01 else None
        if side is None or (side in branches and len(branches[side]) >= len(sub)):
            continue
        chain = [c]  # follow the first child down to a leaf
        while True:
            kids = [k for k in sub if model.parents[k] == chain[-1]]
            if not kids:
                break
            chain.append(kids[0])
        branches[side] = chain
    arms: dict[str, dict[str, str]] = {}
    chains: dict[str, tuple[str, ...]] = {}
    for side, chain in branches.items():
        names = [model.names[j] for j in chain]
        chains[side] = tuple(names)
        roles: dict[str, str] = {}
        for j in chain:
            try:
                kind = _kind(model, data, j, R_torso)
            except ModelError:
                continue
            role = {"pitch": "shoulder_pitch", "roll": "shoulder_roll"}.get(kind)
            if role and role not in roles:
                roles[role] = model.names[j]
        if len(chain) >= 3 and names[-1] not in roles.values():
            roles["elbow"] = names[-1]
        arms[side] = roles
    return arms, chains


def leg_segments(robot: Robot) -> tuple[float, float]:
    """The left leg's thigh and shin (m), measured at q = 0: hip pitch -> knee -> ankle pitch
    joint origins (the joints by role)."""
    model, data = robot.model, pin.Data(robot.model)
    roles = robot.roles  # type: ignore[attr-defined]
    pin.forwardKinematics(model, data, robot.neutral())
    hip, knee, ankle = (
        data.oMi[model.getJointId(roles.joint("left", r))].translation
        for r in ("hip_pitch", "knee", "ankle_pitch")
    )
    return float(np.linalg.norm(knee - hip)), float(np.linalg.norm(ankle - knee))


#: the walking design file, in the stacks' folder (``tasks/``): the robot the walking
#: references' default settings and the package's stacks' weights were tuned on
DESIGN_FILE = "walking/design.toml"


@dataclass(frozen=True)
class DesignRobot:
    """The robot the walking defaults were designed on (:data:`DESIGN_FILE`): its name, its
    thigh and shin (m, hip pitch -> knee -> ankle pitch) and its foot's width (m)."""

    robot: str
    thigh: float
    shin: float
    foot_width: float

    @property
    def leg(self) -> float:
        """Its hip-to-ankle length, thigh + shin (m)."""
        return self.thigh + self.shin


@functools.cache
def design_robot() -> DesignRobot:
    """The design robot of the walking references, read once from :data:`DESIGN_FILE`
    (ConfigurationError naming the file and key if a length is missing or not in (0, 1) m)."""
    path = stacks_dir() / DESIGN_FILE
    raw = read_toml(path, "walking design file", ConfigurationError)
    keys = ("robot", "thigh", "shin", "foot_width")
    extra = sorted(set(raw) - set(keys))
    if extra:
        raise ConfigurationError(f"{path}: unknown keys {extra}; allowed: {', '.join(keys)}")
    if not isinstance(raw.get("robot"), str):
        raise ConfigurationError(f"{path}: robot = {raw.get('robot')!r}: the robot's name")
    for key in keys[1:]:
        v = raw.get(key)
        if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < 1:
            raise ConfigurationError(f"{path}: {key} = {v!r}: a length in (0, 1) m")
    return DesignRobot(raw["robot"], *(float(raw[k]) for k in keys[1:]))


def leg_length(ratio: float) -> float:
    """The hip-to-ankle length (m) of :func:`leg_ratio` ``ratio`` (the design robot's at 1)."""
    return ratio * design_robot().leg


def leg_ratio(leg: float) -> float:
    """λ = leg / the design robot's thigh + shin (:func:`design_robot`: the Bioloid, whose
    defaults the walking settings and stack weights are), rounded to 1e-9 so that the design
    robot's stated leg gives exactly 1."""
    return round(leg / design_robot().leg, 9)


def length_unit(robot: Robot) -> float:
    """The robot's :func:`leg_ratio`: its thigh + shin (``robot.toml`` ``[legs]`` thigh and shin
    if stated, else :func:`leg_segments`) over the design robot's; 1 for a robot without both
    sole frames (no legs to measure). The stacks divide the weights of their length rows by
    λ² (:func:`wbc.stacks.build_stack`): a centimetre on a robot twice the Bioloid's size
    weighs what half a centimetre weighs on the Bioloid, against the same joint angles."""
    if not all(robot.has_frame(f) for f in SOLE_FRAMES.values()):
        return 1.0
    stated = getattr(getattr(robot, "robot_data", None), "legs", {})
    if "thigh" in stated and "shin" in stated:
        thigh, shin = float(stated["thigh"]), float(stated["shin"])  # type: ignore[arg-type]
    else:
        measured = leg_segments(robot)
        thigh = float(stated.get("thigh", measured[0]))  # type: ignore[arg-type]
        shin = float(stated.get("shin", measured[1]))  # type: ignore[arg-type]
    return leg_ratio(thigh + shin)
