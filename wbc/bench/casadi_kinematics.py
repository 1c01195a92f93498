"""Forward kinematics and centre of mass as casadi expressions, read from the URDF.

pinocchio's casadi module is not in the PyPI wheel, so the NLP reference
(:mod:`wbc.bench.nlp`) gets its kinematics here: the URDF's kinematic tree (joint origins
``xyz`` + ``rpy``, axes, revolute / prismatic / fixed joints) and link inertials (mass, CoM
origin), with the root link on a free-flyer base like :class:`wbc.model.Robot`.

For a link reached by joints j₁…j_k from the root, with the base placement (p_b, R_b),

    R = R_b · Π R_origin(j) R_motion(j),   p = p_b + Σ R_before(j) · xyz(j) (+ prismatic travel),

R_origin = Rz(yaw) Ry(pitch) Rx(roll) (URDF rpy) and, about the unit axis a with K = [a]×,
R_motion(θ) = I + sin θ K + (1 − cos θ) K² (Rodrigues). The CoM is Σ mᵢ (pᵢ + Rᵢ cᵢ) / Σ mᵢ.

Configurations follow pinocchio's free-flyer convention ``q = [x, y, z, qx, qy, qz, qw,
joints in robot.joint_names order]``; :meth:`CasadiKinematics.forward` also takes the base as
a position and a rotation matrix, so an NLP may parametrise the base rotation as it likes.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from ..exceptions import ModelError
from ..model import Robot

JOINT_KINDS = ("revolute", "prismatic", "fixed")


@dataclass(frozen=True)
class UrdfJoint:
    """One URDF joint: placement of the child link in the parent link at zero motion."""

    name: str
    kind: str  # "revolute", "prismatic" or "fixed"
    parent: str
    child: str
    xyz: np.ndarray  # (3,)
    rotation: np.ndarray  # (3, 3) from rpy
    axis: np.ndarray  # (3,) unit


@dataclass(frozen=True)
class UrdfTree:
    """The kinematic tree of a URDF: root link, joints parent-before-child, inertials."""

    root: str
    joints: tuple[UrdfJoint, ...]
    masses: dict[str, float]
    com_offsets: dict[str, np.ndarray]  # CoM of each link in its own frame


def rpy_matrix(rpy: Sequence[float]) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _vector(element: ET.Element | None, key: str, default: str, where: str) -> np.ndarray:
    text = default if element is None else element.get(key, default)
    try:
        v = np.array([float(s) for s in text.split()])
    except ValueError:
        raise ModelError(f"{where}: {key}={text!r} is not three numbers") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ModelError(f"{where}: {key}={text!r} is not three finite numbers")
    return v


def parse_urdf(path: str | Path) -> UrdfTree:
    """Read the kinematic tree and the link masses / CoM offsets of a URDF file."""
    path = Path(path)
    try:
        root_el = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise ModelError(f"cannot read URDF {path}: {exc}") from exc
    masses: dict[str, float] = {}
    com_offsets: dict[str, np.ndarray] = {}
    for link in root_el.findall("link"):
        name = link.get("name")
        if not name:
            raise ModelError(f"URDF {path}: a <link> has no name")
        inertial = link.find("inertial")
        mass = 0.0
        com = np.zeros(3)
        if inertial is not None:
            mass_el = inertial.find("mass")
            try:
                mass = float(mass_el.get("value")) if mass_el is not None else 0.0
            except (TypeError, ValueError):
                raise ModelError(f"URDF {path}: link {name!r} has a bad mass") from None
            com = _vector(inertial.find("origin"), "xyz", "0 0 0", f"URDF {path}: link {name!r}")
        masses[name] = mass
        com_offsets[name] = com
    joints: dict[str, UrdfJoint] = {}  # by child link
    for j in root_el.findall("joint"):
        name, kind = j.get("name"), j.get("type")
        where = f"URDF {path}: joint {name!r}"
        if kind == "continuous":
            raise ModelError(f"{where}: continuous joints are not supported (pinocchio nq = 2)")
        if kind not in JOINT_KINDS:
            raise ModelError(f"{where}: type {kind!r} is not one of {JOINT_KINDS}")
        parent, child = j.find("parent"), j.find("child")
        if parent is None or child is None:
            raise ModelError(f"{where}: needs <parent> and <child>")
        parent_link, child_link = parent.get("link"), child.get("link")
        for link in (parent_link, child_link):
            if link not in masses:
                raise ModelError(f"{where}: unknown link {link!r}")
        if child_link in joints:
            raise ModelError(f"{where}: link {child_link!r} has two parent joints")
        origin = j.find("origin")
        xyz = _vector(origin, "xyz", "0 0 0", where)
        rpy = _vector(origin, "rpy", "0 0 0", where)
        axis = _vector(j.find("axis"), "xyz", "1 0 0", where)
        norm = np.linalg.norm(axis)
        if kind != "fixed" and norm < 1e-12:
            raise ModelError(f"{where}: zero axis")
        joints[child_link] = UrdfJoint(
            name, kind, parent_link, child_link, xyz, rpy_matrix(rpy), axis / max(norm, 1e-300)
        )
    roots = [link for link in masses if link not in joints]
    if len(roots) != 1:
        raise ModelError(f"URDF {path}: expected one root link, found {roots}")
    ordered: list[UrdfJoint] = []
    placed = {roots[0]}
    pending = list(joints.values())
    while pending:
        ready = [j for j in pending if j.parent in placed]
        if not ready:
            raise ModelError(f"URDF {path}: joints {[j.name for j in pending]} form a cycle")
        for j in ready:
            ordered.append(j)
            placed.add(j.child)
        pending = [j for j in pending if j.child not in placed]
    return UrdfTree(roots[0], tuple(ordered), masses, com_offsets)


def quaternion_matrix(quat: Any) -> Any:
    """Rotation matrix of a unit quaternion (x, y, z, w), Eigen's formula (casadi or numpy)."""
    x, y, z, w = quat[0], quat[1], quat[2], quat[3]
    tx, ty, tz = 2 * x, 2 * y, 2 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    rows = [
        [1 - (tyy + tzz), txy - twz, txz + twy],
        [txy + twz, 1 - (txx + tzz), tyz - twx],
        [txz - twy, tyz + twx, 1 - (txx + tyy)],
    ]
    return _matrix(rows)


def _matrix(rows: list[list[Any]]) -> Any:
    if all(not isinstance(v, (ca.SX, ca.MX, ca.DM)) for row in rows for v in row):
        return np.array(rows, dtype=float)
    return ca.vertcat(*[ca.horzcat(*row) for row in rows])


def _motion(joint: UrdfJoint, value: Any) -> Any:
    """R_motion(θ) = I + sin θ K + (1 − cos θ) K², written without structural zeros."""
    a = joint.axis
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    K2 = K @ K
    s, c1 = ca.sin(value), 1 - ca.cos(value)
    rows = []
    for i in range(3):
        row = []
        for k in range(3):
            entry: Any = 1.0 if i == k else 0.0
            if K[i, k] != 0:
                entry = entry + K[i, k] * s
            if K2[i, k] != 0:
                entry = entry + K2[i, k] * c1
            row.append(entry)
        rows.append(row)
    return ca.vertcat(*[ca.horzcat(*row) for row in rows])


class CasadiKinematics:
    """Symbolic forward kinematics and CoM of ``robot`` (parsed from ``robot.urdf_path``)."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.tree = parse_urdf(robot.urdf_path)
        actuated = [j.name for j in self.tree.joints if j.kind != "fixed"]
        if sorted(actuated) != sorted(robot.joint_names):
            raise ModelError(
                f"URDF {robot.urdf_path}: actuated joints {actuated} differ from the model's "
                f"{list(robot.joint_names)}"
            )
        self._index = {name: i for i, name in enumerate(robot.joint_names)}
        self.total_mass = float(sum(self.tree.masses.values()))
        if not np.isclose(self.total_mass, robot.total_mass, rtol=1e-12, atol=1e-12):
            raise ModelError(
                f"URDF mass {self.total_mass} differs from pinocchio's {robot.total_mass}"
            )
        if self.total_mass <= 0:
            raise ModelError(f"URDF {robot.urdf_path}: total mass is not positive")
        # frame name -> link: every link, and every joint (its frame is its child link's)
        self._frame_link = {link: link for link in self.tree.masses}
        self._frame_link.update({j.name: j.child for j in self.tree.joints})
        self.frames: tuple[str, ...] = tuple(self._frame_link)
        self._q = ca.SX.sym("q", robot.nq)

    # ------------------------------------------------------------------ expressions
    def link_of(self, frame: str) -> str:
        """The link whose frame is ``frame`` (a link name or a joint name)."""
        try:
            return self._frame_link[frame]
        except KeyError:
            raise ModelError(
                f"unknown frame {frame!r}; frames: {', '.join(sorted(self.frames))}"
            ) from None

    def forward(self, base_position: Any, base_rotation: Any, joints: Any) -> dict[str, Any]:
        """World placement ``(p (3x1), R (3x3))`` of every link, as casadi expressions.

        ``joints`` is in ``robot.joint_names`` order; all three arguments may be casadi
        symbols/expressions (SX or MX) or numbers.
        """
        placements: dict[str, tuple[Any, Any]] = {
            self.tree.root: (ca.reshape(base_position, 3, 1), base_rotation)
        }
        for j in self.tree.joints:
            p, R = placements[j.parent]
            p = p + ca.mtimes(R, ca.DM(j.xyz))
            R = ca.mtimes(R, ca.DM(j.rotation))
            if j.kind == "revolute":
                R = ca.mtimes(R, _motion(j, joints[self._index[j.name]]))
            elif j.kind == "prismatic":
                p = p + ca.mtimes(R, ca.DM(j.axis)) * joints[self._index[j.name]]
            placements[j.child] = (p, R)
        return placements

    def placement(self, frame: str, placements: dict[str, Any]) -> tuple[Any, Any]:
        """``(p, R)`` of a frame from the output of :meth:`forward`."""
        return placements[self.link_of(frame)]

    def com(self, placements: dict[str, Any]) -> Any:
        """Centre of mass (3x1) from the output of :meth:`forward`."""
        total: Any = ca.DM.zeros(3, 1)
        for link, mass in self.tree.masses.items():
            if mass == 0.0:
                continue
            p, R = placements[link]
            total = total + mass * (p + ca.mtimes(R, ca.DM(self.tree.com_offsets[link])))
        return total / self.total_mass

    def forward_q(self, q: Any) -> dict[str, Any]:
        """:meth:`forward` from a pinocchio configuration (unit quaternion base)."""
        return self.forward(q[0:3], quaternion_matrix(q[3:7]), q[7:])

    # ------------------------------------------------------------------ functions of q
    def frame_placement_function(self, frame: str) -> ca.Function:
        """casadi ``Function`` q (nq) -> (p (3), R (3x3)) of ``frame`` in the world."""
        p, R = self.placement(frame, self.forward_q(self._q))
        return ca.Function(f"placement_{frame}", [self._q], [p, R], ["q"], ["p", "R"])

    def com_function(self) -> ca.Function:
        """casadi ``Function`` q (nq) -> centre of mass (3) in the world."""
        c = self.com(self.forward_q(self._q))
        return ca.Function("com", [self._q], [c], ["q"], ["com"])

    # ------------------------------------------------------------------ numeric helpers
    def frame_placement(self, q: np.ndarray, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """Numeric ``(p, R)`` of ``frame`` at q (builds a Function; for tests and checks)."""
        p, R = self.frame_placement_function(frame)(self.robot.check_configuration(q))
        return np.array(p).ravel(), np.array(R)
