"""The constraints of a compiled plan: their rows G Δq <= h, level by level, in the buffers
the tick reads.

A constraint with a constraint kernel (:attr:`wbc.limits.Constraint.row_kernel`) is a row of
the spec table ``cspec`` (:data:`wbc.compiled.dispatch.CONSTRAINT_COLUMNS`: its kernel, its
parameters in ``cparams``, its frame slots in ``cslots``, its first row and row count): the
tick calls its kernel, which writes its rows into ``G[r0:r0+m]``, ``h[r0:r0+m]``. The others
compute their rows in Python: written there in place by a constraint with ``rows_into`` (the
self-collision pairs, with room reserved for their most rows), else copied (a
:class:`~wbc.limits.LinearInequality`). Every constraint's rows keep their place: level by
level, in the level's order, as :func:`wbc.solvers.assembly.stack_constraints` stacks them.

Per tick, in Python: each kernel constraint's :meth:`~wbc.limits.Constraint.prepare` (where
its class has one), then a check of its row count, frames and parameter arrays against the
layout (a support polygon rebuilt, a swing sole switched: the layout is redone, the tick's
arguments re-bound) — one identity test where its class keeps a
:attr:`~wbc.limits.Constraint.layout_token` — the other constraints' rows, the parameters
gathered.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..compiled import dispatch as D
from ..compiled.signature import sources
from ..exceptions import ConfigurationError
from ..limits import BoxLimit, Constraint
from ..limits.collision_packed import (
    P_COUNT,
    P_FIRST,
    P_LEVEL,
    P_LEVELS,
    P_MADE,
    P_ROW,
    ROW_PLACER,
)
from ..limits.joint_limits import position_bounds, velocity_bounds
from ..model import Kinematics


def _token(c: Constraint) -> object | None:
    """``c``'s :attr:`~wbc.limits.Constraint.layout_token` if its own class keeps it (not
    inherited: a subclass may lay out its rows otherwise), else None."""
    return c.layout_token if type(c).__dict__.get("keeps_layout_token", False) else None


def joint_box_arrays(
    limits: Sequence[BoxLimit],
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The arrays the box of ``limits`` is made of (q_min, q_max, steps) if they are the joint
    position limit then the joint velocity limit, as their bound kernels say
    (:func:`~wbc.limits.collision_packed.joint_box` makes that box the compiled tick's way);
    else None."""
    kinds = [type(b).bound_kernel for b in limits]
    if kinds != [position_bounds, velocity_bounds]:
        return None
    arrays = (limits[0].q_min, limits[0].q_max, limits[1].steps)  # type: ignore[attr-defined]
    for a in arrays:  # (read in place at each tick: the limits' own arrays, never copies)
        if not (isinstance(a, np.ndarray) and a.dtype == np.float64 and a.ndim == 1):
            return None
        if not a.flags.c_contiguous:
            return None
    return arrays


def placed_constraint(
    levels: Sequence[Sequence[Constraint]], kin: Kinematics, package: bool, solver: object
) -> Constraint | None:
    """The constraint whose rows a compiled tick makes itself (``rows_in_tick``: its
    ``row_placer``, the package's :data:`~wbc.limits.collision_packed.ROW_PLACER`, called
    first in the tick), if there is one and only one, the tick is the package's (one fused
    call), reads the frames' views (not copies) and the ``solver`` carries no rows to the
    next tick; else None."""
    carry = getattr(solver, "carry_rows", False) or getattr(solver, "carry_at_switch", False)
    if not package or carry or kin.frame_placements() is None:
        return None
    found = [c for lv in levels for c in lv if getattr(c, "rows_in_tick", False)]
    if len(found) != 1 or getattr(type(found[0]), "row_placer", None) != ROW_PLACER:
        return None
    return found[0]


def compiled_constraint(c: Constraint) -> bool:
    """True if a constraint's rows have a compiled form (a constraint kernel)."""
    return type(c).row_kernel is not None


class InequalityRows:
    """The inequality rows G Δq <= h of a tick, level by level, in buffers that the tick reads
    (written there by the constraint kernels, or copied from Python: :class:`ConstraintRows`;
    ``g_rows``: each level's first row, then the end), with each level's working set (its warm
    start, forgotten when the levels' row counts change)."""

    def __init__(self, n_levels: int, nv: int, capacity: int = 8) -> None:
        self.n_levels, self.nv = n_levels, nv
        self.g_rows = np.zeros(n_levels + 1, dtype=np.int64)
        self.counts = (0,) * n_levels
        self.total = 0  # rows at the last tick
        self._allocate(capacity)

    def _allocate(self, capacity: int) -> None:
        self.G = np.zeros((capacity, self.nv))
        self.h = np.zeros(capacity)
        self.h_eff = np.zeros(capacity)
        self.working = np.zeros((self.n_levels, capacity), dtype=np.bool_)

    def reserve(self, rows: int) -> bool:
        """Room for ``rows`` rows (the rows so far kept: a constraint writes its rows in
        place, :meth:`ConstraintRows.tick`); True if the buffers were re-allocated."""
        if rows <= self.h.shape[0]:
            return False
        kept = self.G, self.h, self.h_eff, self.working
        self._allocate(max(rows, 2 * self.h.shape[0]))
        n = kept[1].shape[0]
        self.G[:n], self.h[:n], self.h_eff[:n], self.working[:, :n] = kept
        return True

    def layout(self, counts: tuple[int, ...]) -> bool:
        """Each level's row count ``counts``; True if the buffers were re-allocated (the
        caller's argument tuple is stale; the rows written so far kept)."""
        grown = False
        if counts != self.counts:
            total = 0
            g_rows = self.g_rows
            for k, m in enumerate(counts):
                total += m
                g_rows[k + 1] = total
            if total > self.h.shape[0]:
                self.reserve(total)
                grown = True
            # (the working sets: every tick's plan starts them afresh after its rows,
            # :meth:`wbc.solvers.plan._Plan.forget_warm_start`)
            self.counts = counts
            self.total = total
        return grown


def _into(c: Constraint) -> tuple | None:
    """What writes ``c``'s rows straight into a plan's buffers (its ``rows_into``, the room it
    needs: ``max_rows``, and whether it takes the tick's box: ``rows_in_box``), or None."""
    into = getattr(c, "rows_into", None)
    if into is None:
        return None
    return into, int(c.max_rows), bool(getattr(c, "rows_in_box", False))


class ConstraintRows:
    """The constraints of a plan's levels (``levels``: each level's active constraints) and
    their rows (:attr:`rows`); ``kinds`` maps each constraint kernel to its index in the
    generated tick, ``slot`` each frame of the plan to its slot."""

    def __init__(
        self,
        levels: Sequence[Sequence[Constraint]],
        kinds: dict,
        slot: dict[int, int],
        nv: int,
        box: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
        placed: Constraint | None = None,
    ) -> None:
        self.levels = [list(lv) for lv in levels]
        #: the tick's box of Δq as its limits' arrays (q_min, q_max, steps: a stack whose box
        #: limits are the joint position then the joint velocity limit), passed to the
        #: constraints that leave out the rows that cannot bind in it (``rows_in_box``); None:
        #: every row
        self.box = box
        self.items = [c for lv in self.levels for c in lv]
        self.kinds, self.slot = kinds, slot
        self.rows = InequalityRows(len(self.levels), nv)
        self.kernel_items = [c for c in self.items if compiled_constraint(c)]
        #: those with a :meth:`~wbc.limits.Constraint.prepare` of their own (the default's
        #: does nothing: not called)
        self._prepared = [
            c
            for c in self.kernel_items
            if type(c).prepare is not Constraint.prepare or "prepare" in c.__dict__
        ]
        #: whether each keeps a layout token (:func:`_token`)
        self._tokened = [_token(c) is not None for c in self.kernel_items]
        index = {id(c): j for j, c in enumerate(self.kernel_items)}
        #: each level's constraints, with their row of :attr:`cspec` (-1: rows from Python),
        #: what gives their rows from Python (``rows_view``: views copied at once) and what
        #: writes them in place (``rows_into``, with the room it needs; None: copied)
        self.order = [
            [(c, index.get(id(c), -1), getattr(c, "rows_view", c.compute), _into(c)) for c in lv]
            for lv in self.levels
        ]
        n = len(self.kernel_items)
        self.cspec = np.zeros((n, D.CONSTRAINT_COLUMNS), dtype=np.int64)
        self.cparams = np.zeros(0)
        self.cslots = np.zeros(0, dtype=np.int64)
        #: each kernel constraint's layout: (rows, frame ids, parameter arrays as read, as
        #: gathered, its layout token or None); None: not laid out yet
        self._layout: list[tuple | None] = [None] * n
        #: kernel constraints whose frames the plan lacks: their rows come from Python
        self._python = [False] * n
        self._row_at = [0] * n  # (:attr:`cspec`'s C_ROW column as written, as ints)
        self._gather = None
        self._addresses = np.zeros(0, dtype=np.int64)
        self._sizes = np.zeros(0, dtype=np.int64)
        self._empty = np.zeros(0)
        #: each constraint's row count at the last tick (in :attr:`items` order)
        self.counts = [0] * len(self.items)
        #: the constraint whose rows the tick makes (:func:`placed_constraint`; None: every
        #: row before the tick), its placement for the tick (``place``:
        #: :data:`~wbc.limits.collision_packed.P_ROW`..., written at a layout: :meth:`_place`),
        #: where its rows go (G, h, first row) and whether this layout has the tick make them
        self.placed = placed
        self.place = np.full(P_FIRST + len(self.levels) + 2 + 2 * n, -1, dtype=np.int64)
        self._where: tuple | None = None
        self.in_tick = False
        #: True if every row is made in the tick (the kernel constraints', and the placed
        #: constraint's if :attr:`in_tick`): laid out by :meth:`_place` at a change only;
        #: False: some rows come from Python, laid out at every tick (:meth:`tick`)
        self.static = False
        #: the layout without the placed rows: each level's count, the total, the placed
        #: constraint's level and index in :attr:`items`
        self._base: tuple = ((), 0, 0, 0)

    def _changed(self) -> bool:
        for c, lay, tokened in zip(self.kernel_items, self._layout, self._tokened, strict=True):
            if lay is None:
                return True
            if tokened and c.layout_token is lay[4]:  # (the same rows, frames and arrays)
                continue
            if c.rows != lay[0] or c.frame_ids() != lay[1]:
                return True
            for name, a in zip(type(c).param_fields, lay[2], strict=True):
                if getattr(c, name) is not a:
                    return True
        return False

    def _relayout(self) -> None:
        """The kernel constraints' rows of :attr:`cspec`, their parameters and frame slots
        (new arrays: the caller re-binds the tick's arguments)."""
        from ..compiled.checks import entry, gather

        slots: list[int] = []
        arrays: list[np.ndarray] = []
        offset = 0
        for j, c in enumerate(self.kernel_items):
            fields = type(c).param_fields
            fids = c.frame_ids()
            raw = [getattr(c, name) for name in fields]
            srcs = sources(c, fields)
            m = c.rows
            self._layout[j] = (m, fids, raw, srcs, _token(c))
            inplan = all(f in self.slot for f in fids)
            self._python[j] = not inplan
            size = sum(int(a.size) for a in srcs)
            row = self.cspec[j]
            row[D.C_KIND] = self.kinds[type(c).row_kernel]
            row[D.C_PARAM], row[D.C_PARAM_SIZE] = offset, size
            row[D.C_SLOT], row[D.C_SLOTS] = len(slots), len(fids) if inplan else 0
            row[D.C_ROWS] = m if inplan else 0
            if inplan:
                slots.extend(self.slot[f] for f in fids)
            arrays.extend(srcs)
            offset += size
        self.cparams = np.zeros(offset)
        self.cslots = np.array(slots, dtype=np.int64)
        self._addresses = np.array([a.ctypes.data for a in arrays], dtype=np.int64)
        self._sizes = np.array([a.size for a in arrays], dtype=np.int64)
        self._gather = entry(gather)

    def tick(self, kin: Kinematics, gather: bool = True) -> bool:
        """The rows at ``kin``: the kernel constraints prepared and laid out (the tick writes
        their rows), the others' rows copied, their parameters gathered (:meth:`gather`; not
        with ``gather`` False: the caller's, :meth:`wbc.solvers.plan._Plan.forget_warm_start`);
        True if the tick's arguments must be re-bound (new arrays)."""
        kernel_items = self.kernel_items
        for c in self._prepared:
            c.prepare(kin)
        rebind = False
        if kernel_items and self._changed():
            self._relayout()
            rebind = True
        where = self._where
        if rebind or where is None or where[0] is not self.rows.G:
            rebind = self._place() or rebind
        if self.static:  # (every row made in the tick: laid out at a change only)
            if self.in_tick:
                self.placed.placing(self._where)  # type: ignore[union-attr]
            if gather and self._gather is not None:
                self.gather()
            return rebind
        cspec, python, layout, counts = self.cspec, self._python, self._layout, self.counts
        row_at = self._row_at
        g = self.rows
        copies = []
        level_counts = []
        r = i = 0
        for level in self.order:
            start = r
            for _, j, rows, into in level:
                if j >= 0 and not python[j]:
                    m = layout[j][0]
                    if row_at[j] != r:  # (a numpy write only for a change: cold in a tick)
                        cspec[j, D.C_ROW] = row_at[j] = r
                elif into is not None:  # (written in place: room for its most rows first)
                    if r + into[1] > g.h.shape[0] and g.reserve(r + into[1]):
                        rebind = True
                    if into[2]:
                        m = into[0](kin, g.G, g.h, r, self.box)
                    else:
                        m = into[0](kin, g.G, g.h, r)
                else:
                    G, h = rows(kin)
                    m = h.shape[0]
                    if m:
                        copies.append((r, m, G, h))
                counts[i] = m
                r += m
                i += 1
            level_counts.append(r - start)
        counts_now = tuple(level_counts)
        if counts_now != g.counts and g.layout(counts_now):  # (a call only for a change)
            rebind = True
        G_all, h_all = g.G, g.h
        for r0, m, G, h in copies:
            G_all[r0 : r0 + m] = G
            h_all[r0 : r0 + m] = h
        if gather and self._gather is not None:
            self.gather()
        return rebind

    def _place(self) -> bool:
        """The layout of a tick that makes every row (:attr:`static`): the kernel constraints'
        first rows and the levels' bounds where they go without :attr:`placed`'s rows, room
        for its most rows after them, and :attr:`place`, for the tick to move the rows after
        them by their count (:func:`~wbc.limits.collision_packed.placed_rows`; no placed
        constraint: ``place[P_ROW]`` −1, the tick's placer returns at once). Not static
        (``place[P_ROW]`` −1, every row laid out at each :meth:`tick`) where a constraint's
        rows come from Python. True if the buffers were re-allocated."""
        placed, g, python, layout = self.placed, self.rows, self._python, self._layout
        place, row_at = self.place, self._row_at
        row0 = level0 = index = -1
        after: list[int] = []
        levels: list[int] = []
        r = i = 0
        for k, level in enumerate(self.order):
            start = r
            for c, j, _, _ in level:
                if c is placed:
                    row0, level0, index = r, k, i
                elif j < 0 or python[j]:  # (rows from Python: laid out before the tick)
                    return self._not_in_tick()
                else:
                    if row0 >= 0:
                        after.extend((j, r))
                    self.cspec[j, D.C_ROW] = row_at[j] = r
                    self.counts[i] = layout[j][0]
                    r += layout[j][0]
                i += 1
            levels.append(r - start)
        grown = g.reserve(r + (placed.max_rows if row0 >= 0 else 0))  # type: ignore[union-attr]
        n = len(levels)
        first = np.cumsum([0, *levels])
        place[:] = -1
        place[P_ROW], place[P_COUNT], place[P_MADE] = row0, 0, 0
        place[P_LEVEL], place[P_LEVELS] = level0, n
        place[P_FIRST : P_FIRST + n + 1] = first
        place[P_FIRST + n + 1] = len(after) // 2
        place[P_FIRST + n + 2 : P_FIRST + n + 2 + len(after)] = after
        g.g_rows[:] = first
        g.counts, g.total = tuple(levels), r
        if index >= 0:
            self.counts[index] = 0
        self._base = (tuple(levels), r, level0, index)
        self._where = (g.G, g.h, row0)
        self.in_tick = row0 >= 0
        self.static = True
        return grown

    def _not_in_tick(self) -> bool:
        """:meth:`_place` for a layout with rows from Python: every row laid out at each
        :meth:`tick`, made before the tick (``place[P_ROW]`` −1); False."""
        self.in_tick = self.static = False
        self.place[P_ROW] = -1
        self._where = (self.rows.G, self.rows.h, -1)
        self._row_at[:] = [-1] * len(self._row_at)  # (cspec's rows: written again)
        return False

    def took(self) -> None:
        """After a tick that made :attr:`placed`'s rows: their count where Python reads it
        (:attr:`counts`, the rows' levels, the constraint's own)."""
        place = self.place
        m = place.item(P_COUNT)
        if m < 0:
            raise ConfigurationError(f"{self.placed.name}: no room for its rows in the tick")
        self.placed.placed(self._where, m, place.item(P_MADE) != 0)  # type: ignore[union-attr]
        levels, total, level0, index = self._base
        if m != self.counts[index]:
            self.counts[index] = m
            counts = list(levels)
            counts[level0] += m
            self.rows.counts, self.rows.total = tuple(counts), total + m

    def placed_args(self, kin: Kinematics) -> tuple:
        """The fused tick's last arguments (:data:`~wbc.compiled.template.PLACED_ARGS`):
        :attr:`placed`'s buffers by address and :attr:`place` — without a placed constraint,
        none and ``place[P_ROW]`` −1 (the tick's placer returns at once). ConfigurationError:
        the placed constraint's frames are copies."""
        if self.placed is None:
            return (np.zeros(0, np.int64), np.zeros((0, 3), np.int64), self.place)
        args = self.placed.placed_args(kin)  # type: ignore[attr-defined]
        if args is None:
            raise ConfigurationError("no constraint whose rows a tick makes with the frames' views")
        return (*args, self.place)

    def gather(self) -> None:
        """The kernel constraints' parameters into :attr:`cparams` (one compiled call)."""
        if self._gather is not None:
            e = self._empty
            self._gather(self._addresses, self._sizes, self.cparams, e, e)

    def gather_args(self) -> tuple | None:
        """:meth:`gather`'s arrays (addresses, sizes, :attr:`cparams`; None: nothing to
        gather), for a compiled call that gathers them with its own work."""
        if self._gather is None:
            return None
        return self._addresses, self._sizes, self.cparams

    def level_blocks(self) -> list[tuple[np.ndarray, np.ndarray, list[tuple[str, slice]]]]:
        """Each level's (G, h, row slices) of the last tick: views of :attr:`rows` (refilled
        at the next tick), as :func:`~wbc.solvers.assembly.stack_constraints` gives them."""
        g = self.rows
        out = []
        i = 0
        for k, level in enumerate(self.levels):
            g0, g1 = int(g.g_rows[k]), int(g.g_rows[k + 1])
            slices = []
            r = 0
            for c in level:
                m = self.counts[i]
                slices.append((c.name, slice(r, r + m)))
                r += m
                i += 1
            out.append((g.G[g0:g1], g.h[g0:g1], slices))
        return out
