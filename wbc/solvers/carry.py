"""The damped last level's working rows carried from one compiled tick to the next.

The hierarchy's last level is damped (μ‖Δq‖², μ > 0): strictly convex, so where its active
set starts changes only the rounding of its one minimiser. Its inequality rows' working set
could not simply be kept, since a self-collision row's index names another pair from tick to
tick; so the rows it held at a tick's end are kept by value (G and h) and found again at the
next tick as the nearest rows (:func:`wbc.compiled.carried.carry_rows`). The last level then
starts from them and from the last tick's bounds' set instead of from its solve without rows
(:func:`wbc.compiled.ticks.cascade_solve`; if that fails, from its solve without rows as
without them): on ``walk_strict``'s slowest ticks (a row held in each single support) the
cascade took ~80 µs, ~33 from the carried rows; but where the rows carried leave (a streak's
end) it takes more than from its solve without rows, and on ``turn`` the cascade's p99 rose
3-6 %: off by default (``HierarchicalQP(carry_rows=True)``; benchmarks/self_collision.md,
twelfth pass).
"""

from __future__ import annotations

import numpy as np

#: a row kept at a tick's end is the next tick's nearest row within this, relative
#: (‖ΔG‖ + |Δh| <= CARRY_TOL (‖G‖ + |h|))
CARRY_TOL = 0.2


def _entry(name: str, args: tuple):
    """The entry point of the compiled kernel ``name`` of :mod:`wbc.compiled.carried` for the
    types of ``args``, called once on them (loaded, or compiled, here: not in a tick; numba's
    dispatcher resolves the types at every call, ~2 µs)."""
    from ..compiled import carried
    from ..compiled.entry import entry_point

    kernel = getattr(carried, name)
    kernel(*args)
    return entry_point(kernel, args)


class CarriedRows:
    """The last level's working rows at the end of the last tick, kept in ``scratch`` (the
    solver's plans share them, as the bounds' states: the first tick of a phase starts from
    the last tick of the phase before)."""

    def __init__(self, scratch, nv: int) -> None:
        self.G = scratch.get("carried_G", (nv, nv))
        self.h = scratch.get("carried_h", (nv,))
        #: how many rows are kept (0: none)
        self.count = 0
        self._carry = self._keep = None
        #: the plan whose tick ran last (:meth:`switch`: its buffers hold that tick's rows)
        self.source = None

    def bind(self) -> None:
        """The kernels' entry points loaded now (once per solver), not at a tick."""
        if self._keep is None:
            self._bind()

    def _bind(self) -> None:
        """The kernels' entry points, for the argument types of a tick (at the first rows
        kept: loaded, or compiled, once per solver)."""
        G, h, working = np.zeros((1, self.G.shape[1])), np.zeros(1), np.zeros(1, np.bool_)
        p = np.int64(0)
        self._carry = _entry("carry_rows", (self.G, self.h, 0, G, h, p, working, CARRY_TOL))
        self._keep = _entry("keep_rows", (G, h, p, working, self.G, self.h))

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_carry": None, "_keep": None}  # (entry points: not pickled)

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update({"source": None, **state})

    def carry(self, G: np.ndarray, h: np.ndarray, p: int, working: np.ndarray) -> None:
        """The kept rows marked in ``working`` (the last level's, of this tick's rows G[:p],
        h[:p]), each as its nearest row by value."""
        if self.count and p and self._carry is not None:
            self._carry(self.G, self.h, self.count, G, h, p, working, CARRY_TOL)

    def keep(self, G: np.ndarray, h: np.ndarray, p: int, working: np.ndarray) -> None:
        """The rows of G[:p], h[:p] in ``working`` kept for the next tick."""
        if self._keep is None:
            self._bind()
        self.count = int(self._keep(G, h, p, working, self.G, self.h))  # type: ignore[misc]

    def switch(
        self, states: np.ndarray, G: np.ndarray, h: np.ndarray, p: int, working: np.ndarray
    ) -> None:
        """At the first tick of another plan (a support switch): if the last tick ended with
        a row active in its damped level (``states[-1, 0]``, the solver's shared states), the
        rows of that level's working set at its end — still in the last plan's buffers,
        untouched since — kept and marked in ``working`` (this plan's rows G[:p], h[:p]) as
        the nearest rows by value. That level is strictly convex: where it starts changes the
        rounding of its one minimiser, not which it is; a start that fails falls back to its
        solve without rows (:func:`wbc.compiled.ticks.cascade_solve`)."""
        source = self.source
        self.count = 0
        if source is None or not p or not states.item(-1, 0):
            return
        g, k = source.inequalities, source.damped_level or 0
        if self._keep is None:
            self._bind()
        self.count = int(self._keep(g.G, g.h, g.g_rows[k + 1], g.working[k], self.G, self.h))  # type: ignore[misc]
        self.carry(G, h, p, working)
        self.count = 0
