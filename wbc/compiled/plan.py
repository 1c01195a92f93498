"""The Python side of the compiled hot path: a stack's tasks laid out for the kernels.

A plan is built when a solver (re)plans its layout (never on a plain target update): every
task becomes a row of an integer spec table, its target arrays are gathered into one packed
buffer per tick (one ``np.concatenate``), its error rows become ``task.last_error`` views,
and the frames' placements are the cached views into Pinocchio's data. Only the task types
whose ``fill`` the kernels reproduce exactly are compiled (see :data:`KINDS`); a stack with any
other task, or with extra box limits, keeps the numpy path.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..model import Kinematics, Robot
from ..tasks import (
    ComTask,
    ContactTask,
    DampingTask,
    FrameOrientationTask,
    FramePoseTask,
    FramePositionTask,
    PostureTask,
    SwingFootOrientationTask,
    Task,
    TorsoOrientationTask,
)
from . import layout as R


def numba_available() -> bool:
    """True if numba imports (the compiled path's only extra dependency)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


#: exact task types the kernels reproduce (subclasses may override fill: not compiled)
KINDS: dict[type, int] = {
    ComTask: R.COM,
    FramePositionTask: R.POSITION,
    FrameOrientationTask: R.ORIENTATION,
    FramePoseTask: R.POSE,
    ContactTask: R.POSE,
    PostureTask: R.POSTURE,
    DampingTask: R.DAMPING,
    SwingFootOrientationTask: R.SWING_AXES,
    TorsoOrientationTask: R.TORSO_AXIS,
}


def compilable(tasks: Sequence[Task]) -> bool:
    """True if every task has a compiled counterpart."""
    return all(type(t) in KINDS for t in tasks)


def _target_attributes(task: Task) -> tuple[str, ...]:
    """The task's target arrays, in the kernel's layout (rotations row-major)."""
    if isinstance(task, FramePoseTask):
        return ("target_position", "target_rotation")
    if isinstance(task, DampingTask):
        return ()
    if isinstance(task, TorsoOrientationTask):
        return ("axis",)
    return ("target",)


#: entry points resolved so far, by (kernel, variant): resolving one costs ~1 ms (numba's
#: typeof of every argument), far too much to repeat at every support switch
_ENTRIES: dict[tuple[object, int], object] = {}


class Kernel:
    """A numba function called through the entry point compiled for its argument types, which
    skips numba's per-call type dispatch (about 1 µs for the ~30 arguments of a tick).

    Only for call sites whose argument types never change: a plan's own arrays and
    C-contiguous float64 configurations. ``variant`` tells apart the argument types a kernel
    does get (the number of frame slots: the length of the frame tuples).
    """

    def __init__(self, dispatcher, variant: int = 0) -> None:
        self.dispatcher = dispatcher
        self.key = (dispatcher, variant)
        self.entry = _ENTRIES.get(self.key)

    def __call__(self, *args):
        if self.entry is not None:
            return self.entry(*args)
        result = self.dispatcher(*args)
        try:
            from numba import typeof

            signature = tuple(typeof(a) for a in args)
            self.entry = self.dispatcher.overloads[signature].entry_point
        except (KeyError, AttributeError):  # another numba: keep the dispatcher
            self.entry = self.dispatcher
        _ENTRIES[self.key] = self.entry
        return result


#: bumped whenever a plan points tasks' target arrays at its buffer
_BINDINGS = [0]


class Targets:
    """Every compiled task's targets, as views into one buffer: the tasks' target arrays *are*
    slices of it (their ``set_target`` writes in place), so a tick copies nothing.

    Several plans may hold the same task (a solver keeps one plan per support phase, and a
    task may sit in two solvers): a plan re-points the tasks at its own buffer, with their
    current values, whenever another plan did so since its last tick.
    """

    def __init__(self) -> None:
        self.entries: list[tuple[Task, str, int]] = []
        self.size = 0
        self.buffer = np.zeros(0)
        self.binding = -1

    def add(self, task: Task) -> int:
        offset = self.size
        for name in _target_attributes(task):
            self.entries.append((task, name, self.size))
            self.size += getattr(task, name).size
        return offset

    def seal(self) -> None:
        self.buffer = np.zeros(self.size)
        self.bind()

    def bind(self) -> None:
        for task, name, offset in self.entries:
            current = getattr(task, name)
            view = self.buffer[offset : offset + current.size].reshape(current.shape)
            view[...] = current
            setattr(task, name, view)
        _BINDINGS[0] += 1
        self.binding = _BINDINGS[0]

    def gather(self) -> np.ndarray:
        """The buffer, re-bound first if another plan took the tasks meanwhile."""
        if self.binding != _BINDINGS[0]:
            self.bind()
        return self.buffer


class Frames:
    """One slot per frame used by a task: its world rotation/position views and joint support."""

    def __init__(self, robot: Robot, kin: Kinematics, frame_ids: Sequence[int]) -> None:
        self.slot: dict[int, int] = {}
        for fid in frame_ids:
            self.slot.setdefault(fid, len(self.slot))
        ids = list(self.slot)
        self.support = np.zeros((max(len(ids), 1), robot.nv), dtype=np.bool_)
        for s, fid in enumerate(ids):
            self.support[s] = robot.frame_support(fid)
        # views that follow every Kinematics.update (a 1-frame dummy keeps the types fixed)
        fids = ids or [0]
        self.R = tuple(kin.rotation(f) for f in fids)
        self.p = tuple(kin.translation(f) for f in fids)


class Rows:
    """A fixed list of tasks as one block of rows: J (m x nv), raw errors E, right side b.

    ``weighted``: rows scaled by √w and b = α √w e (costs, and every level of the cascade);
    otherwise J and b = α e unscaled (the weighted QP's hard equalities).
    """

    def __init__(
        self,
        tasks: Sequence[Task],
        nv: int,
        frames: Frames,
        targets: Targets,
        weighted: bool,
    ) -> None:
        self.tasks = list(tasks)
        self.m = sum(t.rows for t in self.tasks)
        self.J = np.zeros((self.m, nv))
        self.E = np.zeros(self.m)
        self.b = np.zeros(self.m)
        spec = np.zeros((len(self.tasks), R.SPEC_COLUMNS), dtype=np.int64)
        sel: list[np.ndarray] = []
        sqrt_w = np.ones(self.m)
        gain_w = np.zeros(self.m)
        self.slices: list[tuple[str, slice]] = []
        r = s = 0
        for i, t in enumerate(self.tasks):
            k = t.rows
            kind = KINDS[type(t)]
            frame = frames.slot[t.frame_id] if hasattr(t, "frame_id") else -1
            spec[i] = (kind, frame, targets.add(t), r, s, k)
            rows = np.flatnonzero(t.mask)
            sel.append(rows)
            w = np.sqrt(t.weight) if weighted else np.ones(k)
            sqrt_w[r : r + k] = w
            gain_w[r : r + k] = t.gain * w
            self.slices.append((t.name, slice(r, r + k)))
            r += k
            s += rows.size
        self.spec = spec
        self.sel = np.concatenate(sel) if sel else np.zeros(0, dtype=np.int64)
        self.sqrt_w = sqrt_w
        self.gain_w = gain_w
        self.bind_errors()

    def bind_errors(self) -> None:
        """Every task's :attr:`~wbc.tasks.Task.last_error` becomes a view of its rows of E."""
        for t, view in self.error_views():
            t.last_error = view

    def error_views(self) -> list[tuple[Task, np.ndarray]]:
        return [(t, self.E[sl]) for t, (_, sl) in zip(self.tasks, self.slices, strict=True)]

    @property
    def args(self) -> tuple:
        return (self.spec, self.sel, self.sqrt_w, self.gain_w, self.J, self.E, self.b)


def frame_ids(tasks: Sequence[Task]) -> list[int]:
    return [t.frame_id for t in tasks if hasattr(t, "frame_id")]


class _Plan:
    """What both compiled solvers share: targets, frames, bounds and the output buffer.

    Every argument of the kernel call is a buffer of the plan, filled in place before the
    call (the configuration, the velocity steps and the scalars), so that one prebuilt tuple
    serves every tick.
    """

    def __init__(self, solver, kin: Kinematics, tasks: Sequence[Task]) -> None:
        robot = solver.robot
        self.solver = solver
        self.targets = Targets()
        self.frames = Frames(robot, kin, frame_ids(tasks))
        self.Jw = kin.data.J  # views that follow every Kinematics.update
        self.com = kin.com
        self.Jcom = kin.com_jacobian
        self.q_min, self.q_max = robot.q_min, robot.q_max
        self.q = np.zeros(robot.nq)
        self.step = np.zeros(robot.n_joints)
        self._params_key: tuple | None = None
        #: [use the velocity steps (0/1), μ (damping of the last level), hard tolerance]
        self.params = np.zeros(3)
        self.lower = np.full(robot.nv, -np.inf)
        self.upper = np.full(robot.nv, np.inf)
        self.dq = np.zeros(robot.nv)
        self.q_next = np.zeros(robot.nq)
        #: the box of the last solve (lower, upper)
        self.box = (self.lower, self.upper)
        self.unbounded = (np.full(robot.nv, -np.inf), np.full(robot.nv, np.inf))
        from .ticks import integrate

        self.integrate = Kernel(integrate)
        #: (task, view of its rows of E): re-pointed at every solve, since anything may have
        #: re-pointed a task's last_error meanwhile (Task.compute, the numpy path, another plan)
        self.error_views: list[tuple[Task, np.ndarray]] = []
        self.args: tuple = ()

    def _shared_args(self) -> tuple:
        f = self.frames
        return (
            self.targets.buffer, f.R, f.p, f.support, self.Jw, self.com, self.Jcom, self.q,
            self.q_min, self.q_max, self.step, self.params, self.lower, self.upper,
        )  # fmt: skip

    def solve(self, kin: Kinematics, dt: float | None) -> int:
        """Fill the per-tick inputs and run the kernel; returns its status (0: solved)."""
        for task, view in self.error_views:
            task.last_error = view
        if self.targets.binding != _BINDINGS[0]:
            self.targets.bind()
        np.copyto(self.q, kin.q)
        solver = self.solver
        key = (dt, solver.regularization, solver.hard_tol)
        if key != self._params_key:
            limit = solver.stack.velocity_limit
            use = dt is not None and limit is not None
            if use:
                np.copyto(self.step, limit.step(dt))
            self.params[:] = (1.0 if use else 0.0, solver.regularization, solver.hard_tol)
            self._params_key = key
        return self.kernel(*self.args)


class WeightedPlan(_Plan):
    """The weighted QP's soft rows (weighted) and hard rows (equalities), compiled."""

    def __init__(self, solver, kin: Kinematics, soft: Sequence[Task], hard: Sequence[Task]):
        super().__init__(solver, kin, [*soft, *hard])
        nv = solver.robot.nv
        self.soft = Rows(soft, nv, self.frames, self.targets, weighted=True)
        self.hard = Rows(hard, nv, self.frames, self.targets, weighted=False)
        self.targets.seal()
        self.error_views = self.soft.error_views() + self.hard.error_views()
        self.state = np.zeros(nv, dtype=np.int8)
        from .ticks import weighted_tick

        self.kernel = Kernel(weighted_tick, len(self.frames.R))
        self.args = (
            *self.soft.args, *self.hard.args, *self._shared_args(), self.state, self.dq,
            self.q_next,
        )  # fmt: skip


class CascadePlan(_Plan):
    """Every level's rows (weighted) in one block, solved level by level in one call."""

    def __init__(self, solver, kin: Kinematics, levels: Sequence[Sequence[Task]], hard):
        tasks = [t for lv in levels for t in lv]
        super().__init__(solver, kin, tasks)
        nv = solver.robot.nv
        self.rows = Rows(tasks, nv, self.frames, self.targets, weighted=True)
        self.targets.seal()
        bounds = np.cumsum([0] + [sum(t.rows for t in lv) for lv in levels])
        self.level_rows = bounds.astype(np.int64)
        self.level_hard = np.array(hard, dtype=np.bool_)
        self.error_views = self.rows.error_views()
        self.states = np.zeros((len(levels), nv), dtype=np.int8)
        self.achieved = np.zeros(self.rows.m)
        from .ticks import cascade_tick

        self.kernel = Kernel(cascade_tick, len(self.frames.R))
        self.args = (
            *self.rows.args, self.level_rows, self.level_hard, *self._shared_args(),
            self.states, self.achieved, self.dq, self.q_next,
        )  # fmt: skip
