"""Task stacks: tasks and constraints arranged in priority levels.

A stack is solver-agnostic: the weighted QP flattens it (hard tasks become equalities, soft
tasks weighted costs), the hierarchical QP solves its levels lexicographically, and the
pseudo-inverse baselines read the same task objects.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from numbers import Integral

import numpy as np

from ..exceptions import TaskError
from ..limits import BoxLimit, Constraint, JointPositionLimit, JointVelocityLimit
from ..model import Kinematics, Robot
from ..tasks import Task


@dataclass
class Level:
    """One priority level: tasks (equalities) and constraints (inequalities).

    ``hard``: the level must be met exactly (its residual must vanish); the weighted QP
    turns its tasks into equality constraints and its constraints into hard inequalities.
    """

    priority: int
    hard: bool = False
    tasks: list[Task] = field(default_factory=list)
    constraints: list[Constraint] = field(default_factory=list)

    def active_tasks(self) -> list[Task]:
        return [t for t in self.tasks if t.active]

    def active_constraints(self) -> list[Constraint]:
        return [c for c in self.constraints if c.active]


class TaskStack:
    """Levels of tasks/constraints plus box limits (joint position always; velocity optional).

    >>> stack = TaskStack(robot)
    >>> stack.add(ContactTask(robot, "l_sole"), level=0, hard=True)
    >>> stack.add(ComTask(robot), level=1, weight=10.0)
    """

    def __init__(self, robot: Robot, velocity_limits: bool = True) -> None:
        self.robot = robot
        self._levels: dict[int, Level] = {}
        self.position_limit = JointPositionLimit(robot)
        self.velocity_limit: JointVelocityLimit | None = (
            JointVelocityLimit(robot) if velocity_limits else None
        )
        self.extra_limits: list[BoxLimit] = []
        #: changes so far that the solvers' layouts depend on: :attr:`version`, and a task's or
        #: constraint's activity, gain, mask, weight or frame (never a target); solvers re-plan
        #: on a new one (a plain attribute: every tick reads it)
        self.revision = 0
        #: bumped when a level, task, constraint or limit is added
        self.version = 0

    @property
    def version(self) -> int:
        return self._version

    @version.setter
    def version(self, value: int) -> None:
        self._version = value
        self.revision += 1

    # ------------------------------------------------------------------ building
    def level(self, priority: int, hard: bool | None = None) -> Level:
        """The level of a priority (created on first use); lower numbers come first."""
        if isinstance(priority, bool) or not isinstance(priority, Integral) or priority < 0:
            raise TaskError(f"level must be an integer >= 0 (0 = first), got {priority!r}")
        if priority not in self._levels:
            self._levels[priority] = Level(priority, bool(hard))
            self.version += 1
        lvl = self._levels[priority]
        if hard is not None and lvl.hard != hard:
            if lvl.tasks or lvl.constraints:
                raise TaskError(
                    f"level {priority} is already {'hard' if lvl.hard else 'soft'}; "
                    f"cannot make it {'hard' if hard else 'soft'}"
                )
            lvl.hard = hard
        return lvl

    def add(
        self,
        task: Task,
        level: int = 0,
        hard: bool | None = None,
        weight: float | None = None,
        gain: float | None = None,
    ) -> Task:
        """Add a task at a priority level; returns the task (to keep a handle on it)."""
        if not isinstance(task, Task):
            raise TaskError(f"expected a Task, got {type(task).__name__}")
        if any(t.name == task.name for t in self.tasks()):
            raise TaskError(f"a task named {task.name!r} is already in the stack")
        if weight is not None:
            task.weight = weight
        if gain is not None:
            task.gain = gain
        self.level(level, hard).tasks.append(task)
        task._stacks = [*getattr(task, "_stacks", ()), self]  # its changes re-plan this stack
        self.version += 1
        return task

    def add_constraint(self, constraint: Constraint, level: int = 0, hard: bool | None = None):
        """Add inequality rows at a priority level."""
        if not isinstance(constraint, Constraint):
            raise TaskError(f"expected a Constraint, got {type(constraint).__name__}")
        self.level(level, hard).constraints.append(constraint)
        constraint._stacks = [*getattr(constraint, "_stacks", ()), self]
        self.version += 1
        return constraint

    def add_limit(self, limit: BoxLimit) -> BoxLimit:
        """Add another box limit (intersected with the joint limits)."""
        self.extra_limits.append(limit)
        self.version += 1
        return limit

    # ------------------------------------------------------------------ reading
    @property
    def levels(self) -> list[Level]:
        """Non-empty levels in priority order."""
        return [
            self._levels[p]
            for p in sorted(self._levels)
            if self._levels[p].active_tasks() or self._levels[p].active_constraints()
        ]

    def all_levels(self) -> list[Level]:
        """Every level, active or not (a phase's tasks off), in priority order."""
        return [self._levels[p] for p in sorted(self._levels)]

    def tasks(self) -> Iterator[Task]:
        for p in sorted(self._levels):
            yield from self._levels[p].tasks

    def task(self, name: str) -> Task:
        """A task by name."""
        for t in self.tasks():
            if t.name == name:
                return t
        raise TaskError(f"no task named {name!r}; tasks: {[t.name for t in self.tasks()]}")

    def members(self) -> tuple[list[Task], list[Constraint]]:
        """Every task and every constraint, active or not, in priority order (kept until
        :attr:`version` changes: the solvers read them at each support switch)."""
        cached = getattr(self, "_members", None)
        if cached is None or cached[0] != self._version:
            cached = self._members = (self._version, list(self.tasks()), list(self.constraints()))
        return cached[1], cached[2]

    def constraints(self) -> Iterator[Constraint]:
        for p in sorted(self._levels):
            yield from self._levels[p].constraints

    def constraint(self, name: str) -> Constraint:
        for c in self.constraints():
            if c.name == name:
                return c
        raise TaskError(f"no constraint named {name!r}")

    def errors(self) -> dict[str, np.ndarray]:
        """Each active task's error e = x* − x from the last solve (masked rows).

        Units follow the task's rows: metres for positions (CoM, frame and contact positions),
        radians for orientations (the log map of the rotation error; contact and pose tasks:
        3 position rows, then 3 orientation rows) and for joint rows (posture; damping: base
        translation in metres, base rotation and joints in radians)."""
        return {t.name: t.last_error.copy() for t in self.tasks() if t.active}

    def evaluate(self, kin: Kinematics) -> dict[str, np.ndarray]:
        """Each active task's error at the configuration of ``kin`` (no solve)."""
        out = {}
        for t in self.tasks():
            if t.active:
                out[t.name] = t.compute(kin)[1].copy()
        return out

    def set_active(self, names: Iterable[str], active: bool) -> None:
        """Switch tasks or constraints on/off by name (e.g. at a support change)."""
        wanted = set(names)
        found = set()
        for t in self.tasks():
            if t.name in wanted:
                t.active = active
                found.add(t.name)
        for c in self.constraints():
            if c.name in wanted:
                c.active = active
                found.add(c.name)
        missing = wanted - found
        if missing:
            raise TaskError(f"no task or constraint named {sorted(missing)}")
