"""The peers placo and pink as :class:`~wbc.walking.loop.Controller` objects.

Both are configured with our URDF and the tasks of our recommended ``walk`` stack: hard
support contact (both soles hard in double support), the swing sole's 6-D pose, the CoM
(weight 1000, swing 100), the torso orientation (1) and a light posture task (0.01), with joint
position limits and servo velocity limits. Neither gets the CoM-polygon or ground-clearance
constraints (pink has none; placo has a polygon constraint but no clearance), so they solve a
slightly easier problem than ``walk``. The weights of length rows (the CoM, the soles' positions)
are divided by the robot's size squared as the stacks' are (:func:`wbc.roles.length_unit`).
They are optional: :func:`available` says which are installed.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pinocchio as pin

from ..exceptions import SolverError
from ..model import Robot
from ..roles import length_unit
from ..walking.loop import Controller, TickTargets
from ..walking.reference import WalkingReference

# the weights of tasks/walk.toml
COM_WEIGHT = 1000.0
SWING_WEIGHT = 100.0
TORSO_WEIGHT = 1.0
POSTURE_WEIGHT = 0.01


def available() -> dict[str, bool]:
    """Which peers can be imported here."""
    return {
        name: importlib.util.find_spec(mod) is not None
        for name, mod in (("placo", "placo"), ("pink", "pink"))
    }


class PlacoController(Controller):
    """placo 0.10 ``KinematicsSolver`` (C++, eiquadprog): hard/soft tasks, one QP per tick."""

    name = "placo"
    family = "peer"

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
        self.unit2 = length_unit(robot) ** 2
        self.com.configure("com", "soft", COM_WEIGHT / self.unit2)
        R0 = self.pr.get_T_world_frame(urdf("torso", "torso"))[:3, :3]
        self.torso = solver.add_orientation_task(urdf("torso", "torso"), R0)
        self.torso.configure("torso", "soft", TORSO_WEIGHT)
        posture = solver.add_joints_task()
        posture.set_joints({n: float(q0[7 + i]) for i, n in enumerate(robot.joint_names)})
        posture.configure("posture", "soft", POSTURE_WEIGHT)
        solver.add_regularization_task(1e-6)

    def _set(self, q: np.ndarray, targets: TickTargets, phase_changed: bool) -> None:
        self.pr.state.q = q
        if phase_changed:
            for sole, task in self.feet.items():
                hard = sole == targets.support or targets.phase == "double"
                task.T_world_frame = (
                    targets.l_sole if sole == "l_sole" else targets.r_sole
                ).homogeneous
                weight = 1.0 if hard else SWING_WEIGHT / self.unit2  # (the position's)
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


class PinkController(Controller):
    """pink 4.x ``solve_ik`` with DAQP: costs as tasks, hard feet as ``constraints``."""

    name = "pink"
    family = "peer"

    def start(self, robot: Robot, q0: np.ndarray, ref: WalkingReference) -> None:
        from pink import Configuration
        from pink.limits import ConfigurationLimit, VelocityLimit
        from pink.tasks import ComTask, FrameTask, PostureTask

        self.robot_model = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.config = Configuration(self.model, self.data, q0.copy())
        urdf = robot.frame_aliases.get  # the URDF's names of the standard frames
        cost, unit = np.sqrt(SWING_WEIGHT), length_unit(robot)
        self.feet = {
            s: FrameTask(urdf(s, s), position_cost=cost / unit, orientation_cost=cost)
            for s in ("l_sole", "r_sole")
        }
        for s, task in self.feet.items():
            task.set_target(self.config.get_transform_frame_to_world(urdf(s, s)))
        self.com = ComTask(cost=np.sqrt(COM_WEIGHT) / unit)
        self.com.set_target(robot.com(q0))
        torso = urdf("torso", "torso")
        self.torso = FrameTask(torso, position_cost=0.0, orientation_cost=np.sqrt(TORSO_WEIGHT))
        self.torso.set_target(self.config.get_transform_frame_to_world(torso))
        self.posture = PostureTask(cost=np.sqrt(POSTURE_WEIGHT))
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
