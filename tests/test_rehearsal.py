"""A support phase's first tick rehearsed in the loop's idle part and forgotten
(:mod:`wbc.solvers.rehearsal`): the walk's answers bit for bit those without the rehearsal,
and every buffer the rehearsed tick wrote put back; the same for every tick's rehearsal at the
idle part's end (:meth:`StackSolver.warm`, ``warm_ahead``)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from wbc.bench.trajectories import build
from wbc.limits import SelfCollisionConstraint
from wbc.solvers import rehearsal
from wbc.stacks import load_stack
from wbc.walking.handover import SwitchHandover
from wbc.walking.loop import Session, StackController

TICKS = 150  # (walk10: a support switch every 20-40 ticks, rows active around 104)


def _walk(robot, name: str, solver: str, rehearse: bool, warm: bool = False):
    """``name`` along walk10's first :data:`TICKS` ticks, the idle part after each (the next
    support switch made ahead; with ``warm`` the tick then rehearsed, as at the idle part's
    end): each tick's q and Δq, the self-collision limit's smallest distance and row count;
    and how many rehearsals ran (the switches' and the warm-ups')."""
    stack = load_stack(name, robot, solver=solver)
    controller = StackController(stack)
    qp = controller.solver
    qp.rehearse_switch = rehearse
    qp.warm_ahead = warm
    limit = next(c for c in qp.stack.constraints() if isinstance(c, SelfCollisionConstraint))
    ran = []
    own, own_warm = qp.rehearse, qp.warm
    qp.rehearse = lambda dt: ran.append(own(dt)) or ran[-1]
    qp.warm = lambda dt: ran.append(own_warm(dt)) or ran[-1]
    session = Session(controller, robot, build("walk10", robot))
    out = []
    for i in range(TICKS):
        q = session.tick(i)
        assert not session.failed
        out.append((q.copy(), qp.fast.dq.copy(), limit._closest[0], limit._n_rows))
        session.prepare_next()
        session.warm_next()
    assert qp.handed_back_ticks == 0
    return out, sum(ran)


@pytest.mark.parametrize("name, solver", [("walk_strict", "hierarchical"), ("walk", "weighted")])
def test_rehearsed_switches_walk_as_without(robot, name, solver):
    """walk10 with each support phase's first tick rehearsed: every tick's q, Δq, the limit's
    closest pair and row count bit for bit as without; rehearsals ran (else vacuous)."""
    without, none = _walk(robot, name, solver, False)
    rehearsed, ran = _walk(robot, name, solver, True)
    assert none == 0 and ran >= 3
    for i, (a, b) in enumerate(zip(without, rehearsed, strict=True)):
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]), f"tick {i}"
        assert a[2:] == b[2:], f"tick {i}"


@pytest.mark.parametrize("name, solver", [("walk", "hierarchical"), ("walk_strict", "weighted")])
def test_warmed_ticks_walk_as_without(robot, name, solver):
    """walk10 with every tick rehearsed at the end of the idle part before it (``warm_ahead``,
    the switches' rehearsal off): every tick's q, Δq, the limit's closest pair and row count
    bit for bit as without; a warm-up before every tick but the first."""
    without, none = _walk(robot, name, solver, False)
    warmed, ran = _walk(robot, name, solver, False, warm=True)
    assert none == 0 and ran == TICKS
    for i, (a, b) in enumerate(zip(without, warmed, strict=True)):
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]), f"tick {i}"
        assert a[2:] == b[2:], f"tick {i}"


def test_a_rehearsal_puts_back_what_the_tick_wrote(robot, monkeypatch):
    """Around each rehearsal: the arrays of the plan's tick that outlive it (its warm start,
    the solution) and every buffer of the limit whose rows the tick makes but its scratch as
    before it, though the tick wrote some of them on most (else the check is vacuous)."""
    checked = []
    own = rehearsal.rehearse

    def watched(plan, kin, dt):
        placed = plan.constraints.placed
        scratch = (placed.distances._work, placed.distances._iwork)
        kept = [b for b in placed._packed[2] if not any(b is w for w in scratch)]
        buffers = [*rehearsal._state(plan), *kept]
        before = [a.copy() for a in buffers]
        solve = plan.solve
        wrote = []

        def solve_and_look(*args):
            status = solve(*args)
            wrote.append(
                any(
                    not np.array_equal(a, b, equal_nan=True)
                    for a, b in zip(buffers, before, strict=True)
                )
            )
            return status

        plan.solve = solve_and_look
        try:
            ran = own(plan, kin, dt)
        finally:
            del plan.solve
        same = all(
            np.array_equal(a, b, equal_nan=True) for a, b in zip(buffers, before, strict=True)
        )
        checked.append((ran, wrote == [True], same))
        return ran

    monkeypatch.setattr(rehearsal, "rehearse", watched)
    _walk(robot, "walk_strict", "hierarchical", True)
    assert len(checked) >= 3
    assert all(ran and same for ran, _, same in checked), checked
    assert sum(wrote for _, wrote, _ in checked) >= 3, checked  # (it wrote: not vacuous)


def test_a_loop_at_half_the_reference_rate_switches_ahead(robot, monkeypatch):
    """A live loop at 50 Hz plays every other tick of a 100 Hz reference: the idle part
    prepares the tick it will play (the last plus the last gap, at its step), so every support
    switch is made ahead, none in a tick, every landing tick takes its share made ahead, and
    the walk is bit for bit the one without the idle part."""
    ref = build("walk10", robot)
    taken = []
    made_ahead = SwitchHandover._made_ahead

    def watched(self, *args):
        out = made_ahead(self, *args)
        taken.append(out is not None)
        return out

    monkeypatch.setattr(SwitchHandover, "_made_ahead", watched)
    runs = []
    for idle in (False, True):
        controller = StackController(load_stack("walk", robot, solver="hierarchical"))
        control = controller.control
        calls = []

        def counted(*a, own=control.set_phase, calls=calls, **k):
            calls.append(1)
            return own(*a, **k)

        control.set_phase = counted
        session = Session(controller, robot, ref)
        qs, in_tick = [], 0
        for i in range(0, 2 * TICKS, 2):
            before = len(calls)
            qs.append(session.tick(i).copy())
            in_tick += len(calls) - before  # (a switch made in the tick, not ahead)
            assert not session.failed
            if idle:
                session.prepare_next()
                session.warm_next()
        runs.append((qs, in_tick))
    (without, made_in_tick), (with_idle, made_ahead_missed) = runs
    assert made_in_tick >= 5 and made_ahead_missed == 0, runs[0][1]
    landings = taken[len(taken) // 2 :]  # (the second walk's: the first made none ahead)
    assert not any(taken[: len(taken) // 2]) and len(landings) >= 5 and all(landings), taken
    for i, (a, b) in enumerate(zip(without, with_idle, strict=True)):
        assert np.array_equal(a, b), f"tick {2 * i}"
