"""A solver family behind one interface: :class:`Controller`, and :class:`StackController`, a
declarative task stack (:mod:`wbc.stacks`) driven by the walking targets, which the control loop
(:mod:`wbc.walking.loop`) drives along a reference (both importable from there too)."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from ..compiled.checks import entry as check_entry
from ..compiled.targets import copy_targets
from ..exceptions import WbcError
from ..geometry import wrap_angle
from ..model import Kinematics, Robot
from ..stacks import ControlStack
from ..tasks import (
    ComTask,
    ContactTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    SwingFootOrientationTask,
    YawMomentumTask,
)
from ..tasks.task import ROTATION_TOL
from .handover import SwitchHandover
from .reference import WalkingReference
from .tick_targets import TickTargets

#: the checked entry of a tick's targets' copy (StackController._copy_targets), arrays as below
_copy_targets = check_entry(copy_targets)
_F8 = np.dtype(np.float64)
_VECTOR, _MATRIX = (3,), (3, 3)


class Controller(ABC):
    """A solver family behind one interface (the control loop's: :mod:`wbc.walking.loop`)."""

    name: str = "controller"
    family: str = "family"

    def start(self, robot: Robot, q0: np.ndarray, ref: WalkingReference) -> None:  # noqa: B027
        """Reset internal state before a run."""

    @abstractmethod
    def track(
        self, q: np.ndarray, targets: TickTargets, dt: float, phase_changed: bool
    ) -> np.ndarray:
        """One control tick (one QP or one iteration): the next configuration."""

    def rehearse(self, q: np.ndarray, targets: TickTargets, dt: float) -> None:  # noqa: B027
        """Solve the first tick once ahead and forget it (after :meth:`start`): a first tick
        otherwise runs code nothing has run yet (default: nothing)."""

    def prepare_phase(  # noqa: B027
        self, q: np.ndarray, targets: TickTargets, dt: float | None = None
    ) -> None:
        """The idle part of a loop before the tick of ``targets`` (the next tick, known from
        the reference; ``q`` the last tick's answer; ``dt`` its step, None: :attr:`dt`): its
        support switch made now, so that the tick does not pay it; the tick checks it and
        takes it back if it needs another phase or other anchors (default: nothing)."""

    def prepare_tick(  # noqa: B027
        self, q: np.ndarray, targets: TickTargets, dt: float | None = None
    ) -> None:
        """The idle part of a loop before the tick of ``targets`` when it switches no phase
        (:meth:`prepare_phase` else; ``dt`` as there): work of that tick that does not need
        its solve made now; the tick checks it was made from its own inputs, else makes it
        (default: nothing)."""

    def warm(self, dt: float) -> None:  # noqa: B027
        """The end of a paced loop's idle part, just before its next tick (of time step
        ``dt``): what that tick will touch brought back into the caches, with no effect on its
        answer (default: nothing)."""

    #: the reference's time step, set by the loop before :meth:`start`
    dt: float = 0.01

    def converge(
        self,
        q: np.ndarray,
        targets: TickTargets,
        tol: float,
        max_iterations: int,
        phase_changed: bool,
    ) -> tuple[np.ndarray, int]:
        """Iterate on one pose until it converges; returns (q, iterations).

        Default: repeat :meth:`track` on the same targets until the configuration stops moving
        (max |Δq| < ``tol``): the fixed point of the per-tick controller.
        """
        for iteration in range(1, max_iterations + 1):
            q_next = self.track(q, targets, self.dt, phase_changed and iteration == 1)
            step = np.abs(q_next - q)
            if np.max(step[7:]) < tol and np.max(step[:3]) < tol:
                return q_next, iteration
            q = q_next
        return q, max_iterations

    def task_errors(self) -> dict[str, np.ndarray]:
        """Task errors at the last solve, for the recording (optional)."""
        return {}

    @property  # the last solve relaxed a hard level, kept its least-squares best (no levels: no)
    def relaxed(self) -> bool:
        return False

    @property  # its solver relaxes an infeasible hard level (on_infeasible "relax"; no levels: no)
    def relaxes(self) -> bool:
        return False

    #: the stack's support-switch handover (:class:`~wbc.walking.handover.SwitchHandover`;
    #: None: no stack's, or a stack without a ``[support_switch]`` table)
    handover: SwitchHandover | None = None


class StackController(Controller):
    """A declarative task stack (:mod:`wbc.stacks`) driven by the walking targets."""

    family = "qp"

    def __init__(self, control: ControlStack, name: str | None = None) -> None:
        self.control = control
        self.solver = control.solver
        kind = "hierarchical" if "Hierarchical" in type(self.solver).__name__ else "weighted"
        self.family = f"qp-{kind}"
        self.name = name or f"{control.name}[{self.solver.backend.name}]"
        robot = control.robot
        stack = control.stack
        self._com = [t for t in stack.tasks() if isinstance(t, ComTask)]
        swing_tasks = control.role_tasks("swing")
        self._swing_pos = [t for t in swing_tasks if isinstance(t, FramePositionTask)]
        self._swing_pose = [
            t
            for t in swing_tasks
            if isinstance(t, FramePoseTask) and not type(t).__name__ == "ContactTask"
        ]
        self._swing_rot = [
            t
            for t in swing_tasks
            if isinstance(t, (SwingFootOrientationTask, FrameOrientationTask))
        ]
        torso = robot.frame_id("torso")
        self._torso = [
            t
            for t in stack.tasks()
            if isinstance(t, FrameOrientationTask) and t.frame_id == torso and t not in swing_tasks
        ]
        self._yaw_steps = [t for t in stack.tasks() if isinstance(t, YawMomentumTask) and t.follow]
        self._torso_yaw: float | None = None  # (the last tick's reference: a yaw step's start)
        self._kin = Kinematics(robot)
        # each contact task with the sole role its frame follows (None: its own frame)
        self._contacts = [
            (t, getattr(control.bindings.get(t.name), "role", None))
            for t in stack.tasks()
            if isinstance(t, ContactTask)
        ]
        self._writes, self._write_arrays = self._target_writes()
        #: a switch made ahead (:meth:`prepare_phase`): (phase, support, swing), soles, undo
        self._ahead: tuple | None = None
        #: the stack's [support_switch] across the walk's switches (None: the file has none)
        switch = control.support_switch
        self.handover = SwitchHandover(control, self._com, self._torso) if switch else None

    def _target_writes(self) -> tuple[np.ndarray | None, list[np.ndarray]]:
        """Where a tick's targets go, for :func:`~wbc.compiled.targets.copy_targets` (one
        compiled call for the CoM, swing and torso targets instead of a setter call each:
        ~1.5 µs less per tick): rows (address of a task's own target array, source: 0 CoM,
        1 swing position, 2 swing rotation, 3 torso rotation), and those arrays (kept alive:
        the tasks own them and never re-bind them). None if a task's setter is its subclass's
        own (not the checked copy of the class named here): then the setters run one by one."""
        rotation = lambda t: (  # noqa: E731
            SwingFootOrientationTask
            if isinstance(t, SwingFootOrientationTask)
            else FrameOrientationTask
        )
        writes = [
            *((t, ComTask, "set_target", "target", 0) for t in self._com),
            *((t, FramePositionTask, "set_target", "target", 1) for t in self._swing_pos),
            *((t, FramePoseTask, "set_position_target", "target_position", 1)
              for t in self._swing_pose),
            *((t, FramePoseTask, "set_rotation_target", "target_rotation", 2)
              for t in self._swing_pose),
            *((t, rotation(t), "set_target", "target", 2) for t in self._swing_rot),
            *((t, FrameOrientationTask, "set_target", "target", 3) for t in self._torso),
        ]  # fmt: skip
        rows, arrays = [], []
        for task, cls, setter, name, source in writes:
            out = getattr(task, name)
            shape = (3,) if source < 2 else (3, 3)
            if (
                getattr(type(task), setter) is not getattr(cls, setter)
                or not isinstance(out, np.ndarray)
                or out.dtype != np.float64
                or out.shape != shape
                or not out.flags.c_contiguous
            ):
                return None, []
            rows.append((out.ctypes.data, source))
            arrays.append(out)
        return np.array(rows, dtype=np.int64).reshape(-1, 2), arrays

    def _copy_targets(self, targets: TickTargets) -> bool:
        """The tick's targets into the tasks' arrays in one compiled call, checked as their
        setters check them; False if they cannot go that way (nothing copied: the setters
        then run, and raise if a target is invalid)."""
        v0, v1 = targets.com, targets.swing_position
        R0, R1 = targets.swing_rotation, targets.torso_rotation
        return (
            self._writes is not None
            and type(v0) is np.ndarray
            and type(v1) is np.ndarray
            and type(R0) is np.ndarray
            and type(R1) is np.ndarray
            and v0.dtype is _F8
            and v1.dtype is _F8
            and R0.dtype is _F8
            and R1.dtype is _F8
            and v0.shape == _VECTOR
            and v1.shape == _VECTOR
            and R0.shape == _MATRIX
            and R1.shape == _MATRIX
            and _copy_targets(v0, v1, R0, R1, self._writes, ROTATION_TOL)
        )

    def start(self, robot: Robot, q0: np.ndarray, ref: WalkingReference) -> None:
        self._ahead = None
        self._kin.update(q0)
        for task in self.control.stack.tasks():  # posture etc. from the start pose
            if hasattr(task, "set_target_from") and task not in self._com:
                task.set_target_from(self._kin)
        if self.handover is not None:
            self.handover.start()
        self._prepare_phases(q0)
        self.solver.prepare(q0, self.dt)  # setup, not the first tick's cost

    def _prepare_phases(self, q0: np.ndarray) -> None:
        """Build the solver's layout of every support phase before the loop, so that no
        support switch inside it builds one (~1 ms: the tail of the tick times otherwise).
        The loop's first tick then sets the phase and anchors the contacts on the reference."""
        control = self.control
        if not control.bindings:
            return
        for phase in ("single", "double"):
            for support, swing in (("r_sole", "l_sole"), ("l_sole", "r_sole")):
                control.set_phase(phase, support, swing, self._kin)
                self.solver.prepare(q0, self.dt)
        control.forget_anchors()
        self.solver.forget_warm_starts()

    def rehearse(self, q: np.ndarray, targets: TickTargets, dt: float) -> None:
        """The first tick solved once and forgotten (the solver's counts kept, the contacts
        anchored afresh by the first tick, as after :meth:`start`): the solve at the start
        (:meth:`StackSolver.prepare`) meets a QP without errors, and walk10's first tick then
        ran cold (the QP's active-set code, the contacts' anchoring: ~80 against ~16 µs of a
        tick; benchmarks/tick_tail.md). Only on the compiled path, whose ticks depend on no
        earlier one (each starts its active sets afresh; a backend such as OSQP starts from
        its last solution). The constraints compute their rows again (the same rows: the
        self-collision kernel ran last at the start, and walk10's second tick, the first at
        another configuration, took ~26 µs in it against ~12)."""
        solver = self.solver
        if solver.fast is None:
            return
        counts = solver.compiled_ticks, solver.handed_back_ticks, solver.interim_ticks
        for constraint in solver.stack.constraints():
            constraint.forget_rows()
        try:
            self.track(q, targets, dt, True)
        except WbcError:
            pass  # the first tick raises it again
        solver.compiled_ticks, solver.handed_back_ticks, solver.interim_ticks = counts
        self.control.forget_anchors()
        if self.handover is not None:
            self.handover.reset()

    def prepare_phase(self, q: np.ndarray, targets: TickTargets, dt: float | None = None) -> None:
        """The support switch to ``targets``' phase made ahead
        (:meth:`ControlStack.set_phase_ahead`), its contacts anchored on ``targets``' soles,
        and the solver's layout switched (:meth:`StackSolver.switch_layout`):
        the switch tick then only checks it was the right one (the same phase, the same sole
        objects, the stack untouched since), else takes it back (:meth:`_set_targets`).
        Nothing if the switch needs the configuration (a contact without a reference sole).
        A landing, the tick's output and a rehearsal of the tick are made ahead too."""
        dt = self.dt if dt is None else dt
        if self.handover is not None:
            self.handover.prepare(q, targets, dt)
        control = self.control
        key = (targets.phase, targets.support, targets.swing)
        anchors = {"l_sole": targets.l_sole, "r_sole": targets.r_sole}
        free = self._ahead is None and control.bindings and control.phase is not None
        if free and self._anchored(targets, anchors):
            undo = control.set_phase_ahead(*key, self._kin, anchors)
            self._ahead = (key, targets.l_sole, targets.r_sole, undo)
            if self.handover is not None:
                self.handover.place_ahead()  # (the landing's anchor: the rehearsal's too)
            self.solver.switch_layout()  # (its layout too: kept, taken by the phase's key)
            self.solver.rehearse(dt)  # (its first tick run once and forgotten)
        self.solver.prepare_output()

    def prepare_tick(self, q: np.ndarray, targets: TickTargets, dt: float | None = None) -> None:
        """A landing's next share made ahead (:meth:`SwitchHandover.prepare`) and written
        into its contact (:meth:`SwitchHandover.place_ahead`: the warm-up rehearses the tick
        with it), the output too."""
        if self.handover is not None:
            self.handover.prepare(q, targets, self.dt if dt is None else dt)
            self.handover.place_ahead()
        self.solver.prepare_output()

    def warm(self, dt: float) -> None:
        """The solver's tick rehearsed (:meth:`StackSolver.warm`; off unless its
        ``warm_ahead``)."""
        self.solver.warm(dt)

    def _set_targets(self, q: np.ndarray, targets: TickTargets, phase_changed: bool) -> None:
        ahead = self._ahead
        if ahead is not None:  # a switch made ahead: this one (phase, anchors), or undone
            self._ahead, (key, left, right, undo) = None, ahead
            if (
                phase_changed
                and targets.l_sole is left
                and targets.r_sole is right
                and key == (targets.phase, targets.support, targets.swing)
                and self.control.ahead_intact(undo)
            ):
                phase_changed = False
            else:
                self.control.undo_phase(undo, self._kin)
        if phase_changed:
            anchors = {"l_sole": targets.l_sole, "r_sole": targets.r_sole}
            if not self._anchored(targets, anchors):  # a contact is made where a frame is now
                self._kin.update(q)
            self.control.set_phase(
                targets.phase, targets.support, targets.swing, self._kin, anchors
            )
        self.control.lower_swing_floor(targets.swing_floor)  # (0 but in a caught landing)
        if self._yaw_steps:
            last, self._torso_yaw = self._torso_yaw, targets.torso_yaw
            for task in self._yaw_steps:
                task.set_target(0.0 if last is None else wrap_angle(targets.torso_yaw - last))
        if targets.contacts_move:
            soles = {"l_sole": targets.l_sole, "r_sole": targets.r_sole}
            for task, _ in self._contacts:
                if task.active and task.frame in soles:
                    task.set_target(soles[task.frame])
        if self._copy_targets(targets):
            return
        for com in self._com:
            com.set_target(targets.com)
        position, rotation = targets.swing_position, targets.swing_rotation
        for point in self._swing_pos:
            point.set_target(position)
        for pose in self._swing_pose:
            pose.set_position_target(position)  # type: ignore[arg-type]
            pose.set_rotation_target(rotation)
        for axes in self._swing_rot:
            axes.set_target(rotation)
        for torso in self._torso:
            torso.set_target(targets.torso_rotation)

    def _anchored(self, targets: TickTargets, anchors: dict) -> bool:
        """True if every contact that the switch to ``targets`` may make has its anchor in
        ``anchors`` (the reference's soles): then the switch needs no kinematics at q (a
        kinematics update at each support switch, ~13 µs of its tail along walk10)."""
        roles = {"support": targets.support, "swing": targets.swing}
        for task, role in self._contacts:
            frame = roles.get(role) if role else task.frame
            if frame is not None and frame not in anchors:
                return False
        return True

    def track(self, q, targets, dt, phase_changed):
        self._set_targets(q, targets, phase_changed)
        if self.handover is None:
            return self.solver.step(q, dt)
        self.handover.update(q, targets, phase_changed, dt)
        return self.handover.solve(self.solver, q, targets, dt)  # (its landing_fallback)

    def converge(self, q, targets, tol, max_iterations, phase_changed):
        self._set_targets(q, targets, phase_changed)
        if self.handover is not None:
            self.handover.update(q, targets, phase_changed, self.dt)
        result = self.solver.solve_pose(q, tol=tol, max_iterations=max_iterations)
        return result.q, result.iterations

    def task_errors(self) -> dict[str, np.ndarray]:
        return self.control.stack.errors()

    relaxed = property(lambda self: self.solver.relaxed)  # (its QP's: StackSolver.relaxed)
    relaxes = property(lambda self: self.solver.on_infeasible == "relax")
