"""The peers placo and pink as :class:`~wbc.walking.controller.Controller` objects.

Both are configured with our URDF and the tasks of the run's stack (:func:`peer_stack`: the
``--stack`` given, else the robot folder's ``stack.toml``, else ``tasks/walk.toml``), read from
the :class:`~wbc.stacks.ControlStack` the stack loader builds (:func:`peer_tasks`: its weights,
the length rows already scaled to the robot): hard support contact (both soles hard in double
support), the swing sole's 6-D pose, the CoM, the torso orientation and the posture, in one
weighted level, with joint position limits and servo velocity limits. What they cannot express
(self-collision rows, ground clearance, the CoM polygon, a second soft level, another task
type) is listed in :attr:`PeerTasks.cannot` and printed by ``wbc bench`` in one line.
They are optional: :func:`available` says which are installed.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..exceptions import SolverError, TaskError
from ..model import Robot
from ..stacks import ControlStack, load_stack, robot_stack
from ..tasks import ComTask, ContactTask, FrameOrientationTask, FramePoseTask, PostureTask
from ..walking.loop import Controller, TickTargets
from ..walking.reference import WalkingReference


@dataclass(frozen=True)
class PeerTasks:
    """The soft tasks of a stack as the peers and the NLP take them: weights (the CoM's and
    the swing sole's position rows already scaled to the robot by the stack loader), the CoM
    polygon's margin (m; None without one), the stack's name and source, and what a peer
    cannot express (one phrase each)."""

    com: float
    swing_position: float
    swing_orientation: float
    torso: float
    posture: float
    com_margin: float | None
    stack: str
    source: str
    cannot: tuple[str, ...] = field(default_factory=tuple)

    def line(self) -> str:
        """One line: the stack, its weights and what the peers leave out."""
        w = (
            f"CoM {self.com:g}, swing {self.swing_position:g} / {self.swing_orientation:g}, "
            f"torso {self.torso:g}, posture {self.posture:g}"
        )
        left = f"; cannot express: {', '.join(self.cannot)}" if self.cannot else ""
        return f"stack {self.stack} ({self.source}): {w}{left}"


def _uniform(task, what: str, cannot: list[str]) -> float:
    w = np.asarray(task.weight, dtype=float)
    if np.ptp(w) > 0:
        cannot.append(f"{what}'s per-row weights (their largest taken)")
    return float(w.max())


def peer_tasks(control: ControlStack) -> PeerTasks:
    """Read the peers' tasks from a loaded stack: hard contacts, then one weighted level of
    the CoM, the swing sole's pose, the torso's orientation and the posture. A task or
    constraint outside that is named in ``cannot``; a stack without a CoM, swing or posture
    task is refused in one line."""
    robot = control.robot
    torso = robot.frame_id("torso")
    swing = set(id(t) for t in control.role_tasks("swing"))
    found: dict[str, float] = {}
    margin: float | None = None
    cannot: list[str] = []
    soft_levels = 0
    for level in control.stack.all_levels():
        soft_levels += not level.hard
        for task in level.tasks:
            if isinstance(task, ContactTask) and level.hard:
                continue
            if isinstance(task, ComTask) and not level.hard:
                found["com"] = _uniform(task, "com", cannot)
            elif isinstance(task, FramePoseTask) and id(task) in swing and not level.hard:
                w = np.asarray(task.weight, dtype=float)
                found["swing_position"], found["swing_orientation"] = float(w[0]), float(w[-1])
            elif (
                isinstance(task, FrameOrientationTask) and task.frame_id == torso and not level.hard
            ):
                found["torso"] = _uniform(task, "torso", cannot)
            elif type(task) is PostureTask and not level.hard:
                found["posture"] = _uniform(task, "posture", cannot)
            else:
                kind = "hard " if level.hard else ""
                cannot.append(f"{kind}{type(task).__name__} {task.name!r}")
        for c in level.constraints:
            kind = type(c).__name__.removesuffix("Constraint")
            if kind == "ComPolygon":
                margin = float(c.margin)
                cannot.append(f"com_polygon {margin:g} m (placo, pink; the NLP keeps it)")
            elif kind == "SelfCollision":
                cannot.append(f"self_collision {float(c.margin) * 1e3:g} mm")
            else:
                cannot.append(_snake(kind))
    if soft_levels > 1:
        cannot.append(f"{soft_levels} soft levels (flattened into one weighted level)")
    missing = [k for k in ("com", "swing_position", "torso", "posture") if k not in found]
    if missing:
        raise TaskError(
            f"the peers cannot run stack {control.name} ({control.source}): it has no "
            f"{', '.join(missing)} task (they need the CoM, swing pose, torso and posture)"
        )
    return PeerTasks(
        com=found["com"],
        swing_position=found["swing_position"],
        swing_orientation=found["swing_orientation"],
        torso=found["torso"],
        posture=found["posture"],
        com_margin=margin,
        stack=control.name,
        source=control.source,
        cannot=tuple(dict.fromkeys(cannot)),
    )


def _snake(name: str) -> str:
    return "".join("_" + ch.lower() if ch.isupper() else ch for ch in name).lstrip("_")


def peer_stack(robot: Robot, stack: str | Path | None = None) -> PeerTasks:
    """The peers' tasks on ``robot``: the stack a command runs there (:func:`robot_stack`:
    ``stack``, else the robot folder's ``stack.toml``, else ``tasks/walk.toml``), loaded by
    the stack loader and read by :func:`peer_tasks`."""
    return peer_tasks(load_stack(robot_stack(robot, stack)[0], robot))


def available() -> dict[str, bool]:
    """Which peers can be imported here."""
    return {
        name: importlib.util.find_spec(mod) is not None
        for name, mod in (("placo", "placo"), ("pink", "pink"))
    }


class _Peer(Controller):
    """A peer's tasks: given, or the robot's stack read at start (:func:`peer_stack`); the
    stack's name recorded in :attr:`stack`."""

    family = "peer"

    def __init__(self, tasks: PeerTasks | None = None) -> None:
        self.tasks = tasks
        self.stack = None if tasks is None else tasks.stack  # (recorded)

    def _tasks_on(self, robot: Robot) -> PeerTasks:
        """The tasks to run on ``robot`` (the given ones, else its stack's), :attr:`stack` set."""
        tasks = self.tasks or peer_stack(robot)
        self.stack = tasks.stack
        return tasks


class PlacoController(_Peer):
    """placo 0.10 ``KinematicsSolver`` (C++, eiquadprog): hard/soft tasks, one QP per tick."""

    name = "placo"

    def start(self, robot: Robot, q0: np.ndarray, ref: WalkingReference) -> None:
        import placo

        self.robot_model = robot
        self.pr = placo.RobotWrapper(str(robot.urdf_path), placo.Flags.ignore_collisions)
        self.pr.state.q = q0.copy()
        self.pr.update_kinematics()
        solver = placo.KinematicsSolver(self.pr)
        solver.mask_fbase(False)
        solver.enable_joint_limits(True)
        solver.enable_velocity_limits(True)
        solver.dt = ref.dt
        self.solver = solver
        urdf = robot.frame_aliases.get  # the URDF's names of the standard frames
        self.feet = {
            s: solver.add_frame_task(urdf(s, s), self.pr.get_T_world_frame(urdf(s, s)))
            for s in ("l_sole", "r_sole")
        }
        self.com = solver.add_com_task(self.pr.com_world())
        w = self.w = self._tasks_on(robot)
        self.com.configure("com", "soft", w.com)
        R0 = self.pr.get_T_world_frame(urdf("torso", "torso"))[:3, :3]
        self.torso = solver.add_orientation_task(urdf("torso", "torso"), R0)
        self.torso.configure("torso", "soft", w.torso)
        posture = solver.add_joints_task()
        posture.set_joints({n: float(q0[7 + i]) for i, n in enumerate(robot.joint_names)})
        posture.configure("posture", "soft", w.posture)
        solver.add_regularization_task(1e-6)

    def _set(self, q: np.ndarray, targets: TickTargets, phase_changed: bool) -> None:
        self.pr.state.q = q
        if phase_changed:
            for sole, task in self.feet.items():
                hard = sole == targets.support or targets.phase == "double"
                task.T_world_frame = (
                    targets.l_sole if sole == "l_sole" else targets.r_sole
                ).homogeneous
                weight = 1.0 if hard else self.w.swing_position  # (the position's)
                task.configure(sole, "hard" if hard else "soft", weight)
        if targets.phase == "single":
            self.feet[targets.swing].T_world_frame = targets.swing_placement.homogeneous
        self.com.target_world = targets.com
        self.torso.R_world_frame = targets.torso_rotation

    def track(self, q, targets, dt, phase_changed):
        self._set(q, targets, phase_changed)
        self.pr.update_kinematics()
        try:
            self.solver.solve(True)
        except RuntimeError as exc:  # placo.QPError
            raise SolverError(f"placo: {exc}") from exc
        return np.array(self.pr.state.q)


class PinkController(_Peer):
    """pink 4.x ``solve_ik`` with DAQP: costs as tasks, hard feet as ``constraints``."""

    name = "pink"

    def start(self, robot: Robot, q0: np.ndarray, ref: WalkingReference) -> None:
        from pink import Configuration
        from pink.limits import ConfigurationLimit, VelocityLimit
        from pink.tasks import ComTask, FrameTask, PostureTask

        self.robot_model = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.config = Configuration(self.model, self.data, q0.copy())
        urdf = robot.frame_aliases.get  # the URDF's names of the standard frames
        w = self._tasks_on(robot)
        position, orientation = np.sqrt(w.swing_position), np.sqrt(w.swing_orientation)
        self.feet = {
            s: FrameTask(urdf(s, s), position_cost=position, orientation_cost=orientation)
            for s in ("l_sole", "r_sole")
        }
        for s, task in self.feet.items():
            task.set_target(self.config.get_transform_frame_to_world(urdf(s, s)))
        self.com = ComTask(cost=np.sqrt(w.com))
        self.com.set_target(robot.com(q0))
        torso = urdf("torso", "torso")
        self.torso = FrameTask(torso, position_cost=0.0, orientation_cost=np.sqrt(w.torso))
        self.torso.set_target(self.config.get_transform_frame_to_world(torso))
        self.posture = PostureTask(cost=np.sqrt(w.posture))
        self.posture.set_target(q0.copy())
        self.limits = [ConfigurationLimit(self.model), VelocityLimit(self.model)]
        self.hard: list = [self.feet["l_sole"], self.feet["r_sole"]]
        self.soft: list = [self.com, self.torso, self.posture]

    def track(self, q, targets, dt, phase_changed):
        from pink import solve_ik

        if phase_changed:
            for sole, task in self.feet.items():
                task.set_target(targets.l_sole if sole == "l_sole" else targets.r_sole)
            if targets.phase == "double":
                self.hard = [self.feet["l_sole"], self.feet["r_sole"]]
                self.soft = [self.com, self.torso, self.posture]
            else:
                self.hard = [self.feet[targets.support]]
                self.soft = [self.feet[targets.swing], self.com, self.torso, self.posture]
        if targets.phase == "single":
            self.feet[targets.swing].set_target(targets.swing_placement)
        self.com.set_target(targets.com)
        self.torso.set_target(pin.SE3(targets.torso_rotation, np.zeros(3)))
        self.config.update(q)
        try:
            v = solve_ik(
                self.config,
                self.soft,
                dt,
                solver="daqp",
                limits=self.limits,
                constraints=self.hard,
                safety_break=False,
            )
        except Exception as exc:  # pink.exceptions.NoSolutionFound and friends
            raise SolverError(f"pink: {exc}") from exc
        return pin.integrate(self.model, q, v * dt)


PEERS = {"placo": PlacoController, "pink": PinkController}
