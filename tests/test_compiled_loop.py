"""The walking loop's tick path: its targets go into the tasks' own arrays in one compiled
call, checked as the setters check them (wbc.compiled.targets.copy_targets)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from wbc.bench.trajectories import build
from wbc.compiled.targets import copy_targets
from wbc.exceptions import TaskError
from wbc.stacks import load_stack
from wbc.tasks import ComTask
from wbc.walking.loop import Session, StackController


def _rotation(rpy) -> np.ndarray:
    return pin.rpy.rpyToMatrix(*rpy)


def test_copy_targets_copies_all_or_nothing():
    v0, v1 = np.array([1.0, 2.0, 3.0]), np.array([-1.0, 0.5, 0.25])
    R0, R1 = _rotation([0.1, 0.2, 0.3]), _rotation([-0.3, 0.0, 1.0])
    outs = [np.zeros(3), np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3)]
    table = np.array(
        [(o.ctypes.data, s) for o, s in zip(outs, (0, 1, 2, 3, 1), strict=True)], dtype=np.int64
    )
    assert copy_targets(v0, v1, R0, R1, table, 1e-6)
    for o, src in zip(outs, (v0, v1, R0, R1, v1), strict=True):
        assert np.array_equal(o, src)
    for o in outs:
        o[...] = 7.0
    bad = [
        (np.array([np.nan, 0.0, 0.0]), v1, R0, R1),
        (v0, np.array([0.0, np.inf, 0.0]), R0, R1),
        (v0, v1, 2.0 * R0, R1),  # not a rotation
        (v0, v1, R0, np.diag([1.0, 1.0, -1.0])),  # a reflection
        (v0, v1, R0, np.full((3, 3), np.nan)),
        (np.array([1e200, 0.0, 0.0]), v1, R0, R1),  # finite, but its square overflows
    ]
    for args in bad:
        assert not copy_targets(*args, table, 1e-6)
        assert all((o == 7.0).all() for o in outs)  # nothing copied


def _session(robot, stack: str = "walk") -> Session:
    return Session(StackController(load_stack(stack, robot)), robot, build("walk10", robot))


def test_a_tick_writes_its_targets_into_the_tasks_arrays(robot):
    session = _session(robot)
    controller = session.controller
    assert controller._writes is not None  # the package's tasks: one compiled call
    com = controller._com[0]
    handle = com.target
    targets = session.targets(150)
    controller._set_targets(session.q, targets, True)
    assert com.target is handle  # never re-bound
    assert np.array_equal(handle, targets.com)
    swing = controller._swing_pose[0]
    assert np.array_equal(swing.target_position, targets.swing_position)
    assert np.array_equal(swing.target_rotation, targets.swing_rotation)
    torso = controller._torso[0]
    assert np.array_equal(torso.target, targets.torso_rotation)


def test_invalid_tick_targets_raise_from_the_setter_and_copy_nothing_first(robot):
    session = _session(robot)
    controller = session.controller
    targets = session.targets(150)
    controller._set_targets(session.q, targets, True)
    com = controller._com[0]
    before = com.target.copy()
    later = session.targets(160)
    bad = dataclasses.replace(later, com=np.array([np.nan, 0.0, 0.2]))
    with pytest.raises(TaskError, match=com.name):
        controller._set_targets(session.q, bad, False)
    assert np.array_equal(com.target, before)
    bad = dataclasses.replace(later, torso_rotation=2.0 * later.torso_rotation)
    with pytest.raises(TaskError, match="not a rotation matrix"):
        controller._set_targets(session.q, bad, False)
    # (the setters ran in order: those before the torso's took their targets, as before)
    assert np.array_equal(com.target, later.com)
    # a target of another type (a list) goes through the setters, which accept it
    listed = dataclasses.replace(later, com=list(later.com + 0.001))
    controller._set_targets(session.q, listed, False)
    assert np.array_equal(com.target, later.com + 0.001)


def test_a_task_with_its_own_setter_keeps_it(robot):
    """A task whose class overrides the setter: the loop calls it (no compiled copy)."""
    calls = []

    class Recorded(ComTask):
        def set_target(self, target) -> None:
            calls.append(np.array(target))
            super().set_target(target)

    control = load_stack("walk", robot)
    com = next(t for t in control.stack.tasks() if isinstance(t, ComTask))
    com.__class__ = Recorded
    session = Session(StackController(control), robot, build("walk10", robot))
    assert session.controller._writes is None
    targets = session.targets(150)
    calls.clear()
    session.controller._set_targets(session.q, targets, False)
    assert len(calls) == 1 and np.array_equal(calls[0], targets.com)


def test_the_compiled_copy_walks_as_the_setters_do(robot):
    """The same walk, bitwise, with the targets copied in one call and set one by one."""
    fast, one_by_one = _session(robot), _session(robot)
    one_by_one.controller._writes = None  # (the setters, as a task with its own would)
    for i in range(0, 200, 3):  # support switches included
        assert np.array_equal(fast.tick(i), one_by_one.tick(i)), i


@pytest.mark.parametrize(
    ("solver", "backend", "rehearsed"), [("hierarchical", None, True), ("weighted", "osqp", False)]
)
def test_the_rehearsed_first_tick_changes_nothing(robot, solver, backend, rehearsed):
    """A session solves its first tick once ahead (Controller.rehearse, the compiled path
    only): the walk is bitwise the one without it, the solver's counts too; OSQP, which starts
    from its last solution, is not rehearsed (it would move the first tick by ~1e-13)."""
    ref = build("walk10", robot)
    sessions, calls = [], []
    for rehearse in (True, False):
        controller = StackController(load_stack("walk", robot, backend=backend, solver=solver))
        if rehearse:
            _count_tracks(controller, calls)
        else:
            controller.rehearse = lambda *a: None  # type: ignore[method-assign]
        sessions.append(Session(controller, robot, ref))
    assert len(calls) == (1 if rehearsed else 0)  # (before the first tick)
    for i in range(100):  # the first support switch included (tick 80)
        assert np.array_equal(sessions[0].tick(i), sessions[1].tick(i)), i
    a, b = (s.controller.solver for s in sessions)
    assert (a.compiled_ticks, a.handed_back_ticks) == (b.compiled_ticks, b.handed_back_ticks)


def _count_tracks(controller: StackController, calls: list) -> None:
    track = controller.track

    def counted(*a):
        calls.append(a[0])
        return track(*a)

    controller.track = counted  # type: ignore[method-assign]
