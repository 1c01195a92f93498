"""The self-collision rows made inside the compiled tick (``in_tick``): one call from Python
for the rows and the solve, every row after them moved by their count in the tick — the
walk's rows and answers bit for bit those of the rows made before the tick."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from wbc.bench.trajectories import build
from wbc.limits import SelfCollisionConstraint
from wbc.model import Kinematics
from wbc.stacks import build_stack, load_stack
from wbc.walking.loop import Session, StackController

TICKS = 150  # (walk10's first touch-down at 104: rows active around it)


def _limit(stack) -> SelfCollisionConstraint:
    """The stack's self-collision limit."""
    constraints = stack.solver.stack.constraints()
    return next(c for c in constraints if isinstance(c, SelfCollisionConstraint))


def _walk(robot, name: str, in_tick: bool, solver: str = "hierarchical"):
    """``name`` along walk10 (:data:`TICKS`) with the limit's ``in_tick``: each tick's Δq, its
    rows level by level (G, h, each constraint's count) and the limit's row count."""
    stack = load_stack(name, robot, solver=solver) if solver else load_stack(name, robot)
    limit = _limit(stack)
    limit.in_tick = in_tick
    controller = StackController(stack)
    fast_solver = controller.solver
    session = Session(controller, robot, build("walk10", robot))
    out = []
    made = 0
    for i in range(TICKS):
        session.tick(i)
        plan = fast_solver.fast
        assert plan.tick_name in ("weighted_tick", "cascade_tick")  # (one tick either way)
        assert plan.constraints.in_tick is in_tick
        blocks = [
            (G.copy(), h.copy(), [s for _, s in sl]) for G, h, sl in plan.constraints.level_blocks()
        ]
        made += limit._n_rows > 0
        out.append((fast_solver.fast.dq.copy(), blocks, limit._n_rows, limit._closest[0]))
    assert fast_solver.handed_back_ticks == 0
    return out, made


@pytest.mark.parametrize("name, solver", [("walk_strict", "hierarchical"), ("walk", "weighted")])
def test_rows_made_in_the_tick_walk_as_the_rows_made_before_it(robot, name, solver):
    """walk10 with the rows made in the tick: every tick's Δq, every level's rows (the
    self-collision rows and those after them: ``walk_strict``'s ground clearance in the same
    level, and the levels below) and counts bit for bit as with the rows made by Python before
    the tick; rows on some ticks (the test would pass vacuously without)."""
    before, made = _walk(robot, name, False, solver)
    inside, _ = _walk(robot, name, True, solver)
    assert made > 10
    for i, (a, b) in enumerate(zip(before, inside, strict=True)):
        np.testing.assert_array_equal(a[0], b[0], err_msg=f"tick {i}")
        assert a[2] == b[2] and a[3] == b[3], i
        for (Ga, ha, sa), (Gb, hb, sb) in zip(a[1], b[1], strict=True):
            assert sa == sb, i
            np.testing.assert_array_equal(Ga, Gb, err_msg=f"tick {i}")
            np.testing.assert_array_equal(ha, hb, err_msg=f"tick {i}")


def test_the_limits_own_call_after_the_tick_finds_the_rows_it_made(robot):
    """After a tick that made the rows, the limit's own :meth:`compute` at the same
    configuration (a hand-back's) gives those rows (its kernel's "same configuration" exit,
    copied from the plan's buffers), and a fresh limit's rows are the same; a tick at that
    configuration after it makes the rows in the plan's buffers again."""
    stack = load_stack("walk_strict", robot)
    limit = _limit(stack)
    limit.in_tick = True
    controller = StackController(stack)
    session = Session(controller, robot, build("walk10", robot))
    for i in range(110):
        session.tick(i)
    plan = controller.solver.fast
    G, h, r0 = limit._where
    r = limit._n_rows
    assert G is plan.inequalities.G and r > 0
    rows = limit.compute(limit._call[0])
    np.testing.assert_array_equal(rows.G, G[r0 : r0 + r])
    np.testing.assert_array_equal(rows.h, h[r0 : r0 + r])
    fresh = SelfCollisionConstraint(robot).compute(limit._call[0])
    np.testing.assert_array_equal(fresh.h, rows.h)
    # the limit's last rows now in its own buffers (compute's): a tick at the same
    # configuration makes them again in the plan's, not the rows it finds there
    G[r0 : r0 + r] = 0.0
    h[r0 : r0 + r] = 0.0
    assert plan.solve(limit._call[0], 0.01) == 0
    np.testing.assert_array_equal(G[r0 : r0 + r], rows.G)
    np.testing.assert_array_equal(h[r0 : r0 + r], rows.h)


def test_the_option_is_on_by_default_and_read_from_the_stack_file(robot):
    """``in_tick``: on unless the stack file says ``false`` (the rows then made before the
    tick); anything but a boolean is one error line."""
    from wbc.exceptions import TaskError

    assert _limit(load_stack("walk_strict", robot)).in_tick is True
    spec = {"solver": "hierarchical", "levels": [{"tasks": [{"type": "com"}], "constraints": [
        {"type": "self_collision", "in_tick": False}]}]}  # fmt: skip
    assert _limit(build_stack(spec, robot)).in_tick is False
    spec["levels"][0]["constraints"][0]["in_tick"] = 1
    with pytest.raises(TaskError, match="in_tick"):
        build_stack(spec, robot)


@pytest.mark.parametrize("name, solver", [("walk_strict", "hierarchical"), ("walk", "weighted")])
def test_one_package_tick_with_or_without_rows_made_in_it(robot, name, solver):
    """The package's stacks share one compiled tick per solver, which workers build: a stack
    whose tick makes the self-collision rows and one without the limit (or with ``in_tick``
    off) call the same function of the same set, the latter with no placed rows
    (``place[P_ROW]`` −1: the placer returns at once)."""
    from wbc.limits.collision_packed import P_ROW
    from wbc.solvers.plan import package_ticks

    q = robot.configuration("stand")

    def plan_of(control):
        control.set_phase("single", "l_sole", "r_sole", Kinematics(robot, q))
        assert control.solver.step(q, 0.01) is not None
        return control.solver.fast

    ticks = package_ticks()
    assert ticks.buildable() and not ticks.split and ticks.placer is not None
    with_rows = plan_of(load_stack(name, robot, solver=solver))
    off = load_stack(name, robot, solver=solver)
    _limit(off).in_tick = False
    without = plan_of(off)
    plain = plan_of(load_stack("cj_com", robot, solver=solver))  # (no constraint)
    for plan in (with_rows, without, plain):
        assert plan.ticks is ticks
        assert plan.tick_name == with_rows.tick_name
    assert with_rows.constraints.in_tick and with_rows.constraints.place[P_ROW] >= 0
    for plan in (without, plain):
        assert not plan.constraints.in_tick and plan.constraints.place[P_ROW] == -1


def test_rows_all_made_in_the_tick_are_laid_out_once_and_walk_as_laid_out_each_tick(
    robot, monkeypatch
):
    """A plan whose rows are all kernel rows (``walk_strict`` without the limit: its ground
    clearance, in single support) is laid out at a change only (``static``, no placed rows):
    walk10's Δq and
    every level's rows bit for bit as with the per-tick layout (the layout of rows from
    Python, forced here)."""
    import tomllib
    from pathlib import Path

    from wbc.solvers.inequalities import ConstraintRows

    spec = tomllib.loads((Path(__file__).parents[1] / "tasks" / "walk_strict.toml").read_text())
    for level in spec["levels"]:
        level["constraints"] = [
            c for c in level.get("constraints", []) if c["type"] != "self_collision"
        ]

    def walk(static: bool):
        controller = StackController(build_stack(spec, robot))
        session = Session(controller, robot, build("walk10", robot))
        out = []
        for i in range(TICKS):
            session.tick(i)
            plan = controller.solver.fast
            if plan.constraints.items:  # (single support: the swing's ground clearance)
                assert plan.constraints.static is static and not plan.constraints.in_tick
            blocks = [(G.copy(), h.copy()) for G, h, _ in plan.constraints.level_blocks()]
            out.append((plan.dq.copy(), blocks))
        return out

    static = walk(True)
    monkeypatch.setattr(ConstraintRows, "_place", ConstraintRows._not_in_tick)
    each_tick = walk(False)
    rows = 0
    for i, (a, b) in enumerate(zip(static, each_tick, strict=True)):
        np.testing.assert_array_equal(a[0], b[0], err_msg=f"tick {i}")
        for (Ga, ha), (Gb, hb) in zip(a[1], b[1], strict=True):
            np.testing.assert_array_equal(Ga, Gb, err_msg=f"tick {i}")
            np.testing.assert_array_equal(ha, hb, err_msg=f"tick {i}")
            rows += ha.shape[0]
    assert rows > 0  # (the ground clearance's rows in single support)
