"""Declarative task stacks: TOML files in ``tasks/`` turned into a stack and its solver.

A file names the solver (``weighted`` or ``hierarchical``), its options and a list of levels::

    name = "cj_foot"
    solver = "hierarchical"
    [[levels]]
    hard = true
    tasks = [{ type = "contact", frame = "support" }]
    [[levels]]
    tasks = [{ type = "frame_position", frame = "swing", weight = 1.0 }]
    constraints = [{ type = "com_polygon", margin = 0.01 }]

``frame = "support"`` / ``"swing"`` bind a task to whichever sole has that role; a walking
controller re-binds them at every support change (:meth:`ControlStack.set_phase`).
``phases = ["double"]`` (or ``["single"]``) makes a task active only in those phases.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import inspect
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from .exceptions import TaskError, WbcError
from .limits import (
    ComPolygonConstraint,
    Constraint,
    GroundClearanceConstraint,
    SelfCollisionConstraint,
)
from .model import Kinematics, Robot
from .paths import read_toml, stacks_dir
from .roles import leg_length, length_unit
from .solvers import HierarchicalQP, StackSolver, TaskStack, WeightedQP
from .stack_tables import SupportSwitch, is_positive, parse_support_switch
from .tasks import ContactTask, Task
from .tasks.task import STACK_TYPES

ROLES = ("support", "swing")
PHASES = ("double", "single")
SOLVERS = ("weighted", "hierarchical")
_TASK_KEYS = {"type", "name", "frame", "weight", "gain", "mask", "phases", "joints"}
#: ``joints = ...`` of a joint-space task (posture, damping): its rows on the legs' joints
#: (:attr:`wbc.model.Robot.roles`) or on every other joint (arms, head); the base's rows off
JOINT_GROUPS = ("legs", "others")


def _check_keys(cls, kw: dict) -> None:
    """A key the task class does not take (e.g. ``gain`` on a damping task) is one line."""
    accepted = inspect.signature(cls).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in accepted.values()):
        return
    bad = sorted(k for k in kw if k not in accepted)
    if bad:
        allowed = sorted(k for k in accepted if k in _TASK_KEYS)
        raise TaskError(f"{cls.__name__} takes no {bad}; its keys: {allowed}")


CONSTRAINT_TYPES = ("com_polygon", "ground_clearance", "self_collision")


@dataclass
class RoleBinding:
    """A task or constraint whose frame follows a sole role and/or is limited to phases."""

    role: str | None
    phases: tuple[str, ...]


@dataclass
class _PhaseMoves:
    """A support phase's bindings, in the order :meth:`ControlStack.set_phase` applies them:
    role-bound frames, CoM polygons' soles, phase switches, contacts (active or not)."""

    version: tuple[int, int]
    frames: list[tuple[Any, str]] = field(default_factory=list)
    polygons: list[tuple[Any, list[str]]] = field(default_factory=list)
    switches: list[tuple[Any, bool]] = field(default_factory=list)
    contacts: list[tuple[Any, bool]] = field(default_factory=list)


@dataclass
class PhaseUndo:
    """What :meth:`ControlStack.set_phase_ahead` changed: the (phase, support, swing) before,
    the contacts' anchoring record, each contact's target (position, rotation) before, and
    the stack's revision after the move."""

    phase: tuple[str | None, str | None, str | None]
    anchored: dict[str, str]
    targets: list[tuple[Any, np.ndarray, np.ndarray]]
    revision: int = -1


@dataclass
class ControlStack:
    """A loaded stack: the :class:`TaskStack`, its solver and the role bindings."""

    name: str
    description: str
    robot: Robot
    stack: TaskStack
    solver: StackSolver
    bindings: dict[str, RoleBinding] = field(default_factory=dict)
    source: str = ""
    #: the file's ``[support_switch]`` (None: a switch asks the tasks' jumps in one tick)
    support_switch: SupportSwitch | None = None
    phase: str | None = None
    support: str | None = None
    swing: str | None = None
    _anchored: dict[str, str] = field(default_factory=dict)  # contact task -> anchored sole
    #: (phase, support, swing) -> what set_phase does then (kept until the stack changes)
    _phases: dict[tuple, _PhaseMoves] = field(default_factory=dict, repr=False)
    #: the stack's revision after the last set_phase, and a token of the current stretch of
    #: set_phase calls with no other change to the stack between them (see set_phase)
    _after: int | None = field(default=None, repr=False)
    _epoch: object = field(default=None, repr=False)
    #: m: the swing's ground clearances lowered this much (:meth:`lower_swing_floor`), and
    #: those clearances each with its own (None: not read yet)
    swing_floor: float = 0.0
    _floors: list | None = field(default=None, repr=False)

    # ------------------------------------------------------------------ roles
    def role_tasks(self, role: str) -> list[Task]:
        return [t for t in self.stack.tasks() if self.bindings.get(t.name, _NO).role == role]

    def lower_swing_floor(self, floor: float) -> None:
        """The ground clearances whose frame follows the swing sole set ``floor`` m (≤ 0)
        from their own (:attr:`~wbc.walking.tick_targets.TickTargets.swing_floor`; 0: their
        own again)."""
        if floor == self.swing_floor:
            return
        if self._floors is None:  # (their own clearances, read once)
            self._floors = [
                (c, c.clearance)
                for c in self.stack.constraints()
                if isinstance(c, GroundClearanceConstraint)
                and self.bindings.get(c.name, _NO).role == "swing"
            ]
        for constraint, clearance in self._floors:
            constraint.clearance = clearance + floor
        self.swing_floor = float(floor)

    # ------------------------------------------------------------------ phases
    def set_phase(
        self,
        phase: str,
        support: str,
        swing: str | None,
        kin: Kinematics,
        anchors: Mapping[str, Any] | None = None,
    ) -> None:
        """Bind role frames and switch phase-limited tasks; anchor contacts that start.

        ``phase``: "double" or "single"; ``support``/``swing``: sole frame names (in double
        support the "swing" sole is the one that will lift next, or the trailing one).
        ``anchors``: optional {sole frame: pinocchio.SE3} where a contact should be held
        (default: where the sole is now).
        """
        stack = self.stack
        if stack.revision != self._after:  # the stack changed since the last set_phase
            self._epoch = object()
        entry = self._entry(phase, support, swing)
        for item, frame in entry.frames:  # (set when it changes: a lookup and a re-plan)
            if item.frame != frame:
                item.set_frame(frame)
        for item, soles in entry.polygons:  # (always: its polygon is taken afresh)
            item.set_support(soles)
        for item, active in entry.switches:
            item.active = active
        anchored = self._anchored
        for item, active in entry.contacts:
            was_active = item.active
            item.active = active
            if active and (not was_active or anchored.get(item.name) != item.frame):
                anchor = None if anchors is None else anchors.get(item.frame)
                if anchor is None:
                    item.make_contact(kin)
                else:
                    item.set_target(anchor)
                anchored[item.name] = item.frame
        self.phase, self.support, self.swing = phase, support, swing
        # within one epoch the stack changed only by set_phase, whose moves set everything
        # they touch: its layout is a function of (phase, support, swing), which the solver
        # then takes from its memo instead of reading the stack (a support switch's cost)
        self._after = stack.revision
        self.solver.note_phase((self._epoch, phase, support, swing), self._after)

    def set_phase_ahead(
        self,
        phase: str,
        support: str,
        swing: str | None,
        kin: Kinematics,
        anchors: Mapping[str, Any] | None = None,
    ) -> PhaseUndo:
        """:meth:`set_phase` made ahead of the tick that needs it (a control loop's idle part,
        the next phase known from its reference), and what takes it back exactly
        (:meth:`undo_phase`: the phase before, its contacts' anchors and targets) should the
        tick turn out to need another phase or other anchors."""
        entry = self._entry(phase, support, swing)
        undo = PhaseUndo(
            (self.phase, self.support, self.swing),
            dict(self._anchored),
            [(c, c.target_position.copy(), c.target_rotation.copy()) for c, _ in entry.contacts],
        )
        try:
            self.set_phase(phase, support, swing, kin, anchors)
        except WbcError:  # (a bad anchor: nothing made ahead; the tick raises it again)
            self.undo_phase(undo, kin)
            raise
        undo.revision = self.stack.revision
        return undo

    def ahead_intact(self, undo: PhaseUndo) -> bool:
        """True if nothing changed the stack since :meth:`set_phase_ahead` returned ``undo``
        (its moves are then those :meth:`set_phase` would make now)."""
        return self.stack.revision == undo.revision

    def undo_phase(self, undo: PhaseUndo, kin: Kinematics) -> None:
        """Take a :meth:`set_phase_ahead` back: the phase before it, its contacts anchored
        where they were (the same targets, the same anchoring record). Exact after a
        :meth:`set_phase` (a stack with no phase yet keeps the frames and activity moved)."""
        phase, support, swing = undo.phase
        if phase is not None and support is not None:
            self.set_phase(phase, support, swing, kin)
        for contact, position, rotation in undo.targets:
            contact.target_position[:] = position
            contact.target_rotation[:] = rotation
        self._anchored.clear()
        self._anchored.update(undo.anchored)

    def _entry(self, phase: str, support: str, swing: str | None) -> _PhaseMoves:
        """The moves of :meth:`set_phase` in this phase (kept, :meth:`_phase_moves`)."""
        entry = self._phases.get((phase, support, swing))
        if entry is None or entry.version != (self.stack.version, len(self.bindings)):
            entry = self._phase_moves(phase, support, swing)
        return entry

    def _phase_moves(self, phase: str, support: str, swing: str | None) -> _PhaseMoves:
        """What :meth:`set_phase` makes of the role-bound tasks and constraints in this phase,
        worked out once per (phase, support, swing) and kept until the stack changes (a
        support switch is on a control loop's clock: it then only compares and sets)."""
        if phase not in PHASES:
            raise TaskError(f"phase must be one of {PHASES}, got {phase!r}")
        version = (self.stack.version, len(self.bindings))
        if any(e.version != version for e in self._phases.values()):
            self._phases.clear()
        roles = {"support": support, "swing": swing}
        soles = [support] if phase == "single" or swing is None else [support, swing]
        entry = _PhaseMoves(version)
        tasks, constraints = self.stack.members()
        members: list[Task | Constraint] = [*tasks, *constraints]
        for item in members:
            polygon = isinstance(item, ComPolygonConstraint)
            binding = self.bindings.get(item.name)
            if binding is None:
                if polygon:  # (no binding: it follows the phase's soles)
                    entry.polygons.append((item, soles))
                continue
            frame = roles.get(binding.role) if binding.role else None
            if frame is not None:
                if polygon:
                    entry.polygons.append((item, [frame]))
                else:
                    entry.frames.append((item, frame))
            active = phase in binding.phases and not (binding.role and frame is None)
            kind = entry.contacts if isinstance(item, ContactTask) else entry.switches
            kind.append((item, active))
        self._phases[(phase, support, swing)] = entry
        return entry

    def forget_anchors(self) -> None:
        """The next :meth:`set_phase` anchors every active contact afresh."""
        self._anchored.clear()


_NO = RoleBinding(None, PHASES)


#: former names of stack files, still accepted by :func:`load_stack` (old name -> file stem)
RENAMED_STACKS = {"walk_lexicographic": "walk_strict"}


def stack_file(name_or_path: str | Path) -> Path | None:
    """The stack file a name in ``tasks/`` (or a former name, :data:`RENAMED_STACKS`) or a
    ``.toml`` path stands for; None if there is no such file."""
    path = Path(name_or_path)
    if path.suffix != ".toml":
        name = RENAMED_STACKS.get(str(name_or_path), str(name_or_path))
        path = stacks_dir() / f"{name}.toml"
    return path if path.is_file() else None


#: the stack a command runs on a robot whose folder has no ``stack.toml``
DEFAULT_STACK = "walk"


def robot_stack(robot: Robot, stack: str | Path | None = None) -> tuple[str | Path, str]:
    """The stack a command runs on ``robot``, and the line saying so: ``stack`` when given,
    else the robot folder's ``stack.toml`` (:attr:`wbc.model.Robot.default_stack`), else
    :data:`DEFAULT_STACK` (``tasks/walk.toml``). Every command that runs a stack (walk, sim,
    bench --physics, deploy --live, the closed loop) picks its stack here."""
    if stack is not None:
        path = stack_file(stack)
        return stack, f"stack {stack} ({path if path is not None else 'not found'})"
    if robot.default_stack is not None:
        return robot.default_stack, f"stack {robot.default_stack} (the robot folder's)"
    return DEFAULT_STACK, f"stack {DEFAULT_STACK} (tasks/{DEFAULT_STACK}.toml; no robot stack.toml)"


def available_stacks() -> list[str]:
    """Names of the stack files in ``tasks/``."""
    return sorted(p.stem for p in stacks_dir().glob("*.toml"))


def load_stack(
    name_or_path: str | Path,
    robot: Robot,
    q: np.ndarray | None = None,
    backend: str | None = None,
    solver: str | None = None,
    **solver_options: Any,
) -> ControlStack:
    """Build a stack and its solver from a TOML file (by name in ``tasks/`` or by path).

    ``q`` (default Walk Ready) gives the initial targets (contacts anchored where the soles
    are, posture = q); ``backend``, ``solver`` ("weighted"/"hierarchical") and
    ``solver_options`` override the file's settings.
    """
    path = stack_file(name_or_path)
    if path is None:
        raise TaskError(
            f"unknown task stack {str(name_or_path)!r}; available: {available_stacks()}"
        )
    spec = read_toml(path, "task stack", TaskError)
    if solver is not None:
        spec = {**spec, "solver": solver}
    return build_stack(spec, robot, q, backend, source=str(path), **solver_options)


def build_stack(
    spec: Mapping[str, Any],
    robot: Robot,
    q: np.ndarray | None = None,
    backend: str | None = None,
    source: str = "<dict>",
    **solver_options: Any,
) -> ControlStack:
    """Build from an already parsed spec (see the module docstring for the format)."""
    where = f"task stack {source}"
    unknown = set(spec) - {
        "name",
        "description",
        "solver",
        "backend",
        "velocity_limits",
        "regularization",
        "method",
        "levels",
        "on_infeasible",
        "import",
        "design_leg",
        "support_switch",
        "pdas_ties",
        "carry_at_switch",
        "defer_rows_join",
        "skip_degenerate",
    }
    if unknown:
        raise TaskError(f"{where}: unknown keys {sorted(unknown)}")
    solver_kind = spec.get("solver", "weighted")
    if solver_kind not in SOLVERS:
        raise TaskError(f"{where}: solver must be one of {SOLVERS}, got {solver_kind!r}")
    levels = spec.get("levels")
    if not isinstance(levels, list) or not levels:
        raise TaskError(f"{where}: needs at least one [[levels]] entry")
    if "import" in spec:
        import_task_modules(spec["import"], _named_types(levels), source)
    q = robot.configuration("stand") if q is None else robot.check_configuration(q)
    kin = Kinematics(robot, q)
    velocity_limits = spec.get("velocity_limits", True)
    if not isinstance(velocity_limits, bool):
        raise TaskError(f"{where}: velocity_limits must be true or false, got {velocity_limits!r}")
    for key in ("pdas_ties", "carry_at_switch", "defer_rows_join", "skip_degenerate"):
        if not isinstance(spec.get(key, False), bool):
            raise TaskError(f"{where}: {key} must be true or false, got {spec[key]!r}")
    stack = TaskStack(robot, velocity_limits=velocity_limits)
    unit = _stack_length_unit(spec.get("design_leg"), robot, where)
    switch = parse_support_switch(spec.get("support_switch"), unit, where)
    bindings: dict[str, RoleBinding] = {}
    given: set[str] = set()  # tasks whose entry gives their target
    for priority, level in enumerate(levels):
        if not isinstance(level, dict):
            raise TaskError(f"{where}: level {priority} must be a table")
        extra = set(level) - {"hard", "tasks", "constraints"}
        if extra:
            raise TaskError(f"{where}: level {priority} has unknown keys {sorted(extra)}")
        hard = level.get("hard", False)
        if not isinstance(hard, bool):
            raise TaskError(f"{where}: level {priority}: hard must be true or false, got {hard!r}")
        stack.level(priority, hard)
        for entry in level.get("tasks", []):
            task, binding = _make_task(entry, robot, where, priority)
            _scale_length_weights(task, unit, f"{where}: level {priority}")
            stack.add(task, level=priority)
            if binding is not None:
                bindings[task.name] = binding
            if "target" in entry:
                given.add(task.name)
        for entry in level.get("constraints", []):
            constraint, binding = _make_constraint(entry, robot, where, priority)
            if constraint is None:  # an optional self-collision entry this robot lacks
                continue
            stack.add_constraint(constraint, level=priority)
            if binding is not None:
                bindings[constraint.name] = binding
    options = {k: spec[k] for k in ("regularization", "on_infeasible") if k in spec}
    options.update(solver_options)
    be = backend or spec.get("backend", "daqp")
    solver_keys = ("method", "pdas_ties", "carry_at_switch", "defer_rows_join", "skip_degenerate")
    for key in solver_keys:  # (its own)
        if solver_kind != "weighted" and key in spec:
            options.setdefault(key, spec[key])
    try:
        solver: StackSolver = (WeightedQP if solver_kind == "weighted" else HierarchicalQP)(
            stack, be, **options
        )
    except WbcError as exc:  # (a solver option out of range: the file's key named)
        raise TaskError(f"{where}: {exc}") from exc
    control = ControlStack(
        spec.get("name", Path(source).stem),
        spec.get("description", ""),
        robot,
        stack,
        solver,
        bindings,
        source,
        switch,
    )
    _initial_targets(control, kin, given)
    return control


def _stack_length_unit(design_leg: Any, robot: Robot, where: str) -> float:
    """λ for a stack's length rows: the robot's hip-to-ankle length over the stack file's
    ``design_leg`` (m: the leg of the robot its weights were tuned on; the package's stacks
    state the Bioloid's), or 1 for a stack that states none (a robot folder's own stack is in
    that robot's units)."""
    if design_leg is None:
        return 1.0
    if not is_positive(design_leg):
        raise TaskError(
            f"{where}: design_leg must be a positive length in m (the hip-to-ankle length "
            f"its weights were tuned on), got {design_leg!r}"
        )
    return round(length_unit(robot) * leg_length(1.0) / float(design_leg), 9)


def _scale_length_weights(task: Task, unit: float, where: str) -> None:
    """A stack's weights are stated for the robot its file names by ``design_leg`` (the
    package's stacks: the Bioloid): on a robot ``unit`` times that size the task's length rows
    (:attr:`~wbc.tasks.Task.length_rows`) weigh ``1 / unit²`` as much, so that a weight trades
    the same share of the robot's size against the same joint angle on any robot (a weighted
    level's solution then scales with the robot: tests/test_walking_sizing.py)."""
    n = task.length_rows
    if unit == 1.0 or n == 0:
        return
    w = np.array(task._weight_full, dtype=float)  # (the full task's rows, before its mask)
    w[:n] /= unit * unit
    try:
        task.weight = w.tolist()
    except WbcError as exc:
        raise TaskError(f"{where}: on a robot {unit:g}x the design size: {exc}") from exc


def _named_types(levels: list) -> set[str]:
    """The task types a stack's levels name (malformed entries are left to their checks)."""
    return {
        entry["type"]
        for level in levels
        if isinstance(level, dict) and isinstance(level.get("tasks"), list)
        for entry in level["tasks"]
        if isinstance(entry, dict) and isinstance(entry.get("type"), str)
    }


_IMPORT_RULE = (
    'import = ["module", ...]: names of Python modules defining task types (Task subclasses '
    "with a stack_type), looked for beside the stack file, then on the Python path"
)


def import_task_modules(names: Any, named: set[str], source: str = "<dict>") -> list[ModuleType]:
    """A stack file's ``import = ["my_tasks", ...]``: import each module — from the stack
    file's folder first (a ``my_tasks.py`` or a package beside ``source``), then from the
    Python path — so that the task types it defines (classes setting
    :attr:`~wbc.tasks.Task.stack_type`) join :data:`wbc.tasks.task.STACK_TYPES`; each module
    must define at least one type of ``named`` (the types the stack names). A module already
    imported is not run again. Anything else is one :class:`TaskError` line naming the file,
    the key and what is allowed."""
    where = f"task stack {source}"
    if not (isinstance(names, list) and all(isinstance(n, str) and n for n in names)):
        raise TaskError(f"{where}: import = {names!r}: {_IMPORT_RULE}")
    folder = Path(source).resolve().parent if Path(source).is_file() else None
    modules = []
    for name in names:
        if not all(part.isidentifier() for part in name.split(".")):
            raise TaskError(
                f"{where}: import = {names!r}: {name!r} is not a module name; {_IMPORT_RULE}"
            )
        module = _import_beside(name, folder, where)
        defined = sorted(
            kind
            for kind, cls in STACK_TYPES.items()
            if cls.__module__ == name
            or cls.__module__.startswith(name + ".")
            or getattr(module, cls.__name__, None) is cls
        )
        if not set(defined) & named:
            raise TaskError(
                f"{where}: import {name!r} ({getattr(module, '__file__', name)}) defines no task "
                f"type the stack names (it defines {defined}; the stack names {sorted(named)}): "
                'a task class sets stack_type = "its_type"'
            )
        modules.append(module)
    return modules


def _import_beside(name: str, folder: Path | None, where: str) -> ModuleType:
    """Module ``name``, found in ``folder`` first (on the path only for the import: the
    module may import its neighbours), else on the Python path."""
    top = name.split(".", 1)[0]
    beside = None
    if folder is not None:
        spec = importlib.machinery.PathFinder.find_spec(top, [str(folder)])
        beside = spec.origin if spec is not None and spec.origin else None
    loaded = sys.modules.get(top)
    if beside is not None and loaded is not None:
        if Path(getattr(loaded, "__file__", "") or "").resolve() != Path(beside).resolve():
            raise TaskError(
                f"{where}: import {name!r}: {beside} is beside the file, but another module "
                f"{top!r} is loaded ({getattr(loaded, '__file__', 'built in')}): rename one"
            )
    added = beside is not None
    if added:  # (first: the module beside the file wins over one of its name on the path)
        sys.path.insert(0, str(folder))
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name is not None and (name == exc.name or name.startswith(exc.name + ".")):
            raise TaskError(
                f"{where}: import {name!r}: no such module "
                f"{'beside the file (' + str(folder) + ') nor ' if folder else ''}on the Python "
                f"path; {_IMPORT_RULE}"
            ) from None
        raise TaskError(f"{where}: import {name!r}: {exc}") from exc
    except WbcError as exc:  # (e.g. a stack_type another class holds)
        raise TaskError(f"{where}: import {name!r}: {exc}") from exc
    except Exception as exc:  # (its own error while importing: one line, the cause chained)
        raise TaskError(f"{where}: import {name!r} failed: {type(exc).__name__}: {exc}") from exc
    finally:
        if added:
            sys.path.remove(str(folder))


def _make_task(entry, robot: Robot, where: str, priority: int) -> tuple[Task, RoleBinding | None]:
    """A task entry -> its class of :data:`wbc.tasks.task.STACK_TYPES` (the package's and the
    stack's ``import`` modules' types, one table), built with the entry's keys."""
    if not isinstance(entry, dict) or "type" not in entry:
        raise TaskError(f"{where}: level {priority}: each task needs a 'type'")
    kind = entry["type"]
    cls = STACK_TYPES.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise TaskError(
            f"{where}: unknown task type {kind!r}; known: {sorted(STACK_TYPES)} (a type of "
            'your own: import = ["its_module"] in the file)'
        )
    keys = set(cls.stack_keys)
    extra = set(entry) - _TASK_KEYS - keys
    if extra:
        raise TaskError(f"{where}: task {kind!r} has unknown keys {sorted(extra)}")
    frame = entry.get("frame")
    role = frame if frame in ROLES else None
    name = entry.get("name")
    if name is None:
        name = kind if frame is None else f"{kind}_{frame}"
    at = f"{where}: level {priority}: task {name!r}"
    takes_frame = inspect.signature(cls).parameters.get("frame")
    if frame is not None and takes_frame is None:
        raise TaskError(f"{at}: task type for {cls.__name__} takes no 'frame'")
    if frame is None and takes_frame is not None and takes_frame.default is takes_frame.empty:
        raise TaskError(f"{at}: task {kind!r} needs a 'frame' (a frame name or a role {ROLES})")
    if role and not hasattr(cls, "set_frame"):
        raise TaskError(
            f"{where}: task {kind!r}: frame = {frame!r}: give a frame name (the roles"
            f" {ROLES} bind only tasks with a set_frame method)"
        )
    phases = tuple(entry.get("phases", PHASES))
    if not set(phases) <= set(PHASES):
        raise TaskError(f"{where}: task {kind!r}: phases must be among {PHASES}, got {phases}")
    kw = {k: entry[k] for k in ("weight", "gain", "mask") if k in entry}
    _check_numbers(kw, at)
    if "joints" in entry:
        kw["mask"] = _joint_group_mask(entry, cls, robot, at)
    kw.update({k: entry[k] for k in keys if k in entry})
    try:
        _check_keys(cls, kw)
        if frame is not None:  # (a role: the left sole until the first set_phase)
            kw["frame"] = {"support": "l_sole", "swing": "r_sole"}.get(frame, frame)
        make: Callable[..., Task] = cls  # (a task type's __init__ takes the robot first)
        task = make(robot, name=name, **kw)
    except WbcError as exc:
        raise TaskError(f"{at}: {exc}") from exc
    binding = RoleBinding(role, phases) if (role or phases != PHASES) else None
    return task, binding


def _joint_group_mask(entry: Mapping[str, Any], cls: type, robot: Robot, where: str) -> list:
    """The mask of ``joints = "legs"`` / ``"others"`` (:data:`JOINT_GROUPS`) on a task with
    one row per joint (a posture: n_joints rows) or per degree of freedom (a damping: nv rows,
    the base's six off): the legs are those :attr:`wbc.model.Robot.roles` finds, so a file
    names no joint. Not with ``mask``; not on a task of another kind."""
    group = entry["joints"]
    if group not in JOINT_GROUPS:
        raise TaskError(f"{where}: joints = {group!r}: must be one of {JOINT_GROUPS}")
    if "mask" in entry:
        raise TaskError(f"{where}: give joints or mask, not both")
    rows = {"posture": robot.n_joints, "damping": robot.model.nv}.get(
        getattr(cls, "stack_type", "")
    )
    if rows is None:
        raise TaskError(f"{where}: joints = {group!r} applies to posture and damping tasks only")
    legs = {robot.joint_index(j) for s in ("left", "right") for j in robot.roles.leg(s)}
    mask = [(j in legs) == (group == "legs") for j in range(robot.n_joints)]
    return [False] * (rows - robot.n_joints) + mask


def _check_numbers(kw: Mapping[str, Any], where: str) -> None:
    """``weight`` (a number or a list of numbers, >= 0), ``gain`` (a number, >= 0) and ``mask``
    (a list of booleans) before they reach the task: a wrong type is named, not a traceback."""

    def number(v: Any) -> bool:
        return isinstance(v, (int, float)) and not isinstance(v, bool)

    if "weight" in kw:
        w = kw["weight"]
        if not (number(w) or (isinstance(w, list) and w and all(number(x) for x in w))):
            raise TaskError(
                f"{where}: weight = {w!r}: must be a number >= 0 or a list of numbers (one per row)"
            )
    if "gain" in kw and not number(kw["gain"]):
        raise TaskError(f"{where}: gain = {kw['gain']!r}: must be a number >= 0")
    if "mask" in kw:
        m = kw["mask"]
        if not (isinstance(m, list) and m and all(isinstance(x, bool) for x in m)):
            raise TaskError(f"{where}: mask = {m!r}: must be a list of true/false, one per row")


def _make_constraint(entry, robot: Robot, where: str, priority: int):
    if not isinstance(entry, dict) or entry.get("type") not in CONSTRAINT_TYPES:
        raise TaskError(
            f"{where}: level {priority}: constraint type must be one of "
            f"{CONSTRAINT_TYPES}, got {entry!r}"
        )
    kind = entry["type"]
    if kind == "self_collision":
        return _self_collision(entry, robot, where), None
    extra = set(entry) - {"type", "name", "frame", "margin", "clearance", "phases"}
    if extra:
        raise TaskError(f"{where}: constraint {kind!r} has unknown keys {sorted(extra)}")
    frame = entry.get("frame")
    role = frame if frame in ROLES else None
    phases = tuple(entry.get("phases", PHASES))
    actual = {"support": "l_sole", "swing": "r_sole"}.get(frame, frame) if frame else frame
    try:
        constraint = _build_constraint(kind, entry, robot, where, actual, frame)
    except WbcError as exc:
        raise TaskError(f"{where}: level {priority}: constraint {kind!r}: {exc}") from exc
    binding = RoleBinding(role, phases) if (role or phases != PHASES) else None
    return constraint, binding


#: the range (m) of each length a stack file gives a constraint: a CoM polygon's margin (inward
#: from the soles' hull), a ground clearance
CONSTRAINT_LENGTHS = {"margin": (-0.1, 0.1), "clearance": (0.0, 0.1)}


def _build_constraint(kind, entry, robot, where, actual, frame) -> Constraint:
    constraint: Constraint
    for key, (lo, hi) in CONSTRAINT_LENGTHS.items():
        value = entry.get(key, 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
            raise TaskError(f"{key} must be a number of metres in [{lo:g}, {hi:g}], got {value!r}")
    if kind == "com_polygon":
        soles = [actual] if actual else ["l_sole", "r_sole"]
        constraint = ComPolygonConstraint(
            robot, soles, margin=entry.get("margin", 0.01), name=entry.get("name", "com_polygon")
        )
    else:
        if actual is None:
            raise TaskError(f"{where}: ground_clearance needs a 'frame'")
        constraint = GroundClearanceConstraint(
            robot,
            actual,
            entry.get("clearance", 0.0),
            name=entry.get("name", f"ground_clearance_{frame}"),
        )
    return constraint


_SELF_COLLISION_KEYS = {
    *("type", "name", "margin", "trigger", "damping", "include", "exclude", "pairs", "optional"),
    "common_frame",
    "cut_in_box",
    "in_tick",
}


def _self_collision(entry: dict, robot: Robot, where: str) -> SelfCollisionConstraint | None:
    """``{ type = "self_collision", margin = 0.005, trigger = 0.02, damping = 0.4,
    include = [[link, link], ...], exclude = [...], pairs = [...], optional = false,
    common_frame = true, cut_in_box = false, in_tick = true }`` (all but ``type``
    optional). ``pairs``: only these link pairs (e.g. their own margin); ``optional =
    true``: pairs naming a link this robot does not have are left out of ``pairs`` /
    ``exclude`` (a stack shared by robots; with no pair left, no constraint); ``cut_in_box``,
    ``in_tick``:
    :class:`~wbc.limits.SelfCollisionConstraint`'s."""
    extra = set(entry) - _SELF_COLLISION_KEYS
    if extra:
        raise TaskError(
            f"{where}: constraint 'self_collision' has unknown keys {sorted(extra)}; "
            f"allowed: {sorted(_SELF_COLLISION_KEYS)}"
        )
    keys = (
        *("margin", "trigger", "damping", "include", "exclude", "pairs", "common_frame"),
        *("cut_in_box", "in_tick"),
    )
    kw = {k: entry[k] for k in keys if k in entry}
    if entry.get("optional", False) is not False:
        if entry["optional"] is not True:
            raise TaskError(f"{where}: self_collision optional must be true or false")
        from .limits.self_collision import collision_model

        links = set(collision_model(robot).links)
        for k in ("exclude", "pairs"):
            if k in kw:
                kw[k] = [p for p in kw[k] if not _names_absent_links(p, links)]
        if "pairs" in kw and not kw["pairs"]:
            return None
    try:
        return SelfCollisionConstraint(robot, name=entry.get("name", "self_collision"), **kw)
    except WbcError as exc:
        raise TaskError(f"{where}: {exc}") from exc


def _names_absent_links(pair: Any, links: set[str]) -> bool:
    """A well-formed ``[link, link]`` naming a link outside ``links`` (malformed entries are
    kept, for the constraint to name them)."""
    return (
        isinstance(pair, list)
        and len(pair) == 2
        and all(isinstance(n, str) for n in pair)
        and not set(pair) <= links
    )


def _initial_targets(control: ControlStack, kin: Kinematics, given: set[str]) -> None:
    """Targets = the current state: contacts where the soles are, every other task with a
    ``set_target_from`` (CoM, frames, posture, a user's type) by it, unless its entry
    (``given``) sets its target."""
    for task in control.stack.tasks():
        if task.name in given:
            continue
        if isinstance(task, ContactTask):
            task.make_contact(kin)
        elif hasattr(task, "set_target_from"):
            task.set_target_from(kin)
    control.set_phase("double", "l_sole", "r_sole", kin)
