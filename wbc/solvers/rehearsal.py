"""A support phase's first tick rehearsed in a loop's idle part, then forgotten.

Back to back, the first tick of a support phase ran its compiled call about twice as long as
the others (walk10, ``walk``: 54–74 µs against 34), although replayed at once the same call
took what the others take (30–33 µs): the work is the same, the memory and code of the
layout switched to were cold (the switch made ahead, :meth:`StackController.prepare_phase
<wbc.walking.controller.StackController.prepare_phase>`, runs ~100 µs of Python right before the
tick). :func:`rehearse` runs the new layout's tick once at the last tick's kinematics in the
idle part and puts back what that tick writes and a later one reads (the active sets' warm
start, the solution the solver hands out, the constraint whose rows it makes: its buffers and
where its last rows are, the tasks' error views, the carried rows' count; not the rows, the
work space, the rest of its arguments, written before they are read: copying those, ~2 MB
with the rows' headroom, evicted what the rehearsal brought in), so the next tick computes
exactly what it would have without the rehearsal — bit for bit, its active sets started as
before — with its layout's memory and code in the caches (issue 34's tail;
benchmarks/self_collision.md, twentieth session).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..exceptions import WbcError
from ..model import Kinematics


def _state(plan: Any) -> list[np.ndarray]:
    """The arrays of ``plan``'s tick that outlive it: its active sets' warm start (shared by
    the solver's plans) and the solution the solver hands out (Δq, its bounds, q ⊕ Δq), and
    q. Every other array of its arguments is written by a tick before it reads it (the rows,
    the targets, the frames, the work space), or is the plan's own layout."""
    return [plan.warm_start, plan.dq, plan.lower, plan.upper, plan.q_next, plan.q]


def rehearse(plan: Any, kin: Kinematics, dt: float) -> bool:
    """Run ``plan``'s tick once at ``kin`` (the last tick's kinematics) with time step ``dt``,
    and put back what it wrote (:mod:`this module <wbc.solvers.rehearsal>`). Nothing (False)
    where a rehearsal could leave a trace: the plan not compiled yet, its output array lent to
    a caller, rows from Python before the tick (their constraints' own state), rows carried
    from tick to tick. True if it ran."""
    rows = plan.constraints
    if (
        plan._entry is None
        or plan.lent
        or plan.q_next is not plan.own_q_next
        or (rows.items and not rows.static)
        or plan.carries_rows()
        or plan.carries_rows("carry_at_switch")
    ):
        return False
    arrays = _state(plan)
    kept = [a.copy() for a in arrays]
    placed = rows.placed if rows.in_tick else None
    put_back = placed.snapshot() if placed is not None else None
    errors = [(task, task.last_error) for task, _ in plan.error_views]
    carried = plan.carried
    carry = (carried.count, carried.source) if carried is not None else None
    try:
        plan.solve(kin, dt)
    except WbcError:
        pass  # (the tick itself says so)
    finally:
        for a, b in zip(arrays, kept, strict=True):
            np.copyto(a, b)
        if put_back is not None:
            put_back()
        for task, e in errors:
            task.last_error = e
        if carried is not None and carry is not None:
            carried.count, carried.source = carry
    return True
