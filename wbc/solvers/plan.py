"""The Python side of the compiled hot path: a stack's tasks and box limits laid out for the
kernels.

A plan is built when a solver (re)plans its layout (never on a plain target update): every
task becomes a row of an integer spec table (its row kernel, target, frames and output rows),
every box limit a row of another (its bound kernel, parameters and frames), their target and
parameter arrays are gathered by the tick into one packed buffer (by address: the tasks and
limits keep owning them), the tasks' error rows become ``task.last_error`` views, and the
frames' placements are the cached views into Pinocchio's data. Every task with a row kernel
and every limit with a bound kernel is compiled, wherever its class is defined
(:mod:`wbc.compiled.dispatch` generates the tick of the plan's set of kernels, which this
module passes in: the compiled kernels know no task); a stack with a task or a box limit
without one keeps the numpy path.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..compiled import dispatch as D
from ..compiled.signature import momentum_into, velocity
from ..exceptions import TaskError
from ..limits import BoxLimit, Constraint
from ..limits.collision_packed import ROW_PLACER
from ..limits.limit import PACKAGE_BOUND_KERNELS, PACKAGE_CONSTRAINT_KERNELS
from ..model import Kinematics
from ..tasks import Task
from ..tasks.task import PACKAGE_KERNELS
from ..types import CONSTRAINT_TOL, Solution
from .buffers import Scratch, restore
from .carry import CarriedRows
from .frames import Frames
from .inequalities import ConstraintRows, compiled_constraint, joint_box_arrays, placed_constraint


def numba_available() -> bool:
    """True if numba imports (the compiled path's only extra dependency)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def compiled(item: Task | BoxLimit) -> bool:
    """True if a task's rows (a row kernel) or a box limit's bounds (a bound kernel) have a
    compiled form."""
    if isinstance(item, BoxLimit):
        return type(item).bound_kernel is not None
    return type(item).row_kernel is not None


def box_limits(stack) -> list[BoxLimit]:
    """The box limits of a stack, in the order their boxes are folded
    (:func:`wbc.limits.box_bounds`): joint positions, joint velocities (if any), the others."""
    first = [stack.position_limit]
    if stack.velocity_limit is not None:
        first.append(stack.velocity_limit)
    return [*first, *stack.extra_limits]


def _ordered(own: Sequence, kernels) -> tuple:
    """The package's own kernels ``own`` (so the usual stacks share one compiled tick), then
    the other ones among ``kernels``, by module and name."""
    others = set(kernels) - set(own)
    key = lambda k: (k.py_func.__module__, k.py_func.__qualname__)  # noqa: E731
    return tuple(own) + tuple(sorted(others, key=key))


def kernel_set(tasks: Sequence[Task]) -> tuple:
    """The row kernels a tick of ``tasks`` dispatches over: the package's own, then those of
    other task types among ``tasks``."""
    return _ordered(PACKAGE_KERNELS, {type(t).row_kernel for t in tasks})


def bound_set(limits: Sequence[BoxLimit]) -> tuple:
    """The bound kernels a tick of ``limits`` dispatches over: the package's own, then those
    of other box limit types among ``limits``."""
    return _ordered(PACKAGE_BOUND_KERNELS, {type(b).bound_kernel for b in limits})


def constraint_set(constraints: Sequence[Constraint]) -> tuple:
    """The constraint kernels a tick of ``constraints`` dispatches over: the package's own,
    then those of other constraint types among ``constraints`` (with a kernel)."""
    kernels = {type(c).row_kernel for c in constraints if compiled_constraint(c)}
    return _ordered(PACKAGE_CONSTRAINT_KERNELS, kernels)


def kernel_inputs(items: Sequence[Task | BoxLimit | Constraint]) -> frozenset[str]:
    """The optional kernel inputs that the kernels of ``items`` declare."""
    return frozenset().union(*(type(i).kernel_inputs for i in items))


def package_ticks() -> D.Ticks:
    """The compiled tick of the package's own kernels (that of every package stack)."""
    # (the package's task and limit types are defined: this module imports them)
    return D.ticks(
        tuple(PACKAGE_KERNELS),
        tuple(PACKAGE_BOUND_KERNELS),
        False,
        True,
        tuple(PACKAGE_CONSTRAINT_KERNELS),
        ROW_PLACER,
    )


def start_package_ticks(announce: bool = True) -> bool:
    """Start compiling the package's control ticks in background processes unless numba is
    missing or they are cached or already being built (:meth:`wbc.compiled.dispatch.Ticks.
    start_build`); True if this call started them. A caller can do other work meanwhile
    (``wbc bench`` runs the baselines), then :func:`wait_for_package_ticks`."""
    return numba_available() and package_ticks().start_build(announce=announce)


def wait_for_package_ticks() -> None:
    """Wait for the package ticks' background build, if any (so that every tick after this
    solves on the compiled tick: a lockstep run is then repeatable across processes, and
    nothing compiles beside a timed run)."""
    if numba_available():
        package_ticks().wait_all()


#: the inequality rows' buffers hold this many times the rows of a plan's prepared tick
#: (:meth:`_Plan.reserve_rows`)
ROW_HEADROOM = 2


class Targets:
    """Every compiled task's targets, copied into one buffer at each tick from the tasks' own
    arrays (never re-bound: a handle on a task's target stays valid on every path)."""

    def __init__(self) -> None:
        self.sources: list[np.ndarray] = []
        self.size = 0
        self.buffer = np.zeros(0)
        self._gather = None
        self.by_address = False
        self.tick_sources: tuple[np.ndarray, ...] = ()

    def add(self, item: Task | BoxLimit) -> tuple[int, int]:
        """(offset, size) of the packed targets of a task (:attr:`~wbc.tasks.Task.target_fields`)
        or the parameters of a box limit (:attr:`~wbc.limits.BoxLimit.param_fields`)."""
        offset = self.size
        limit = isinstance(item, BoxLimit)
        for name in item.param_fields if isinstance(item, BoxLimit) else item.target_fields:
            view = getattr(item, name).reshape(-1)  # a view of the item's own array
            if not np.shares_memory(view, getattr(item, name)):
                what = (
                    f"box limit {item.name!r}: parameter"
                    if limit
                    else f"task {item.name!r}: target"
                )
                raise TaskError(f"{what} {name!r} must be contiguous")
            last = self.sources[-1] if self.size > offset else None
            if last is not None and _adjacent(last, view):  # one source (a cheaper gather)
                self.sources[-1] = np.lib.stride_tricks.as_strided(
                    last, shape=(last.size + view.size,), strides=(last.itemsize,)
                )
            else:
                self.sources.append(view)
            self.size += view.size
        return offset, self.size - offset

    def seal(self) -> None:
        self.buffer = np.zeros(self.size)
        self._bind()
        self.gather()

    def _bind(self) -> None:
        """The sources' addresses for the compiled gather (:attr:`sources` keeps them alive),
        if every source is a contiguous float64 vector (else np.concatenate)."""
        from ..compiled.checks import entry, gather

        direct = all(s.dtype == np.float64 and s.flags.c_contiguous for s in self.sources)
        self._gather = entry(gather) if direct else None
        self._addresses = np.array([s.ctypes.data for s in self.sources], dtype=np.int64)
        self._sizes = np.array([s.size for s in self.sources], dtype=np.int64)
        #: True: a tick gathers the sources itself (:attr:`tick_sources`: their addresses and
        #: sizes); False: none, :meth:`gather` runs before it
        self.by_address = direct
        self.tick_sources = (
            (self._addresses, self._sizes) if direct else (np.zeros(0, np.int64),) * 2
        )

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_gather"] = None  # (addresses are per object: a copy binds its own sources)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if self.buffer.size == self.size:  # (sealed)
            self._bind()

    def gather(self, q: np.ndarray | None = None, q_out: np.ndarray | None = None) -> np.ndarray:
        """The buffer, holding the tasks' current targets; and q copied into ``q_out`` (both
        float64 vectors), in the same compiled call (~0.6 µs less than np.concatenate and
        np.copyto)."""
        if self._gather is not None:
            if q is None or q_out is None:
                q = q_out = self.buffer[:0]
            self._gather(self._addresses, self._sizes, self.buffer, q, q_out)
            return self.buffer
        if self.sources:
            np.concatenate(self.sources, out=self.buffer)
        if q is not None and q_out is not None:
            np.copyto(q_out, q)
        return self.buffer


def _adjacent(a: np.ndarray, b: np.ndarray) -> bool:
    """True if the contiguous float vector b starts where a ends, in the same array (as the
    target position and rotation of a pose task: views of one packed array)."""

    def address(x: np.ndarray) -> int:
        return x.__array_interface__["data"][0]

    return (
        a.base is not None
        and a.base is b.base
        and a.dtype == b.dtype == np.float64
        and a.flags.c_contiguous
        and b.flags.c_contiguous
        and address(a) + a.nbytes == address(b)
    )


class Rows:
    """A fixed list of tasks as one block of rows: J (m x nv), raw errors E, right side b.

    ``weighted``: rows scaled by √w and b = α √w e (costs, and every level of the cascade);
    otherwise J and b = α e unscaled (the weighted QP's hard equalities). ``kinds`` maps each
    row kernel to its index in the generated tick; J and b are in ``scratch``'s blocks
    ``name``.J and ``name``.b.
    """

    def __init__(
        self,
        tasks: Sequence[Task],
        nv: int,
        frames: Frames,
        targets: Targets,
        kinds: dict,
        weighted: bool,
        scratch: Scratch,
        name: str,
    ) -> None:
        self.tasks = list(tasks)
        self.m = sum(t.rows for t in self.tasks)
        self.J = scratch.get(f"{name}.J", (self.m, nv))  # (filled at every tick)
        self.E = np.zeros(self.m)  # the tasks' last errors: the plan's own
        self.b = scratch.get(f"{name}.b", (self.m,))
        spec = np.zeros((len(self.tasks), D.SPEC_COLUMNS), dtype=np.int64)
        sel: list[np.ndarray] = []
        sqrt_w = np.ones(self.m)
        gain_w = np.zeros(self.m)
        self.slices: list[tuple[str, slice]] = []
        r = s = 0
        for i, t in enumerate(self.tasks):
            k = t.rows
            spec[i, D.KIND] = kinds[type(t).row_kernel]
            spec[i, D.TARGET], spec[i, D.TARGET_SIZE] = targets.add(t)
            spec[i, D.SLOT], spec[i, D.SLOTS] = frames.add(t)
            spec[i, D.ROW], spec[i, D.SEL], spec[i, D.ROWS] = r, s, k
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

    def error_views(self) -> list[tuple[Task, np.ndarray]]:
        return [(t, self.E[sl]) for t, (_, sl) in zip(self.tasks, self.slices, strict=True)]

    @property
    def args(self) -> tuple:
        return (self.spec, self.sel, self.sqrt_w, self.gain_w, self.J, self.E, self.b)


class _Plan:
    """What both compiled solvers share: targets, frames, bounds and the output buffer.

    Every argument of the kernel call is a buffer of the plan, filled in place before the
    call (the configuration, the targets, the velocity steps and the scalars), so that one
    prebuilt tuple serves every tick and a tick allocates nothing.
    """

    #: the active sets a tick starts from (cleared before every tick but the damped level's
    #: bounds: :meth:`forget_warm_start`; each plan's own array)
    warm_start: np.ndarray
    #: the index in :attr:`warm_start` of the level whose bounds' active set a tick keeps
    #: for the next (None: none kept; see :meth:`forget_warm_start`)
    damped_level: int | None = None
    #: the damped level's working rows carried to the next tick (None: none)
    carried: CarriedRows | None = None
    #: :meth:`forget_warm_start`'s compiled call and :attr:`warm_start` as rows (or None)
    _forget: Callable | None = None
    _sets: np.ndarray | None = None
    _gather_forget: Callable | None = None

    def __init__(
        self,
        solver,
        kin: Kinematics,
        tasks: Sequence[Task],
        constraints: Sequence[Sequence[Constraint]],
    ) -> None:
        robot = solver.robot
        self.solver = solver
        self.limits = limits = box_limits(solver.stack)
        flat = [c for lv in constraints for c in lv]
        compiled_constraints = [c for c in flat if compiled_constraint(c)]
        kernels, bounds = kernel_set(tasks), bound_set(limits)
        cons = constraint_set(flat)
        #: the optional kernel inputs that this plan's tasks, limits and constraints read
        self.inputs = inputs = kernel_inputs([*tasks, *limits, *compiled_constraints])
        package = (
            kernels == tuple(PACKAGE_KERNELS)
            and bounds == tuple(PACKAGE_BOUND_KERNELS)
            and cons == tuple(PACKAGE_CONSTRAINT_KERNELS)
            and not inputs
        )
        placed = placed_constraint(constraints, kin, package, solver)
        placer = ROW_PLACER if package else ()  # (the package's tick makes those rows itself)
        self.ticks = D.ticks(kernels, bounds, "frame_velocities" in inputs, package, cons, placer)
        self.kinds = {k: i for i, k in enumerate(kernels)}
        self.bound_kinds = {k: i for i, k in enumerate(bounds)}
        self.targets = Targets()
        self.scratch = scratch = solver.plan_scratch
        self.frames = Frames(robot, kin, [*tasks, *limits, *compiled_constraints], scratch)
        #: the limits whose parameters depend on the time step (:meth:`BoxLimit.prepare`)
        self._timed = [b for b in limits if type(b).prepare is not BoxLimit.prepare]
        self.variant = 0  # (one set of argument types for every stack)
        nv = robot.nv
        dim = max([6, *(t.dim for t in tasks)])
        self.Jf = scratch.get("Jf", (6, nv))
        self.efull = scratch.get("efull", (dim,))
        self.Jfull = scratch.get("Jfull", (dim, nv))
        self.Jw = kin.data.J  # views that follow every Kinematics.update
        self.com = kin.data.com[0]  # a live view while kin lives (kin.com is a copy)
        self.Jcom = kin.com_jacobian
        self.q_min, self.q_max = robot.q_min, robot.q_max
        self.q = scratch.get("q", (robot.nq,))
        self.v = np.zeros(nv)  # (the optional inputs: the plan's own, zeros unless read)
        self.hg = np.zeros(6)
        self.Ag = np.zeros((6, nv))
        self.bspec = np.zeros((len(limits), D.BOUND_COLUMNS), dtype=np.int64)
        self.boxes = np.zeros((len(limits), 2, nv))
        self._mu: float | None = None  # (the solver's regularization and hard tolerance
        self._hard_tol: float | None = None  # that the parameters were set for)
        self._dt: float | None = -1.0  # (no time step yet: the parameters are set at a solve)
        self._defer = False  # (the solver's defer_with_rows the parameters were set for)
        self._entry = None  # the tick's compiled entry point, after the first call
        #: [1 to defer the levels above with inequality rows too, 2 with the rows joining, 3
        #: and not after a degenerate answer (``defer_with_rows``, ``defer_rows_join``,
        #: ``skip_degenerate``), else 0, μ, hard tolerance,
        #: tolerance of the inequality rows, PDAS's ties (the solver's ``pdas_ties``), the
        #: share of the weakly held bounds released (its ``release_small``)]
        self.params = np.zeros(6)
        self.lower = scratch.get("lower", (nv,))  # (the tick's bounds: filled first)
        self.upper = scratch.get("upper", (nv,))
        self.dq = scratch.get("dq", (nv,))
        #: where the tick writes q ⊕ Δq (:attr:`own_q_next`, or an array bound by
        #: :func:`wbc.solvers.buffers.bind`; ``lent``: handed to a caller, not to be written)
        self.q_next = self.own_q_next = scratch.get("q_next", (robot.nq,))
        self.lent = False
        #: what a solved tick returns (the same arrays at every tick)
        self.solution = Solution(self.dq, self.lower, self.upper, self.q_next)
        #: (task, view of its rows of E): re-pointed at every solve, since anything may have
        #: re-pointed a task's last_error meanwhile (Task.compute, the numpy path, another plan)
        self.error_views: list[tuple[Task, np.ndarray]] = []
        #: the body's arguments (:data:`wbc.compiled.dispatch.WEIGHTED_ARGS`, ``CASCADE_ARGS``)
        self.args: tuple = ()
        #: the tick's arguments after q: those buffers' addresses and shapes, then the
        #: arguments passed directly (:meth:`_bind_args`)
        self.packed: tuple = ()
        self.tick_name = ""
        #: the arguments of the solve of a split tick (:meth:`_build_solve_args`)
        self.solve_args: tuple = ()
        self._solve_entry = None
        #: the constraints' rows, level by level (the kernel constraints' written by the tick)
        self.constraints = ConstraintRows(
            constraints,
            {k: i for i, k in enumerate(cons)},
            self.frames.slot,
            nv,
            joint_box_arrays(limits),
            placed,
        )
        self.inequalities = self.constraints.rows
        self._placed_args = self.constraints.placed_args(kin)
        self.is_ready = False  # (:meth:`ready`'s answer once True: a tick reads it first)

    def ready(self) -> bool:
        """True if the compiled tick runs at once; False while it is being compiled in the
        background (:meth:`wbc.compiled.dispatch.Ticks.ready`): solve on the numpy path."""
        if not self.is_ready:
            solve = (self._solve_kernel(), self.solve_args) if self.ticks.split else ()
            ready = self.ticks.ready(self.tick_name, (self.q, *self.packed), solve)
            if ready and self.ticks.split:  # and the solve (the package's, once compiled)
                ready = package_ticks().kernel_ready(self._solve_kernel(), self.tick_name)
            self.is_ready = ready
        return self.is_ready

    def forget_warm_start(
        self, keep_damped: bool = False, rows: ConstraintRows | None = None
    ) -> None:
        """Start the active sets of the bounds and of the inequality rows afresh (and gather
        ``rows``' parameters in the same compiled call: :meth:`ConstraintRows.gather`).

        ``keep_damped`` (before every tick: :meth:`solve`): all but the bounds' active set of
        the damped level (the weighted QP's one level, the hierarchy's last), which the next
        tick starts from. That level is strictly convex (μ‖Δq‖², μ > 0): its minimiser is
        unique, so where its solve starts changes only the rounding of the answer, never
        which optimum it is (the levels above, whose optima need not be unique, start afresh:
        their answer then depends on no earlier tick, issue 28). Started cold, a level whose
        reference outruns the servos (``walk_strict``'s third level in single support, ~6
        joints at their speed) took 12–17 subproblem solves, ~60–90 µs; from the last tick's
        active set 1–3 (benchmarks/self_collision.md). The inequality rows start afresh but
        for the damped level's found again by value (:mod:`wbc.solvers.carry`)."""
        forget, sets = self._forget, self._sets  # (warm_start as rows: the weighted's one)
        if forget is None:  # (its entry point, once: a tick makes one compiled call here)
            from ..compiled.entry import entry_point
            from ..compiled.prelude import forget_sets

            sets = self._sets = self.warm_start.reshape(-1, self.warm_start.shape[-1])
            args = (sets, sets.shape[0], self.inequalities.working)
            forget = self._forget = entry_point(forget_sets, args, True)
        if keep_damped and self.damped_level is not None and self.solver.regularization > 0.0:
            upto = self.damped_level
        else:
            upto = sets.shape[0]
        gathered = rows.gather_args() if rows is not None else None
        if gathered is None:
            forget(sets, upto, self.inequalities.working)  # (and every inequality row's flag)
        else:  # (one compiled call: its entry point bound at the first)
            args = (*gathered, sets, upto, self.inequalities.working)
            both = self._gather_forget
            if both is None:
                from ..compiled.entry import entry_point
                from ..compiled.prelude import gather_forget

                both = self._gather_forget = entry_point(gather_forget, args, True)
            both(*args)
        if not keep_damped and self.carried is not None:
            self.carried.count = 0

    def reserve_rows(self, factor: int = ROW_HEADROOM) -> None:
        """Room in the inequality rows' buffers for ``factor`` times the rows of the last tick
        (kept, and the tick's arguments re-bound), so that a tick whose constraints write more
        rows (self-collision pairs coming closer) does not re-allocate them and re-bind the
        arguments (~50 µs: the walk's first ticks and each phase's first visits)."""
        g = self.inequalities
        capacity = factor * g.total
        if capacity <= g.h.shape[0]:
            return
        kept = g.G, g.h, g.h_eff, g.working
        g._allocate(capacity)
        n = kept[1].shape[0]
        g.G[:n], g.h[:n], g.h_eff[:n], g.working[:, :n] = kept
        self._bind_args()

    def _add_limits(self) -> None:
        """The box limits' rows of :attr:`bspec`: kernel, parameters, frames (after the
        tasks', before the targets are sealed)."""
        for i, limit in enumerate(self.limits):
            row = self.bspec[i]
            row[0] = self.bound_kinds[type(limit).bound_kernel]
            row[1], row[2] = self.targets.add(limit)
            row[3], row[4] = self.frames.add(limit)

    def _shared_args(self) -> tuple:
        f = self.frames
        return (
            self.targets.buffer, f.slots, f.ids, f.R, f.p, f.Rs, f.ps, f.vs, f.support, self.Jw,
            self.com, self.Jcom, self.hg, self.Ag, self.v, self.Jf, self.efull, self.Jfull,
            self.q, self.q_min, self.q_max, self.bspec, self.boxes, self.params, self.lower,
            self.upper,
        )  # fmt: skip

    def _constraint_args(self) -> tuple:
        c = self.constraints
        return (c.cspec, c.cparams, c.cslots)

    def _build_args(self) -> tuple:
        """The body's arguments, every one a buffer of the plan (rebuilt when the inequality
        rows outgrow their buffers)."""
        raise NotImplementedError  # (each plan's own tick)

    def _build_solve_args(self) -> tuple:
        """The arguments of the solve of a split tick (:meth:`_solve_kernel`)."""
        raise NotImplementedError  # (each plan's own tick)

    def _bind_args(self) -> None:
        """:attr:`args`, and the tick's :attr:`packed` arguments: the addresses and shapes of
        the buffers among them (each checked: the tick views it as C-contiguous, of its
        dtype; :attr:`args` keeps them alive), then the arguments passed directly."""
        self.args = args = self._build_args()
        self.solve_args = self._build_solve_args()
        spec = D.TICK_ARGS[self.tick_name]
        addresses, shapes, direct = [], [], []
        for (name, dtype, ndim), a in zip(spec, args, strict=True):
            if dtype == "direct":
                direct.append(a)
                continue
            if a.dtype != np.dtype(dtype) or a.ndim != ndim or not a.flags.c_contiguous:
                raise TypeError(
                    f"tick argument {name!r} must be a C-contiguous {dtype} array of "
                    f"{ndim} dimensions, got {a.dtype} {a.shape} (C: {a.flags.c_contiguous})"
                )
            addresses.append(a.ctypes.data)
            shapes.append([*a.shape, *(0,) * (3 - ndim)])
        self.packed = (
            np.array(addresses, dtype=np.int64),
            np.array(shapes, dtype=np.int64).reshape(-1, 3),
            *direct,
        )

    def solve(self, kin: Kinematics, dt: float | None) -> int:
        """Fill the per-tick inputs (the constraints' rows: :class:`ConstraintRows`) and run
        the tick (which gathers the targets and q itself, and writes the kernel constraints'
        rows); returns its status (0: solved, Δq finite: :attr:`solution`)."""
        if self.lent:  # (its q ⊕ Δq handed out, no fresh array bound since: its own again)
            restore(self)
        for limit in self._timed:  # (before the rows: a box they are left out in reads them)
            limit.prepare(dt)
        rows = self.constraints if self.constraints.items else None
        if rows is not None and rows.tick(kin, gather=False):  # (gathered with the reset)
            self._bind_args()
        # every tick from no active set, as the numpy path solves: started from the last
        # tick's, the hierarchy's degenerate levels kept other (equally optimal) active sets,
        # and the answer depended on the ticks before, up to 2e-7 rad from the numpy path's
        # (issue 28); the warm start saved no measurable time on walk10 (benchmarks/stress.md)
        self.forget_warm_start(keep_damped=True, rows=rows)
        g, k = self.inequalities, self.damped_level or 0
        carried = self.carried  # (the damped level's rows at the last tick's end)
        if carried is not None:
            if carried.count and self.carries_rows():
                carried.carry(g.G, g.h, g.g_rows[k + 1], g.working[k])
            elif carried.source is not self and self.carries_rows("carry_at_switch"):
                carried.switch(self.warm_start, g.G, g.h, g.g_rows[k + 1], g.working[k])
        if self.inputs:
            self._optional_inputs(kin)
        for task, view in self.error_views:
            task.last_error = view
        if self.frames.copies:
            self.frames.refresh()
        if not self.targets.by_address:  # (sources the tick cannot gather itself)
            self.targets.gather()
        solver = self.solver
        defer = getattr(solver, "defer_with_rows", False)
        if (
            dt != self._dt
            or solver.regularization != self._mu
            or solver.hard_tol != self._hard_tol
            or defer != self._defer
        ):
            self._set_params(dt)
        entry = self._entry
        if entry is None:  # the first call: compiles or loads the tick, then its entry point
            np.copyto(self.q, kin.q)  # (typed on the plan's own q: kin.q may be read-only)
            status = self.ticks.call(self.tick_name, self.variant, (self.q, *self.packed))
            self._entry = self.ticks.entry(self.tick_name, self.variant)
            if self.ticks.split:  # (the rows of a set other than the package's: the solve)
                status = self._first_solve()
        elif self.ticks.split:
            entry(kin.q, *self.packed)
            status = self._solve_entry(*self.solve_args)
        else:
            status = entry(kin.q, *self.packed)
        if rows is not None and rows.in_tick:  # (the rows the tick made: their count)
            rows.took()
        if carried is not None:  # (warm_start[-1, 0]: the tick ended with a row active)
            if self.carries_rows() and self.warm_start.item(-1, 0):
                carried.keep(g.G, g.h, g.g_rows[k + 1], g.working[k])
            else:
                carried.count = 0
            carried.source = self
        return status

    def carries_rows(self, option: str = "carry_rows") -> bool:
        """Whether the damped level's working rows go to the next tick (the solver's ``option``
        and μ > 0; "carry_at_switch": to another layout's first tick only, CarriedRows.switch)."""
        solver = self.solver
        return self.carried is not None and bool(
            getattr(solver, option, False) and solver.regularization > 0.0
        )

    def _first_solve(self) -> int:
        """The first solve of a split tick (:attr:`wbc.compiled.dispatch.Ticks.split`):
        loads the solve kernel, then keeps its entry point."""
        from ..compiled.entry import entry_point

        kernel = self._solve_kernel()
        status = kernel(*self.solve_args)
        self._solve_entry = entry_point(kernel, self.solve_args)
        return status

    def _solve_kernel(self):
        """The solve a split tick calls after its rows (each plan's own)."""
        raise NotImplementedError

    def _optional_inputs(self, kin: Kinematics) -> None:
        """The optional inputs the plan's kernels read (:attr:`inputs`): v, and the centroidal
        momentum (the frames' velocities: the tick)."""
        np.copyto(self.v, velocity(kin))
        if "momentum" in self.inputs:
            momentum_into(kin, self.v, self.hg, self.Ag)

    def _set_params(self, dt: float | None) -> None:
        """The scalar parameters of the tick, for ``dt``."""
        solver = self.solver
        self._defer = bool(getattr(solver, "defer_with_rows", False))
        join = bool(getattr(solver, "defer_rows_join", False))
        skip = join and bool(getattr(solver, "skip_degenerate", False))
        self.params[:] = (
            (1.0 + join + skip) if self._defer else 0.0,
            solver.regularization,
            solver.hard_tol,
            CONSTRAINT_TOL,
            getattr(solver, "pdas_budget", 0),  # (the weighted QP: none)
            getattr(solver, "release_small", 0.0),
        )
        self._dt = dt
        self._mu, self._hard_tol = solver.regularization, solver.hard_tol


class WeightedPlan(_Plan):
    """The weighted QP's soft rows (weighted) and hard rows (equalities), compiled."""

    def __init__(
        self,
        solver,
        kin: Kinematics,
        soft: Sequence[Task],
        hard: Sequence[Task],
        constraints: Sequence[Constraint] = (),
    ):
        super().__init__(solver, kin, [*soft, *hard], [list(constraints)])
        nv = solver.robot.nv
        rows = (nv, self.frames, self.targets, self.kinds)
        self.soft = Rows(soft, *rows, weighted=True, scratch=self.scratch, name="soft")
        self.hard = Rows(hard, *rows, weighted=False, scratch=self.scratch, name="hard")
        self._add_limits()
        self.targets.seal()
        self.error_views = self.soft.error_views() + self.hard.error_views()
        self.state = self.scratch.get("state", (nv,), np.int8)
        self.state.fill(0)
        self.warm_start = self.state
        self.tick_name = "weighted_tick"
        self._bind_args()

    def _solve_kernel(self):
        from ..compiled.ticks import weighted_solve

        return weighted_solve

    def _build_solve_args(self) -> tuple:
        g = self.inequalities
        return (
            self.soft.J, self.soft.b, self.hard.J, self.hard.b, g.G, g.h, g.g_rows, self.q,
            self.q_min, self.q_max, self.params, self.lower, self.upper, self.state,
            g.working[0], self.dq, self.q_next,
        )  # fmt: skip

    def _build_args(self) -> tuple:
        g = self.inequalities
        return (
            *self.soft.args, *self.hard.args, g.G, g.h, g.g_rows, *self._constraint_args(),
            *self._shared_args(),
            self.state, g.working[0], self.dq, self.q_next, *self.targets.tick_sources,
            *self._placed_args,
        )  # fmt: skip


class CascadePlan(_Plan):
    """Every level's rows (weighted) in one block, solved level by level in one call."""

    #: the tick works in the solver's work space (:mod:`wbc.compiled.space`); False: none
    #: given, the solve allocates its arrays at every call (as before; the same answers)
    work_space = True

    def __init__(
        self,
        solver,
        kin: Kinematics,
        levels: Sequence[Sequence[Task]],
        hard,
        constraints: Sequence[Sequence[Constraint]] | None = None,
    ):
        tasks = [t for lv in levels for t in lv]
        if constraints is None:
            constraints = [[] for _ in levels]
        super().__init__(solver, kin, tasks, constraints)
        nv = solver.robot.nv
        self.rows = Rows(
            tasks, nv, self.frames, self.targets, self.kinds, True, self.scratch, "rows"
        )
        self._add_limits()
        self.targets.seal()
        bounds = np.cumsum([0] + [sum(t.rows for t in lv) for lv in levels])
        self.level_rows = bounds.astype(np.int64)
        self.level_hard = np.array(hard, dtype=np.bool_)
        self.error_views = self.rows.error_views()
        # (shared by the solver's plans; cleared before every tick: forget_warm_start, but
        # for the last level's and, after it, that level's without its inequality rows and
        # whether the last tick, in whichever layout, ended with a row active: cascade_solve)
        self.states = self.scratch.get("states", (len(levels) + 2, nv), np.int8)
        self.states.fill(0)
        self.warm_start = self.states
        self.damped_level = len(levels) - 1
        self.carried = self.scratch.shared("carried", lambda: CarriedRows(self.scratch, nv))
        if self.carries_rows("carry_at_switch"):
            self.carried.bind()  # (its kernels loaded now, not in a tick)
        self.achieved = np.zeros(self.rows.m)
        self.tick_name = "cascade_tick"
        self.space = (np.zeros(0), np.zeros(0, np.int64))  # (_bind_args: the solver's)
        self._bind_args()

    def _solve_kernel(self):
        from ..compiled.ticks import cascade_solve

        return cascade_solve

    def _build_solve_args(self) -> tuple:
        g = self.inequalities
        return (
            self.rows.J, self.rows.b, self.level_rows, self.level_hard, g.G, g.h, g.g_rows,
            self.q, self.q_min, self.q_max, self.params, self.lower, self.upper, self.states,
            g.working, g.h_eff, self.achieved, self.dq, self.q_next, *self.space,
        )  # fmt: skip

    def _build_args(self) -> tuple:
        from ..compiled.space import cascade_space_size

        # the work space (wbc.compiled.space) for the rows' capacity, in the solver's
        # scratch: its plans share it, at the same addresses at every tick
        g, nv = self.inequalities, self.dq.shape[0]
        f, i = cascade_space_size(self.level_rows, nv, g.h.shape[0]) if self.work_space else (0, 0)
        self.space = self.scratch.get("fspace", (f,)), self.scratch.get("ispace", (i,), np.int64)
        return (
            *self.rows.args, self.level_rows, self.level_hard, g.G, g.h, g.g_rows,
            *self._constraint_args(), *self._shared_args(), self.states, g.working, g.h_eff,
            self.achieved, self.dq, self.q_next, *self.space, *self.targets.tick_sources,
            *self._placed_args,
        )  # fmt: skip
