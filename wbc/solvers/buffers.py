"""The compiled plans' buffers: those the plans of one solver share (:class:`Scratch`), and
the tick's q ⊕ Δq written straight into the array that :meth:`StackSolver.step
<wbc.solvers.base.StackSolver.step>` returns: allocated in a loop's idle part
(:meth:`~wbc.solvers.base.StackSolver.prepare_output`), so that the tick makes no copy (a
numpy allocation is ~10 µs of a tick in a 50 Hz loop, its code cold; issue 34).

The plan's tick writes q ⊕ Δq where its argument table says (:attr:`_Plan.packed
<wbc.solvers.plan._Plan.packed>`: addresses); :func:`bind` points it at another array. An
array handed to the caller is *lent*: the plan's next solve points its tick back at its own
array first (:meth:`~wbc.solvers.plan._Plan.solve`), unless the idle part bound a fresh one.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from ..compiled import dispatch as D

T = TypeVar("T")


class Scratch:
    """Arrays that the plans of one solver share: whatever a tick writes before it reads it
    (the rows J and b, the kernels' work rows, the frames' copies, q, the bounds, Δq, q ⊕ Δq).
    The first tick after a support switch then works in memory the last tick used, instead of
    in the buffers of a layout last used a support phase ago (evicted from the caches: that
    tick was ~10 µs slower)."""

    def __init__(self) -> None:
        self._blocks: dict[str, np.ndarray] = {}
        self._objects: dict[str, object] = {}

    def shared(self, name: str, build: Callable[[], T]) -> T:
        """The object ``name`` that the plans share (built by ``build`` for the first)."""
        if name not in self._objects:
            self._objects[name] = build()
        return self._objects[name]  # type: ignore[return-value]

    def get(self, name: str, shape: tuple[int, ...], dtype: type = np.float64) -> np.ndarray:
        """A C-contiguous array of ``shape`` and ``dtype`` in the block ``name`` (grown as
        needed; a plan keeps the block it was given)."""
        size = int(np.prod(shape))
        block = self._blocks.get(name)
        if block is None or block.size < size or block.dtype != dtype:
            block = self._blocks[name] = np.zeros(size, dtype)
        return block[:size].reshape(shape)


def _slot(plan: Any) -> int:
    """The row of ``q_next`` in ``plan``'s table of argument addresses."""
    spec = D.WEIGHTED_ARGS if plan.tick_name == "weighted_tick" else D.CASCADE_ARGS
    return [name for name, dtype, _ in spec if dtype != "direct"].index("q_next")


def bind(plan: Any, out: np.ndarray) -> None:
    """``plan``'s tick writes q ⊕ Δq into ``out`` (nq float64, C-contiguous: kept alive by the
    plan) from its next call on, and its :attr:`solution` names it; not lent."""
    if out.dtype != np.float64 or out.shape != plan.q_next.shape or not out.flags.c_contiguous:
        raise TypeError(f"q ⊕ Δq needs a C-contiguous float64 array of {plan.q_next.shape}")
    old = plan.q_next
    if plan.packed:  # (bound: the tick's table; else the first tick binds it)
        plan.packed[0][_slot(plan)] = out.ctypes.data
        plan.args = tuple(out if a is old else a for a in plan.args)
        plan.solve_args = tuple(out if a is old else a for a in plan.solve_args)
    plan.q_next = out
    plan.solution = plan.solution._replace(q_next=out)
    plan.lent = False


def restore(plan: Any) -> None:
    """``plan``'s tick back on its own array (the one it was built with): its last one was
    handed to a caller and no fresh one was bound since."""
    bind(plan, plan.own_q_next)
